//! ROS 2 `simulation_interfaces` services on the gateway (docs/ros2.md): under the gateway's
//! ROS namespace, `get_simulator_features`, `get_simulation_state`, `set_simulation_state`,
//! `step_simulation` and `reset_simulation`, and the action `simulate_steps` ([`action`]),
//! each call carried out on the run's control plane ([`lifecycle`]) as `tutti ctl` would. Offered by a gateway in or beside a framework, not by
//! a mirror nor a passive gateway (`--passive`).
//!
//! Each service is served by the engine ([`Engine::serve`]), which carries its requests and
//! responses in its own wire form (a DDS engine as rmw_cyclonedds or Fast DDS do, chosen per
//! request; docs/ros2.md, "Wire forms") and delivers a response once its client can receive
//! it. A request's sink only hands it to the services' thread (`tutti-gw-simif`), which makes
//! the control calls (they block: never on the engine's receive path nor on the manager's
//! loop), encodes the response and hands it to the engine.

pub mod action;
pub mod lifecycle;
pub mod messages;
pub mod wire;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tutti_core::ddf::Model;
use tutti_engine::{EndpointId, Engine, ReplyTo, Request, Responder, Service};

use crate::GatewayError;
use lifecycle::{Control, Lifecycle, RunControl};
use messages::{Body, Out, Outcome};
use wire::SERVICES;

/// Requests waiting for the services' thread; more are dropped (a client that floods the
/// services gets no answer to the excess, the gateway keeps its memory).
const QUEUE: usize = 256;
/// The longest wait for an answer of the run (`step N` is answered after its N steps).
const CONTROL_TIMEOUT: Duration = Duration::from_secs(300);
/// How long a goal's feedback waits for discovery to show the client's feedback reader: a
/// reliable, volatile writer gives a reader it has not matched yet nothing.
const READER_WAIT: Duration = Duration::from_secs(2);

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
    /// The client's request writer: its peer is the client's node.
    client: EndpointId,
    /// Whom the response goes to (the engine's form).
    reply_to: ReplyTo,
    le: bool,
    /// The request's body: its first field at 0.
    body: Vec<u8>,
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

