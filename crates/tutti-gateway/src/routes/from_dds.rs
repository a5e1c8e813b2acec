//! DDS -> shared memory.
//!
//! Each reader's sink ([`sink`], called on the engine's receive path: Cyclone's receive
//! thread, or a task of the rustdds engine) decodes samples and drops the gateway's own.
//! A mirror's sink hands each sample straight to the mirror's thread ([`Target::Mirror`]),
//! which publishes it as the local framework's step. Otherwise each DDS writer that
//! sends to the framework is a [`RemoteWriter`]: a shared-memory connection (marked remote)
//! that commits its samples, so the core's rules apply unchanged — the first writer to
//! publish owns an exclusive set until its connection goes, a synchronous domain waits for
//! its commit of each step (`publish_lock` waits for the step the sample answers), and its
//! first commit seeds a `states=yes` domain.
//!
//! In an asynchronous domain a commit never waits, so the sink commits the sample itself,
//! the moment it is decoded ([`Direct`]): no hand-off to another thread, which on these
//! machines costs tens of µs per sample. In a synchronous domain a commit may wait for the
//! step, which must not hold up the receive path: the sink commits in place when no wait is
//! needed (the sample answers the step the framework is at, the usual case in lock-step),
//! and otherwise hands the sample to the connection's own thread, which waits for the step.
//! The manager sees a sample only when its writer has no connection yet (its first sample,
//! before discovery has listed it): it then gives the writer one.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread;
use std::time::{Duration, Instant};

use tokio::sync::mpsc::UnboundedSender;
use tracing::{debug, info, warn};
use tutti_core::mapping::Qos;
use tutti_core::shm::{ConnectOptions, Participant, SharedState, ShmError};

use super::{Counters, Event, Inbound, ShmConfig};
use crate::cdr::{CdrError, Payload, SetCodec, TypedSample};
use crate::engine::{Data, Decode, EndpointId, Engine, Sink, TopicType};
use crate::stats::{LogLimit, SetStats, Stats};
use crate::GatewayError;

/// The remote writers of one route whose samples the reader's sink commits itself (or, in
/// a synchronous domain, hands to the writer's thread); the manager adds and removes them
/// as discovery changes.
#[derive(Debug, Clone, Default)]
pub struct Direct(Arc<Mutex<HashMap<EndpointId, RemoteWriter>>>);

impl Direct {
    pub fn insert(&self, gid: EndpointId, w: RemoteWriter) {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).insert(gid, w);
    }

    pub fn remove(&self, gid: &EndpointId) {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).remove(gid);
    }

    pub fn clear(&self) {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).clear();
    }

    fn get(&self, gid: &EndpointId) -> Option<RemoteWriter> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner).get(gid).cloned()
    }

    /// Commits `payload` of `writer` here (or hands it straight to the writer's thread in a
    /// synchronous domain) if the writer is known and working; else hands it back.
    pub fn commit(&self, writer: &EndpointId, sample: Sample<'_>) -> Option<Payload> {
        match self.get(writer) {
            Some(w) => w.send(sample).err(),
            None => Some(sample.into_owned()),
        }
    }
}

/// Where a reader's samples go: its route (as the manager knows it), the manager's events,
/// and what takes the samples.
#[derive(Debug, Clone)]
pub struct Destination {
    pub route: usize,
    pub events: UnboundedSender<Event>,
    pub target: Target,
}

/// What takes a reader's samples.
#[derive(Debug, Clone)]
pub enum Target {
    /// The remote writers' connections (a writer not among them yet goes to the manager).
    Writers(Direct),
    /// A mirror's thread, which publishes each sample as a step of its local framework.
    Mirror(Sender<TypedSample>),
}

