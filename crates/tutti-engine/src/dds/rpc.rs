//! ROS 2 services over DDS (docs/ros2.md, "Wire forms"): service `/NS/NAME` is the request
//! topic `rq/NS/NAMERequest` and the reply topic `rr/NS/NAMEReply`, with the types
//! `PKG::srv::dds_::SRV_Request_` and `…_Response_` and rmw's services QoS, in either of two
//! forms, chosen request by request:
//!
//! * rmw_cyclonedds's: each sample's body starts with a 16-byte request header (the client's
//!   64-bit writer id and the request's sequence number), which the reply echoes;
//! * Fast DDS's (rmw_fastrtps, ros2-client's `Enhanced` mapping): no header; the request is
//!   named by its own sample identity, and the reply carries it as its related sample
//!   identity (only an engine that reads and writes sample identities serves it: rustdds).
//!
//! A reliable, volatile writer gives a reader it has not matched nothing, and a client finds
//! the service once *it* has discovered the server, which may be before the server has
//! discovered the client's reply reader. So a response is written only once it reaches its
//! client: as many readers of the client's participant as the participant has request
//! writers (clients) of the service are in step with the reply writer, where the engine can
//! say so (rustdds: each has answered one of the writer's heartbeats; a Cyclone DDS reader
//! that has matched but not yet seen a heartbeat skips what was written before the first one
//! it sees, so a reply written then and lost on the way would never be repaired), else as
//! discovery shows them (Cyclone, whose writers keep that handshake themselves). Until then it
//! is held, and the engine's reply thread (`tutti-dds-replies`) writes it as soon as it
//! reaches. After [`REPLY_WAIT`] it is written anyway (in case the count is wrong) but still
//! kept, and written again once it reaches, for as long as the client is there and at most
//! [`REPLY_KEEP`]: a reply must reach a client that is still waiting, however late the
//! gateway's side of discovery is (a ROS 2 client ignores a second reply to a request it has
//! its answer to).

use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tutti_core::cdr::{split_header, CdrError};
use tutti_core::mapping::Qos;

use super::{endpoint, CYCLONE_VENDOR};
use crate::{EndpointId, EngineError, PeerId, Remote, Request, RequestSink, Responder};

/// How long a response is held for a client whose reply reader has not matched yet (a
/// client finds the service once it has discovered the gateway's endpoints, which may be
/// before the gateway has discovered the client's: seconds on a loaded machine); after this
/// long it is written anyway.
pub(crate) const REPLY_WAIT: Duration = Duration::from_secs(30);
/// How long a response written anyway is kept, to be written again once it reaches its client
/// (as long as the client's request writer is there).
pub(crate) const REPLY_KEEP: Duration = Duration::from_secs(180);
/// How often held responses are looked at while there are some.
const RETRY_EVERY: Duration = Duration::from_millis(5);
/// How often responses written anyway, and kept, are looked at.
const TICK_EVERY: Duration = Duration::from_millis(100);
/// Responses held at once per service; more are dropped (a client that floods a service
/// gets no answer to the excess, the gateway keeps its memory).
const MAX_HELD: usize = 256;

/// rmw's services default (`tutti_ros2::simulation::services_qos`).
pub(crate) fn qos() -> Qos {
    tutti_ros2::simulation::services_qos()
}

/// A sample's identity on the wire: the GUID of its writer and the writer's sequence number
/// for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct SampleIdentity {
    pub writer: [u8; 16],
    pub sequence: i64,
}

/// The request header at the start of a body in rmw_cyclonedds's form.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct RequestHeader {
    /// The client's request writer, as rmw_cyclonedds names it (its instance handle).
    pub client: u64,
    pub sequence: i64,
}

impl RequestHeader {
    /// Its size: the request's own fields start here (16 is a multiple of every CDR
    /// alignment, so they keep theirs).
    pub const LEN: usize = 16;

    /// The header at the start of `body`, in the sample's byte order.
    pub fn read(le: bool, body: &[u8]) -> Result<RequestHeader, CdrError> {
        let word = |at: usize| -> Result<u64, CdrError> {
            let b: [u8; 8] =
                body.get(at..at + 8).and_then(|b| b.try_into().ok()).ok_or(CdrError::Truncated { len: body.len() })?;
            Ok(if le { u64::from_le_bytes(b) } else { u64::from_be_bytes(b) })
        };
        Ok(RequestHeader { client: word(0)?, sequence: word(8)? as i64 })
    }

    /// The header, little-endian (a reply's body is).
    pub fn bytes(&self) -> [u8; Self::LEN] {
        let mut b = [0u8; Self::LEN];
        b[..8].copy_from_slice(&self.client.to_le_bytes());
        b[8..].copy_from_slice(&self.sequence.to_le_bytes());
        b
    }
}

