//! ROS 2 `simulation_interfaces` services on the gateway (docs/ros2.md): under the gateway's
//! ROS namespace, `get_simulator_features`, `get_simulation_state`, `set_simulation_state`,
//! `step_simulation` and `reset_simulation`, and the action `simulate_steps` ([`action`]),
//! each call carried out on the run's control plane ([`lifecycle`]) as `tutti ctl` would. Offered by a gateway in or beside a framework, not by
//! a mirror nor a passive gateway (`--passive`).
//!
//! A service is a request topic and a reply topic ([`wire`]), in either of two forms: rmw_cyclonedds's,
//! each sample's body starting with a 16-byte request header that the reply echoes, and Fast
//! DDS's, where the reply carries the request's sample identity as its related sample identity
//! (the rustdds engine serves both, choosing per request; Cyclone's, the first only). It is
//! built over the engine layer's identified readers and related writers: a reader's sink only checks a
//! request and hands it to the services' thread (`tutti-gw-simif`), which makes the control
//! calls (they block: never on the engine's receive path nor on the manager's loop), encodes
//! the response and writes it.

pub mod action;
pub mod lifecycle;
pub mod messages;
pub mod wire;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tutti_core::cdr::split_header;
use tutti_core::ddf::Model;

use crate::engine::{Engine, Guid, Identified, Remote, Writer, PREFIX_LEN};
use crate::GatewayError;
use lifecycle::{Control, Lifecycle, RunControl};
use messages::{Body, Out, Outcome};
use wire::{ReplyTo, Service, SERVICES};

/// Requests waiting for the services' thread; more are dropped (a client that floods the
/// services gets no answer to the excess, the gateway keeps its memory).
const QUEUE: usize = 256;
/// The longest wait for an answer of the run (`step N` is answered after its N steps).
const CONTROL_TIMEOUT: Duration = Duration::from_secs(300);
/// How long a goal's feedback waits for discovery to show the client's feedback reader: a
/// reliable, volatile writer gives a reader it has not matched yet nothing.
const READER_WAIT: Duration = Duration::from_secs(2);
/// How long a reply is kept for a client whose reply reader discovery has not shown yet (a
/// client finds the service once it has discovered the gateway's endpoints, which may be
/// before the gateway has discovered the client's: seconds on a loaded machine). Meanwhile
/// the services' thread answers other requests; the reply goes as soon as the reader shows,
/// or, after this long, is written anyway.
const REPLY_WAIT: Duration = Duration::from_secs(30);

/// What the services' thread is handed.
#[derive(Debug)]
pub enum Msg {
    Call(Call),
    /// A goal of the action has ended: its waiting `get_result` requests are answered.
    Done(action::GoalId),
}

/// One request as the services' thread gets it.
#[derive(Debug)]
pub struct Call {
    service: usize,
    /// The request writer's GUID: its prefix is the client's participant.
    client: Guid,
    /// How the reply names the request (the wire form).
    reply_to: ReplyTo,
    le: bool,
    /// The body, request header included in rmw_cyclonedds's form.
    body: Vec<u8>,
}

/// The reply side of one service.
struct Server {
    service: &'static Service,
    request_topic: String,
    reply_topic: String,
    writer: Box<dyn Writer>,
}

/// Why stepping cannot apply to a run of `model`: every domain is asynchronous.
pub fn no_stepping(model: &Model) -> Option<String> {
    if model.domains.iter().any(|d| d.flags.synchronous) {
        return None;
    }
    let names: Vec<&str> = model.domains.iter().map(|d| d.name.as_str()).collect();
    Some(format!(
        "every domain of this run is asynchronous ({}): their participants do not step with the framework, so \
         there is no step to count; set the state PLAYING and PAUSED instead",
        names.join(", ")
    ))
}

