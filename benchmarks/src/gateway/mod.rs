//! `tutti-bench gateway`: for each core placement and each DDS engine, the round trip
//! shared memory -> gateway -> DDS -> echo peer -> DDS -> gateway -> shared memory and the
//! engine's own ping -> echo without the gateway; Cyclone's `ddsperf` and a Fast DDS
//! ping-pong on the same cores; the rate of an 8-item asynchronous set through the gateway
//! each way and of a synchronous set out to DDS (every step once, in order); lock-step steps
//! per second with the DDS echo answering each step; and, per engine, the start-up and
//! memory of a gateway serving ddf/large-1000.ddf.
//!
//! The framework is this process; the DDS peers (`--echo`, `--sink`, `--source`: separate
//! DDS participants on the engine under test, using the gateway's codec) are child
//! processes, each pinned to its CPU. The gateway is measured both ways, in the same run and
//! for each placement: as a child process (`tutti gateway`), and inside the framework's
//! process (`tutti_gateway::in_process`, as `tutti host --gateway` runs it: the framework's
//! step writes its PUBLISH set to DDS; the gateway's other threads are started on the
//! gateway's CPU). Every sub-run has a DDS domain id and a shared-memory namespace of its
//! own, so nothing left of one reaches the next.
//!
//! The module: the options, the run and its sub-runs (here), the processes of a sub-run and
//! where they run ([`processes`]), the figures ([`figures`]), the measurements through the
//! gateway ([`measure`]), DDS without tutti ([`baseline`]), the gateway on the large DDF
//! ([`large`]), the hidden DDS peer modes ([`modes`]), and the output ([`tables`],
//! [`json`]).

mod baseline;
mod figures;
mod json;
mod large;
mod measure;
mod modes;
mod processes;
mod security;
mod tables;
mod zenoh;

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context as _;
use tutti_gateway::EngineKind;

use crate::{CliResult, Failure};
use figures::{fig, noted, rate, EngineRun, Fig, LargeRuns, PlacementRun};
use processes::{ddf_text, Cpus};

/// The items of the benchmark's sets, each a float64.
const ITEMS: usize = 8;
/// Longest wait for a path to work end to end (discovery, start-up).
const PATIENCE: Duration = Duration::from_secs(30);
/// The highest DDS domain id (port mapping of the RTPS specification).
const MAX_DOMAIN_ID: u16 = 232;

