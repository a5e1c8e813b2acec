//! What `tutti-bench event` and `tutti-bench scale` share: a `Host` in the benchmark's
//! process, driven step by step as fast as its participants go, each step timed.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use anyhow::{bail, Context as _};
use tutti_host::{Host, Report};

/// The process's CPU time so far, every thread, user and system.
pub fn process_cpu() -> Duration {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ProcessCPUTime);
    Duration::new(t.tv_sec.max(0) as u64, t.tv_nsec.clamp(0, 999_999_999) as u32)
}

/// A driven run: what [`drive`] measured.
#[derive(Debug)]
pub struct Driven {
    /// Simulated steps (those an event-driven host jumped over included).
    pub steps: u64,
    /// Wall and CPU time (this process's) from the start to the last step.
    pub wall: Duration,
    pub cpu: Duration,
    /// The wall time of each `Host::step` call, sorted.
    pub step_times: Vec<Duration>,
    /// Steps that timed out waiting for a participant.
    pub timeouts: u64,
}

/// Waits (at most 60 s) until `participants` connections are up in the host's domains,
/// starts the run and makes `steps` simulated steps, timing each `Host::step`; `what` names
/// the benchmark in its messages.
pub fn drive(host: &mut Host, steps: u64, participants: usize, what: &str) -> anyhow::Result<Driven> {
    let deadline = Instant::now() + Duration::from_secs(60);
    let connected = |h: &Host| h.framework().domains.iter().map(|d| d.connection_count() as usize).sum::<usize>();
    while connected(host) < participants {
        if Instant::now() >= deadline {
            bail!("{} of {participants} participants connected within 60 s", connected(host));
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let stop = AtomicBool::new(false);
    let mut timeouts = 0u64;
    let mut on_report = |r: Report| {
        if let Report::StepTimedOut { .. } = r {
            timeouts += 1;
            eprintln!("bench {what}: {r}");
        }
    };
    let cpu0 = process_cpu();
    let t0 = Instant::now();
    if !host.start(&stop, &mut on_report).context("starting the run")? {
        bail!("the run stopped before it started");
    }
    let mut step_times = Vec::with_capacity(steps as usize);
    let mut next = 0u64;
    while next < steps {
        let s = Instant::now();
        next = host.step(&mut on_report).context("a step")?.k + 1;
        step_times.push(s.elapsed());
    }
    let (wall, cpu) = (t0.elapsed(), process_cpu().saturating_sub(cpu0));
    step_times.sort();
    Ok(Driven { steps: next, wall, cpu, step_times, timeouts })
}