/// The sink of every reader: a sample (the engine hands over none of the gateway's own)
/// becomes a payload (decoded here when the engine hands over raw bytes), committed right away for
/// the writers in `to.target` (on the engine's receive path: no thread hop) or handed to
/// the mirror's thread; a writer without a connection yet goes to the manager, and what
/// cannot be decoded is reported to it.
pub fn sink(decode: Decode, to: Destination) -> Sink {
    let Destination { route, events, target } = to;
    Arc::new(move |writer: EndpointId, data: Data<'_>| {
        let sample = match data {
            Data::Decoded(r) => r.map(Sample::Owned),
            Data::Raw(raw) => match &decode {
                // Checked here, decoded straight into shared memory by the commit.
                Decode::Set(codec) => codec.check(raw).map(|(le, body)| Sample::Encoded { codec, le, body }),
                Decode::Item(..) | Decode::Raw => Data::Raw(raw).into_payload(&decode).map(Sample::Owned),
            },
        };
        let ev = match (sample, &target) {
            (Ok(sample), Target::Writers(direct)) => {
                let Some(payload) = direct.commit(&writer, sample) else { return };
                Event::Sample(Inbound { route, writer, payload })
            }
            (Ok(sample), Target::Mirror(tx)) => match sample.into_owned() {
                Payload::Set(s) => {
                    // A mirror whose thread has ended is stopping with the gateway.
                    let _ = tx.send(s);
                    return;
                }
                Payload::Item { .. } => {
                    Event::Bad { route, error: CdrError::Unexpected("a per-item sample for a mirror") }
                }
            },
            (Err(error), _) => Event::Bad { route, error },
        };
        let _ = events.send(ev);
    })
}

/// The reader of a DDS -> shared-memory route on ROS 2 topic `topic` (of type `ty`, reader QoS
/// `rq`, samples read by `decode`): its sink decodes each sample on the engine's receive
/// path and delivers it to `to` (see [`sink`]).
pub fn reader(
    dds: &dyn Engine,
    topic: &str,
    ty: &TopicType,
    rq: &Qos,
    decode: Decode,
    to: Destination,
) -> Result<(), GatewayError> {
    let sink = sink(decode.clone(), to);
    Ok(dds.reader(topic, ty, rq, decode, sink)?)
}

/// The shared-memory connection of one remote DDS writer.
#[derive(Debug, Clone)]
pub struct RemoteWriter {
    kind: Kind,
}

#[derive(Debug, Clone)]
enum Kind {
    /// Synchronous domain: committed by the caller when that needs no wait, else by a thread
    /// that waits for the step.
    Thread(Arc<Lockstep>),
    /// Asynchronous domain: committed by the caller.
    Inline(Arc<Mutex<Inline>>),
}

/// Where one remote writer's samples go, and how they are counted and logged: the same
/// for a writer committed inline and for one with its own thread.
#[derive(Debug)]
pub(super) struct Delivery {
    pub(super) domain: String,
    pub(super) name: String,
    /// The gateway's totals and the counters of the set this writer writes.
    pub(super) counters: Counters,
    own_commits: Arc<AtomicU64>,
    refused_log: LogLimit,
    error_log: LogLimit,
    /// Steps of lookahead: a sample answering step n is committed for step n + `ahead`.
    pub(super) ahead: u64,
}

impl Delivery {
    fn new(domain: String, name: String, counters: Counters, own_commits: Arc<AtomicU64>, ahead: u64) -> Self {
        let limit = || LogLimit::new(Duration::from_secs(5));
        Delivery { domain, name, counters, own_commits, refused_log: limit(), error_log: limit(), ahead }
    }

    /// Commits `payload` through `p` (None: the domain is not running, and the sample is
    /// dropped); a connection that cannot go on is dropped (`p` set to None) for the caller
    /// to connect again.
    pub(super) fn deliver(&mut self, p: &mut Option<Participant>, sample: Sample<'_>) {
        let Some(part) = p.as_mut() else {
            SetStats::add(Some(&*self.counters.set), |s| &s.dropped, &self.counters.total.errors, 1);
            if self.error_log.allow().is_some() {
                warn!(domain = %self.domain, "{}: sample dropped: the domain is not running", self.name);
            }
            return;
        };
        let r = commit(part, sample, &self.own_commits, self.ahead);
        self.settle(p, r);
    }

    /// Answers the step locked with the values as they are (a lookahead's first steps, or a
    /// step whose answer never came): a commit of nothing new.
    pub(super) fn hold(&mut self, p: &mut Option<Participant>) {
        if let Some(part) = p.as_mut() {
            let r = part.commit().map(|()| Committed::Held);
            self.settle(p, r);
        }
    }