/// Round trips and throughput through the gateway on each DDS engine, next to ddsperf and
/// Fast DDS.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  cargo build --release -p tutti -p tutti-bench && target/release/tutti-bench gateway\n  tutti-bench gateway --engines rustdds --placement same --samples 300 --duration 1s --json\n  tutti-bench gateway --engines cyclone --gateways in-process --placement same\n  tutti-bench gateway --security --placement same   # secured vs unsecured, beside ddsperf\n\nNeeds ddsperf (apt-get install -y cyclonedds-tools) and, for the Fast DDS ping-pong, g++ and\nlibfastrtps-dev; without them those rows say \"not run\". Progress goes to stderr; figures go\nto docs/benchmarks.md."
)]
pub struct Args {
    /// Round trips timed per placement, engine and mode.
    #[arg(long, default_value_t = 2000)]
    samples: u32,
    /// How long each throughput and lock-step run lasts.
    #[arg(long, default_value = "3s", value_parser = tutti_core::parse::parse_duration)]
    duration: Duration,
    /// Core placements to run: same (everything on CPU 0), split (the gateway alone on CPU 1),
    /// apart (the DDS peer alone on CPU 1), both (same and split), all; none: only the gateway
    /// on the large DDF.
    #[arg(long, default_value = "all")]
    placement: String,
    /// DDS engines to measure (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "cyclone,rustdds", value_name = "ENGINES")]
    engines: Vec<EngineKind>,
    /// Where the gateway runs: process (`tutti gateway`), in-process (in the framework's
    /// process, as `tutti host --gateway`); comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "process,in-process", value_name = "WHERE")]
    gateways: Vec<GatewayMode>,
    /// First DDS domain id of the runs; each sub-run takes the next one.
    #[arg(long, default_value_t = 140)]
    ros_domain_id: u16,
    /// Also start a gateway on this DDF, per engine, and record its start-up time and memory.
    #[arg(long, default_value = "ddf/large-1000.ddf")]
    large: PathBuf,
    /// Print one JSON object on stdout instead of the tables.
    #[arg(long)]
    json: bool,
    /// Measure what DDS Security costs instead: per placement, ddsperf and the gateway round
    /// trip (cyclone engine) unsecured and secured, in enclaves of a keystore made for the
    /// run (needs openssl and Debian's libddsc0debian plugins).
    #[arg(long)]
    security: bool,
    /// Internal: the DDS engine of a peer mode.
    #[arg(long = "dds", hide = true, default_value = "cyclone", value_name = "ENGINE")]
    dds: EngineKind,
    /// Internal: run the echo peer for DDF (used by the benchmark itself).
    #[arg(long, hide = true, value_name = "DDF")]
    echo: Option<PathBuf>,
    /// Internal: count the samples on DDF's PUBLISH (`publish`) or SUBSCRIBE topic.
    #[arg(long, hide = true, num_args = 2, value_names = ["DDF", "ROLE"])]
    sink: Vec<String>,
    /// Internal: with --sink, read with the domain's QoS and check the steps' order.
    #[arg(long, hide = true)]
    ordered: bool,
    /// Internal: write SUBSCRIBE samples of DDF flat out.
    #[arg(long, hide = true, value_name = "DDF")]
    source: Option<PathBuf>,
    /// Internal: the Zenoh router of the run, for a peer on the Zenoh engine.
    #[arg(long, hide = true, value_name = "ENDPOINT")]
    zenoh_connect: Option<String>,
    /// Internal: run Zenoh's pong (answer every ping with its payload).
    #[arg(long, hide = true)]
    zenoh_pong: bool,
}

/// Where the gateway runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum GatewayMode {
    /// A `tutti gateway` child process, following the framework in shared memory.
    Process,
    /// In the framework's process: the step writes to DDS.
    InProcess,
}

impl GatewayMode {
    fn key(self) -> &'static str {
        match self {
            GatewayMode::Process => "process",
            GatewayMode::InProcess => "in-process",
        }
    }
}

/// One sub-run's DDS domain id and shared-memory namespace.
#[derive(Debug)]
struct Slot {
    dom: u16,
    ns: String,
}

/// DDS domain ids taken per placement (ddsperf twice, Fast DDS), per engine and placement
/// (round trip, ping, three throughput runs, the synchronous set, lock-step) and per engine
/// (the check that it opens, the large DDF).
const IDS_PER_PLACEMENT: u16 = 3;
const IDS_PER_ENGINE_RUN: u16 = 7;
/// The same for an in-process gateway (round trip, two throughput runs, the synchronous set,
/// lock-step).
const IDS_PER_IN_PROCESS_RUN: u16 = 5;
const IDS_PER_ENGINE: u16 = 2;

/// The state of a benchmark run: where things are and the next sub-run's number.
struct Bench<'a> {
    args: &'a Args,
    /// The `tutti` executable (the gateway) and this one (the DDS peers).
    exe: PathBuf,
    bench_exe: PathBuf,
    dir: PathBuf,
    async_ddf: PathBuf,
    sync_ddf: PathBuf,
    next: u16,
    /// The endpoint of the run's Zenoh router, when the zenoh engine is measured.
    zenoh_router: Option<String>,
    /// The keystore the sub-run's parties take their enclaves from; None: unsecured.
    secured: Option<PathBuf>,
}

/// The scratch directory of this run (the benchmark's DDFs).
fn scratch_dir() -> PathBuf {
    std::env::temp_dir().join(format!("tutti-bench-gw-{}", std::process::id()))
}

