//! The pieces of a framework's step that every runner shares (the host, the demo, the
//! benchmarks, replay): one step of every domain, and holding the first step until the
//! participants that must answer it are connected.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use tutti_core::shm::{Framework, StepReport};

use crate::{HostError, Tick};

/// One step of every domain of `fw` at simulated time `sim`: publish to all, then complete
/// all, so that the participants of the different domains work in parallel; records the
/// loop's timing for `tutti status`. `publish[i]` is domain i's PUBLISH set.
pub fn step_all(
    fw: &mut Framework,
    publish: &[Vec<u8>],
    sim: f64,
    period: Duration,
    tick: &Tick,
) -> Result<Vec<StepReport>, HostError> {
    publish_all(fw, publish, sim, period)?;
    complete_all(fw, period, tick)
}

/// The first half of [`step_all`]: publishes the next step of every domain (`publish[i]` is
/// domain i's PUBLISH set), waiting for none of their participants yet.
pub fn publish_all(fw: &mut Framework, publish: &[Vec<u8>], sim: f64, period: Duration) -> Result<(), HostError> {
    for (host, data) in fw.domains.iter_mut().zip(publish) {
        // Known before the step is: a participant sizes its step by it (tutti fmu run).
        host.set_period(period);
        host.publish_step(data, sim)
            .map_err(|source| HostError::Domain { domain: host.info().name.clone(), source })?;
    }
    Ok(())
}

/// The second half of [`step_all`]: completes the step [`publish_all`] published in every
/// domain (a synchronous one waits for its participants) and records the loop's timing.
pub fn complete_all(fw: &mut Framework, period: Duration, tick: &Tick) -> Result<Vec<StepReport>, HostError> {
    let mut reports = Vec::with_capacity(fw.domains.len());
    for host in fw.domains.iter_mut() {
        let report =
            host.complete_step().map_err(|source| HostError::Domain { domain: host.info().name.clone(), source })?;
        host.record_timing(period, tick.late, tick.overrun);
        reports.push(report);
    }
    Ok(reports)
}

/// A `--wait-for DOMAIN=N` that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WaitForError {
    #[error("'{0}': expected DOMAIN=N (e.g. multiuav_uav2=1)")]
    Form(String),
    #[error("'{given}': '{count}' is not a number of writers")]
    Count { given: String, count: String },
}

/// `--wait-for DOMAIN=N`: hold the first step until N writers have connected to DOMAIN.
pub fn parse_wait_for(s: &str) -> Result<(String, usize), WaitForError> {
    let (domain, n) = s.split_once('=').ok_or_else(|| WaitForError::Form(s.to_string()))?;
    let n: usize = n.trim().parse().map_err(|_| WaitForError::Count { given: s.to_string(), count: n.to_string() })?;
    Ok((domain.trim().to_string(), n))
}

/// How a wait for writers stands (reported every 5 s while it lasts).
#[derive(Debug, Clone)]
pub struct WriterWait {
    pub domain: String,
    pub want: usize,
    pub seen: usize,
    pub waited: Duration,
}

/// Holds the participants of `fw` in wait-to-go until each domain of `wants` has its number
/// of writers (participants that have claimed the SUBSCRIBE set, e.g. by a first commit), so
/// that the first step is answered by all of them; calls `on_wait` every 5 s while it waits.
/// Returns false when `stop` was set first. The framework must have been created holding.
pub fn wait_for_writers(
    fw: &mut Framework,
    wants: &[(String, usize)],
    stop: &AtomicBool,
    mut on_wait: impl FnMut(&WriterWait),
) -> Result<bool, HostError> {
    let started = Instant::now();
    let mut last_report = Instant::now();
    for (domain, n) in wants {
        let host = fw.domain(domain).ok_or_else(|| HostError::WaitForDomain {
            domain: domain.clone(),
            writers: *n,
            ddf: "the framework".into(),
        })?;
        loop {
            if stop.load(Ordering::SeqCst) {
                return Ok(false);
            }
            let seen = host
                .wait_for_writers(*n, Duration::from_millis(200))
                .map_err(|source| HostError::Domain { domain: domain.clone(), source })?;
            if seen >= *n {
                break;
            }
            if last_report.elapsed() >= Duration::from_secs(5) {
                last_report = Instant::now();
                on_wait(&WriterWait { domain: domain.clone(), want: *n, seen, waited: started.elapsed() });
            }
        }
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wait_for_takes_a_domain_and_a_count() {
        assert_eq!(parse_wait_for(" d = 2"), Ok(("d".into(), 2)));
        assert!(parse_wait_for("d").unwrap_err().to_string().contains("expected DOMAIN=N"));
        assert!(parse_wait_for("d=x").unwrap_err().to_string().contains("not a number of writers"));
    }
}
