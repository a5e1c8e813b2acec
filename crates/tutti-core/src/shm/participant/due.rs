//! When an event-driven connection takes part (`docs/timing.md`): what it said about its
//! next due step, and its answers to the steps it is due at.

use super::Participant;
use crate::shm::handshake::{item_bit, CONN_EVENT, CONN_WAKE, MASK_WORDS};
use crate::shm::segment;
use crate::shm::ShmError;
use crate::sync::Ordering;

/// What an event-driven participant said about when it is due (`docs/timing.md`).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Due {
    /// It said something: it takes part only in the steps it is due at.
    said: bool,
    /// Due at the first step at or after this simulated time (once).
    request: Option<f64>,
    /// Due every this many steps (at steps whose simulated time is a multiple of it).
    period_steps: Option<u64>,
    /// Also due at any step whose PUBLISH set changed.
    wake: bool,
    /// Its commit answers the step (a DDS writer: it never asks for a step itself).
    pub(super) answer_on_commit: bool,
    /// The PUBLISH items it reads ([`item_bit`]; none: all), for waking on change.
    reads: [u64; MASK_WORDS],
    /// The step it last answered by asking for its next, while nothing it said has changed
    /// since: asking again (the RTAPI's gate, then its lock) answers nothing new.
    asked: Option<u64>,
}

/// A time within this fraction of a step of a step's time counts as that step.
const STEP_TOLERANCE: f64 = 1e-6;

impl Participant {
    /// Whether this connection takes part only in the steps it is due at: it said when it
    /// is due, in an event-driven domain.
    pub(super) fn event_driven(&self) -> bool {
        self.due.said && self.seg.info.flags.event
    }

    /// Event-driven: answers the step this connection is at (what it committed for it is in)
    /// and says when it is next due, from what it asked for during the step. Returns the
    /// step answered; the connection's next step is the first due one after it.
    pub(super) fn ask_next(&mut self) -> u64 {
        let s = self.last_read.max(self.locked_step);
        if self.due.asked == Some(s) {
            return s;
        }
        self.due.asked = Some(s);
        let next = if self.has_read || self.locked_step > 0 { self.next_due_after() } else { 0 };
        self.due.request = None;
        self.answer_as(s, next);
        s
    }

    /// Event-driven: tells the framework that this connection has answered step `s` and is
    /// next due from step `next`, or before it where an item it reads changes if it wakes on
    /// change.
    fn answer_as(&self, s: u64, next: u64) {
        let seg = &self.seg;
        if let (Some(c), Some(conn)) = (seg.conn(self.slot), seg.conn_ctl(self.slot)) {
            seg.step_ctl().answer(&conn, s, next, &self.due.reads);
            // The kind of due-ness after the answer: the framework reads the flags first.
            if self.due.wake {
                c.flags.fetch_or(CONN_WAKE, Ordering::AcqRel);
            } else {
                c.flags.fetch_and(!CONN_WAKE, Ordering::AcqRel);
            }
            if c.flags.load(Ordering::Acquire) & CONN_EVENT == 0 {
                c.flags.fetch_or(CONN_EVENT, Ordering::AcqRel);
            }
        }
        let h = seg.header();
        segment::wake(&h.ack_seq, &h.ack_waiters);
    }

    /// A wake-on-change writer's first lock ([`Participant::wake_on_change_writer`]): from the
    /// step the framework is at on, it takes part as an event-driven connection, due where the
    /// PUBLISH set changed. The lock flags it a writer; until its first commit it would
    /// otherwise be a lock-step writer owing every step, and that commit may be long in coming:
    /// a DDS node's first sample can answer a step the framework has left (the gateway drops
    /// it, docs/gateway.md) and the node then sends nothing until the set changes again.
    pub(super) fn join_on_change(&self) {
        let seg = &self.seg;
        if seg.conn(self.slot).is_some_and(|c| c.flags.load(Ordering::Acquire) & CONN_EVENT == 0) {
            let k = seg.header().pub_step.load(Ordering::Acquire);
            // Due at step k itself only if its set changed: the node answers that change.
            self.answer_as(k.saturating_sub(1), u64::MAX);
        }
    }

