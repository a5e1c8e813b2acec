//! The real-time loop: absolute deadlines (`start + k × period`, so no drift accumulates),
//! lateness and overruns measured; real-time scheduling (SCHED_FIFO, locked memory, a pinned
//! CPU) where the machine allows it; one step of every domain of a framework. Used by
//! `tutti host` and the UAV demo.

use std::time::{Duration, Instant};

use anyhow::Context;
use tutti_core::shm::{os, Framework, StepReport};

/// What `--realtime` asks for.
#[derive(Debug, Clone, Copy, Default)]
pub struct RealtimeRequest {
    /// Pin the stepping thread to this CPU.
    pub cpu: Option<usize>,
    /// SCHED_FIFO priority (default: the middle of the range, 50 on Linux).
    pub priority: Option<i32>,
}

/// What could be applied: each entry is a line for the user.
#[derive(Debug, Default)]
pub struct RealtimeOutcome {
    pub applied: Vec<String>,
    pub warnings: Vec<String>,
}

/// Applies `req` to the calling thread, as far as the machine allows: memory locking
/// (mlockall), CPU pinning, SCHED_FIFO. Nothing here is fatal: what fails becomes a warning
/// naming the privilege or limit that is missing, and the loop runs with normal scheduling.
pub fn enter_realtime(req: &RealtimeRequest) -> RealtimeOutcome {
    let mut out = RealtimeOutcome::default();
    match os::lock_memory() {
        Ok(()) => out.applied.push("memory locked (mlockall)".into()),
        Err(e) => out.warnings.push(format!(
            "memory not locked: mlockall failed ({e}); needs CAP_IPC_LOCK or a larger RLIMIT_MEMLOCK (ulimit -l)"
        )),
    }
    if let Some(cpu) = req.cpu {
        let allowed = os::allowed_cpus().unwrap_or_default();
        if !allowed.is_empty() && !allowed.contains(&cpu) {
            out.warnings.push(format!("not pinned: CPU {cpu} is not one of the allowed CPUs {allowed:?}"));
        } else {
            match os::pin_to_cpu(cpu) {
                Ok(()) => out.applied.push(format!("pinned to CPU {cpu}")),
                Err(e) => out.warnings.push(format!("not pinned to CPU {cpu}: {e}")),
            }
        }
    }
    let (lo, hi) = os::fifo_priority_range();
    let prio = req.priority.unwrap_or((lo + hi) / 2).clamp(lo, hi);
    if req.priority.is_some_and(|p| p != prio) {
        out.warnings.push(format!("priority clamped to {prio} (SCHED_FIFO allows {lo}..{hi})"));
    }
    match os::set_fifo_priority(prio) {
        Ok(()) => out.applied.push(format!("SCHED_FIFO priority {prio}")),
        Err(e) => out.warnings.push(format!(
            "normal scheduling: SCHED_FIFO {prio} refused ({e}); needs root or CAP_SYS_NICE (e.g. sudo setcap \
             cap_sys_nice,cap_ipc_lock+ep $(which tutti)), or an RLIMIT_RTPRIO of at least {prio}; \
             containers usually forbid it"
        )),
    }
    out
}

/// Applies `req` and prints what was applied and what was not, prefixed by `who`.
pub fn enter_realtime_verbose(who: &str, req: &RealtimeRequest) -> RealtimeOutcome {
    let out = enter_realtime(req);
    if !out.applied.is_empty() {
        eprintln!("{who}: real-time: {}", out.applied.join(", "));
    }
    for w in &out.warnings {
        eprintln!("{who}: warning: {w}");
    }
    out
}

/// One step of every domain of `fw` at simulated time `sim`: publish to all, then complete
/// all, so that the participants of the different domains work in parallel; records the
/// loop's timing for `tutti status`. `publish[i]` is domain i's PUBLISH set.
pub fn step_all(
    fw: &mut Framework,
    publish: &[Vec<u8>],
    sim: f64,
    period: Duration,
    tick: &Tick,
) -> anyhow::Result<Vec<StepReport>> {
    for (host, data) in fw.domains.iter_mut().zip(publish) {
        // Known before the step is: a participant sizes its step by it (tutti fmu run).
        host.set_period(period);
        host.publish_step(data, sim).with_context(|| format!("domain '{}'", host.info().name))?;
    }
    let mut reports = Vec::with_capacity(fw.domains.len());
    for host in fw.domains.iter_mut() {
        let report = host.complete_step().with_context(|| format!("domain '{}'", host.info().name))?;
        host.record_timing(period, tick.late, tick.overrun);
        reports.push(report);
    }
    Ok(reports)
}

