//! `tutti-bench …`: benchmarks that print percentiles and compare against a peer in the
//! same run. Results are recorded in `docs/benchmarks.md`.

//!
//! A workspace member of its own, so that `tutti` links none of what only the benchmarks
//! need (iceoryx2, the DDS peers). The runs that need `tutti` itself (the gateway, the
//! studio) start the `tutti` executable next to this one ([`tutti_exe`]).

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod checkpoint;
mod ddf;
mod drive;
mod event;
mod fanout;
mod gateway;
mod iceoryx;
mod peers;
mod record;
mod rtapi;
mod scale;
mod scale_plot;
mod shm;
mod sites;
mod studio;

/// Benchmarks of tutti, each next to a peer in the same run.
#[derive(Debug, Parser)]
#[command(name = "tutti-bench", version)]
struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Debug, Subcommand)]
enum What {
    /// Checkpoint save and restore of a 1,000-domain run and of the UAV demo's, next to the
    /// time of one step; target: each at most 50 ms for the 1,000-domain run.
    Checkpoint(checkpoint::Args),
    /// Parse and validate a large DDF (default: the 1,000-domain file) and print the time.
    Ddf(ddf::Args),
    /// An event-driven domain next to its lock-step twin: one participant due at every step
    /// and 20 due every 100th, steps per second and CPU time per step.
    Event(event::Args),
    /// The gateway per DDS engine: round trips, throughput, lock-step rate and start-up, next to
    /// Cyclone's ddsperf and a Fast DDS ping-pong.
    Gateway(gateway::Args),
    /// What recording costs a real-time host: step lateness without a recording, with MCAP
    /// and with CSV, and MB per minute.
    Record(record::Args),
    /// What a step costs as participants and domains grow (barrier, hub, leaves, ring), next
    /// to HELICS federates in the same run.
    Scale(scale::Args),
    /// Round trips through shared-memory domains, next to iceoryx2 in the same run.
    Shm(shm::Args),
    /// Lock-step between two sites joined by a slow link (two network namespaces), per
    /// lookahead, next to K / RTT; every value checked against a K-step delay.
    Sites(sites::Args),
    /// RTPublishLock's latency in a client whose writer thread runs beside a reader thread
    /// looping on RTSubscribeLock, next to a one-thread client.
    RtapiThreads(rtapi::Args),
    Studio(studio::Args),
    /// (internal) a participant process of `tutti-bench scale --processes`.
    #[command(hide = true)]
    ScalePart(scale::PartArgs),
    /// (internal) the pong side of `tutti-bench shm`.
    #[command(hide = true)]
    ShmPong(shm::PongArgs),
    /// (internal) the pong side of iceoryx2's ping-pong.
    #[command(hide = true)]
    IoxPong(iceoryx::PongArgs),
}

pub use tutti_exit::{load_ddf, tutti_exe, CliResult, Failure};

fn main() -> ExitCode {
    let result = match Args::parse().what {
        What::Checkpoint(a) => checkpoint::run(a),
        What::Ddf(a) => ddf::run(a),
        What::Event(a) => event::run(a),
        What::Gateway(a) => gateway::run(a),
        What::Record(a) => record::run(a),
        What::Scale(a) => scale::run(a),
        What::ScalePart(a) => scale::part(a),
        What::Shm(a) => shm::run(a),
        What::Sites(a) => sites::run(a),
        What::RtapiThreads(a) => rtapi::run(a).map_err(Into::into),
        What::Studio(a) => studio::run(a),
        What::ShmPong(a) => shm::pong(a),
        What::IoxPong(a) => iceoryx::pong_main(a),
    };
    tutti_exit::exit(result)
}

/// (p50, p99, p99.9, max) of nanosecond samples, in microseconds.
pub fn percentiles(ns: &[f64]) -> (f64, f64, f64, f64) {
    if ns.is_empty() {
        return (0.0, 0.0, 0.0, 0.0);
    }
    let mut v = ns.to_vec();
    v.sort_by(f64::total_cmp);
    let q = |p: f64| nearest_rank(&v, p) / 1e3;
    (q(0.50), q(0.99), q(0.999), v[v.len() - 1] / 1e3)
}

/// The nearest-rank `q`-quantile of non-empty sorted samples.
pub fn nearest_rank<T: Copy>(sorted: &[T], q: f64) -> T {
    sorted[((sorted.len() as f64 * q).ceil() as usize).clamp(1, sorted.len()) - 1]
}

/// Warm-up round trips before `iterations` measured ones (tutti and its peers alike).
pub fn warmup(iterations: usize) -> usize {
    iterations.min(10_000)
}

/// One turn of a polling loop: give the core away (both sides on one core) or spin.
#[inline]
pub fn relax(yield_core: bool) {
    if yield_core {
        std::thread::yield_now();
    } else {
        std::hint::spin_loop();
    }
}
