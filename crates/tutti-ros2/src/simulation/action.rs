//! The action `simulate_steps` (`simulation_interfaces/action/SimulateSteps`, docs/ros2.md):
//! its goals, their statuses on the status topic, the feedback after each step, cancel, and
//! the result. The three services are answered on the services' thread; a goal is carried
//! out on a thread of its own (`tutti-gw-simsteps`), one step of the control plane at a
//! time, so that a cancel between two steps is heard and the other services stay answered.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{SystemTime, UNIX_EPOCH};

use tutti_host::control::Request;

use super::lifecycle::{Control, Lifecycle, Outcome, RunControl};
use super::{result, FEEDBACK, STATUS};
use crate::{Message, Struct, Value};

/// `action_msgs/msg/GoalStatus` values.
pub mod status {
    pub const UNKNOWN: i8 = 0;
    pub const ACCEPTED: i8 = 1;
    pub const EXECUTING: i8 = 2;
    pub const CANCELING: i8 = 3;
    pub const SUCCEEDED: i8 = 4;
    pub const CANCELED: i8 = 5;
    pub const ABORTED: i8 = 6;
}

/// `action_msgs/srv/CancelGoal` return codes.
pub mod cancel {
    pub const ERROR_NONE: i8 = 0;
    pub const ERROR_UNKNOWN_GOAL_ID: i8 = 2;
    pub const ERROR_GOAL_TERMINATED: i8 = 3;
}

/// Terminated goals kept for `get_result` and the status topic.
const KEPT: usize = 32;

pub type GoalId = [u8; 16];

/// A `unique_identifier_msgs/UUID` value as a goal id.
pub fn uuid(v: &Value) -> Option<GoalId> {
    let bytes = v.get("uuid")?.as_array()?;
    let mut id = [0u8; 16];
    if bytes.len() != id.len() {
        return None;
    }
    for (b, v) in id.iter_mut().zip(bytes) {
        *b = u8::try_from(v.as_u64()?).ok()?;
    }
    Some(id)
}

/// A goal id as a `unique_identifier_msgs/UUID` value.
fn uuid_value(id: &GoalId) -> Value {
    Struct::new().with("uuid", id.iter().map(|b| Value::from(*b)).collect::<Vec<_>>()).into()
}

/// A `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
pub struct Stamp {
    pub sec: i32,
    pub nanosec: u32,
}

impl Stamp {
    pub fn now() -> Stamp {
        let d = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
        Stamp { sec: i32::try_from(d.as_secs()).unwrap_or(i32::MAX), nanosec: d.subsec_nanos() }
    }

    /// A `builtin_interfaces/Time` value (a field it lacks is 0).
    pub fn of(v: &Value) -> Stamp {
        let sec = v.get("sec").and_then(Value::as_i64).and_then(|s| i32::try_from(s).ok()).unwrap_or(0);
        let nanosec = v.get("nanosec").and_then(Value::as_u64).and_then(|n| u32::try_from(n).ok()).unwrap_or(0);
        Stamp { sec, nanosec }
    }

    /// As a `builtin_interfaces/Time` value.
    pub fn value(&self) -> Value {
        Struct::new().with("sec", self.sec).with("nanosec", self.nanosec).into()
    }

    fn is_zero(&self) -> bool {
        *self == Stamp::default()
    }
}

#[derive(Debug, Clone)]
struct Goal {
    id: GoalId,
    stamp: Stamp,
    status: i8,
    result: Option<Outcome>,
    cancel: bool,
}

impl Goal {
    fn active(&self) -> bool {
        matches!(self.status, status::ACCEPTED | status::EXECUTING | status::CANCELING)
    }

    /// Its `action_msgs/GoalInfo`.
    fn info(&self) -> Value {
        goal_info(&self.id, self.stamp)
    }
}

fn goal_info(id: &GoalId, stamp: Stamp) -> Value {
    Struct::new().with("goal_id", uuid_value(id)).with("stamp", stamp.value()).into()
}