/// Records the step every domain of `fw` just made (as [`step_all`] reported it, with the
/// `publish` sets it published at simulated time `sim`) in each of `recorders`.
pub fn record_step(
    recorders: &mut [Box<dyn tutti_record::Recorder>],
    fw: &Framework,
    reports: &[StepReport],
    publish: &[Vec<u8>],
    sim: f64,
    run_start: Instant,
) -> anyhow::Result<()> {
    if recorders.is_empty() {
        return Ok(());
    }
    let (wall_ns, elapsed_s) = (tutti_record::now_ns(), run_start.elapsed().as_secs_f64());
    for (i, (host, report)) in fw.domains.iter().zip(reports).enumerate() {
        let step = tutti_record::Step {
            step: report.step,
            sim_time: sim,
            wall_ns,
            elapsed_s,
            connections: host.connection_count(),
            owner_pid: host.segment().exclusive_owner_pid(),
            publish: &publish[i],
            subscribe: host.subscribe(),
        };
        for rec in recorders.iter_mut() {
            rec.step(i, &step).context("writing the recording")?;
        }
    }
    Ok(())
}

/// `--wait-for DOMAIN=N`: hold the first step until N writers have connected to DOMAIN.
pub fn parse_wait_for(s: &str) -> Result<(String, usize), String> {
    let (domain, n) = s.split_once('=').ok_or_else(|| format!("'{s}': expected DOMAIN=N (e.g. multiuav_uav2=1)"))?;
    let n: usize = n.trim().parse().map_err(|_| format!("'{s}': '{n}' is not a number of writers"))?;
    Ok((domain.trim().to_string(), n))
}

/// Holds the participants of `fw` in wait-to-go until each domain of `wants` has its number
/// of writers (participants that have claimed the SUBSCRIBE set, e.g. by a first commit), so
/// that the first step is answered by all of them; prints progress every 5 s as `who`.
/// Returns false when `stop` was set first. The framework must have been created holding.
pub fn wait_for_writers(
    fw: &mut Framework,
    wants: &[(String, usize)],
    stop: &std::sync::atomic::AtomicBool,
    who: &str,
    quiet: bool,
) -> anyhow::Result<bool> {
    let started = Instant::now();
    let mut last_report = Instant::now();
    for (domain, n) in wants {
        let host = fw.domain(domain).ok_or_else(|| anyhow::anyhow!("--wait-for {domain}={n}: no domain '{domain}'"))?;
        loop {
            if stop.load(std::sync::atomic::Ordering::SeqCst) {
                return Ok(false);
            }
            let seen =
                host.wait_for_writers(*n, Duration::from_millis(200)).with_context(|| format!("domain '{domain}'"))?;
            if seen >= *n {
                break;
            }
            if !quiet && last_report.elapsed() >= Duration::from_secs(5) {
                last_report = Instant::now();
                eprintln!(
                    "{who}: waiting {:.0} s for {n} writer(s) in {domain} ({seen} so far)",
                    started.elapsed().as_secs_f64()
                );
            }
        }
    }
    if !quiet && !wants.is_empty() {
        let list: Vec<String> = wants.iter().map(|(d, n)| format!("{d}={n}")).collect();
        eprintln!("{who}: writers connected ({}): stepping", list.join(", "));
    }
    Ok(true)
}

/// Periodic deadlines.
#[derive(Debug)]
pub struct Ticker {
    start: Instant,
    period: Duration,
    k: u64,
    /// Late steps run back to back instead of being skipped.
    catch_up: bool,
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
        Ticker { start: Instant::now(), period, k: 0, catch_up: false, overruns: 0, max_late: Duration::ZERO }
    }

    /// A ticker that never skips a deadline: after an overrun the late steps follow each other
    /// at once until the loop is on time again, so that tick `k` is always the `k`-th step
    /// (simulated time stays at one period per step, whatever the machine's load).
    pub fn catching_up(period: Duration) -> Self {
        Ticker { catch_up: true, ..Ticker::new(period) }
    }

    /// Waits for the next deadline. When the loop is a period or more behind, the overrun is
    /// counted and the missed deadlines are skipped (no burst of catch-up steps), unless the
    /// ticker catches up ([`Ticker::catching_up`]).
    pub fn wait(&mut self) -> Tick {
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

    #[test]
    fn realtime_request_never_fails_only_warns() {
        // Whatever this machine allows, the outcome names every part: applied or a warning.
        let out = enter_realtime(&RealtimeRequest { cpu: Some(usize::MAX / 2), priority: Some(1000) });
        let all = [out.applied.clone(), out.warnings.clone()].concat().join("\n");
        assert!(all.contains("memory"), "{all}");
        assert!(all.contains("not pinned"), "{all}");
        assert!(all.contains("SCHED_FIFO"), "{all}");
        assert!(out.warnings.iter().any(|w| w.contains("clamped")), "{all}");
        // Back to normal scheduling so the other tests are not affected.
        let _ = os::set_normal_scheduling();
        let _ = os::unlock_memory();
    }
}
