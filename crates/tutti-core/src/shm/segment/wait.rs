//! Waiting for the other side of a domain: one mechanism, spinning, polling or blocking on
//! a futex word, serves every wait of the crate.

use std::time::{Duration, Instant};

use serde::Serialize;

use crate::shm::os;
use crate::sync::{AtomicU32, Ordering};

/// How a connection or the framework waits for the other side (docs/timing.md, "Waits").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum WaitMode {
    /// Busy-wait: lowest latency, one core at 100 %.
    Spin,
    /// Check every given interval (the product's "flag delay").
    Poll(Duration),
    /// Sleep in the kernel (futex) until woken: no CPU use, but a wake-up costs a context
    /// switch, and tens of µs where it wakes a core that went idle.
    Block,
    /// Yield the core for at most the given time from the start of each wait, then sleep in
    /// the kernel as `Block` does: a hand-off that comes soon costs no wake-up, a long wait
    /// no CPU. The default ([`WaitMode::adaptive`]).
    Adaptive(Duration),
}

impl WaitMode {
    /// How long the default wait yields before it sleeps.
    pub const ADAPTIVE_SPIN: Duration = Duration::from_micros(50);

    /// `adaptive` without a time, the default: yields up to [`ADAPTIVE_SPIN`](Self::ADAPTIVE_SPIN),
    /// then blocks. 50 µs covers a hand-off between two participants with room to spare
    /// (3-4 µs yielding, 35-50 µs blocking on 2 cores; `tutti-bench scale`, docs/benchmarks.md
    /// "Scale"), and costs a run paced at 1 kHz at most 5 % of a core per waiter.
    pub const fn adaptive() -> WaitMode {
        WaitMode::Adaptive(Self::ADAPTIVE_SPIN)
    }
}

impl Default for WaitMode {
    fn default() -> WaitMode {
        WaitMode::adaptive()
    }
}

/// Waits for a condition, spinning, polling or blocking on a futex word, with a deadline
/// and a periodic liveness check. One mechanism serves every wait of the crate.
///
/// `ready` is tested first and after every wake-up; `futex`/`waiters` are the word the other
/// side bumps and the count of sleepers it checks before waking; `check` runs about every
/// `check_every` and may abort the wait.
pub(crate) struct Waiter<'a> {
    pub mode: WaitMode,
    pub futex: &'a AtomicU32,
    pub waiters: &'a AtomicU32,
    pub check_every: Duration,
}

/// Outcome of a wait.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Waited {
    Ready,
    TimedOut,
}

impl Waiter<'_> {
    pub fn wait<E>(
        &self,
        deadline: Instant,
        mut ready: impl FnMut() -> Result<bool, E>,
        mut check: impl FnMut() -> Result<(), E>,
    ) -> Result<Waited, E> {
        let start = Instant::now();
        let mut next_check = start + self.check_every;
        let mut spins: u32 = 0;
        loop {
            let seen = self.futex.load(Ordering::Acquire);
            if ready()? {
                return Ok(Waited::Ready);
            }
            spins = spins.wrapping_add(1);
            // A pure spin reads the time once every 64 turns (Instant::now costs ~25 ns); the
            // other waits, whose turns cost a system call, at every turn.
            if self.mode == WaitMode::Spin && spins % 64 != 0 {
                std::hint::spin_loop();
                continue;
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(Waited::TimedOut);
            }
            if now >= next_check {
                check()?;
                next_check = now + self.check_every;
            }
            match self.mode {
                // Give the core away now and then: on an overloaded machine a pure spin can
                // starve the very process it waits for.
                WaitMode::Spin if spins % 4096 == 0 => std::thread::yield_now(),
                WaitMode::Spin => std::hint::spin_loop(),
                // While its spin lasts an adaptive wait yields at every turn: a thread that is
                // runnable on this core (the one that will answer, where threads outnumber
                // cores) runs at once, and with none the turn comes straight back. The core
                // never goes idle, so the answer costs no wake-up of a sleeping core.
                WaitMode::Adaptive(d) if now.duration_since(start) < d => std::thread::yield_now(),
                WaitMode::Poll(d) => std::thread::sleep(d.min(deadline - now)),
                WaitMode::Adaptive(_) | WaitMode::Block => {
                    self.waiters.fetch_add(1, Ordering::SeqCst);
                    // Re-test after announcing ourselves: the other side bumps the word
                    // and then checks the waiter count, so one of us sees the other.
                    if !ready()? {
                        let limit = (deadline - now)
                            .min(next_check.saturating_duration_since(now))
                            .max(Duration::from_micros(50));
                        os::futex_wait(self.futex, seen, limit);
                    }
                    self.waiters.fetch_sub(1, Ordering::SeqCst);
                }
            }
        }
    }
}

/// Wakes the sleepers of a futex word after bumping it (the bump is the caller's).
pub(crate) fn wake(futex: &AtomicU32, waiters: &AtomicU32) {
    crate::sync::fence(Ordering::SeqCst);
    if waiters.load(Ordering::SeqCst) > 0 {
        os::futex_wake_all(futex);
    }
}