/// Creates the services' readers and writers on `engine` under ROS namespace `ros_ns`
/// (canonical) and starts their thread, which serves the run of shared-memory namespace
/// `namespace` until `stop` is set.
pub fn start(
    engine: Arc<dyn Engine>,
    ros_ns: &str,
    namespace: &str,
    model: &Model,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, GatewayError> {
    let (tx, rx) = mpsc::sync_channel::<Msg>(QUEUE);
    let topic = |(name, _): (&str, &str)| crate::config::dds_topic(ros_ns, name);
    let shared = action::Shared::new(
        engine.writer(&topic(wire::STATUS), &wire::action_topic_type(wire::STATUS), &wire::status_qos())?,
        engine.writer(&topic(wire::FEEDBACK), &wire::action_topic_type(wire::FEEDBACK), &wire::qos())?,
    );
    let mut servers = Vec::new();
    for (i, s) in SERVICES.iter().enumerate() {
        let (rq, rr) = (wire::request_topic(ros_ns, s.name), wire::reply_topic(ros_ns, s.name));
        let writer = engine.related_writer(&rr, &s.response_topic_type(), &wire::qos())?;
        servers.push(Server { service: s, request_topic: rq.clone(), reply_topic: rr, writer });
        let tx = tx.clone();
        let sink = Arc::new(move |sample: Identified<'_>| request(i, sample, &tx));
        engine.identified_reader(&rq, &s.request_topic_type(), &wire::qos(), sink)?;
    }
    let ctl = RunControl { namespace: namespace.to_string(), timeout: CONTROL_TIMEOUT };
    let life = Lifecycle::new(no_stepping(model));
    let feedback_topic = topic(wire::FEEDBACK);
    let mut state = State {
        engine,
        servers,
        shared,
        done: tx,
        ctl,
        life,
        stop,
        waiting: Vec::new(),
        held: Vec::new(),
        feedback_topic,
    };
    std::thread::Builder::new()
        .name("tutti-gw-simif".into())
        .spawn(move || state.serve(rx))
        .map_err(|e| GatewayError::dds("the services' thread", e))
}

/// A reader's sink: a request in either form goes to the services' thread.
fn request(service: usize, sample: Identified<'_>, tx: &SyncSender<Msg>) {
    let Ok((le, body)) = split_header(sample.raw) else {
        tracing::debug!("simulation services: a request that is not plain CDR dropped");
        return;
    };
    let Ok(reply_to) = ReplyTo::of(&sample, Body { le, bytes: body }) else {
        tracing::debug!("simulation services: a request without its header dropped");
        return;
    };
    let call = Call { service, client: sample.writer, reply_to, le, body: body.to_vec() };
    if let Err(TrySendError::Full(_)) = tx.try_send(Msg::Call(call)) {
        tracing::warn!("simulation services: {QUEUE} requests wait already; one dropped");
    }
}

/// The services' thread.
struct State {
    engine: Arc<dyn Engine>,
    servers: Vec<Server>,
    shared: Arc<action::Shared>,
    /// For goal threads, to say they ended.
    done: SyncSender<Msg>,
    ctl: RunControl,
    life: Lifecycle,
    stop: Arc<AtomicBool>,
    /// `get_result` requests of running goals: (goal, the request).
    waiting: Vec<(action::GoalId, Call)>,
    /// Replies waiting for their client's reply reader (at most [`QUEUE`]).
    held: Vec<Held>,
    feedback_topic: String,
}

/// A reply kept until discovery shows its client's reply reader.
struct Held {
    service: usize,
    call: Call,
    body: Vec<u8>,
    until: Instant,
}

/// Where a goal's feedback goes: the client whose feedback reader it waits for.
pub struct Feedback {
    pub engine: Arc<dyn Engine>,
    pub topic: String,
    pub client: Guid,
}

impl std::fmt::Debug for Feedback {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Feedback").field("topic", &self.topic).field("client", &self.client).finish()
    }
}

impl State {
    fn serve(&mut self, rx: Receiver<Msg>) {
        while !self.stop.load(Ordering::Acquire) {
            // Keeps each reply writer's count of matched readers up to date between
            // replies (rustdds queues only a few match statuses).
            for server in &mut self.servers {
                server.writer.take_match_statuses();
            }
            self.send_held();
            let turn = if self.held.is_empty() { Duration::from_millis(100) } else { Duration::from_millis(5) };
            match rx.recv_timeout(turn) {
                Ok(Msg::Call(call)) => self.call(call),
                Ok(Msg::Done(id)) => {
                    let (ready, still): (Vec<_>, Vec<_>) = self.waiting.drain(..).partition(|(g, _)| *g == id);
                    self.waiting = still;
                    ready.into_iter().for_each(|(_, call)| self.call(call));
                }
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => return,
            }
        }
    }

    fn call(&mut self, call: Call) {
        let Some(kind) = self.servers.get(call.service).map(|s| s.service.kind) else { return };
        let mut out = Out::default();
        call.reply_to.start(&mut out);
        let body = Body { le: call.le, bytes: &call.body };
        let at = call.reply_to.fields_at();
        let mut start_goal = None;
        let client = call.client;
        let answered = match kind {
            wire::Kind::SendGoal => body.octets16(at).and_then(|id| {
                let steps = body.u64(at + 16)?;
                if self.shared.send_goal(id, &mut out) {
                    start_goal = Some((id, steps));
                }
                Ok(true)
            }),
            wire::Kind::GetResult => body.octets16(at).map(|id| self.shared.get_result(&id, &mut out)),
            wire::Kind::CancelGoal => body.octets16(at).and_then(|id| {
                let stamp = action::Stamp { sec: body.i32(at + 16)?, nanosec: body.u32(at + 20)? };
                self.shared.cancel_goal(&id, stamp, &mut out);
                Ok(true)
            }),
            _ => answer(kind, body, at, &mut self.life, &mut self.ctl, &mut out).map(|()| true),
        };
        let server = &mut self.servers[call.service];
        match answered {
            Err(e) => tracing::warn!("simulation services: a {} request: {e}", server.service.name),
            Ok(true) => {
                if !reply(&self.engine.remote(), server, &call, &out.0, false) {
                    self.hold(call, out.0);
                }
            }
            Ok(false) => {
                if let Ok(id) = body.octets16(at) {
                    self.waiting.push((id, call));
                }
            }
        }
        if let Some((id, steps)) = start_goal {
            let (ctl, life) = (self.ctl.clone(), self.life.clone());
            let feedback = Feedback { engine: self.engine.clone(), topic: self.feedback_topic.clone(), client };
            action::spawn(self.shared.clone(), id, steps, ctl, life, feedback, self.done.clone(), self.stop.clone());
        }
    }

    /// Keeps the reply `body` to `call` until its client's reply reader shows.
    fn hold(&mut self, call: Call, body: Vec<u8>) {
        if self.held.len() >= QUEUE {
            tracing::warn!("simulation services: {QUEUE} replies wait for their clients already; one dropped");
            return;
        }
        let service = call.service;
        self.held.push(Held { service, call, body, until: Instant::now() + REPLY_WAIT });
    }

    /// Sends the held replies whose client's reader has shown, or whose wait is over.
    fn send_held(&mut self) {
        if self.held.is_empty() {
            return;
        }
        let now = Instant::now();
        // One look at discovery for them all.
        let remote = self.engine.remote();
        let held = std::mem::take(&mut self.held);
        for h in held {
            let server = &mut self.servers[h.service];
            if !reply(&remote, server, &h.call, &h.body, now >= h.until) {
                self.held.push(h);
            }
        }
    }
}

/// The response body (after the header already in `out`, if any) to a request of `kind`,
/// whose fields start at `at` of its body.
fn answer(
    kind: wire::Kind,
    req: Body<'_>,
    at: usize,
    life: &mut Lifecycle,
    ctl: &mut dyn Control,
    out: &mut Out,
) -> Result<(), tutti_core::cdr::CdrError> {
    use wire::Kind::*;
    match kind {
        GetFeatures => {
            let info = format!("tutti {}: docs/ros2.md", env!("CARGO_PKG_VERSION"));
            messages::features(out, &life.features(true), &info);
        }
        GetState => {
            let (s, o) = life.get_state(ctl);
            out.u8(s).outcome(&o);
        }
        SetState => {
            let o = life.set_state(ctl, req.u8(at)?);
            out.outcome(&o);
        }
        Step => {
            let o = life.step(ctl, req.u64(at)?);
            out.outcome(&o);
        }
        Reset => {
            let o: Outcome = life.reset(ctl, req.u8(at)?);
            out.outcome(&o);
        }
        SendGoal | GetResult | CancelGoal => {}
    }
    Ok(())
}

/// Waits (at most [`READER_WAIT`]) until discovery shows a reader on `topic` of the
/// participant `prefix`: a reliable, volatile writer gives a reader it has not matched yet
/// nothing. Whether it came.
pub(crate) fn wait_for_reader(engine: &dyn Engine, topic: &str, prefix: [u8; PREFIX_LEN], stop: &AtomicBool) -> bool {
    let end = Instant::now() + READER_WAIT;
    loop {
        if engine.remote().readers_on(&[topic.to_string()]).iter().any(|g| g.prefix() == prefix) {
            return true;
        }
        if Instant::now() >= end || stop.load(Ordering::Acquire) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Whether a reply written now reaches every client of the server in the participant
/// `prefix`: each client (a request writer there) has its reply reader, which the reply
/// writer has matched (or, where the engine cannot say, discovery shows). A node may make a
/// new client of the same service at any time, so this is counted afresh for every reply.
/// `remote` is what discovery shows.
fn reaches(remote: &Remote, server: &mut Server, prefix: [u8; PREFIX_LEN]) -> bool {
    let clients = remote.writers_on(&server.request_topic).filter(|g| g.prefix() == prefix).count().max(1);
    let readers = match server.writer.matched_readers_of(prefix) {
        Some(n) => n,
        None => {
            remote.readers_on(std::slice::from_ref(&server.reply_topic)).iter().filter(|g| g.prefix() == prefix).count()
        }
    };
    readers >= clients
}

/// Writes `body` on the server's reply topic, in the form of the request `call`, if it
/// reaches the client as `remote` (discovery) and the writer's matches show (or `anyway`);
/// whether it was written.
fn reply(remote: &Remote, server: &mut Server, call: &Call, body: &[u8], anyway: bool) -> bool {
    let client = call.client;
    if !reaches(remote, server, client.prefix()) {
        if !anyway {
            return false;
        }
        tracing::debug!("simulation services: no reply reader of {client:?} on {}; replied anyway", server.reply_topic);
    }
    let written = match call.reply_to {
        ReplyTo::Header(_) => server.writer.write(body),
        ReplyTo::Related(related) => server.writer.write_related(body, related),
    };
    if !written {
        tracing::warn!("simulation services: DDS refused a reply on {}", server.reply_topic);
    }
    server.writer.flush();
    true
}
