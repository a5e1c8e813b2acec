//! `--mirror`: the gateway is the framework of local copies of the domains, fed from DDS.
//!
//! Each PUBLISH sample from `rt/D/publish` is published to the local segment as one step
//! (in a synchronous domain the step then waits, up to the timeout, for the local
//! participants), and the local SUBSCRIBE set goes out on `rt/D/subscribe`: after each step
//! in a synchronous domain (tagged with the step it answers, so the home gateway commits it
//! for that step), whenever local writers commit in an asynchronous one. Nothing is sent
//! before a local writer has published once, so an unseeded mirror never seeds the home side
//! with defaults. DDS is the transport; there is no protocol of our own.
//!
//! A synchronous mirror starts at the home's current step (docs/run.md, "Sites and
//! lookahead"): of the PUBLISH samples waiting, it steps only those within its lookahead K of
//! the newest (K = 0: the newest alone). In lock-step the home publishes at most K + 1 steps
//! the mirror has not answered, so nothing is skipped; steps the home made without this site
//! (before it joined, or while it was away) are skipped instead of worked through one by one
//! long after the home has left them.

use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use tracing::{info, warn};
use tutti_core::ddf::Role;
use tutti_core::shm::DomainHost;

use super::to_dds::Outbound;
use super::ShmConfig;
use crate::cdr::TypedSample;
use crate::stats::{LogLimit, SetStats, Stats};

/// Where a mirror counts: the gateway's totals, and the counters of its PUBLISH set (in
/// from DDS) and of its SUBSCRIBE set (out to DDS).
#[derive(Debug, Clone)]
pub struct MirrorCounters {
    pub total: Arc<Stats>,
    pub publish: Arc<SetStats>,
    pub subscribe: Arc<SetStats>,
}

/// Starts the thread that hosts one mirrored domain: it publishes each sample it receives on
/// `rx` (from the PUBLISH reader's sink, on the engine's receive path) as a step, and sends
/// the local SUBSCRIBE set with `out` (None when the config file leaves that set out).
/// `lookahead`: the steps of lookahead the home gateway gives the domain (the steps it may
/// publish ahead of this site's answers).
pub fn spawn(
    host: DomainHost,
    rx: Receiver<TypedSample>,
    out: Option<Outbound>,
    cfg: ShmConfig,
    counters: MirrorCounters,
    lookahead: u32,
) -> std::io::Result<JoinHandle<()>> {
    thread::Builder::new()
        .name("tutti-gw-mirror".into())
        .stack_size(512 << 10)
        .spawn(move || serve(host, &rx, out, &cfg, counters, u64::from(lookahead)))
}