/// Serves the services on `engine` under ROS namespace `ros_ns` (canonical) and starts their
/// thread, which serves the run of shared-memory namespace `namespace` until `stop` is set.
pub fn start(
    engine: Arc<dyn Engine>,
    ros_ns: &str,
    namespace: &str,
    model: &Model,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, GatewayError> {
    let (tx, rx) = mpsc::sync_channel::<Msg>(QUEUE);
    let topic = |(name, _): (&str, &str)| crate::config::ros_name(ros_ns, name);
    let shared = action::Shared::new(
        engine.writer(&topic(wire::STATUS), &wire::action_topic_type(wire::STATUS), &wire::status_qos())?,
        engine.writer(&topic(wire::FEEDBACK), &wire::action_topic_type(wire::FEEDBACK), &wire::qos())?,
    );
    let mut responders = Vec::new();
    for (i, s) in SERVICES.iter().enumerate() {
        let (name, request, response) = (crate::config::ros_name(ros_ns, s.name), s.request_topic_type(), s.response_topic_type());
        let tx = tx.clone();
        let sink = Arc::new(move |r: Request<'_>| request_to(i, r, &tx));
        responders.push(engine.serve(&Service { name: &name, request: &request, response: &response }, sink)?);
    }
    let ctl = RunControl { namespace: namespace.to_string(), timeout: CONTROL_TIMEOUT };
    let life = Lifecycle::new(no_stepping(model));
    let feedback_topic = topic(wire::FEEDBACK);
    let mut state =
        State { engine, responders, shared, done: tx, ctl, life, stop, waiting: Vec::new(), feedback_topic };
    std::thread::Builder::new()
        .name("tutti-gw-simif".into())
        .spawn(move || state.serve(rx))
        .map_err(|e| GatewayError::Thread("the services' thread", e))
}

/// A request's sink: to the services' thread.
fn request_to(service: usize, r: Request<'_>, tx: &SyncSender<Msg>) {
    let call = Call { service, client: r.client, reply_to: r.reply_to, le: r.little_endian, body: r.body.to_vec() };
    if let Err(TrySendError::Full(_)) = tx.try_send(Msg::Call(call)) {
        tracing::warn!("simulation services: {QUEUE} requests wait already; one dropped");
    }
}

/// The services' thread.
struct State {
    engine: Arc<dyn Engine>,
    /// Per service of [`SERVICES`], in order.
    responders: Vec<Box<dyn Responder>>,
    shared: Arc<action::Shared>,
    /// For goal threads, to say they ended.
    done: SyncSender<Msg>,
    ctl: RunControl,
    life: Lifecycle,
    stop: Arc<AtomicBool>,
    /// `get_result` requests of running goals: (goal, the request).
    waiting: Vec<(action::GoalId, Call)>,
    feedback_topic: String,
}

/// Where a goal's feedback goes: the client whose feedback reader it waits for.
pub struct Feedback {
    pub engine: Arc<dyn Engine>,
    pub topic: String,
    pub client: EndpointId,
}

impl std::fmt::Debug for Feedback {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Feedback").field("topic", &self.topic).field("client", &self.client).finish()
    }
}

impl State {
    fn serve(&mut self, rx: Receiver<Msg>) {
        while !self.stop.load(Ordering::Acquire) {
            match rx.recv_timeout(Duration::from_millis(100)) {
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
        let Some(kind) = SERVICES.get(call.service).map(|s| s.kind) else { return };
        let mut out = Out::default();
        let body = Body { le: call.le, bytes: &call.body };
        let mut start_goal = None;
        let client = call.client;
        let answered = match kind {
            wire::Kind::SendGoal => body.octets16(0).and_then(|id| {
                let steps = body.u64(16)?;
                if self.shared.send_goal(id, &mut out) {
                    start_goal = Some((id, steps));
                }
                Ok(true)
            }),
            wire::Kind::GetResult => body.octets16(0).map(|id| self.shared.get_result(&id, &mut out)),
            wire::Kind::CancelGoal => body.octets16(0).and_then(|id| {
                let stamp = action::Stamp { sec: body.i32(16)?, nanosec: body.u32(20)? };
                self.shared.cancel_goal(&id, stamp, &mut out);
                Ok(true)
            }),
            _ => answer(kind, body, &mut self.life, &mut self.ctl, &mut out).map(|()| true),
        };
        match answered {
            Err(e) => tracing::warn!("simulation services: a {} request: {e}", SERVICES[call.service].name),
            Ok(true) => self.responders[call.service].respond(&call.reply_to, &out.0),
            Ok(false) => {
                if let Ok(id) = body.octets16(0) {
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
}

/// The response body to a request of `kind`.
fn answer(
    kind: wire::Kind,
    req: Body<'_>,
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
            let o = life.set_state(ctl, req.u8(0)?);
            out.outcome(&o);
        }
        Step => {
            let o = life.step(ctl, req.u64(0)?);
            out.outcome(&o);
        }
        Reset => {
            let o: Outcome = life.reset(ctl, req.u8(0)?);
            out.outcome(&o);
        }
        SendGoal | GetResult | CancelGoal => {}
    }
    Ok(())
}

/// Waits (at most [`READER_WAIT`]) until discovery shows a reader on ROS 2 topic `topic` of
/// the client's peer `peer`: a reliable, volatile writer gives a reader it has not matched yet
/// nothing. Whether it came.
pub(crate) fn wait_for_reader(engine: &dyn Engine, topic: &str, peer: tutti_engine::PeerId, stop: &AtomicBool) -> bool {
    let end = Instant::now() + READER_WAIT;
    loop {
        if engine.remote().readers_on(&[topic.to_string()]).iter().any(|g| g.peer == peer) {
            return true;
        }
        if Instant::now() >= end || stop.load(Ordering::Acquire) {
            return false;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}
