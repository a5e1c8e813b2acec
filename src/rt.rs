//! The real-time loop: absolute deadlines (`start + k × period`, so no drift accumulates),
//! lateness and overruns measured. Used by `tutti host` and the UAV demo.

use std::time::{Duration, Instant};

/// Periodic deadlines.
#[derive(Debug)]
pub struct Ticker {
    start: Instant,
    period: Duration,
    k: u64,
    pub overruns: u64,
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
    pub fn new(period: Duration) -> Self {
        Ticker { start: Instant::now(), period, k: 0, overruns: 0, max_late: Duration::ZERO }
    }

    /// Waits for the next deadline. When the loop is a period or more behind, the overrun is
    /// counted and the missed deadlines are skipped (no burst of catch-up steps).
    pub fn wait(&mut self) -> Tick {
        let mut deadline = self.start + self.period.mul_f64(self.k as f64);
        let now = Instant::now();
        let mut overrun = false;
        if now >= deadline + self.period {
            overrun = true;
            self.overruns += 1;
            let behind = (now - deadline).as_nanos() / self.period.as_nanos().max(1);
            self.k += behind as u64;
            deadline = self.start + self.period.mul_f64(self.k as f64);
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
}