/// Where a topic's samples go: called with each sample's little-endian CDR body; false when
/// it was refused.
pub type Publisher = Box<dyn FnMut(&[u8]) -> bool + Send>;

/// One topic of the action: its message, and where it is published.
struct Topic {
    message: Message<'static>,
    publish: Mutex<Publisher>,
}

impl Topic {
    fn publish(&self, v: &Value) {
        match self.message.encode(v) {
            Ok(body) => {
                if !lock(&self.publish)(&body) {
                    tracing::debug!("simulation services: {} refused", self.message.name());
                }
            }
            Err(e) => tracing::warn!("simulation services: {}: {e}", self.message.name()),
        }
    }
}

/// The goals, which the goal threads and the services' thread share, and the action's topics.
pub struct Goals {
    goals: Mutex<Vec<Goal>>,
    status: Topic,
    feedback: Topic,
}

impl std::fmt::Debug for Goals {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Goals").field("goals", &lock(&self.goals).len()).finish()
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Goals {
    /// The goals, whose statuses go to `status` and feedback to `feedback`.
    pub fn new(status: Publisher, feedback: Publisher) -> Arc<Goals> {
        Arc::new(Goals {
            goals: Mutex::new(Vec::new()),
            status: Topic { message: STATUS.message(), publish: Mutex::new(status) },
            feedback: Topic { message: FEEDBACK.message(), publish: Mutex::new(feedback) },
        })
    }

    /// Publishes every kept goal's status (`GoalStatusArray`).
    fn publish_status(&self, goals: &[Goal]) {
        let list: Vec<Value> =
            goals.iter().map(|g| Struct::new().with("goal_info", g.info()).with("status", g.status).into()).collect();
        self.status.publish(&Struct::new().with("status_list", list).into());
    }

    fn set(&self, id: &GoalId, f: impl FnOnce(&mut Goal)) {
        let mut goals = lock(&self.goals);
        if let Some(g) = goals.iter_mut().find(|g| g.id == *id) {
            f(g);
        }
        self.publish_status(&goals);
    }

    /// `send_goal`: whether the goal is accepted (one goal at a time), and its stamp.
    pub fn send_goal(&self, id: GoalId) -> (bool, Stamp) {
        let stamp = Stamp::now();
        let mut goals = lock(&self.goals);
        let accepted = !goals.iter().any(|g| g.active() || g.id == id);
        if accepted {
            goals.push(Goal { id, stamp, status: status::ACCEPTED, result: None, cancel: false });
            let terminated = goals.iter().filter(|g| !g.active()).count();
            if terminated > KEPT {
                if let Some(i) = goals.iter().position(|g| !g.active()) {
                    goals.remove(i);
                }
            }
            self.publish_status(&goals);
        }
        (accepted, stamp)
    }

    /// `get_result`'s response, or None while the goal runs (the request waits until
    /// [`Goals::ended`]).
    pub fn get_result(&self, id: &GoalId) -> Option<Value> {
        let goals = lock(&self.goals);
        let (status, outcome) = match goals.iter().find(|g| g.id == *id) {
            None => (status::UNKNOWN, Outcome::new(result::NOT_FOUND, "no goal with this id")),
            Some(g) => (g.status, g.result.clone()?),
        };
        Some(Struct::new().with("status", status).with("result", Struct::new().with("result", outcome.value())).into())
    }

    /// Whether goal `id` has ended (its `get_result` is answered).
    pub fn ended(&self, id: &GoalId) -> bool {
        lock(&self.goals).iter().any(|g| g.id == *id && g.result.is_some())
    }

    /// `cancel_goal`'s response for `id` and `stamp` (action_msgs' rules: a zero id is every
    /// goal, a non-zero stamp adds the goals accepted at or before it).
    pub fn cancel_goal(&self, id: &GoalId, stamp: Stamp) -> Value {
        let mut goals = lock(&self.goals);
        let every = id.iter().all(|b| *b == 0);
        let mut canceling = Vec::new();
        for g in goals.iter_mut() {
            let chosen = (every && stamp.is_zero()) || g.id == *id || (!stamp.is_zero() && g.stamp <= stamp);
            if chosen && g.active() {
                g.cancel = true;
                g.status = status::CANCELING;
                canceling.push(g.info());
            }
        }
        let code = if !canceling.is_empty() || every {
            cancel::ERROR_NONE
        } else if goals.iter().any(|g| g.id == *id) {
            cancel::ERROR_GOAL_TERMINATED
        } else {
            cancel::ERROR_UNKNOWN_GOAL_ID
        };
        if !canceling.is_empty() {
            self.publish_status(&goals);
        }
        Struct::new().with("return_code", code).with("goals_canceling", canceling).into()
    }

    fn cancel_asked(&self, id: &GoalId) -> bool {
        lock(&self.goals).iter().any(|g| g.id == *id && g.cancel)
    }

    fn feedback(&self, id: &GoalId, completed: u64, remaining: u64) {
        let feedback = Struct::new().with("completed_steps", completed).with("remaining_steps", remaining);
        self.feedback.publish(&Struct::new().with("goal_id", uuid_value(id)).with("feedback", feedback).into());
    }
}

/// What a goal's thread is given beside the goal: the run, and how it tells what it needs.
pub struct GoalRun {
    pub ctl: RunControl,
    pub life: Lifecycle,
    /// Waits (bounded) until the client's feedback reader can receive the goal's feedback;
    /// whether it can.
    pub feedback_reader: Box<dyn FnOnce() -> bool + Send>,
    /// Called once the goal has ended.
    pub done: Box<dyn FnOnce(GoalId) + Send>,
    pub stop: Arc<AtomicBool>,
}

impl std::fmt::Debug for GoalRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GoalRun").field("ctl", &self.ctl).finish_non_exhaustive()
    }
}

