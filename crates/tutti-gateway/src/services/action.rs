//! The action `simulate_steps` (`simulation_interfaces/action/SimulateSteps`, docs/ros2.md):
//! its goals, their statuses on the status topic, the feedback after each step, cancel, and
//! the result. The three services are answered on the services' thread; a goal is carried
//! out on a thread of its own (`tutti-gw-simsteps`), one step of the control plane at a
//! time, so that a cancel between two steps is heard and the other services stay answered.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::SyncSender;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{SystemTime, UNIX_EPOCH};

use tutti_host::control::Request;

use super::lifecycle::{Lifecycle, RunControl};
use super::messages::{result, Out, Outcome};
use super::{Feedback, Msg};
use tutti_engine::Writer;

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
}

/// What the goal threads and the services' thread share.
pub struct Shared {
    goals: Mutex<Vec<Goal>>,
    status: Mutex<Box<dyn Writer>>,
    feedback: Mutex<Box<dyn Writer>>,
}

impl std::fmt::Debug for Shared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Shared").field("goals", &lock(&self.goals).len()).finish()
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn goal_info(out: &mut Out, id: &GoalId, stamp: Stamp) {
    out.octets(id).i32(stamp.sec).u32(stamp.nanosec);
}

impl Shared {
    pub fn new(status: Box<dyn Writer>, feedback: Box<dyn Writer>) -> Arc<Shared> {
        Arc::new(Shared { goals: Mutex::new(Vec::new()), status: Mutex::new(status), feedback: Mutex::new(feedback) })
    }

    /// Publishes every kept goal's status (`GoalStatusArray`).
    fn publish_status(&self, goals: &[Goal]) {
        let mut out = Out::default();
        out.len(goals.len());
        for g in goals {
            goal_info(&mut out, &g.id, g.stamp);
            out.i8(g.status);
        }
        let mut w = lock(&self.status);
        if !w.write(&out.0) {
            tracing::debug!("simulation services: DDS refused a goal status");
        }
        w.flush();
    }

    fn set(&self, id: &GoalId, f: impl FnOnce(&mut Goal)) {
        let mut goals = lock(&self.goals);
        if let Some(g) = goals.iter_mut().find(|g| g.id == *id) {
            f(g);
        }
        self.publish_status(&goals);
    }

    /// `send_goal`: whether the goal is accepted (one goal at a time), and the stamp, after
    /// the request header in `out`.
    pub fn send_goal(&self, id: GoalId, out: &mut Out) -> bool {
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
        out.bool(accepted).i32(stamp.sec).u32(stamp.nanosec);
        accepted
    }

    /// `get_result`: the response after the header in `out`, or false while the goal runs
    /// (the request waits for [`Msg::Done`]).
    pub fn get_result(&self, id: &GoalId, out: &mut Out) -> bool {
        let goals = lock(&self.goals);
        match goals.iter().find(|g| g.id == *id) {
            None => {
                out.i8(status::UNKNOWN).outcome(&Outcome::new(result::NOT_FOUND, "no goal with this id"));
                true
            }
            Some(g) => match &g.result {
                Some(r) => {
                    out.i8(g.status).outcome(r);
                    true
                }
                None => false,
            },
        }
    }

