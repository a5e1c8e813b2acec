//! A connection's wait for the framework: what it waits for, how (its futex word, the
//! checks that end it, a pause that holds its timeout back), and the [`StepGate`] that
//! waits apart from the participant.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::Participant;
use crate::shm::segment::{Segment, WaitMode, Waited, Waiter, STATE_RUNNING};
use crate::shm::state::SharedState;
use crate::shm::{os, ShmError};
use crate::sync::Ordering;

impl Participant {
    /// This connection's wait for `until` (see [`Waiting`]).
    pub(super) fn waiting(&self, until: GateFor) -> Waiting {
        Waiting {
            slot: self.slot,
            id: self.id,
            pid: self.me.pid,
            wait: self.opts.wait,
            timeout: self.opts.timeout,
            until,
            state: if matches!(until, GateFor::Nothing) { None } else { self.opts.state.clone() },
        }
    }

    pub(super) fn gate(&self, until: GateFor) -> StepGate {
        StepGate { seg: self.seg.clone(), waiting: self.waiting(until) }
    }
}

/// What a participant's wait waits for.
#[derive(Debug, Clone, Copy)]
pub(super) enum GateFor {
    /// A step after this one (the connection's last read).
    ReadAfter(u64),
    /// A step to answer after the last commit (or the seed, with `states`).
    PublishAfter { last: u64, states: bool },
    /// Event-driven: a step after this one (the last answered) that the connection is due at.
    DueAfter(u64),
    /// Nothing: only the connection's checks (see [`Waiting::check`]).
    Nothing,
}

/// A connection's wait for the framework, by value: the participant waits with it on its
/// own segment, a [`StepGate`] on a segment it shares, with no borrow of the participant.
#[derive(Debug, Clone)]
pub(super) struct Waiting {
    slot: usize,
    id: u64,
    pid: u32,
    wait: WaitMode,
    timeout: Duration,
    until: GateFor,
    /// The connection's state handler: a wait answers the framework's state requests.
    state: Option<SharedState>,
}

impl Waiting {
    /// Whether the connection is still in place and its framework runs (looking at the
    /// framework's process too with `look_at_process`). A segment shrunk under us reads as
    /// zeros (a stopped framework, a lost connection): that is said instead.
    pub(super) fn check(&self, seg: &Segment, look_at_process: bool) -> Result<(), ShmError> {
        let domain = || seg.info.name.clone();
        let r = if seg.header().state.load(Ordering::Acquire) != STATE_RUNNING {
            Err(ShmError::FrameworkStopped { domain: domain() })
        } else {
            match seg.conn(self.slot) {
                Some(c) if c.active.load(Ordering::Acquire) == self.pid && seg.conn_id(self.slot) == self.id => {
                    if look_at_process && !os::is_alive(seg.framework_id()) {
                        Err(ShmError::FrameworkStopped { domain: domain() })
                    } else {
                        Ok(())
                    }
                }
                _ => Err(ShmError::ConnectionLost { domain: domain() }),
            }
        };
        if r.is_err() {
            seg.intact_checked()?;
        }
        seg.intact()?;
        r
    }

    /// Waits until `until`, at most the timeout, except that a paused framework costs no
    /// timeout (the wait goes on for as long as the pause lasts, and a whole timeout after
    /// it); the connection is checked now and then, and ends the wait with its error.
    pub(super) fn wait(&self, seg: &Segment) -> Result<(), ShmError> {
        let h = seg.header();
        let ctl = seg.step_ctl();
        let until = self.until;
        let keeps_state = self.state.is_some() && !matches!(until, GateFor::Nothing);
        let slot_index = self.slot;
        let mut ready = move || {
            if keeps_state && seg.state_pending(slot_index) {
                return Ok(true);
            }
            Ok(match until {
                GateFor::ReadAfter(last) => ctl.next_step(last).is_some(),
                GateFor::PublishAfter { last, states } => {
                    let k = h.pub_step.load(Ordering::Acquire);
                    k > last || (states && k == 0 && h.seeded.load(Ordering::Acquire) == 0)
                }
                GateFor::DueAfter(answered) => {
                    seg.conn_ctl(self.slot).is_some_and(|conn| ctl.next_due(&conn, answered).is_some())
                }
                GateFor::Nothing => true,
            })
        };
        let what = match until {
            GateFor::PublishAfter { .. } => "a step to publish for",
            _ => "the framework's next step",
        };
        // An event-driven connection waits on its own word, which the framework bumps when it
        // is due, so the steps it is not due at do not wake it.
        let slot = seg.conn(self.slot).filter(|_| matches!(until, GateFor::DueAfter(_)));
        let (futex, waiters) = match slot {
            Some(c) => (&c.due_seq, &c.due_waiters),
            None => (&h.step_seq, &h.step_waiters),
        };
        let waiter = Waiter { mode: self.wait, futex, waiters, check_every: Duration::from_millis(20) };
        loop {
            let deadline = Instant::now() + self.timeout;
            let step_before = h.pub_step.load(Ordering::Acquire);
            match waiter.wait(deadline, &mut ready, || self.check(seg, true))? {
                // A state request: answered here, at the step boundary; then wait on.
                Waited::Ready if self.state.as_ref().is_some_and(|h| seg.serve_state(self.slot, h)) => {}
                Waited::Ready => return Ok(()),
                Waited::TimedOut if !seg.step_wait_may_time_out(self.timeout) => {}
                // Not due yet while the framework goes on stepping: nothing is late.
                Waited::TimedOut
                    if matches!(until, GateFor::DueAfter(_)) && h.pub_step.load(Ordering::Acquire) != step_before => {}
                Waited::TimedOut => {
                    let ms = self.timeout.as_millis() as u64;
                    return Err(ShmError::Timeout { domain: seg.info.name.clone(), what, ms });
                }
            }
        }
    }
}

/// A participant's wait for the framework, apart from the participant (see
/// [`Participant::read_gate`]): it holds the segment, not the connection, so another
/// thread may use the connection meanwhile. It ends as the participant's own wait does:
/// ready, timed out (never while the framework is paused), or with the error of a framework
/// that stopped, a connection that was removed or a segment that was shrunk.
#[derive(Debug)]
pub struct StepGate {
    seg: Arc<Segment>,
    waiting: Waiting,
}

impl StepGate {
    pub fn wait(&self) -> Result<(), ShmError> {
        self.waiting.wait(&self.seg)
    }
}