/// How a response names its request: the two wire forms.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Form {
    /// rmw_cyclonedds's: the request header, echoed at the start of the response's body.
    Header(RequestHeader),
    /// Fast DDS's: the response carries this as its related sample identity.
    Related(SampleIdentity),
}

/// Whom a response goes to ([`crate::ReplyTo`] of a DDS engine).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ReplyTo {
    /// The client's request writer: its participant is the one whose reply reader must match.
    pub client: EndpointId,
    pub form: Form,
}

/// One request sample as a DDS engine reads it.
#[derive(Debug)]
pub(crate) struct Incoming<'a> {
    /// The writer's GUID.
    pub writer: [u8; 16],
    /// The writer's sequence number for the sample; None where the engine does not read it
    /// (Cyclone: then only rmw_cyclonedds's form is served).
    pub sequence: Option<i64>,
    /// The related sample identity it carries, if any (always None where the engine does not
    /// read it).
    pub related: Option<SampleIdentity>,
    /// The serialized sample, encapsulation header included.
    pub raw: &'a [u8],
}

impl Incoming<'_> {
    /// The form of this request, whose body (after the encapsulation header) is `body`:
    /// * an engine that reads no sample identity (Cyclone) serves rmw_cyclonedds's form only;
    /// * a request that carries a related sample identity is in Fast DDS's form (rmw_fastrtps
    ///   sets one on every request: the GUID of its reply reader), and its reply goes to that
    ///   GUID (its own writer's if the identity names none) with the request's sequence number;
    /// * otherwise a request written by a Cyclone DDS participant (its GUID prefix starts with
    ///   Cyclone's vendor id) is in rmw_cyclonedds's form, and any other (ros2-client's
    ///   `Enhanced` clients write no related identity) in Fast DDS's.
    pub fn form(&self, le: bool, body: &[u8]) -> Result<Form, CdrError> {
        let Some(sequence) = self.sequence else { return RequestHeader::read(le, body).map(Form::Header) };
        match self.related {
            Some(r) => {
                let writer = if r.writer == [0; 16] { self.writer } else { r.writer };
                Ok(Form::Related(SampleIdentity { writer, sequence }))
            }
            None if self.writer[..2] == CYCLONE_VENDOR => RequestHeader::read(le, body).map(Form::Header),
            None => Ok(Form::Related(SampleIdentity { writer: self.writer, sequence })),
        }
    }
}

/// Hands a request sample to `sink` as a [`Request`]: its body past the header of its form.
/// A sample that is not plain CDR, or lacks its header, is dropped.
pub(crate) fn deliver(sample: Incoming<'_>, sink: &RequestSink) {
    let Ok((le, body)) = split_header(sample.raw) else {
        tracing::debug!("services: a request that is not plain CDR dropped");
        return;
    };
    let Ok(form) = sample.form(le, body) else {
        tracing::debug!("services: a request without its header dropped");
        return;
    };
    let fields = match form {
        Form::Header(_) => &body[RequestHeader::LEN..],
        Form::Related(_) => body,
    };
    tracing::debug!("services: a request from {:?}, {form:?}", endpoint(sample.writer));
    let reply_to = crate::ReplyTo(crate::Route::Dds(ReplyTo { client: endpoint(sample.writer), form }));
    sink(Request { client: endpoint(sample.writer), little_endian: le, body: fields, reply_to });
}

/// What a DDS engine's reply writer does for the responder.
pub(crate) trait ReplyWriter: Send {
    /// Writes a little-endian CDR body; false when DDS refused it.
    fn write(&mut self, body: &[u8]) -> bool;
    /// Writes a body carrying `related` as its related sample identity; false when refused or
    /// when the engine cannot (Cyclone).
    fn write_related(&mut self, body: &[u8], related: SampleIdentity) -> bool {
        let _ = (body, related);
        false
    }
    /// How many readers of `peer` a sample written now reaches (matched, and in step with
    /// the writer); None where the engine cannot say (then discovery decides).
    fn reaching_readers_of(&mut self, peer: PeerId) -> Option<usize> {
        let _ = peer;
        None
    }
    /// Sends what batching held back.
    fn flush(&mut self) {}
}

/// The engine's discovery, by DDS topic name (services' `rq/` and `rr/` topics included).
pub(crate) type Discovery = Arc<dyn Fn() -> Remote + Send + Sync>;

