//! The typed reads of a segment that other crates use: consistent copies of its sets, and
//! the framework's words (its step, simulated time, period, pause and liveness).

use std::time::{Duration, Instant};

use super::format::{MAX_READ_TRIES, PAUSED, STATE_RUNNING};
use super::wait::{WaitMode, Waiter};
use super::Segment;
use crate::ddf::Role;
use crate::shm::bucket::Stamp;
use crate::shm::os::{self, ProcessId};
use crate::shm::ShmError;
use crate::sync::Ordering;

impl Segment {
    /// A consistent copy of `out.len()` bytes of set `role` from byte `offset` (the caller
    /// keeps the range inside the set); returns the value's generation.
    /// A copy that met a shrunk segment is refused (see [`intact`](Self::intact)).
    pub fn read_set_at(&self, role: Role, offset: usize, out: &mut [u8]) -> Result<u64, ShmError> {
        let generation =
            self.bucket(role).read_at(offset, out, MAX_READ_TRIES).ok_or_else(|| self.never_settles(role))?;
        self.intact()?;
        Ok(generation)
    }

    /// A consistent copy of the whole set `role`; returns its generation.
    pub fn read_set(&self, role: Role, out: &mut [u8]) -> Result<u64, ShmError> {
        self.read_set_at(role, 0, out)
    }

    /// The error of a set that never holds still long enough to be read.
    pub(crate) fn never_settles(&self, role: Role) -> ShmError {
        ShmError::Corrupt { domain: self.info.name.clone(), detail: format!("{role} set never settles") }
    }

    /// Waits (blocking on the step word, at most `timeout`) until the framework has
    /// published past step `after` or stopped; returns the latest step. Needs no connection:
    /// an observer that follows every step this way is never waited for.
    pub fn wait_step_after(&self, after: u64, timeout: Duration) -> u64 {
        let h = self.header();
        let w = Waiter { mode: WaitMode::Block, futex: &h.step_seq, waiters: &h.step_waiters, check_every: timeout };
        let deadline = Instant::now() + timeout;
        let _ = w.wait::<()>(
            deadline,
            || Ok(h.pub_step.load(Ordering::Acquire) > after || h.state.load(Ordering::Acquire) != STATE_RUNNING),
            || Ok(()),
        );
        h.pub_step.load(Ordering::Acquire)
    }

    /// How many times a set was written: a cheap test for new data before copying it.
    pub fn generation(&self, role: Role) -> u64 {
        self.header().sets[role as usize].current.load(Ordering::Acquire)
    }

    /// The step the framework published last (0 before its first).
    pub fn step(&self) -> u64 {
        self.header().pub_step.load(Ordering::Acquire)
    }

    /// The simulated time (seconds) of the step the framework published last.
    pub fn sim_time(&self) -> f64 {
        f64::from_bits(self.header().sim_time_bits.load(Ordering::Acquire))
    }

    /// How many times the framework set its simulated time back
    /// ([`DomainHost::reset_time`](crate::shm::DomainHost::reset_time)); [`sim_time`](Self::sim_time)
    /// is then the time it was set to, until the next step.
    pub fn time_resets(&self) -> u32 {
        self.header().time_resets.load(Ordering::Acquire)
    }

    /// The framework's step period, when it steps at a fixed rate (`None` when it has not
    /// said: it steps as fast as it can, or is driven from outside).
    pub fn period(&self) -> Option<Duration> {
        match self.header().period_ns.load(Ordering::Relaxed) {
            0 => None,
            ns => Some(Duration::from_nanos(ns)),
        }
    }

    /// The simulated time of one step, seconds, as the framework said it
    /// (`DomainHost::set_sim_step`); else the period, if the framework steps at a fixed rate.
    pub fn sim_step(&self) -> Option<f64> {
        match f64::from_bits(self.header().sim_step_bits.load(Ordering::Acquire)) {
            s if s > 0.0 && s.is_finite() => Some(s),
            _ => self.period().map(|p| p.as_secs_f64()),
        }
    }

    /// Whether the SUBSCRIBE set has been committed at least once (its values are no longer
    /// only the DDF's defaults).
    pub fn seeded(&self) -> bool {
        self.header().seeded.load(Ordering::Acquire) != 0
    }

    /// A consistent copy of the whole set `role` if one is had within `tries` attempts (a
    /// writer committing without pause can exhaust them); returns its generation. For a
    /// poller that would rather look again later than wait for a busy set to settle.
    pub fn try_read_set(&self, role: Role, out: &mut [u8], tries: u32) -> Option<u64> {
        self.try_read_set_stamped(role, out, tries).map(|(generation, _)| generation)
    }

    /// [`try_read_set`](Self::try_read_set), with the step the copy belongs to and that step's
    /// simulated time, read with it as one ([`Stamp`]): what a reader that labels values with
    /// their step uses, rather than the framework's latest step, which may have moved on.
    pub fn try_read_set_stamped(&self, role: Role, out: &mut [u8], tries: u32) -> Option<(u64, Stamp)> {
        self.bucket(role).read_stamped_at(0, out, tries).filter(|_| !self.map.truncated())
    }

    /// The stamp of set `role`'s latest value (without copying it), or `None` if it never
    /// holds still for `tries` attempts.
    pub fn stamp(&self, role: Role, tries: u32) -> Option<Stamp> {
        self.bucket(role).read_stamped_at(0, &mut [], tries).map(|(_, stamp)| stamp)
    }

    pub(crate) fn framework_id(&self) -> ProcessId {
        let h = self.header();
        ProcessId { pid: h.owner_pid.load(Ordering::Relaxed), start_time: h.owner_start.load(Ordering::Relaxed) }
    }

    /// Whether the framework is paused (its run holds every domain at a step boundary).
    pub fn paused(&self) -> bool {
        self.header().paused.load(Ordering::Acquire) == PAUSED
    }

    /// Whether a wait of at most `timeout` for the framework's next step may time out now:
    /// not while the framework is paused, nor within `timeout` after it resumed.
    pub(crate) fn step_wait_may_time_out(&self, timeout: Duration) -> bool {
        // Only the framework's own words count: the PAUSED pattern, and a resume that is
        // not in the future. Anything else (a segment written over) leaves the timeout as it
        // is, so that no wait can last for ever on a corrupted word.
        let h = self.header();
        if h.paused.load(Ordering::Acquire) == PAUSED {
            return false;
        }
        let (now, resumed) = (os::now_ns(), h.resumed_ns.load(Ordering::Acquire));
        let timeout = timeout.as_nanos().min(u128::from(u64::MAX)) as u64;
        resumed > now || now - resumed >= timeout
    }

    /// Whether the framework is running (state and process both alive).
    pub fn framework_alive(&self) -> bool {
        self.header().state.load(Ordering::Acquire) == STATE_RUNNING && os::is_alive(self.framework_id())
    }
}
