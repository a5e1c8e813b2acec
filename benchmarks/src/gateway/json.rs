//! The object `--json` prints.

use serde::Serialize;
use tutti_gateway::EngineKind;

use super::figures::{rate, Fig, LargeFig, PlacementRun, Rtt};

/// One engine in one placement, as `--json` prints it.
#[derive(Debug, Serialize)]
struct JsonRun {
    engine: &'static str,
    placement: &'static str,
    /// Where the gateway ran: "process" or "in-process".
    gateway: &'static str,
    rtt_p50_us: Option<f64>,
    rtt_p99_us: Option<f64>,
    ddsperf_rtt_p50_us: Option<f64>,
    fastdds_rtt_p50_us: Option<f64>,
    /// Zenoh's own ping-pong (`z_ping`'s loop) on the same cores.
    zenoh_rtt_p50_us: Option<f64>,
    shm_to_dds_per_s: Option<f64>,
    dds_to_shm_per_s: Option<f64>,
    sync_steps_per_s: Option<f64>,
    rtt_paced_p50_us: Option<f64>,
    ddsperf_rtt_paced_p50_us: Option<f64>,
    /// ddsperf's `ping waitset` (its ping waits on a thread of its own).
    ddsperf_waitset_rtt_p50_us: Option<f64>,
    engine_rtt_p50_us: Option<f64>,
    /// The engine ping answered on the receive thread (as ddsperf's ping is).
    engine_rtt_in_listener_p50_us: Option<f64>,
    engine_alone_per_s: Option<f64>,
    sync_shm_to_dds_per_s: Option<f64>,
    sync_in_order: Option<bool>,
    /// Steps of the synchronous set missing from what the sink got, but for the start of its
    /// stream (`peers::JOINING`).
    sync_steps_lost: Option<u64>,
    /// Steps the sink's reader skipped where its stream started (DDS's start of a volatile
    /// reader: its first gap, within `peers::JOINING` of its first sample).
    sync_steps_skipped_joining: Option<u64>,
    sync_steps_unanswered: Option<u64>,
}

#[derive(Debug, Serialize)]
struct JsonLarge {
    engine: &'static str,
    startup_s: Option<f64>,
    /// Until a DDS peer had discovered every topic bridged.
    discovered_s: Option<f64>,
    /// The topics bridged.
    topics: Option<usize>,
    rss_mib: Option<f64>,
}

#[derive(Debug, Serialize)]
pub(super) struct Json {
    runs: Vec<JsonRun>,
    large: Vec<JsonLarge>,
}

/// `x` rounded to one decimal.
fn tenths(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
}

pub(super) fn to_json(runs: &[PlacementRun], large: &[(EngineKind, LargeFig)]) -> Json {
    let p50 = |f: &Fig<Rtt>| f.as_ref().ok().map(|t| tenths(t.p50));
    let runs = runs
        .iter()
        .flat_map(|run| {
            run.engines.iter().map(move |r| JsonRun {
                engine: r.engine.name(),
                placement: run.cpus.key,
                gateway: r.mode.key(),
                rtt_p50_us: p50(&r.rtt),
                rtt_p99_us: r.rtt.as_ref().ok().map(|t| tenths(t.p99)),
                ddsperf_rtt_p50_us: p50(&run.peers.ddsperf),
                fastdds_rtt_p50_us: p50(&run.peers.fastdds),
                zenoh_rtt_p50_us: p50(&run.peers.zenoh),
                shm_to_dds_per_s: r.to_dds.as_ref().ok().map(|x| x.round()),
                dds_to_shm_per_s: r.from_dds.as_ref().ok().map(|x| x.round()),
                sync_steps_per_s: r.lock.as_ref().ok().map(|l| l.per_s.round()),
                rtt_paced_p50_us: p50(&r.paced),
                ddsperf_rtt_paced_p50_us: p50(&run.peers.ddsperf_paced),
                ddsperf_waitset_rtt_p50_us: p50(&run.peers.ddsperf_waitset),
                engine_rtt_p50_us: p50(&r.ping),
                engine_rtt_in_listener_p50_us: p50(&r.ping_rx),
                engine_alone_per_s: r.alone.as_ref().ok().map(|x| x.round()),
                sync_shm_to_dds_per_s: r.sync.as_ref().ok().map(|s| rate(s).round()),
                sync_in_order: r.sync.as_ref().ok().map(|s| s.lost == 0 && s.misordered == 0),
                sync_steps_lost: r.sync.as_ref().ok().map(|s| s.lost),
                sync_steps_skipped_joining: r.sync.as_ref().ok().map(|s| s.skipped_joining),
                sync_steps_unanswered: r.lock.as_ref().ok().map(|l| l.unanswered),
            })
        })
        .collect();
    let large = large
        .iter()
        .map(|(engine, f)| JsonLarge {
            engine: engine.name(),
            startup_s: f.as_ref().ok().map(|l| (l.up.as_secs_f64() * 1000.0).round() / 1000.0),
            discovered_s: f.as_ref().ok().map(|l| (l.discovered.as_secs_f64() * 1000.0).round() / 1000.0),
            topics: f.as_ref().ok().map(|l| l.topics),
            rss_mib: f.as_ref().ok().map(|l| tenths(l.rss_kib as f64 / 1024.0)),
        })
        .collect();
    Json { runs, large }
}
