//! The figures of a run, each measured or with the reason it was not.

use std::time::Duration;

use anyhow::bail;
use tutti_gateway::EngineKind;

use super::processes::Cpus;
use super::{progress, GatewayMode};
use crate::nearest_rank;
use crate::peers::Received;

/// Round-trip percentiles (µs) and round trips that got no answer.
#[derive(Debug, Clone, Copy)]
pub(super) struct Rtt {
    pub p50: f64,
    pub p99: f64,
    pub lost: u32,
}

impl Rtt {
    pub(super) fn of(mut us: Vec<f64>, lost: u32) -> anyhow::Result<Rtt> {
        if us.is_empty() {
            bail!("no round trip completed");
        }
        us.sort_by(f64::total_cmp);
        Ok(Rtt { p50: nearest_rank(&us, 0.5), p99: nearest_rank(&us, 0.99), lost })
    }
}

/// A figure, or why it was not measured.
pub(super) type Fig<T> = Result<T, String>;

pub(super) fn fig<T>(r: anyhow::Result<T>) -> Fig<T> {
    r.map_err(|e| format!("{e:#}"))
}

/// [`fig`], with a failure also reported as progress under `what`.
pub(super) fn noted<T>(r: anyhow::Result<T>, what: &str) -> Fig<T> {
    let r = fig(r);
    if let Err(why) = &r {
        progress(&format!("{what}: not run ({why})"));
    }
    r
}

/// Lock-step across DDS: steps per second and steps whose answer was not the step's own.
#[derive(Debug, Clone, Copy)]
pub(super) struct LockStep {
    pub per_s: f64,
    pub unanswered: u64,
}

/// The figures of one engine in one placement, with the gateway in one place.
#[derive(Debug)]
pub(super) struct EngineRun {
    pub engine: EngineKind,
    pub mode: GatewayMode,
    pub rtt: Fig<Rtt>,
    pub paced: Fig<Rtt>,
    pub ping: Fig<Rtt>,
    /// The engine ping answered on the receive thread, as ddsperf's.
    pub ping_rx: Fig<Rtt>,
    pub to_dds: Fig<f64>,
    pub from_dds: Fig<f64>,
    pub alone: Fig<f64>,
    pub sync: Fig<Received>,
    pub lock: Fig<LockStep>,
}

/// DDS (and Zenoh) without tutti, once per placement.
#[derive(Debug)]
pub(super) struct Peers {
    pub ddsperf: Fig<Rtt>,
    pub ddsperf_paced: Fig<Rtt>,
    /// ddsperf's ping waiting for each pong on a thread of its own (`ping waitset`): the
    /// shape of a framework awaiting an answer.
    pub ddsperf_waitset: Fig<Rtt>,
    pub fastdds: Fig<Rtt>,
    /// Zenoh's own ping-pong (`z_ping` / `z_pong`'s loop), when the zenoh engine is measured.
    pub zenoh: Fig<Rtt>,
}

#[derive(Debug)]
pub(super) struct PlacementRun {
    pub cpus: Cpus,
    pub peers: Peers,
    pub engines: Vec<EngineRun>,
}

impl EngineRun {
    pub(super) fn not_run(engine: EngineKind, mode: GatewayMode, why: &str) -> EngineRun {
        fn no<T>(why: &str) -> Fig<T> {
            Err(why.to_string())
        }
        EngineRun {
            engine,
            mode,
            rtt: no(why),
            paced: no(why),
            ping: no(why),
            ping_rx: no(why),
            to_dds: no(why),
            from_dds: no(why),
            alone: no(why),
            sync: no(why),
            lock: no(why),
        }
    }
}

/// Samples per second of a sink's result.
pub(super) fn rate(r: &Received) -> f64 {
    if r.secs > 0.0 {
        r.samples as f64 / r.secs
    } else {
        0.0
    }
}

/// The gateway on the large DDF: up, every topic discovered by a DDS peer, topics bridged.
#[derive(Debug, Clone)]
pub(super) struct Large {
    pub up: Duration,
    pub discovered: Duration,
    pub topics: usize,
    pub rss_kib: u64,
}
pub(super) type LargeFig = Fig<Large>;
pub(super) type LargeRuns = Vec<(EngineKind, LargeFig)>;