/// The mirror's thread: until the gateway stops, publishes each sample of `rx` as a step of
/// `host`, and sends the SUBSCRIBE set after each step (synchronous) or whenever local writers
/// commit (asynchronous); sweeps the connections every 50 ms.
fn serve(
    mut host: DomainHost,
    rx: &Receiver<TypedSample>,
    mut out: Option<Outbound>,
    cfg: &ShmConfig,
    counters: MirrorCounters,
    lookahead: u64,
) {
    let MirrorCounters { total: stats, publish, subscribe } = counters;
    let name = host.info().name.clone();
    let sync = host.info().flags.synchronous;
    let mut last_step = 0u64;
    let mut sim_time = 0.0;
    let mut last_sub = host.segment().generation(Role::Subscribe);
    let mut last_sweep = Instant::now();
    let mut log = LogLimit::new(Duration::from_secs(5));
    let patience = cfg.patience();
    let idle = if cfg.poll.is_zero() { Duration::from_micros(100) } else { cfg.poll };
    let mut waiting: VecDeque<TypedSample> = VecDeque::new();
    let mut skip_log = LogLimit::new(Duration::from_secs(5));
    while !cfg.stop.load(Ordering::Acquire) {
        if waiting.is_empty() {
            match rx.recv_timeout(idle) {
                Ok(s) => waiting.push_back(s),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        if sync {
            let skipped = start_at_home(&mut waiting, rx, lookahead);
            if skipped > 0 {
                SetStats::add(Some(&publish), |s| &s.dropped, &stats.skipped, skipped);
                if let (Some(_), Some(s)) = (skip_log.allow(), waiting.front()) {
                    info!(
                        domain = %name,
                        "the mirror starts at step {} (the home's latest, within {lookahead} steps of lookahead): {skipped} steps the home made without this site are skipped",
                        s.step
                    );
                }
            }
        }
        if let Some(s) = waiting.pop_front() {
            if s.data.len() != host.info().publish.size as usize {
                SetStats::add(Some(&publish), |s| &s.bad_input, &stats.bad_samples, 1);
                continue;
            }
            let r = host.publish_step(&s.data, s.sim_time).and_then(|_| {
                if sync {
                    host.complete_step().map(|_| ())
                } else {
                    Ok(())
                }
            });
            if let Err(e) = r {
                SetStats::add(Some(&publish), |s| &s.dropped, &stats.errors, 1);
                if log.allow().is_some() {
                    warn!(domain = %name, "mirror step failed: {e}");
                }
                continue;
            }
            SetStats::add(Some(&publish), |s| &s.samples_in, &stats.from_dds, 1);
            last_step = s.step;
            sim_time = s.sim_time;
            if let (true, true, Some(out)) = (sync, host.seeded(), out.as_mut()) {
                last_sub = host.segment().generation(Role::Subscribe);
                out.send_step(last_step, sim_time, host.subscribe(), &stats, Some(&subscribe), &patience);
            }
        }
        if !sync {
            let cur = host.segment().generation(Role::Subscribe);
            if cur != last_sub && host.seeded() {
                last_sub = cur;
                if let (Some(out), Ok(sub)) = (out.as_mut(), host.read_subscribe()) {
                    out.send(last_step, sim_time, sub, &stats, Some(&subscribe));
                }
            }
        }
        if last_sweep.elapsed() > Duration::from_millis(50) {
            host.sweep();
            last_sweep = Instant::now();
        }
    }
}

/// Takes every sample waiting on `rx` into `waiting`, then drops those more than `lookahead`
/// steps before the newest (steps the home made without this site, which it no longer waits
/// for); returns how many it dropped.
fn start_at_home(waiting: &mut VecDeque<TypedSample>, rx: &Receiver<TypedSample>, lookahead: u64) -> u64 {
    waiting.extend(rx.try_iter());
    let Some(newest) = waiting.back().map(|s| s.step) else { return 0 };
    let mut skipped = 0;
    while waiting.len() > 1 && waiting.front().is_some_and(|s| s.step.saturating_add(lookahead) < newest) {
        waiting.pop_front();
        skipped += 1;
    }
    skipped
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(step: u64) -> TypedSample {
        TypedSample { step, sim_time: 0.0, data: Vec::new() }
    }

    fn steps(w: &VecDeque<TypedSample>) -> Vec<u64> {
        w.iter().map(|s| s.step).collect()
    }

    #[test]
    fn a_mirror_keeps_the_steps_within_its_lookahead_of_the_newest_and_skips_the_rest() {
        let (tx, rx) = std::sync::mpsc::channel();
        let mut w = VecDeque::new();
        // Lock-step: one step waits, nothing to skip.
        tx.send(sample(7)).unwrap();
        assert_eq!((start_at_home(&mut w, &rx, 0), steps(&w)), (0, vec![7]));
        // A backlog the home made alone: only its newest is stepped at K = 0 ...
        w.clear();
        (1..=100).for_each(|n| tx.send(sample(n)).unwrap());
        assert_eq!((start_at_home(&mut w, &rx, 0), steps(&w)), (99, vec![100]));
        // ... and the newest K + 1 with a lookahead of K, which the home may all be owed.
        w.clear();
        (1..=100).for_each(|n| tx.send(sample(n)).unwrap());
        assert_eq!((start_at_home(&mut w, &rx, 4), steps(&w)), (95, vec![96, 97, 98, 99, 100]));
        // A home that started again (its steps count from 1 anew) is not skipped.
        w.clear();
        [500, 501, 1, 2].into_iter().for_each(|n| tx.send(sample(n)).unwrap());
        assert_eq!((start_at_home(&mut w, &rx, 0), steps(&w)), (0, vec![500, 501, 1, 2]));
    }
}