/// A run ended by Ctrl-C or SIGTERM removes what it made first, the segments of its
/// frameworks (every namespace of this process is `gwb<pid>x<n>`) and its scratch directory:
/// no `Drop` runs when the process is ended, and the peers and gateways it started die with it.
fn clean_up_on_signal() -> anyhow::Result<()> {
    let prefix = format!("tutti.gwb{}x", std::process::id());
    ctrlc::set_handler(move || {
        for name in tutti_core::shm::os::list_shm(&prefix).unwrap_or_default() {
            let _ = std::fs::remove_file(Path::new(tutti_core::shm::os::SHM_DIR).join(name));
        }
        let _ = std::fs::remove_dir_all(scratch_dir());
        std::process::exit(130);
    })
    .context("installing the signal handler")
}

pub fn run(args: Args) -> CliResult {
    if let Some(ddf) = &args.echo {
        return modes::echo(ddf, &args);
    }
    if let [ddf, role] = &args.sink[..] {
        return modes::sink(Path::new(ddf), role, &args);
    }
    if let Some(ddf) = &args.source {
        return modes::source(ddf, &args);
    }
    if args.zenoh_pong {
        return zenoh::pong(&args);
    }
    let placements = Cpus::parse(&args.placement).map_err(Failure::invalid)?;
    clean_up_on_signal()?;
    let n_eng = args.engines.len() as u16;
    let per_run: u16 = args
        .gateways
        .iter()
        .map(|m| if *m == GatewayMode::Process { IDS_PER_ENGINE_RUN } else { IDS_PER_IN_PROCESS_RUN })
        .sum();
    let needed = placements.len() as u16 * (IDS_PER_PLACEMENT + n_eng * per_run) + n_eng * IDS_PER_ENGINE;
    if u32::from(args.ros_domain_id) + u32::from(needed) > u32::from(MAX_DOMAIN_ID) + 1 {
        return Err(Failure::invalid(anyhow::anyhow!(
            "--ros-domain-id {}: this run needs {needed} DDS domain ids from it, up to {MAX_DOMAIN_ID}",
            args.ros_domain_id
        )));
    }
    let exe = crate::tutti_exe()?;
    let bench_exe = std::env::current_exe().context("locating this executable")?;
    let dir = scratch_dir();
    std::fs::create_dir_all(&dir).context("creating a scratch directory")?;
    let (async_ddf, sync_ddf) = (dir.join("gwbench.ddf"), dir.join("gwsync.ddf"));
    std::fs::write(&async_ddf, ddf_text("gwbench", false)).context("writing the benchmark DDF")?;
    std::fs::write(&sync_ddf, ddf_text("gwsync", true)).context("writing the benchmark DDF")?;
    // The Zenoh engine's sessions meet at a router, as rmw_zenoh's nodes at rmw_zenohd; kept
    // until the run ends.
    let router = match args.engines.contains(&EngineKind::Zenoh) {
        true => Some(zenoh::router()?),
        false => None,
    };
    let zenoh_router = router.as_ref().map(|(_, endpoint)| endpoint.clone());
    let mut b = Bench { args: &args, exe, bench_exe, dir, async_ddf, sync_ddf, next: 0, zenoh_router, secured: None };
    if args.security {
        let runs = security::make_keystore(&b.dir).map(|ks| b.security_runs(&placements, &ks));
        let _ = std::fs::remove_dir_all(&b.dir);
        let runs = runs?;
        if args.json {
            println!("{}", serde_json::to_string(&security::json(&runs)).context("writing JSON")?);
        } else {
            security::print(&runs);
        }
        return Ok(());
    }
    let result = b.run_all(&placements);
    let _ = std::fs::remove_dir_all(&b.dir);
    let (runs, large) = result?;
    if args.json {
        let json = json::to_json(&runs, &large);
        println!("{}", serde_json::to_string(&json).context("writing JSON")?);
    } else {
        tables::print_tables(&runs, &large, &args.large);
    }
    Ok(())
}

/// Progress, on stderr.
fn progress(what: &str) {
    eprintln!("bench gateway: {what}");
}