    /// `cancel_goal` for `id` and `stamp` (action_msgs' rules: a zero id is every goal, a
    /// non-zero stamp adds the goals accepted at or before it); the response after the header.
    pub fn cancel_goal(&self, id: &GoalId, stamp: Stamp, out: &mut Out) {
        let mut goals = lock(&self.goals);
        let every = id.iter().all(|b| *b == 0);
        let mut canceling = Vec::new();
        for g in goals.iter_mut() {
            let chosen = (every && stamp.is_zero()) || g.id == *id || (!stamp.is_zero() && g.stamp <= stamp);
            if chosen && g.active() {
                g.cancel = true;
                g.status = status::CANCELING;
                canceling.push((g.id, g.stamp));
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
        out.i8(code).len(canceling.len());
        for (id, stamp) in &canceling {
            goal_info(out, id, *stamp);
        }
    }

    fn cancel_asked(&self, id: &GoalId) -> bool {
        lock(&self.goals).iter().any(|g| g.id == *id && g.cancel)
    }

    fn feedback(&self, id: &GoalId, completed: u64, remaining: u64) {
        let mut out = Out::default();
        out.octets(id).u64(completed).u64(remaining);
        let mut w = lock(&self.feedback);
        if !w.write(&out.0) {
            tracing::debug!("simulation services: DDS refused a feedback sample");
        }
        w.flush();
    }
}

/// Carries out goal `id` (`steps` steps) on its own thread; tells the services' thread on
/// `done` when it has ended.
#[allow(clippy::too_many_arguments)]
pub fn spawn(
    shared: Arc<Shared>,
    id: GoalId,
    steps: u64,
    mut ctl: RunControl,
    mut life: Lifecycle,
    feedback: Feedback,
    done: SyncSender<Msg>,
    stop: Arc<AtomicBool>,
) {
    let run = move || {
        // The client's feedback reader first, or its first feedback samples are lost.
        let Feedback { engine, topic, client } = feedback;
        if !super::wait_for_reader(engine.as_ref(), &topic, client.peer, &stop) {
            tracing::debug!("simulation services: no feedback reader of {client:?} on {topic}");
        }
        let (end, outcome) = execute(&shared, &id, steps, &mut ctl, &mut life, &stop);
        shared.set(&id, |g| {
            g.status = end;
            g.result = Some(outcome);
        });
        let _ = done.send(Msg::Done(id));
    };
    if let Err(e) = std::thread::Builder::new().name("tutti-gw-simsteps".into()).spawn(run) {
        tracing::warn!("simulation services: no thread for a goal: {e}");
    }
}

/// The goal's end status and result.
fn execute(
    shared: &Shared,
    id: &GoalId,
    steps: u64,
    ctl: &mut RunControl,
    life: &mut Lifecycle,
    stop: &AtomicBool,
) -> (i8, Outcome) {
    if let Err(refused) = life.can_step(ctl, steps) {
        return (status::ABORTED, refused);
    }
    shared.set(id, |g| {
        if g.status == status::ACCEPTED {
            g.status = status::EXECUTING;
        }
    });
    for done in 0..steps {
        if stop.load(Ordering::Acquire) {
            return (status::ABORTED, Outcome::new(result::OPERATION_FAILED, "the gateway stopped"));
        }
        if shared.cancel_asked(id) {
            return (status::CANCELED, Outcome::new(result::OK, format!("canceled after {done} of {steps} steps")));
        }
        if let Err(e) = super::lifecycle::Control::call(ctl, &Request::Step { n: 1 }) {
            return (status::ABORTED, Outcome::new(result::OPERATION_FAILED, format!("step {}: {e}", done + 1)));
        }
        shared.feedback(id, done + 1, steps - done - 1);
    }
    (status::SUCCEEDED, Outcome::ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A writer that keeps what it is given.
    struct Kept(Arc<Mutex<Vec<Vec<u8>>>>);

    impl Writer for Kept {
        fn write(&mut self, body: &[u8]) -> bool {
            lock(&self.0).push(body.to_vec());
            true
        }
        fn write_serialized(&mut self, _: &[u8]) -> bool {
            false
        }
    }

    #[test]
    fn one_goal_at_a_time_cancel_and_results() {
        let statuses = Arc::new(Mutex::new(Vec::new()));
        let s = Shared::new(Box::new(Kept(statuses.clone())), Box::new(Kept(Arc::new(Mutex::new(Vec::new())))));
        let (a, b) = ([1u8; 16], [2u8; 16]);
        assert!(s.send_goal(a, &mut Out::default()));
        let mut out = Out::default();
        assert!(!s.send_goal(b, &mut out), "a second goal while one runs");
        assert_eq!(out.0[0], 0);
        assert!(!s.get_result(&a, &mut Out::default()), "the result waits for the goal");
        let mut out = Out::default();
        s.cancel_goal(&a, Stamp::default(), &mut out);
        assert_eq!((out.0[0] as i8, &out.0[4..8]), (cancel::ERROR_NONE, &1u32.to_le_bytes()[..]));
        assert!(s.cancel_asked(&a));
        s.set(&a, |g| {
            g.status = status::CANCELED;
            g.result = Some(Outcome::ok());
        });
        let mut out = Out::default();
        assert!(s.get_result(&a, &mut out));
        assert_eq!((out.0[0] as i8, out.0[1]), (status::CANCELED, result::OK));
        let mut out = Out::default();
        s.cancel_goal(&a, Stamp::default(), &mut out);
        assert_eq!(out.0[0] as i8, cancel::ERROR_GOAL_TERMINATED);
        let mut out = Out::default();
        s.cancel_goal(&b, Stamp::default(), &mut out);
        assert_eq!(out.0[0] as i8, cancel::ERROR_UNKNOWN_GOAL_ID);
        let mut out = Out::default();
        assert!(s.get_result(&b, &mut out));
        assert_eq!((out.0[0] as i8, out.0[1]), (status::UNKNOWN, result::NOT_FOUND));
        // The last status: one goal, canceled: count, id, stamp, status.
        let last = lock(&statuses).last().cloned().unwrap_or_default();
        assert_eq!((&last[..4], &last[4..20], last[28] as i8), (&1u32.to_le_bytes()[..], &a[..], status::CANCELED));
    }
}
