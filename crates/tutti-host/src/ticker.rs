//! Periodic deadlines: absolute (`start + k × period`, so no drift accumulates), with lateness
//! and overruns measured; late steps skipped or, for a ticker that catches up, run back to back.

use std::time::{Duration, Instant};

/// Periodic deadlines.
#[derive(Debug)]
pub struct Ticker {
    start: Instant,
    period: Duration,
    k: u64,
    /// Late steps run back to back instead of being skipped.
    catch_up: bool,
    /// Deadlines the loop was a whole period or more behind.
    pub overruns: u64,
    /// The largest lateness of a release so far.
    pub max_late: Duration,
}

/// One release of the loop.
#[derive(Debug, Clone, Copy)]
pub struct Tick {
    /// Index of the period (0, 1, …).
    pub k: u64,
    /// How late the loop woke after the deadline.
    pub late: Duration,
    /// The previous step ran past this deadline by a whole period or more.
    pub overrun: bool,
}

impl Ticker {
    /// A ticker whose first deadline is now, skipping deadlines the loop falls behind.
    pub fn new(period: Duration) -> Self {
        Ticker { start: Instant::now(), period, k: 0, catch_up: false, overruns: 0, max_late: Duration::ZERO }
    }

    /// A ticker that never skips a deadline: after an overrun the late steps follow each other
    /// at once until the loop is on time again, so that tick `k` is always the `k`-th step
    /// (simulated time stays at one period per step, whatever the machine's load).
    pub fn catching_up(period: Duration) -> Self {
        Ticker { catch_up: true, ..Ticker::new(period) }
    }

    /// The index of the next release.
    pub fn next_k(&self) -> u64 {
        self.k
    }

    /// Moves the deadlines so that release `k` is due now (a run that resumes from a pause,
    /// or is reset to step 0): the time in between counts as neither lateness nor overrun.
    pub fn restart_at(&mut self, k: u64) {
        let now = Instant::now();
        self.start = now.checked_sub(self.period.mul_f64(k as f64)).unwrap_or(now);
        self.k = k;
    }

    /// Leaves out the next `n` releases (a run not paced by the wall clock that jumps over
    /// steps nobody is due at).
    pub fn skip(&mut self, n: u64) {
        self.k += n;
    }

    /// A release now, outside the deadlines (a step made while paused).
    pub fn release_now(&mut self) -> Tick {
        let tick = Tick { k: self.k, late: Duration::ZERO, overrun: false };
        self.k += 1;
        tick
    }

    /// Waits for the next deadline. When the loop is a period or more behind, the overrun is
    /// counted and the missed deadlines are skipped (no burst of catch-up steps), unless the
    /// ticker catches up ([`Ticker::catching_up`]).
    pub fn wait(&mut self) -> Tick {
        if self.period.is_zero() {
            // Not paced by the wall clock: as fast as the steps go.
            return self.release_now();
        }
        let mut deadline = self.start + self.period.mul_f64(self.k as f64);
        let now = Instant::now();
        let mut overrun = false;
        if now >= deadline + self.period {
            overrun = true;
            self.overruns += 1;
            if !self.catch_up {
                let behind = (now - deadline).as_nanos() / self.period.as_nanos().max(1);
                self.k += behind as u64;
                deadline = self.start + self.period.mul_f64(self.k as f64);
            }
        }
        // Sleep most of the way, then spin the last stretch for a precise release.
        loop {
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            let left = deadline - now;
            if left > Duration::from_micros(300) {
                std::thread::sleep(left - Duration::from_micros(200));
            } else {
                std::thread::yield_now();
            }
        }
        let late = Instant::now().saturating_duration_since(deadline);
        self.max_late = self.max_late.max(late);
        let tick = Tick { k: self.k, late, overrun };
        self.k += 1;
        tick
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_count_up_and_overruns_skip_ahead() {
        let mut t = Ticker::new(Duration::from_millis(2));
        assert_eq!(t.wait().k, 0);
        assert_eq!(t.wait().k, 1);
        std::thread::sleep(Duration::from_millis(10));
        let tick = t.wait();
        assert!(tick.overrun);
        assert!(tick.k > 2);
        assert_eq!(t.overruns, 1);
    }

    #[test]
    fn a_catching_up_ticker_never_skips_a_tick() {
        let mut t = Ticker::catching_up(Duration::from_millis(2));
        assert_eq!(t.wait().k, 0);
        std::thread::sleep(Duration::from_millis(10));
        let tick = t.wait();
        assert!(tick.overrun);
        assert_eq!(tick.k, 1, "the late tick is the next one, not a later one");
        assert_eq!(t.wait().k, 2);
    }
}