/// A response waiting for its client's reply reader.
struct Held {
    to: ReplyTo,
    body: Vec<u8>,
    /// When it is written anyway.
    until: Instant,
    /// Written anyway already: kept only to be written again once it reaches.
    written: bool,
}

/// One served service's response side.
struct Server {
    request_topic: String,
    reply_topic: String,
    writer: Box<dyn ReplyWriter>,
    held: Vec<Held>,
}

impl Server {
    /// Whether a response written now reaches every client of the service in participant
    /// `peer`: each (a request writer there) has its reply reader, which the writer has
    /// matched (or, where the engine cannot say, discovery shows). A node may make a new
    /// client of the same service at any time, so this is counted afresh for every response.
    fn reaches(&mut self, remote: &Remote, peer: PeerId) -> bool {
        let clients = remote.writers_on(&self.request_topic).filter(|g| g.peer == peer).count().max(1);
        let readers = match self.writer.reaching_readers_of(peer) {
            Some(n) => n,
            None => {
                remote.readers_on(std::slice::from_ref(&self.reply_topic)).iter().filter(|g| g.peer == peer).count()
            }
        };
        readers >= clients
    }

    /// Writes `body` in the form of `to`.
    fn write(&mut self, to: &ReplyTo, body: &[u8]) {
        let written = match to.form {
            Form::Header(h) => self.writer.write(&[&h.bytes()[..], body].concat()),
            Form::Related(related) => self.writer.write_related(body, related),
        };
        if !written {
            tracing::warn!("services: DDS refused a reply on {}", self.reply_topic);
        } else {
            tracing::debug!("services: replied to {:?} on {}", to.client, self.reply_topic);
        }
        self.writer.flush();
    }