/// Carries out goal `id` (`steps` steps) on its own thread.
pub fn spawn(goals: Arc<Goals>, id: GoalId, steps: u64, run: GoalRun) {
    let GoalRun { mut ctl, mut life, feedback_reader, done, stop } = run;
    let go = move || {
        // The client's feedback reader first, or its first feedback samples are lost.
        if !feedback_reader() {
            tracing::debug!("simulation services: no feedback reader of the goal's client");
        }
        let (end, outcome) = execute(&goals, &id, steps, &mut ctl, &mut life, &stop);
        goals.set(&id, |g| {
            g.status = end;
            g.result = Some(outcome);
        });
        done(id);
    };
    if let Err(e) = std::thread::Builder::new().name("tutti-gw-simsteps".into()).spawn(go) {
        tracing::warn!("simulation services: no thread for a goal: {e}");
    }
}

/// The goal's end status and result.
fn execute(
    goals: &Goals,
    id: &GoalId,
    steps: u64,
    ctl: &mut RunControl,
    life: &mut Lifecycle,
    stop: &AtomicBool,
) -> (i8, Outcome) {
    if let Err(refused) = life.can_step(ctl, steps) {
        return (status::ABORTED, refused);
    }
    goals.set(id, |g| {
        if g.status == status::ACCEPTED {
            g.status = status::EXECUTING;
        }
    });
    for done in 0..steps {
        if stop.load(Ordering::Acquire) {
            return (status::ABORTED, Outcome::new(result::OPERATION_FAILED, "the gateway stopped"));
        }
        if goals.cancel_asked(id) {
            return (status::CANCELED, Outcome::new(result::OK, format!("canceled after {done} of {steps} steps")));
        }
        if let Err(e) = Control::call(ctl, &Request::Step { n: 1 }) {
            return (status::ABORTED, Outcome::new(result::OPERATION_FAILED, format!("step {}: {e}", done + 1)));
        }
        goals.feedback(id, done + 1, steps - done - 1);
    }
    (status::SUCCEEDED, Outcome::ok())
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// The action's constants are `action_msgs`' own (called by the module's constants test).
    pub(in crate::simulation) fn the_action_constants_are_the_interfaces_own(constant: fn(&str, &str) -> u64) {
        let g = "action_msgs/msg/GoalStatus";
        for (name, v) in [
            ("STATUS_UNKNOWN", status::UNKNOWN),
            ("STATUS_ACCEPTED", status::ACCEPTED),
            ("STATUS_EXECUTING", status::EXECUTING),
            ("STATUS_CANCELING", status::CANCELING),
            ("STATUS_SUCCEEDED", status::SUCCEEDED),
            ("STATUS_CANCELED", status::CANCELED),
            ("STATUS_ABORTED", status::ABORTED),
        ] {
            assert_eq!(constant(g, name) as i8, v, "{name}");
        }
        let c = "action_msgs/srv/CancelGoal_Response";
        for (name, v) in [
            ("ERROR_NONE", cancel::ERROR_NONE),
            ("ERROR_UNKNOWN_GOAL_ID", cancel::ERROR_UNKNOWN_GOAL_ID),
            ("ERROR_GOAL_TERMINATED", cancel::ERROR_GOAL_TERMINATED),
        ] {
            assert_eq!(constant(c, name) as i8, v, "{name}");
        }
    }

    /// A publisher that keeps what it is given.
    fn kept() -> (Publisher, Arc<Mutex<Vec<Vec<u8>>>>) {
        let all = Arc::new(Mutex::new(Vec::new()));
        let into = all.clone();
        (
            Box::new(move |b: &[u8]| {
                lock(&into).push(b.to_vec());
                true
            }),
            all,
        )
    }

    fn code(v: &Value, field: &str) -> i64 {
        v.get(field).and_then(Value::as_i64).unwrap_or(-99)
    }

    fn cancel_body(v: &Value) -> Vec<u8> {
        crate::registry().service("action_msgs/srv/CancelGoal").unwrap().response().encode(v).unwrap()
    }

    #[test]
    fn one_goal_at_a_time_cancel_and_results() {
        let (status_out, statuses) = kept();
        let s = Goals::new(status_out, kept().0);
        let (a, b) = ([1u8; 16], [2u8; 16]);
        assert!(s.send_goal(a).0);
        assert!(!s.send_goal(b).0, "a second goal while one runs");
        assert!(s.get_result(&a).is_none(), "the result waits for the goal");
        let c = s.cancel_goal(&a, Stamp::default());
        assert_eq!(code(&c, "return_code"), i64::from(cancel::ERROR_NONE));
        assert_eq!(&cancel_body(&c)[..8], &[0, 0, 0, 0, 1, 0, 0, 0], "one goal canceling");
        assert!(s.cancel_asked(&a));
        s.set(&a, |g| {
            g.status = status::CANCELED;
            g.result = Some(Outcome::ok());
        });
        assert!(s.ended(&a));
        let r = s.get_result(&a).unwrap();
        assert_eq!(code(&r, "status"), i64::from(status::CANCELED));
        assert_eq!(r.path("result.result.result").and_then(Value::as_u64), Some(u64::from(result::OK)));
        let c = s.cancel_goal(&a, Stamp::default());
        assert_eq!(code(&c, "return_code"), i64::from(cancel::ERROR_GOAL_TERMINATED));
        let c = s.cancel_goal(&b, Stamp::default());
        assert_eq!(code(&c, "return_code"), i64::from(cancel::ERROR_UNKNOWN_GOAL_ID));
        let r = s.get_result(&b).unwrap();
        assert_eq!(code(&r, "status"), i64::from(status::UNKNOWN));
        assert_eq!(r.path("result.result.result").and_then(Value::as_u64), Some(u64::from(result::NOT_FOUND)));
        // The last status: one goal, canceled: count, id, stamp, status.
        let last = lock(&statuses).last().cloned().unwrap_or_default();
        assert_eq!((&last[..4], &last[4..20], last[28] as i8), (&1u32.to_le_bytes()[..], &a[..], status::CANCELED));
    }

    #[test]
    fn a_goal_id_is_a_uuid_of_sixteen_octets() {
        let id = [7u8; 16];
        assert_eq!(uuid(&uuid_value(&id)), Some(id));
        assert_eq!(uuid(&Struct::new().with("uuid", vec![Value::from(1u8)]).into()), None);
    }
}