impl Bench<'_> {
    fn run_all(&mut self, placements: &[Cpus]) -> anyhow::Result<(Vec<PlacementRun>, LargeRuns)> {
        let args = self.args;
        let engines: Vec<(EngineKind, Fig<()>)> = args.engines.iter().map(|&e| (e, self.check_engine(e))).collect();
        progress("building the Fast DDS ping-pong (once)");
        let fastdds = fig(self.fastdds_program());
        let mut runs = Vec::new();
        for &cpus in placements {
            progress(&format!("{}: ddsperf and Fast DDS", cpus.key));
            let peers = self.peers(cpus, &fastdds);
            let mut per_engine = Vec::new();
            for &mode in &args.gateways {
                for (engine, ok) in &engines {
                    per_engine.push(match ok {
                        Ok(()) => self.engine_run(*engine, cpus, mode),
                        Err(e) => EngineRun::not_run(*engine, mode, e),
                    });
                }
            }
            runs.push(PlacementRun { cpus, peers, engines: per_engine });
        }
        let mut large = Vec::new();
        if self.args.large.exists() {
            for (engine, ok) in &engines {
                progress(&format!("{engine}: gateway on {}", self.args.large.display()));
                let slot = self.slot();
                large.push((*engine, ok.clone().and_then(|()| fig(self.large(*engine, &slot)))));
            }
        } else {
            progress(&format!("{} not found: no start-up figures", self.args.large.display()));
        }
        Ok((runs, large))
    }

    /// The next sub-run's DDS domain id and namespace.
    fn slot(&mut self) -> Slot {
        let n = self.next;
        self.next += 1;
        Slot { dom: self.args.ros_domain_id + n, ns: format!("gwb{}x{n}", std::process::id()) }
    }

    /// Whether engine `e` opens a participant here (the Cyclone engine may not be built).
    fn check_engine(&mut self, e: EngineKind) -> Fig<()> {
        let slot = self.slot();
        let r = modes::peer_opts(&self.async_ddf, slot.dom, e, self.zenoh_router.as_deref())
            .and_then(|(opts, _)| tutti_gateway::engine::open(e, &opts.engine_config()).map_err(anyhow::Error::new));
        noted(r.map(drop), e.name())
    }

    /// Every figure of engine `e` in placement `cpus` with the gateway where `mode` says;
    /// one that fails is reported, not fatal. The figures without a gateway (the engine's
    /// ping, source -> sink) are measured with the separate gateway's runs only.
    fn engine_run(&mut self, e: EngineKind, cpus: Cpus, mode: GatewayMode) -> EngineRun {
        let at = |what: &str| format!("{}: {e}: {} gateway: {what}", cpus.key, mode.key());
        let step = |what: &str| progress(&at(what));
        let process = mode == GatewayMode::Process;
        fn skipped<T>() -> Fig<T> {
            Err("measured with the separate gateway's runs".to_string())
        }
        step("gateway round trip");
        let rtt = noted(self.round_trip(e, cpus, mode), &at("round trip"));
        let (ping, ping_rx) = if process {
            step("ping -> echo without the gateway");
            let ping = noted(self.engine_ping(e, cpus, false), &at("ping"));
            step("ping -> echo without the gateway, answered on the receive thread");
            (ping, noted(self.engine_ping(e, cpus, true), &at("ping on the receive thread")))
        } else {
            (skipped(), skipped())
        };
        step("async set shm -> DDS");
        let to_dds = noted(self.outbound(e, cpus, false, mode).map(|r| rate(&r)), &at("shm -> DDS"));
        step("async set DDS -> shm");
        let from_dds = noted(self.inbound(e, cpus, mode), &at("DDS -> shm"));
        let alone = if process {
            step("DDS source -> DDS sink, no gateway");
            noted(self.alone(e, cpus), &at("source -> sink"))
        } else {
            skipped()
        };
        step("sync set shm -> DDS");
        let sync = noted(self.outbound(e, cpus, true, mode), &at("sync set"));
        step("lock-step");
        let lock = noted(self.lock_step(e, cpus, mode), &at("lock-step"));
        let (rtt, paced) = match rtt {
            Ok((hot, paced)) => (Ok(hot), Ok(paced)),
            Err(why) => (Err(why.clone()), Err(why)),
        };
        EngineRun { engine: e, mode, rtt, paced, ping, ping_rx, to_dds, from_dds, alone, sync, lock }
    }
}