    /// Counts and logs what became of a commit through `p`; drops a connection that cannot
    /// go on.
    fn settle(&mut self, p: &mut Option<Participant>, r: Result<Committed, ShmError>) {
        let (domain, name, stats) = (&self.domain, &self.name, &*self.counters.total);
        let set = Some(&*self.counters.set);
        let dropped = |total: &AtomicU64| SetStats::add(set, |s| &s.dropped, total, 1);
        match r {
            Ok(Committed::Yes) => SetStats::add(set, |s| &s.samples_in, &stats.from_dds, 1),
            Ok(Committed::Held) => {}
            Ok(Committed::Late) => dropped(&stats.late),
            Err(e @ ShmError::NotOwner { .. }) => {
                dropped(&stats.refused);
                if let Some(held) = self.refused_log.allow() {
                    warn!(domain = %domain, "{name}: sample refused ({held} more since the last report): {e}");
                }
                // A refused connection is flagged as a writer; in a synchronous domain the
                // framework would wait for its commits. Leave, and come back with the next sample.
                if p.as_ref().is_some_and(|part| part.info().flags.synchronous) {
                    *p = None;
                }
            }
            Err(e @ (ShmError::ConnectionLost { .. } | ShmError::FrameworkStopped { .. })) => {
                dropped(&stats.errors);
                info!(domain = %domain, "{name}: {e}; reconnecting");
                *p = None;
            }
            Err(e) => {
                dropped(&stats.errors);
                if let Some(held) = self.error_log.allow() {
                    debug!(domain = %domain, "{name}: sample dropped ({held} more): {e}");
                }
            }
        }
    }
}

/// An asynchronous domain's remote writer, committed by the reader's sink.
#[derive(Debug)]
struct Inline {
    out: Delivery,
    cfg: ShmConfig,
    p: Option<Participant>,
    next_try: Instant,
}

impl Inline {
    /// Connects if not connected; never waits (a domain that is not there is retried at
    /// most every 500 ms).
    fn connect(&mut self) -> bool {
        if self.p.is_none() && Instant::now() >= self.next_try {
            let opts = self.cfg.connect_options(self.out.name.clone(), Duration::ZERO);
            self.p = Participant::connect(&self.out.domain, opts).ok();
            if self.p.is_none() {
                self.next_try = Instant::now() + Duration::from_millis(500);
            }
        }
        self.p.is_some()
    }

    fn send(&mut self, sample: Sample<'_>) {
        self.connect();
        self.out.deliver(&mut self.p, sample);
    }
}

impl RemoteWriter {
    /// Connects to `domain` on behalf of a remote writer (a DDS writer, or a Foxglove client)
    /// whose connection shows `name`: in its own thread when the domain is `synchronous`,
    /// else right here (without waiting; retried on the next sample or
    /// [`RemoteWriter::tick`] if the domain is not there). With a `lookahead` of K steps
    /// (synchronous only), its answer to step n is committed for step n + K
    /// (docs/run.md, "Sites and lookahead").
    pub fn spawn(
        domain: String,
        name: String,
        synchronous: bool,
        lookahead: u32,
        cfg: ShmConfig,
        counters: Counters,
        own_commits: Arc<AtomicU64>,
    ) -> std::io::Result<Self> {
        let ahead = if synchronous { u64::from(lookahead) } else { 0 };
        let out = Delivery::new(domain, name, counters, own_commits, ahead);
        if !synchronous {
            let mut inline = Inline { out, cfg, p: None, next_try: Instant::now() };
            inline.connect();
            return Ok(RemoteWriter { kind: Kind::Inline(Arc::new(Mutex::new(inline))) });
        }
        let (tx, rx) = mpsc::channel();
        let state = Mutex::new(WriterState { out, part: None });
        let shared = Arc::new(LockstepState { pending: AtomicUsize::new(0), state });
        let ls = Arc::new(Lockstep { tx, shared: shared.clone(), ahead: ahead > 0 });
        thread::Builder::new().name("tutti-gw-writer".into()).stack_size(256 << 10).spawn(move || {
            if ahead > 0 {
                super::lookahead::run(shared, rx, &cfg)
            } else {
                run(&shared, rx, cfg)
            }
        })?;
        Ok(RemoteWriter { kind: Kind::Thread(ls) })
    }

    /// Commits a sample (inline) or hands it to the connection's thread; hands it back when
    /// that thread has gone.
    pub fn send(&self, sample: Sample<'_>) -> Result<(), Payload> {
        match &self.kind {
            Kind::Thread(ls) => ls.send(sample),
            Kind::Inline(i) => {
                i.lock().unwrap_or_else(PoisonError::into_inner).send(sample);
                Ok(())
            }
        }
    }

