//! The tables the benchmark prints.

use std::path::Path;

use tutti_gateway::EngineKind;

use super::figures::{rate, EngineRun, Fig, LargeFig, Peers, PlacementRun, Rtt};
use super::{GatewayMode, ITEMS};

/// Targets of the Cyclone engine (against ddsperf) and of the Zenoh engine (against Zenoh's
/// own ping-pong): the round trip's p50 over the peer's, the rate shm -> the engine.
const TARGET_RTT_RATIO: f64 = 1.3;
const TARGET_RATE: f64 = 300_000.0;
const TARGET_STARTUP_S: f64 = 2.0;

/// Which figure of an engine's run a row shows.
type Get<T> = fn(&EngineRun) -> &Fig<T>;
/// Whether a figure meets its target, where one applies.
type Target = Option<fn(f64) -> bool>;

/// `met` where engine `e` is one of `engines`, whose target it is.
fn target_of(e: EngineKind, engines: &[EngineKind], met: fn(f64) -> bool) -> Target {
    engines.contains(&e).then_some(met)
}

/// One row of a placement's table: a label and one cell per engine.
fn row(label: &str, cells: impl IntoIterator<Item = String>) {
    let cells: String = cells.into_iter().map(|c| format!(" {c:>17}")).collect();
    println!("  {label:<62}{cells}");
}

/// A figure's cell: `show` of it, "-" when not measured; "ok" or "MISSED" after it where
/// `target` says whether it met its target.
fn cell<T>(f: &Fig<T>, show: impl Fn(&T) -> f64, digits: usize, target: Target) -> String {
    match f {
        Ok(v) => {
            let x = show(v);
            let mark = match target {
                Some(met) if met(x) => " ok",
                Some(_) => " MISSED",
                None => "",
            };
            format!("{x:.digits$}{mark}")
        }
        Err(_) => "-".into(),
    }
}

/// The ratio of two round trips' p50.
fn ratio(a: &Fig<Rtt>, b: &Fig<Rtt>) -> Fig<f64> {
    match (a, b) {
        (Ok(a), Ok(b)) => Ok(a.p50 / b.p50),
        (Err(e), _) | (_, Err(e)) => Err(e.clone()),
    }
}

/// A row of every engine's run, each cell `get` of it.
fn each(engines: &[EngineRun], label: &str, get: &dyn Fn(&EngineRun) -> String) {
    row(label, engines.iter().map(get));
}

/// The benchmark's tables: one per placement, then the gateway on the large DDF.
pub(super) fn print_tables(runs: &[PlacementRun], large: &[(EngineKind, LargeFig)], large_ddf: &Path) {
    println!(
        "gateway: shm -> gateway -> DDS -> echo -> DDS -> gateway -> shm, {ITEMS} x float64 sets (typed samples of 80 bytes)"
    );
    for run in runs {
        println!();
        println!("{}", run.cpus.name);
        let engines = &run.engines;
        row("figure", engines.iter().map(|r| r.engine.name().to_string()));
        row(
            "gateway",
            engines.iter().map(|r| {
                if r.mode == GatewayMode::Process {
                    "process".into()
                } else {
                    "in-process".to_string()
                }
            }),
        );
        round_trip_rows(engines);
        peer_rows(&run.peers);
        ratio_rows(engines, &run.peers);
        rate_rows(engines);
        not_run_lines(engines);
    }
    println!();
    large_lines(large, large_ddf);
}

/// The round trips through the gateway and of the engine alone: p50, p99 and lost.
fn round_trip_rows(engines: &[EngineRun]) {
    let rtt_rows: [(&str, Get<Rtt>); 4] = [
        ("gateway round trip, back to back", |r| &r.rtt),
        ("gateway round trip, paced at 1 kHz", |r| &r.paced),
        ("engine ping -> echo, no gateway, back to back", |r| &r.ping),
        ("engine ping -> echo, answered on the receive thread", |r| &r.ping_rx),
    ];
    for (label, get) in rtt_rows {
        each(engines, &format!("{label}, p50 µs"), &|r| cell(get(r), |t| t.p50, 1, None));
        each(engines, &format!("{label}, p99 µs"), &|r| cell(get(r), |t| t.p99, 1, None));
        each(engines, &format!("{label}, lost"), &|r| cell(get(r), |t| f64::from(t.lost), 0, None));
    }
}

/// ddsperf's and Fast DDS's round trips, or why they were not run.
fn peer_rows(peers: &Peers) {
    for (label, f) in [
        ("ddsperf ping-pong (80 B), back to back", &peers.ddsperf),
        ("ddsperf ping-pong (80 B), ping 1kHz", &peers.ddsperf_paced),
        ("ddsperf ping-pong (80 B), ping waits on a waitset", &peers.ddsperf_waitset),
        ("Fast DDS ping-pong (UDP, 80 B), back to back", &peers.fastdds),
        ("Zenoh ping-pong (z_ping's loop, TCP, 84 B), back to back", &peers.zenoh),
    ] {
        match f {
            Ok(t) => row(&format!("{label}, p50 / p99 µs"), [format!("{:.1} / {:.1}", t.p50, t.p99)]),
            Err(why) => println!("  {}: not run ({why})", label.split(' ').next().unwrap_or(label)),
        }
    }
}