    /// The index of the first step after the one this connection is at (index `read_index`,
    /// simulated time `read_sim`) that it is due at: the step of the time it asked for, the
    /// next multiple of its period, whichever comes first; with neither, the next step unless
    /// it waits for changes only. Indexes count the framework's steps of simulated time, so
    /// they stay right when the framework leaves steps out.
    fn next_due_after(&self) -> u64 {
        let n = self.read_index;
        let step = self.seg.sim_step();
        let mut next = u64::MAX;
        if let Some(t) = self.due.request {
            let ahead = match step {
                Some(dt) => ((t - self.read_sim) / dt - STEP_TOLERANCE).ceil(),
                None => 1.0,
            };
            // At least the next step; far-off times saturate.
            next = next.min(n.saturating_add(if ahead >= 1.0 { ahead as u64 } else { 1 }));
        }
        if let Some(p) = self.due.period_steps {
            next = next.min((n / p).saturating_add(1).saturating_mul(p));
        }
        if next == u64::MAX && !self.due.wake {
            next = n + 1;
        }
        next
    }

    /// Asks to be due next at the first step at or after simulated time `t` (seconds): a
    /// time within a millionth of a step of a step's time counts as that step. Once: the
    /// request is used up at that step. Takes effect when this connection asks for its next
    /// step. In a domain that is not event-driven it changes nothing (the participant is due
    /// at every step there).
    pub fn request_time(&mut self, t: f64) -> Result<(), ShmError> {
        if !t.is_finite() {
            return Err(self.invalid_timing("a requested time", t, "not a finite number".into()));
        }
        self.due.said = true;
        self.due.asked = None;
        self.due.request = Some(self.due.request.map_or(t, |r| r.min(t)));
        Ok(())
    }

    /// Also due at any step whose PUBLISH set differs from the step before (`on`), or not.
    pub fn set_wake_on_change(&mut self, on: bool) {
        self.due.said = true;
        self.due.asked = None;
        self.due.wake = on;
    }

    /// Due every `seconds` of simulated time (a whole multiple of the framework's step), at
    /// the steps whose time is a multiple of it; 0 turns the period off.
    pub fn set_period(&mut self, seconds: f64) -> Result<(), ShmError> {
        self.due.asked = None;
        if seconds == 0.0 {
            self.due.said = true;
            self.due.period_steps = None;
            return Ok(());
        }
        if !seconds.is_finite() || seconds < 0.0 {
            return Err(self.invalid_timing("a period of", seconds, "must be a positive number of seconds".into()));
        }
        let Some(dt) = self.seg.sim_step() else {
            return Err(self.invalid_timing(
                "a period of",
                seconds,
                "the framework has not said its step yet (it says it when it creates the domain)".into(),
            ));
        };
        let n = seconds / dt;
        if n.round() < 1.0 || (n - n.round()).abs() > STEP_TOLERANCE * n.max(1.0) {
            return Err(self.invalid_timing(
                "a period of",
                seconds,
                format!("must be a whole multiple of the framework's step ({dt} s)"),
            ));
        }
        self.due.said = true;
        self.due.period_steps = Some(n.round() as u64);
        Ok(())
    }

    /// A DDS writer through the gateway, in an event-driven domain: due at the steps whose
    /// PUBLISH set changed, each answered by its commit (it never asks for a step itself).
    pub fn wake_on_change_writer(&mut self) {
        self.due = Due { said: true, wake: true, answer_on_commit: true, ..Due::default() };
    }

    /// Notes that this connection reads PUBLISH item `index` (its index in the set): woken on
    /// change, it is due where one of the items it reads changed (none noted: any item). The
    /// RTAPI notes the items of RTSubscribe and of RTGetBuffer.
    pub fn reads_item(&mut self, index: usize) {
        let (w, bit) = item_bit(index);
        if self.due.reads[w] & bit == 0 {
            self.due.reads[w] |= bit;
            self.due.asked = None;
        }
    }

    fn invalid_timing(&self, what: &'static str, value: f64, reason: String) -> ShmError {
        ShmError::InvalidTiming { domain: self.seg.info.name.clone(), what, value, reason }
    }

    /// An event-driven connection whose commit answers its step ([`Participant::wake_on_change_writer`]).
    pub(super) fn answer_if_on_commit(&mut self) {
        if self.due.answer_on_commit && self.event_driven() {
            self.ask_next();
        }
    }
}