    /// Retries a connection that failed (inline writers; a thread retries by itself).
    pub fn tick(&self) {
        if let Kind::Inline(i) = &self.kind {
            i.lock().unwrap_or_else(PoisonError::into_inner).connect();
        }
    }
}

/// A synchronous domain's remote writer: its connection, committed in place by the reader's
/// sink whenever that needs no wait (the framework is at the step the sample answers, the
/// usual case in lock-step: no thread hop), else by its own thread, which waits for the step.
/// Dropping it (with every clone of its [`RemoteWriter`]) ends the thread, which then releases
/// the connection.
#[derive(Debug)]
struct Lockstep {
    tx: Sender<(Payload, Instant)>,
    shared: Arc<LockstepState>,
    /// It has a lookahead: every sample goes to the thread, which commits it K steps on.
    ahead: bool,
}

/// What the sink and the thread share.
#[derive(Debug)]
pub(super) struct LockstepState {
    /// Samples handed to the thread and not yet committed: while any are, later samples
    /// follow them there, so that they are committed in order.
    pub(super) pending: AtomicUsize,
    pub(super) state: Mutex<WriterState>,
}

#[cfg(test)]
impl LockstepState {
    /// A writer's shared state with no connection, K steps of lookahead.
    pub(super) fn for_tests(ahead: u64) -> Arc<LockstepState> {
        let counters = Counters { total: Arc::default(), set: Arc::default() };
        let out = Delivery::new("d".into(), "w".into(), counters, Arc::default(), ahead);
        Arc::new(LockstepState { pending: AtomicUsize::new(0), state: Mutex::new(WriterState { out, part: None }) })
    }
}

/// A synchronous remote writer's delivery and its connection (None: not connected).
#[derive(Debug)]
pub(super) struct WriterState {
    pub(super) out: Delivery,
    pub(super) part: Option<Participant>,
}

impl Lockstep {
    fn send(&self, sample: Sample<'_>) -> Result<(), Payload> {
        let sh = &self.shared;
        if !self.ahead && sh.pending.load(Ordering::Acquire) == 0 {
            if let Ok(mut st) = sh.state.try_lock() {
                let WriterState { out, part } = &mut *st;
                if part.as_ref().is_some_and(Participant::publish_ready) && sh.pending.load(Ordering::Acquire) == 0 {
                    out.deliver(part, sample);
                    return Ok(());
                }
            }
        }
        sh.pending.fetch_add(1, Ordering::AcqRel);
        self.tx.send((sample.into_owned(), Instant::now())).map_err(|e| {
            sh.pending.fetch_sub(1, Ordering::AcqRel);
            e.0 .0
        })
    }
}

/// The thread of a synchronous domain's remote writer: commits each sample it is handed
/// (waiting for its step), connecting again whenever the connection is gone. A writer that
/// owes the framework its answer to a step and sends nothing for `cfg.lease` (killed, or
/// hung) has its connection released, so that the domain stops waiting for it; its next
/// sample connects it again.
fn run(ls: &LockstepState, rx: Receiver<(Payload, Instant)>, cfg: ShmConfig) {
    let connect = |out: &Delivery| connect(out, &cfg, None);
    {
        let mut st = ls.state.lock().unwrap_or_else(PoisonError::into_inner);
        let WriterState { out, part } = &mut *st;
        *part = connect(out);
    }
    // The step found owed, and since when; whether the lease released the connection.
    let mut owing: Option<(u64, Instant)> = None;
    let mut lapsed = false;
    let check = (cfg.lease / 4).clamp(Duration::from_millis(10), Duration::from_millis(100));
    loop {
        let connected = ls.state.lock().unwrap_or_else(PoisonError::into_inner).part.is_some();
        let msg = rx.recv_timeout(if connected { check } else { Duration::from_millis(500) });
        let mut st = ls.state.lock().unwrap_or_else(PoisonError::into_inner);
        let WriterState { out, part: p } = &mut *st;
        match msg {
            Ok((payload, _)) => {
                lapsed = false;
                if p.is_none() {
                    *p = connect(out);
                }
                out.deliver(p, Sample::Owned(payload));
                ls.pending.fetch_sub(1, Ordering::AcqRel);
            }
            Err(RecvTimeoutError::Timeout) => match p.as_ref().map(Participant::owed_step) {
                // Not connected: connect again, unless the lease let it go (then only a
                // sample brings it back).
                None if !lapsed => *p = connect(out),
                None => {}
                Some(None) => owing = None,
                Some(Some(k)) => match owing {
                    Some((s, since)) if s == k && since.elapsed() >= cfg.lease => {
                        info!(
                            domain = %out.domain,
                            "{}: sent nothing for {:?} while step {k} waited for its answer: its lock-step share is released (its next sample joins it again)",
                            out.name, cfg.lease
                        );
                        Stats::add(&out.counters.total.lapsed, 1);
                        *p = None;
                        lapsed = true;
                        owing = None;
                    }
                    Some((s, _)) if s == k => {}
                    _ => owing = Some((k, Instant::now())),
                },
            },
            Err(RecvTimeoutError::Disconnected) => break,
        }
    }
}

