//! ROS 2's `simulation_interfaces` services (run control and entities) and the action
//! `simulate_steps` on the gateway's engine (docs/ros2.md): offered by a gateway in or beside a framework, not by a mirror nor a
//! passive gateway (`--passive`). What each call does is `tutti_ros2::simulation`'s; this
//! module only wires it to the engine.
//!
//! Each service is served by the engine ([`Engine::serve`]), which carries its requests and
//! responses in its own wire form (a DDS engine as rmw_cyclonedds or Fast DDS do, chosen per
//! request; docs/ros2.md, "Wire forms") and delivers a response once its client can receive
//! it. A request's sink only hands it to the services' thread (`tutti-gw-simif`), which
//! decodes it with its interface's codec, makes the control calls (they block: never on the
//! engine's receive path nor on the manager's loop), encodes the response and hands it to the
//! engine.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tutti_core::ddf::Model;
use tutti_engine::{EndpointId, Engine, PeerId, ReplyTo, Request, Responder, Service, TopicType, Writer};
use tutti_ros2::simulation::action::{self, GoalId, GoalRun, Publisher};
use tutti_ros2::simulation::{
    self, Answer, Entities, Goals, Lifecycle, RunControl, Simulation, FEEDBACK, SERVICES, STATUS,
};
use tutti_ros2::Message;

use crate::GatewayError;
use tutti_ros2::names::under as ros_name;

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
enum Msg {
    Call(Call),
    /// A goal of the action has ended: its waiting `get_result` requests are answered.
    Done(GoalId),
}

/// One request as the services' thread gets it.
#[derive(Debug)]
struct Call {
    service: usize,
    /// The client's request writer: its peer is the client's node.
    client: EndpointId,
    /// Whom the response goes to (the engine's form).
    reply_to: ReplyTo,
    le: bool,
    /// The request's body: its first field at 0.
    body: Vec<u8>,
}

/// The type of a message's endpoints, with its hash.
fn topic_type(m: Message<'_>) -> TopicType {
    TopicType::ros2(&m.name().dds(), m.hash())
}

/// A topic's publisher over an engine writer.
fn publisher(mut w: Box<dyn Writer>) -> Publisher {
    Box::new(move |body: &[u8]| {
        let written = w.write(body);
        w.flush();
        written
    })
}

/// Serves the services on `engine` under ROS namespace `ros_ns` (canonical) and starts their
/// thread, which serves the run of shared-memory namespace `namespace` until `stop` is set.
pub fn start(
    engine: Arc<dyn Engine>,
    ros_ns: &str,
    namespace: &str,
    model: &Model,
    entities: Box<dyn Entities>,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<()>, GatewayError> {
    let (tx, rx) = mpsc::sync_channel::<Msg>(QUEUE);
    let status =
        engine.writer(&ros_name(ros_ns, STATUS.name), &topic_type(STATUS.message()), &simulation::status_qos())?;
    let feedback_topic = ros_name(ros_ns, FEEDBACK.name);
    let feedback = engine.writer(&feedback_topic, &topic_type(FEEDBACK.message()), &simulation::feedback_qos())?;
    let goals = Goals::new(publisher(status), publisher(feedback));
    let mut responders = Vec::new();
    for (i, s) in SERVICES.iter().enumerate() {
        let svc = s.service();
        let (name, request, response) =
            (ros_name(ros_ns, s.name), topic_type(svc.request()), topic_type(svc.response()));
        let tx = tx.clone();
        let sink = Arc::new(move |r: Request<'_>| request_to(i, r, &tx));
        responders.push(engine.serve(&Service { name: &name, request: &request, response: &response }, sink)?);
    }
    let ctl = RunControl { namespace: namespace.to_string(), timeout: CONTROL_TIMEOUT };
    let sim = Simulation { life: Lifecycle::new(simulation::no_stepping(model)), goals, entities };
    let mut state = State { engine, responders, sim, ctl, done: tx, stop, waiting: Vec::new(), feedback_topic };
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
    sim: Simulation,
    ctl: RunControl,
    /// For goal threads, to say they ended.
    done: SyncSender<Msg>,
    stop: Arc<AtomicBool>,
    /// `get_result` requests of running goals: (goal, the request).
    waiting: Vec<(GoalId, Call)>,
    feedback_topic: String,
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
        tracing::debug!("simulation services: {} from {:?}", SERVICES[call.service].name, call.client);
        let svc = SERVICES[call.service].service();
        let request = match svc.request().decode(&call.body, call.le) {
            Ok(r) => r,
            Err(e) => {
                tracing::warn!("simulation services: a {} request: {e}", SERVICES[call.service].name);
                return;
            }
        };
        let reply = match self.sim.answer(call.service, &request, &mut self.ctl) {
            Err(e) => return tracing::warn!("simulation services: {e}"),
            Ok(Answer::Wait(goal)) => return self.waiting.push((goal, call)),
            Ok(Answer::Reply(reply)) => reply,
            Ok(Answer::Accepted { reply, goal, steps }) => {
                self.start_goal(goal, steps, call.client);
                reply
            }
        };
        match svc.response().encode(&reply) {
            Ok(body) => self.responders[call.service].respond(&call.reply_to, &body),
            Err(e) => tracing::warn!("simulation services: a {} response: {e}", SERVICES[call.service].name),
        }
    }

    /// Carries out an accepted goal on its own thread; its feedback goes to `client`'s node.
    fn start_goal(&self, goal: GoalId, steps: u64, client: EndpointId) {
        let (engine, topic, stop) = (self.engine.clone(), self.feedback_topic.clone(), self.stop.clone());
        let done = self.done.clone();
        let run = GoalRun {
            ctl: self.ctl.clone(),
            life: self.sim.life.clone(),
            feedback_reader: Box::new(move || wait_for_reader(engine.as_ref(), &topic, client.peer, &stop)),
            done: Box::new(move |id| {
                let _ = done.send(Msg::Done(id));
            }),
            stop: self.stop.clone(),
        };
        action::spawn(self.sim.goals.clone(), goal, steps, run);
    }
}

/// Waits (at most [`READER_WAIT`]) until discovery shows a reader on ROS 2 topic `topic` of
/// the client's peer `peer`: a reliable, volatile writer gives a reader it has not matched yet
/// nothing. Whether it came.
fn wait_for_reader(engine: &dyn Engine, topic: &str, peer: PeerId, stop: &AtomicBool) -> bool {
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
