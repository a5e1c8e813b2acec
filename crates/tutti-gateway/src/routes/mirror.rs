//! `--mirror`: the gateway is the framework of local copies of the domains, fed from DDS.
//!
//! Each PUBLISH sample from `rt/D/publish` is published to the local segment as one step
//! (in a synchronous domain the step then waits, up to the timeout, for the local
//! participants), and the local SUBSCRIBE set goes out on `rt/D/subscribe`: after each step
//! in a synchronous domain (tagged with the step it answers, so the home gateway commits it
//! for that step), whenever local writers commit in an asynchronous one. Nothing is sent
//! before a local writer has published once, so an unseeded mirror never seeds the home side
//! with defaults. DDS is the transport; there is no protocol of our own.

use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use tracing::warn;
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
pub fn spawn(
    host: DomainHost,
    rx: Receiver<TypedSample>,
    out: Option<Outbound>,
    cfg: ShmConfig,
    counters: MirrorCounters,
) -> std::io::Result<JoinHandle<()>> {
    thread::Builder::new()
        .name("tutti-gw-mirror".into())
        .stack_size(512 << 10)
        .spawn(move || serve(host, &rx, out, &cfg, counters))
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
    while !cfg.stop.load(Ordering::Acquire) {
        match rx.recv_timeout(idle) {
            Ok(s) => {
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
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
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
