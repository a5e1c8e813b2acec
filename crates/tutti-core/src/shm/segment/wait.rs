//! Waiting for the other side of a domain: one mechanism, spinning, polling or blocking on
//! a futex word, serves every wait of the crate.

use std::time::{Duration, Instant};

use serde::Serialize;

use crate::shm::os;
use crate::sync::{AtomicU32, Ordering};

/// How a connection or the framework waits for the other side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum WaitMode {
    /// Busy-wait: lowest latency, one core at 100 %.
    Spin,
    /// Check every given interval (the product's "flag delay").
    Poll(Duration),
    /// Sleep in the kernel (futex) until woken: no CPU use, a wake-up costs tens of µs.
    Block,
    /// Spin for at most the given time from the start of each wait, then sleep in the kernel
    /// as `Block` does: a hand-off that comes soon costs no wake-up, a long wait no CPU.
    Adaptive(Duration),
}

impl WaitMode {
    /// `adaptive` without a time: the spin this machine suits. With fewer than 4 cores a
    /// spinning waiter takes the core the thread it waits for needs (`tutti-bench scale` on 2
    /// cores: spinning 5-15x slower than blocking), so it does not spin at all; with more, it
    /// spins up to 50 µs, about three times a blocking hand-off to another core (15-17 µs).
    pub fn adaptive() -> WaitMode {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        WaitMode::Adaptive(if cores >= 4 { Duration::from_micros(50) } else { Duration::ZERO })
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
        // Adaptive: spinning for this long, then blocking.
        let spin_for = match self.mode {
            WaitMode::Adaptive(d) => Some(d),
            _ => None,
        };
        let mut spinning = self.mode == WaitMode::Spin || spin_for.is_some_and(|d| !d.is_zero());
        loop {
            let seen = self.futex.load(Ordering::Acquire);
            if ready()? {
                return Ok(Waited::Ready);
            }
            // Time is read once every 64 turns while spinning: Instant::now costs ~25 ns.
            spins = spins.wrapping_add(1);
            let now = if spinning && spins % 64 != 0 { None } else { Some(Instant::now()) };
            if let Some(now) = now {
                if now >= deadline {
                    return Ok(Waited::TimedOut);
                }
                if now >= next_check {
                    check()?;
                    next_check = now + self.check_every;
                }
                if spin_for.is_some_and(|d| now.duration_since(start) >= d) {
                    spinning = false;
                }
                match self.mode {
                    // Give the core away now and then: on an overloaded machine a pure spin
                    // can starve the very process it waits for.
                    WaitMode::Spin | WaitMode::Adaptive(_) if spinning && spins % 4096 == 0 => std::thread::yield_now(),
                    WaitMode::Spin | WaitMode::Adaptive(_) if spinning => std::hint::spin_loop(),
                    WaitMode::Poll(d) => std::thread::sleep(d.min(deadline - now)),
                    WaitMode::Spin | WaitMode::Adaptive(_) | WaitMode::Block => {
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
            } else {
                std::hint::spin_loop();
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