    /// Sends the held responses that reach their client now, or whose wait is over; forgets
    /// those written anyway whose client has gone, or which were kept [`REPLY_KEEP`].
    fn send_held(&mut self, remote: &Remote, now: Instant) {
        let held = std::mem::take(&mut self.held);
        for mut h in held {
            if self.reaches(remote, h.to.client.peer) {
                if h.written {
                    tracing::info!(
                        "services: the reply to {:?} on {} reaches it now; written again",
                        h.to.client,
                        self.reply_topic
                    );
                }
                self.write(&h.to, &h.body);
                continue;
            }
            if !h.written && now >= h.until {
                tracing::warn!(
                    "services: after {} s the reply reader of {:?} on {} is still not matched; replied anyway, and \
                     again once it is",
                    REPLY_WAIT.as_secs(),
                    h.to.client,
                    self.reply_topic
                );
                self.write(&h.to, &h.body);
                h.written = true;
            }
            let gone = !remote.writers_on(&self.request_topic).any(|g| g.peer == h.to.client.peer);
            if h.written && (gone || now >= h.until + (REPLY_KEEP - REPLY_WAIT)) {
                continue;
            }
            self.held.push(h);
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// What the responders and the reply thread share.
struct Shared {
    discovery: Discovery,
    /// Every responder's server, looked at by the thread.
    waiting: Mutex<Waiting>,
    wake: Condvar,
}

#[derive(Default)]
struct Waiting {
    servers: Vec<Weak<Mutex<Server>>>,
    /// Some responses are held.
    held: bool,
    stop: bool,
}

/// The response side of every service a DDS engine serves, and the thread that writes held
/// responses: one per engine, stopped when it is dropped.
pub(crate) struct Replies {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Replies {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Replies").finish_non_exhaustive()
    }
}

impl Replies {
    /// Starts the reply thread over the engine's `discovery`.
    pub fn start(discovery: Discovery) -> Result<Replies, EngineError> {
        let shared = Arc::new(Shared { discovery, waiting: Mutex::default(), wake: Condvar::new() });
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("tutti-dds-replies".into())
            .spawn(move || retry(&s))
            .map_err(EngineError::Runtime)?;
        Ok(Replies { shared, thread: Some(thread) })
    }

    /// The responder of a service whose DDS request and reply topics are `request_topic` and
    /// `reply_topic`, writing with `writer`.
    pub fn responder(&self, request_topic: String, reply_topic: String, writer: Box<dyn ReplyWriter>) -> DdsResponder {
        let server = Arc::new(Mutex::new(Server { request_topic, reply_topic, writer, held: Vec::new() }));
        lock(&self.shared.waiting).servers.push(Arc::downgrade(&server));
        DdsResponder { server, shared: self.shared.clone() }
    }
}

impl Drop for Replies {
    fn drop(&mut self) {
        lock(&self.shared.waiting).stop = true;
        self.shared.wake.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The reply thread: ticks every reply writer, and while some responses are held, looks at
/// discovery once per round and sends those that reach their clients now.
fn retry(shared: &Shared) {
    loop {
        let servers: Vec<Arc<Mutex<Server>>> = {
            let mut w = lock(&shared.waiting);
            if w.stop {
                return;
            }
            let every = if w.held { RETRY_EVERY } else { TICK_EVERY };
            w = shared.wake.wait_timeout(w, every).map_or_else(|e| e.into_inner().0, |(w, _)| w);
            if w.stop {
                return;
            }
            w.servers.retain(|s| s.strong_count() > 0);
            w.servers.iter().filter_map(Weak::upgrade).collect()
        };
        let mut remote = None;
        let mut held = false;
        let now = Instant::now();
        for s in servers {
            let mut s = lock(&s);
            if !s.held.is_empty() {
                // One look at discovery for them all.
                let remote = remote.get_or_insert_with(|| (shared.discovery)());
                s.send_held(remote, now);
                // Replies written anyway are looked at every tick only.
                held |= s.held.iter().any(|h| !h.written);
            }
        }
        lock(&shared.waiting).held = held;
    }
}

/// A DDS engine's [`Responder`].
pub(crate) struct DdsResponder {
    server: Arc<Mutex<Server>>,
    shared: Arc<Shared>,
}

impl Responder for DdsResponder {
    fn respond(&mut self, to: &crate::ReplyTo, body: &[u8]) {
        let crate::Route::Dds(to) = to.0 else {
            return tracing::warn!("services: a response addressed as Zenoh addresses it dropped");
        };
        let remote = (self.shared.discovery)();
        let mut server = lock(&self.server);
        if server.reaches(&remote, to.client.peer) {
            return server.write(&to, body);
        }
        if server.held.len() >= MAX_HELD {
            tracing::warn!("services: {MAX_HELD} replies wait for their clients already; one dropped");
            return;
        }
        tracing::debug!("services: a reply to {:?} on {} held for its reader", to.client, server.reply_topic);
        server.held.push(Held { to, body: body.to_vec(), until: Instant::now() + REPLY_WAIT, written: false });
        drop(server);
        lock(&self.shared.waiting).held = true;
        self.shared.wake.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(writer: [u8; 2], sequence: Option<i64>, related: Option<SampleIdentity>) -> Incoming<'static> {
        let mut g = [7u8; 16];
        g[..2].copy_from_slice(&writer);
        Incoming { writer: g, sequence, related, raw: &[] }
    }

    #[test]
    fn the_header_is_read_in_either_order_and_echoed_in_little_endian() {
        let mut be = Vec::new();
        be.extend_from_slice(&0x0102_0304_0506_0708u64.to_be_bytes());
        be.extend_from_slice(&9i64.to_be_bytes());
        let h = RequestHeader::read(false, &be).unwrap();
        assert_eq!(h, RequestHeader { client: 0x0102_0304_0506_0708, sequence: 9 });
        let out = h.bytes();
        assert_eq!(&out[..8], &0x0102_0304_0506_0708u64.to_le_bytes());
        assert_eq!(&out[8..], &9i64.to_le_bytes());
        assert!(RequestHeader::read(true, &be[..12]).is_err());
    }

    #[test]
    fn each_request_is_answered_in_its_own_form() {
        let mut header = Vec::new();
        header.extend_from_slice(&0x0102_0304_0506_0708u64.to_le_bytes());
        header.extend_from_slice(&9i64.to_le_bytes());
        let cyclone_header = Form::Header(RequestHeader { client: 0x0102_0304_0506_0708, sequence: 9 });
        // The Cyclone engine reads no identity: rmw_cyclonedds's form whoever writes.
        assert_eq!(sample([0x01, 0x0f], None, None).form(true, &header).unwrap(), cyclone_header);
        // A Cyclone DDS client, no related identity: rmw_cyclonedds's form.
        assert_eq!(sample(CYCLONE_VENDOR, Some(3), None).form(true, &header).unwrap(), cyclone_header);
        // ros2-client's Enhanced client (rustdds): its own identity.
        let s = sample([0x01, 0x12], Some(3), None);
        assert_eq!(s.form(true, &header).unwrap(), Form::Related(SampleIdentity { writer: s.writer, sequence: 3 }));
        // rmw_fastrtps: the reply reader's GUID in the related identity, the sequence number unknown.
        let reader = [9u8; 16];
        let unknown = SampleIdentity { writer: reader, sequence: -(1 << 32) };
        let s = sample([0x01, 0x0f], Some(5), Some(unknown));
        assert_eq!(s.form(true, &header).unwrap(), Form::Related(SampleIdentity { writer: reader, sequence: 5 }));
        // A related identity wins over the vendor; one that names no writer names the request's.
        let none = SampleIdentity { writer: [0; 16], sequence: 0 };
        let s = sample(CYCLONE_VENDOR, Some(6), Some(none));
        assert_eq!(s.form(true, &header).unwrap(), Form::Related(SampleIdentity { writer: s.writer, sequence: 6 }));
        // rmw_cyclonedds's form without its header is refused.
        assert!(sample(CYCLONE_VENDOR, Some(1), None).form(true, &header[..8]).is_err());
    }

    #[test]
    fn a_request_reaches_the_sink_without_its_header() {
        let got = Arc::new(Mutex::new(Vec::new()));
        let g = got.clone();
        let sink: RequestSink = Arc::new(move |r: Request<'_>| lock(&g).push((r.body.to_vec(), r.reply_to)));
        let mut raw = vec![0, 1, 0, 0];
        raw.extend_from_slice(&5u64.to_le_bytes());
        raw.extend_from_slice(&2i64.to_le_bytes());
        raw.extend_from_slice(&42u64.to_le_bytes());
        let writer = {
            let mut w = [3u8; 16];
            w[..2].copy_from_slice(&CYCLONE_VENDOR);
            w
        };
        deliver(Incoming { writer, sequence: None, related: None, raw: &raw }, &sink);
        deliver(Incoming { writer, sequence: None, related: None, raw: &raw[..10] }, &sink);
        let got = lock(&got);
        assert_eq!(got.len(), 1, "the sample without its header is dropped");
        assert_eq!(got[0].0, 42u64.to_le_bytes());
        let form = Form::Header(RequestHeader { client: 5, sequence: 2 });
        assert_eq!(got[0].1, crate::ReplyTo(crate::Route::Dds(ReplyTo { client: endpoint(writer), form })));
    }

    /// A reply writer that counts its writes, with as many matched readers as the test says.
    struct Counting {
        writes: Arc<Mutex<usize>>,
        matched: Arc<Mutex<usize>>,
    }

    impl ReplyWriter for Counting {
        fn write(&mut self, _: &[u8]) -> bool {
            *lock(&self.writes) += 1;
            true
        }
        fn reaching_readers_of(&mut self, _: PeerId) -> Option<usize> {
            Some(*lock(&self.matched))
        }
    }

    #[test]
    fn a_reply_written_anyway_is_written_again_once_it_reaches_while_its_client_is_there() {
        let (writes, matched) = (Arc::new(Mutex::new(0)), Arc::new(Mutex::new(0)));
        let writer = Counting { writes: writes.clone(), matched: matched.clone() };
        let mut server = Server {
            request_topic: "rq/xRequest".into(),
            reply_topic: "rr/xReply".into(),
            writer: Box::new(writer),
            held: Vec::new(),
        };
        let client = endpoint([1; 16]);
        let mut remote = Remote::default();
        remote.writers.entry("rq/xRequest".into()).or_default().insert(client);
        let to = ReplyTo { client, form: Form::Header(RequestHeader { client: 1, sequence: 1 }) };
        let t0 = Instant::now();
        let held = |until| Held { to, body: vec![0; 4], until, written: false };
        server.held.push(held(t0 + REPLY_WAIT));
        // Not matched, not due: kept, not written.
        server.send_held(&remote, t0);
        assert_eq!((*lock(&writes), server.held.len()), (0, 1));
        // Due: written anyway, and kept.
        server.send_held(&remote, t0 + REPLY_WAIT);
        assert_eq!((*lock(&writes), server.held.len()), (1, 1));
        server.send_held(&remote, t0 + REPLY_WAIT + Duration::from_secs(1));
        assert_eq!((*lock(&writes), server.held.len()), (1, 1), "written anyway once only");
        // The reader matches late: written again, and forgotten.
        *lock(&matched) = 1;
        server.send_held(&remote, t0 + REPLY_WAIT + Duration::from_secs(5));
        assert_eq!((*lock(&writes), server.held.len()), (2, 0));

        // A reply written anyway whose client has gone is forgotten; one kept too long as well.
        *lock(&matched) = 0;
        server.held.push(held(t0));
        server.send_held(&remote, t0);
        assert_eq!((*lock(&writes), server.held.len()), (3, 1));
        server.send_held(&Remote::default(), t0 + Duration::from_secs(1));
        assert!(server.held.is_empty(), "the client has gone");
        server.held.push(held(t0));
        server.send_held(&remote, t0);
        server.send_held(&remote, t0 + REPLY_KEEP);
        assert!(server.held.is_empty(), "kept REPLY_KEEP at most");
        assert_eq!(*lock(&writes), 4);
    }
}