/// The gateway's round trip over the peers'.
fn ratio_rows(engines: &[EngineRun], peers: &Peers) {
    let met_rtt: fn(f64) -> bool = |x| x <= TARGET_RTT_RATIO;
    each(engines, &format!("ratio gateway / ddsperf p50, back to back (cyclone <= {TARGET_RTT_RATIO})"), &|r| {
        cell(&ratio(&r.rtt, &peers.ddsperf), |x| *x, 2, target_of(r.engine, &[EngineKind::Cyclone], met_rtt))
    });
    each(engines, "ratio gateway / ddsperf ping on a waitset p50, back to back", &|r| {
        cell(&ratio(&r.rtt, &peers.ddsperf_waitset), |x| *x, 2, None)
    });
    each(engines, "ratio gateway / ddsperf p50, paced at 1 kHz", &|r| {
        cell(&ratio(&r.paced, &peers.ddsperf_paced), |x| *x, 2, None)
    });
    each(engines, "ratio gateway / Fast DDS p50, back to back", &|r| {
        cell(&ratio(&r.rtt, &peers.fastdds), |x| *x, 2, None)
    });
    if peers.zenoh.is_ok() {
        each(
            engines,
            &format!("ratio gateway / Zenoh ping-pong p50, back to back (zenoh <= {TARGET_RTT_RATIO})"),
            &|r| {
                let target = target_of(r.engine, &[EngineKind::Zenoh], met_rtt);
                cell(&ratio(&r.rtt, &peers.zenoh), |x| *x, 2, target)
            },
        );
    }
}

/// Throughput each way, the synchronous set's steps and lock-step.
fn rate_rows(engines: &[EngineRun]) {
    let met_rate: fn(f64) -> bool = |x| x >= TARGET_RATE;
    let rate_rows: [(&str, Get<f64>, bool); 3] = [
        ("async set shm -> gateway -> DDS sink, samples/s", |r| &r.to_dds, true),
        ("async set DDS source -> gateway -> shm, samples/s", |r| &r.from_dds, true),
        ("async set DDS source -> DDS sink, no gateway, samples/s", |r| &r.alone, false),
    ];
    for (label, get, targeted) in rate_rows {
        each(engines, label, &|r| {
            let target = target_of(r.engine, &[EngineKind::Cyclone, EngineKind::Zenoh], met_rate);
            cell(get(r), |x| *x, 0, target.filter(|_| targeted))
        });
    }
    each(engines, "sync set shm -> gateway -> DDS sink, samples/s", &|r| cell(&r.sync, rate, 0, None));
    each(engines, "sync set steps lost (but for the start of the reader's stream)", &|r| {
        cell(&r.sync, |s| s.lost as f64, 0, None)
    });
    each(engines, "sync set steps skipped while the reader joined", &|r| {
        cell(&r.sync, |s| s.skipped_joining as f64, 0, None)
    });
    each(engines, "sync set steps duplicated or reordered", &|r| cell(&r.sync, |s| s.misordered as f64, 0, None));
    each(engines, "lock-step, DDS echo answering each step, steps/s", &|r| cell(&r.lock, |l| l.per_s, 0, None));
    each(engines, "lock-step steps not answered for themselves", &|r| cell(&r.lock, |l| l.unanswered as f64, 0, None));
}

/// Why each engine's figures that were not measured were not.
fn not_run_lines(engines: &[EngineRun]) {
    for r in engines {
        let mut reasons: Vec<&String> = [&r.rtt, &r.ping].into_iter().filter_map(|f| f.as_ref().err()).collect();
        let others = [&r.to_dds, &r.from_dds, &r.alone].into_iter().filter_map(|f| f.as_ref().err());
        reasons.extend(others.chain(r.sync.as_ref().err()).chain(r.lock.as_ref().err()));
        reasons.retain(|why| !why.starts_with("measured with"));
        reasons.dedup();
        for why in reasons {
            println!("  {} ({} gateway): not run ({why})", r.engine, r.mode.key());
        }
    }
}

/// The gateway on the large DDF, per engine.
fn large_lines(large: &[(EngineKind, LargeFig)], large_ddf: &Path) {
    for (engine, f) in large {
        match f {
            Ok(l) => println!(
                "gateway ({engine}) on {} hosted by a framework: up in {:.2} s{}, {} topics bridged, all discovered by a DDS peer in {:.2} s, RSS {:.1} MiB",
                large_ddf.display(),
                l.up.as_secs_f64(),
                if *engine == EngineKind::Cyclone {
                    format!(" (target < {TARGET_STARTUP_S} s)")
                } else {
                    String::new()
                },
                l.topics,
                l.discovered.as_secs_f64(),
                l.rss_kib as f64 / 1024.0
            ),
            Err(why) => println!("gateway ({engine}) on {}: not run ({why})", large_ddf.display()),
        }
    }
}