/// The connection of a synchronous domain's remote writer, or None (the domain is not there);
/// with `state`, one that keeps a state (a lookahead's queue).
pub(super) fn connect(out: &Delivery, cfg: &ShmConfig, state: Option<SharedState>) -> Option<Participant> {
    let opts = ConnectOptions { state, ..cfg.connect_options(out.name.clone(), Duration::from_millis(100)) };
    let mut p = Participant::connect(&out.domain, opts).ok()?;
    if p.info().flags.event {
        // In an event-driven domain a DDS writer is due where its inputs changed, and its
        // sample answers the step (docs/timing.md).
        p.wake_on_change_writer();
    }
    Some(p)
}

/// What became of a sample.
enum Committed {
    Yes,
    /// No sample: the step was answered with the values as they were.
    Held,
    /// It answers a step the framework has already left (it timed out waiting).
    Late,
}

fn commit(p: &mut Participant, sample: Sample<'_>, own_commits: &AtomicU64, ahead: u64) -> Result<Committed, ShmError> {
    if p.info().flags.synchronous {
        // Waits for the step this sample answers (a seed needs none), `ahead` steps on with
        // a lookahead. A sample answering an earlier step is not committed for the current
        // one, or every later step would get its predecessor's answer; the lock alone makes
        // the connection a writer, so the framework waits for the next answer.
        let locked = p.publish_lock()?;
        if let Some(step) = sample.step() {
            if step != 0 && step.saturating_add(ahead) < locked {
                return Ok(Committed::Late);
            }
        }
    }
    own_commits.fetch_add(1, Ordering::AcqRel);
    let r = match sample {
        Sample::Owned(Payload::Set(s)) => {
            let staging = p.staging_mut();
            if staging.len() == s.data.len() {
                staging.copy_from_slice(&s.data);
            }
            p.commit()
        }
        Sample::Owned(Payload::Item { path, bytes }) => p.stage(&path, &bytes).and_then(|()| p.commit()),
        // Decoded straight into the slot being filled: no copy on the way.
        Sample::Encoded { codec, le, body } => p.commit_all_with(|_, out| {
            let _ = codec.decode_into(le, body, out);
        }),
    };
    if r.is_err() {
        own_commits.fetch_sub(1, Ordering::AcqRel);
    }
    r.map(|()| Committed::Yes)
}

/// A sample on its way to a commit: decoded already, or a typed set still in its CDR body
/// (checked: long enough, plain CDR), decoded by the commit straight into shared memory.
#[derive(Debug)]
pub enum Sample<'a> {
    Owned(Payload),
    Encoded { codec: &'a SetCodec, le: bool, body: &'a [u8] },
}

impl Sample<'_> {
    /// The step a typed sample answers.
    pub(super) fn step(&self) -> Option<u64> {
        match self {
            Sample::Owned(Payload::Set(s)) => Some(s.step),
            Sample::Owned(Payload::Item { .. }) => None,
            Sample::Encoded { codec, le, body } => Some(codec.step(*le, body)),
        }
    }

    /// The sample as a [`Payload`], for a hand-off to another thread.
    fn into_owned(self) -> Payload {
        match self {
            Sample::Owned(p) => p,
            Sample::Encoded { codec, le, body } => Payload::Set(codec.decode_body(le, body)),
        }
    }
}
