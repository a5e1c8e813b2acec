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

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::peers::Received;
use anyhow::{bail, Context as _};
use serde::Serialize;
use tutti_core::ddf::Role;
use tutti_core::shm::{os, DomainHost, Framework, FrameworkOptions, WaitMode};
use tutti_gateway::in_process::{GatewaySink, InProcess};
use tutti_gateway::{EngineKind, GatewayOptions};

use crate::nearest_rank;
use crate::{load_ddf, CliResult, Failure};
use tutti_host::{ChildProcess, SIGINT};

const ITEMS: usize = 8;
/// The log filter of the benchmark's children: errors only, nothing from the DDS stack.
const QUIET_LOG: &str = "error,rustdds=off,ros2_client=off";
const LOOPBACK: &str = "<CycloneDDS xmlns=\"https://cdds.io/config\"><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><Peers><Peer address=\"127.0.0.1\"/></Peers><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex></Discovery></Domain></CycloneDDS>";
/// The Fast DDS ping-pong, built with g++ on first use.
const FASTDDS_SRC: &str = include_str!("fastdds_pingpong.cpp");
/// Longest wait for a path to work end to end (discovery, start-up).
const PATIENCE: Duration = Duration::from_secs(30);
/// The highest DDS domain id (port mapping of the RTPS specification).
const MAX_DOMAIN_ID: u16 = 232;
/// Targets of the Cyclone engine.
const TARGET_RTT_RATIO: f64 = 1.3;
const TARGET_RATE: f64 = 300_000.0;
const TARGET_STARTUP_S: f64 = 2.0;

/// Round trips and throughput through the gateway on each DDS engine, next to ddsperf and
/// Fast DDS.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  cargo build --release -p tutti -p tutti-bench && target/release/tutti-bench gateway\n  tutti-bench gateway --engines rustdds --placement same --samples 300 --duration 1s --json\n  tutti-bench gateway --engines cyclone --gateways in-process --placement same\n\nNeeds ddsperf (apt-get install -y cyclonedds-tools) and, for the Fast DDS ping-pong, g++ and\nlibfastrtps-dev; without them those rows say \"not run\". Progress goes to stderr; figures go\nto docs/benchmarks.md."
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

/// The gateway of a sub-run, wherever it runs.
enum Gw {
    Process(ChildProcess),
    /// `_handle` is kept for its drop, which stops the gateway's threads.
    InProcess {
        _handle: InProcess,
        sink: GatewaySink,
    },
}

impl Gw {
    /// Fails if a gateway process has exited.
    fn check(&mut self) -> anyhow::Result<()> {
        match self {
            Gw::Process(kid) => check_alive(&mut [kid]),
            Gw::InProcess { .. } => Ok(()),
        }
    }

    /// The framework just published `host`'s step with `set`: an in-process gateway writes it
    /// to DDS (what its step sink does in a host); a separate one finds it in shared memory.
    /// `more`: the framework steps on at once (flat out), as a host that is catching up says.
    fn published(&mut self, host: &DomainHost, sim: f64, set: &[u8], more: bool) {
        if let Gw::InProcess { sink, .. } = self {
            sink.send(0, host.current_step(), sim, set, more);
        }
    }

    /// Sends what a flat-out run left in the writers' batches.
    fn flush(&mut self) {
        if let Gw::InProcess { sink, .. } = self {
            sink.flush();
        }
    }
}

/// The benchmark's DDF: one domain `name` whose PUBLISH and SUBSCRIBE sets are 8 x float64.
fn ddf_text(name: &str, synchronous: bool) -> String {
    let items: String = (0..ITEMS).map(|i| format!("<item name=\"v{i}\"><type>double</type></item>")).collect();
    let sync = if synchronous { "yes" } else { "no" };
    format!(
        "<orchestra><domain name=\"{name}\"><synchronous>{sync}</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>\
         <block name=\"{name}/Publish\">{items}</block><block name=\"{name}/Subscribe\">{items}</block></domain></orchestra>"
    )
}

/// Starts a child pinned to `cpu`; dropped, it gets SIGINT and 3 s to leave (a gateway
/// says goodbye on DDS), then SIGKILL.
fn start(name: &str, cmd: Command, cpu: usize) -> anyhow::Result<ChildProcess> {
    Ok(ChildProcess::spawn(name, cmd, Some(cpu))?.stop_on_drop(Some(SIGINT), Duration::from_secs(3)))
}

/// Fails if one of `kids` has exited (a gateway or a peer that could not start or died).
fn check_alive(kids: &mut [&mut ChildProcess]) -> anyhow::Result<()> {
    for kid in kids.iter_mut() {
        if let Some(status) = kid.poll() {
            bail!("{} exited ({status})", kid.name);
        }
    }
    Ok(())
}

/// Pins this process's main thread (the framework) to `cpu`.
fn pin_self(cpu: usize) {
    let _ = os::pin_to_cpu(cpu);
}

/// Every item of the benchmark's set set to `v`.
fn fill(data: &mut [u8], v: f64) {
    for c in data.chunks_exact_mut(8) {
        c.copy_from_slice(&v.to_ne_bytes());
    }
}

/// The first item of a set.
fn first_item(set: &[u8]) -> f64 {
    set.get(..8).and_then(|b| b.try_into().ok()).map_or(f64::NAN, f64::from_ne_bytes)
}

fn rss_kib(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    s.lines().find_map(|l| l.strip_prefix("VmRSS:")).and_then(|v| v.split_whitespace().next()?.parse().ok())
}

/// Where the framework (this process), the gateway and the DDS peer run.
#[derive(Debug, Clone, Copy)]
struct Cpus {
    key: &'static str,
    name: &'static str,
    fw: usize,
    gw: usize,
    peer: usize,
}

impl Cpus {
    const SAME: Cpus = Cpus { key: "same", name: "same core (all on CPU 0)", fw: 0, gw: 0, peer: 0 };
    const SPLIT: Cpus =
        Cpus { key: "split", name: "two cores (gateway CPU 1; framework and DDS peer CPU 0)", fw: 0, gw: 1, peer: 0 };
    const APART: Cpus =
        Cpus { key: "apart", name: "two cores (framework and gateway CPU 0; DDS peer CPU 1)", fw: 0, gw: 0, peer: 1 };

    fn parse(s: &str) -> anyhow::Result<Vec<Cpus>> {
        Ok(match s {
            "same" => vec![Cpus::SAME],
            "split" => vec![Cpus::SPLIT],
            "apart" => vec![Cpus::APART],
            "both" => vec![Cpus::SAME, Cpus::SPLIT],
            "all" => vec![Cpus::SAME, Cpus::SPLIT, Cpus::APART],
            "none" => Vec::new(),
            other => bail!("--placement {other}: expected same, split, apart, both, all or none"),
        })
    }

    /// How the framework and the gateway wait for each other in shared memory: spinning,
    /// except in lock-step on one core, where a spinner holds the core the other one needs
    /// (until it yields, every few thousand looks: a few hundred µs a step).
    fn wait(self, synchronous: bool) -> WaitMode {
        if synchronous && self.fw == self.gw {
            WaitMode::Block
        } else {
            WaitMode::Spin
        }
    }

    /// The CPUs of a ping-pong between two DDS programs (ping, pong): one per core when the
    /// DDS sides of the placement are on two cores.
    fn ping_pong(self) -> (usize, usize) {
        (self.gw.min(self.peer), self.gw.max(self.peer))
    }
}

/// Round-trip percentiles (µs) and round trips that got no answer.
#[derive(Debug, Clone, Copy)]
struct Rtt {
    p50: f64,
    p99: f64,
    lost: u32,
}

impl Rtt {
    fn of(mut us: Vec<f64>, lost: u32) -> anyhow::Result<Rtt> {
        if us.is_empty() {
            bail!("no round trip completed");
        }
        us.sort_by(f64::total_cmp);
        Ok(Rtt { p50: nearest_rank(&us, 0.5), p99: nearest_rank(&us, 0.99), lost })
    }
}

/// A figure, or why it was not measured.
type Fig<T> = Result<T, String>;

fn fig<T>(r: anyhow::Result<T>) -> Fig<T> {
    r.map_err(|e| format!("{e:#}"))
}

/// [`fig`], with a failure also reported as progress under `what`.
fn noted<T>(r: anyhow::Result<T>, what: &str) -> Fig<T> {
    let r = fig(r);
    if let Err(why) = &r {
        progress(&format!("{what}: not run ({why})"));
    }
    r
}

/// Lock-step across DDS: steps per second and steps whose answer was not the step's own.
#[derive(Debug, Clone, Copy)]
struct LockStep {
    per_s: f64,
    unanswered: u64,
}

/// The figures of one engine in one placement, with the gateway in one place.
#[derive(Debug)]
struct EngineRun {
    engine: EngineKind,
    mode: GatewayMode,
    rtt: Fig<Rtt>,
    paced: Fig<Rtt>,
    ping: Fig<Rtt>,
    /// The engine ping answered on the receive thread, as ddsperf's.
    ping_rx: Fig<Rtt>,
    to_dds: Fig<f64>,
    from_dds: Fig<f64>,
    alone: Fig<f64>,
    sync: Fig<Received>,
    lock: Fig<LockStep>,
}

/// DDS without tutti, once per placement.
#[derive(Debug)]
struct Peers {
    ddsperf: Fig<Rtt>,
    ddsperf_paced: Fig<Rtt>,
    /// ddsperf's ping waiting for each pong on a thread of its own (`ping waitset`): the
    /// shape of a framework awaiting an answer.
    ddsperf_waitset: Fig<Rtt>,
    fastdds: Fig<Rtt>,
}

#[derive(Debug)]
struct PlacementRun {
    cpus: Cpus,
    peers: Peers,
    engines: Vec<EngineRun>,
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
        return echo(ddf, &args);
    }
    if let [ddf, role] = &args.sink[..] {
        return sink(Path::new(ddf), role, &args);
    }
    if let Some(ddf) = &args.source {
        return source(ddf, &args);
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
    let mut b = Bench { args: &args, exe, bench_exe, dir, async_ddf, sync_ddf, next: 0 };
    let result = b.run_all(&placements);
    let _ = std::fs::remove_dir_all(&b.dir);
    let (runs, large) = result?;
    if args.json {
        let json = to_json(&runs, &large);
        println!("{}", serde_json::to_string(&json).context("writing JSON")?);
    } else {
        print_tables(&runs, &large, &args.large);
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
        let r = peer_opts(&self.async_ddf, slot.dom, e)
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

    fn ddf(&self, synchronous: bool) -> &Path {
        if synchronous {
            &self.sync_ddf
        } else {
            &self.async_ddf
        }
    }

    /// A `tutti` child on engine `e` in `slot`'s DDS domain and namespace.
    fn tutti(&self, e: EngineKind, slot: &Slot, args: &[&str]) -> Command {
        self.command(&self.exe, e, slot, args)
    }

    /// `exe ARGS` for `slot` and engine `e`.
    fn command(&self, exe: &Path, e: EngineKind, slot: &Slot, args: &[&str]) -> Command {
        let mut cmd = Command::new(exe);
        cmd.args(args)
            .args(["--ros-domain-id", &slot.dom.to_string(), "--dds", e.name()])
            .env("TUTTI_NAMESPACE", &slot.ns)
            .env("RUST_LOG", QUIET_LOG)
            .stdin(Stdio::null());
        cmd
    }

    /// `tutti gateway` on the benchmark's DDF, on `cpu`, as fast as it goes.
    fn gateway(&self, e: EngineKind, slot: &Slot, synchronous: bool, cpus: Cpus) -> anyhow::Result<ChildProcess> {
        let ddf = self.ddf(synchronous).to_string_lossy();
        let wait = if cpus.wait(synchronous) == WaitMode::Spin { "spin" } else { "block" };
        let mut args = vec!["gateway", &ddf, "--interface", "127.0.0.1", "--poll", "0", "--wait", wait, "-q"];
        // The synchronous runs measure every step through DDS: the gateway reads in lock-step
        // (by default a DDS reader never holds the framework back, and a framework stepping
        // flat out with no one to wait for would outrun it).
        if synchronous {
            args.push("--every-step");
        }
        start("the gateway", self.tutti(e, slot, &args), cpus.gw)
    }

    /// The gateway of a sub-run: `tutti gateway` (see [`Bench::gateway`]), or started in
    /// this process for the framework `fw` has just created, its threads (the engine's
    /// receive threads, the manager, the poller) on the gateway's CPU.
    fn start_gateway(
        &self,
        e: EngineKind,
        slot: &Slot,
        synchronous: bool,
        cpus: Cpus,
        mode: GatewayMode,
    ) -> anyhow::Result<Gw> {
        if mode == GatewayMode::Process {
            return Ok(Gw::Process(self.gateway(e, slot, synchronous, cpus)?));
        }
        let (mut opts, _) = peer_opts(self.ddf(synchronous), slot.dom, e)?;
        opts.poll = Duration::ZERO;
        opts.wait = cpus.wait(synchronous);
        // Threads inherit the CPU of the thread that starts them.
        pin_self(cpus.gw);
        let started = tutti_gateway::in_process::start(opts, &slot.ns, Duration::from_secs(3600), Box::new(|_| {}));
        pin_self(cpus.fw);
        let (gw, sink) = started.context("starting the gateway in this process")?;
        Ok(Gw::InProcess { _handle: gw, sink })
    }

    /// A DDS peer of the benchmark (`--echo`, `--sink`, `--source` …) on `cpu`.
    fn peer(&self, e: EngineKind, slot: &Slot, cpu: usize, what: &[&str]) -> anyhow::Result<ChildProcess> {
        let window = format!("{}ms", self.args.duration.as_millis());
        let args: Vec<&str> = ["gateway", "--duration", &window].into_iter().chain(what.iter().copied()).collect();
        let mut cmd = self.command(&self.bench_exe, e, slot, &args);
        cmd.stdout(Stdio::piped());
        start(&format!("the DDS peer ({})", what.first().unwrap_or(&"")), cmd, cpu)
    }

    fn echo_peer(&self, e: EngineKind, slot: &Slot, synchronous: bool, cpu: usize) -> anyhow::Result<ChildProcess> {
        self.peer(e, slot, cpu, &["--echo", &self.ddf(synchronous).to_string_lossy()])
    }

    /// The framework of the benchmark's domain in `slot`'s namespace.
    fn framework(&self, slot: &Slot, synchronous: bool, cpus: Cpus) -> anyhow::Result<Framework> {
        let model = load_ddf(self.ddf(synchronous)).map_err(|f| f.error)?;
        let wait = cpus.wait(synchronous);
        let opts = FrameworkOptions { namespace: slot.ns.clone(), wait, ..Default::default() };
        Framework::create(&model, &opts).context("creating the benchmark domain")
    }

    /// The gateway round trip back to back, then paced at 1 kHz (same processes).
    fn round_trip(&mut self, e: EngineKind, cpus: Cpus, mode: GatewayMode) -> anyhow::Result<(Rtt, Rtt)> {
        let slot = self.slot();
        let mut fw = self.framework(&slot, false, cpus)?;
        let host = &mut fw.domains[0];
        let mut gw = self.start_gateway(e, &slot, false, cpus, mode)?;
        let mut echo = self.echo_peer(e, &slot, false, cpus.peer)?;
        pin_self(cpus.fw);
        let mut data = vec![0u8; ITEMS * 8];
        let mut seq = 0f64;
        let mut send = |host: &mut DomainHost, gw: &mut Gw, seq: f64| {
            fill(&mut data, seq);
            host.publish_step(&data, seq)?;
            gw.published(host, seq, &data, false);
            anyhow::Ok(())
        };
        let back = |host: &mut DomainHost| host.read_subscribe().map_or(f64::NAN, first_item);
        // Until the echo path works end to end.
        let end = Instant::now() + PATIENCE;
        loop {
            seq += 1.0;
            send(host, &mut gw, seq)?;
            let t = Instant::now();
            while t.elapsed() < Duration::from_millis(100) && back(host) != seq {
                std::hint::spin_loop();
            }
            if back(host) == seq {
                break;
            }
            gw.check()?;
            check_alive(&mut [&mut echo])?;
            if Instant::now() > end {
                bail!("no echo within {} s (is the loopback interface up?)", PATIENCE.as_secs());
            }
        }
        let mut measure = |paced: bool| -> anyhow::Result<Rtt> {
            let mut times = Vec::with_capacity(self.args.samples as usize);
            let mut lost = 0;
            let start = Instant::now();
            for k in 0..self.args.samples {
                if paced {
                    // One round trip per millisecond, as ddsperf's `ping 1kHz`: everything may
                    // go idle between them.
                    let due = start + Duration::from_millis(u64::from(k));
                    if let Some(wait) = due.checked_duration_since(Instant::now()) {
                        std::thread::sleep(wait);
                    }
                }
                seq += 1.0;
                let t = Instant::now();
                send(host, &mut gw, seq)?;
                let mut spins = 0u32;
                while back(host) != seq && t.elapsed() < Duration::from_secs(1) {
                    // Spin, but give the core away between looks: the echo and the gateway may
                    // share it (a pure spinner is only preempted at the end of its time slice).
                    spins += 1;
                    crate::relax(spins >= 16);
                }
                if back(host) == seq {
                    times.push(t.elapsed().as_secs_f64() * 1e6);
                } else {
                    lost += 1;
                    gw.check()?;
                    check_alive(&mut [&mut echo])?;
                }
            }
            Rtt::of(times, lost)
        };
        let hot = measure(false)?;
        let paced = measure(true)?;
        Ok((hot, paced))
    }

    /// The echo pinged by a participant of the same engine in this process (where the
    /// gateway was), with no gateway and no shared memory: what the engine itself costs on
    /// this path. `in_listener`: each ping is written on the receive thread as the last one's
    /// answer arrives (as ddsperf pings), rather than by a thread that waits for the answer.
    fn engine_ping(&mut self, e: EngineKind, cpus: Cpus, in_listener: bool) -> anyhow::Result<Rtt> {
        let slot = self.slot();
        let _echo = self.echo_peer(e, &slot, false, cpus.peer)?;
        let (mut opts, d) = peer_opts(&self.async_ddf, slot.dom, e)?;
        opts.node_name = "tutti_bench_ping".into();
        pin_self(cpus.gw);
        let t = if in_listener {
            crate::peers::ping_in_listener(&opts, &d, self.args.samples, PATIENCE)
        } else {
            crate::peers::ping(&opts, &d, self.args.samples, PATIENCE)
        };
        pin_self(cpus.fw);
        let t = t?;
        let lost = self.args.samples.saturating_sub(t.len() as u32);
        Rtt::of(t, lost)
    }

    /// shm -> DDS: this process steps flat out (an asynchronous set: publishes, yielding
    /// between steps so a peer on the same core runs; a synchronous one: publishes and
    /// completes each step, the gateway's lock-step reader taking part); the gateway sends
    /// what it sees; a sink in another process counts what arrives over `--duration`
    /// (for the synchronous set a Cyclone reader with the domain's QoS, checking the steps'
    /// order).
    fn outbound(
        &mut self,
        e: EngineKind,
        cpus: Cpus,
        synchronous: bool,
        mode: GatewayMode,
    ) -> anyhow::Result<Received> {
        let slot = self.slot();
        let mut fw = self.framework(&slot, synchronous, cpus)?;
        let host = &mut fw.domains[0];
        pin_self(cpus.fw);
        let mut gw = self.start_gateway(e, &slot, synchronous, cpus, mode)?;
        let ddf = self.ddf(synchronous).to_string_lossy();
        let mut what = vec!["--sink", &ddf, "publish"];
        if synchronous {
            what.push("--ordered");
        }
        // The synchronous set's sink reads with Cyclone on either engine: a rustdds KEEP_ALL
        // reader acknowledges samples as they arrive and then drops those its reader task has
        // not taken when its cache holds more than 64 (docs/gateway.md, "Not done / known
        // limits"), which would count rustdds' reader, not the gateway, as losing steps.
        let sink_engine = if synchronous { EngineKind::Cyclone } else { e };
        let mut sink = self.peer(sink_engine, &slot, cpus.peer, &what)?;
        let mut data = vec![0u8; ITEMS * 8];
        let end = Instant::now() + self.args.duration + PATIENCE + Duration::from_secs(10);
        let mut k = 0u64;
        while sink.poll().is_none() {
            if k % 1024 == 0 {
                gw.check()?;
                if Instant::now() > end {
                    bail!("the sink did not finish");
                }
            }
            k += 1;
            fill(&mut data, k as f64);
            host.publish_step(&data, k as f64)?;
            // Flat out: another step follows at once.
            gw.published(host, k as f64, &data, true);
            if synchronous {
                host.complete_step()?;
            } else {
                std::thread::yield_now();
            }
        }
        gw.flush();
        sink_result(&mut sink)
    }

    /// DDS -> shm: a source writes SUBSCRIBE samples flat out; the commits the gateway makes
    /// in shared memory are counted over `--duration`.
    fn inbound(&mut self, e: EngineKind, cpus: Cpus, mode: GatewayMode) -> anyhow::Result<f64> {
        let slot = self.slot();
        let fw = self.framework(&slot, false, cpus)?;
        let host = &fw.domains[0];
        pin_self(cpus.fw);
        let mut gw = self.start_gateway(e, &slot, false, cpus, mode)?;
        let mut source = self.peer(e, &slot, cpus.peer, &["--source", &self.async_ddf.to_string_lossy()])?;
        let commits = || host.status().subscribe_commits;
        let c0 = commits();
        let end = Instant::now() + PATIENCE;
        while commits() < c0 + 100 {
            gw.check()?;
            check_alive(&mut [&mut source])?;
            if Instant::now() > end {
                bail!("no commits from DDS within {} s", PATIENCE.as_secs());
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        let (c1, t) = (commits(), Instant::now());
        std::thread::sleep(self.args.duration);
        Ok((commits() - c1) as f64 / t.elapsed().as_secs_f64())
    }

    /// The same source and a sink on the gateway's and the peer's cores, without the
    /// gateway: the engine's own ceiling.
    fn alone(&mut self, e: EngineKind, cpus: Cpus) -> anyhow::Result<f64> {
        let slot = self.slot();
        let ddf = self.async_ddf.to_string_lossy();
        let mut sink = self.peer(e, &slot, cpus.gw, &["--sink", &ddf, "subscribe"])?;
        let _source = self.peer(e, &slot, cpus.peer, &["--source", &ddf])?;
        Ok(rate(&sink_result(&mut sink)?))
    }

    /// Lock-step across DDS: this process steps a synchronous domain flat out; the DDS echo
    /// answers each step through the gateway, whose commit for the step completes it.
    fn lock_step(&mut self, e: EngineKind, cpus: Cpus, mode: GatewayMode) -> anyhow::Result<LockStep> {
        let slot = self.slot();
        let mut fw = self.framework(&slot, true, cpus)?;
        let host = &mut fw.domains[0];
        pin_self(cpus.fw);
        let mut gw = self.start_gateway(e, &slot, true, cpus, mode)?;
        let mut echo = self.echo_peer(e, &slot, true, cpus.peer)?;
        let mut data = vec![0u8; ITEMS * 8];
        let mut k = 0u64;
        // One step (published, handed to an in-process gateway, completed); true when the
        // SUBSCRIBE set it read is the echo's answer to it.
        let mut step = |host: &mut DomainHost, gw: &mut Gw| -> anyhow::Result<bool> {
            k += 1;
            fill(&mut data, k as f64);
            host.publish_step(&data, k as f64)?;
            gw.published(host, k as f64, &data, false);
            host.complete_step()?;
            Ok(first_item(host.subscribe()) == k as f64)
        };
        let end = Instant::now() + PATIENCE;
        let mut tries = 0u64;
        while !step(host, &mut gw)? {
            tries += 1;
            if tries % 256 == 0 {
                gw.check()?;
                check_alive(&mut [&mut echo])?;
                if Instant::now() > end {
                    bail!("no step answered within {} s", PATIENCE.as_secs());
                }
            }
        }
        let (mut steps, mut unanswered) = (0u64, 0u64);
        let t = Instant::now();
        while t.elapsed() < self.args.duration {
            steps += 1;
            if !step(host, &mut gw)? {
                unanswered += 1;
            }
        }
        gw.check()?;
        check_alive(&mut [&mut echo])?;
        Ok(LockStep { per_s: steps as f64 / t.elapsed().as_secs_f64(), unanswered })
    }

    /// ddsperf (back to back and paced) and Fast DDS on the placement's cores.
    fn peers(&mut self, cpus: Cpus, fastdds: &Fig<PathBuf>) -> Peers {
        let at = |what: &str| format!("{}: {what}", cpus.key);
        let ddsperf = noted(self.ddsperf(cpus, None, false), &at("ddsperf"));
        let ddsperf_paced = noted(self.ddsperf(cpus, Some("1kHz"), false), &at("ddsperf 1kHz"));
        let ddsperf_waitset = noted(self.ddsperf(cpus, None, true), &at("ddsperf ping waitset"));
        let fastdds = match fastdds {
            Ok(bin) => noted(self.fastdds(bin, cpus), &at("fastdds")),
            Err(why) => Err(why.clone()),
        };
        Peers { ddsperf, ddsperf_paced, ddsperf_waitset, fastdds }
    }

    /// ddsperf ping-pong, back to back (`rate` None: a ping as soon as the pong is in) or at
    /// a rate ("1kHz"), with samples of the gateway's size (`size 80`: the 16 header bytes and
    /// the 8 doubles); it prints half the round trip. `waitset`: the ping waits for each pong
    /// on a thread of its own (ddsperf's `ping waitset`) rather than writing the next ping from
    /// the pong's data-available listener, on the receive thread (its default).
    fn ddsperf(&mut self, cpus: Cpus, rate: Option<&str>, waitset: bool) -> anyhow::Result<Rtt> {
        let dom = self.slot().dom.to_string();
        let mut pong = Command::new("ddsperf");
        pong.args(["-i", &dom, "-D8", "pong"]).env("CYCLONEDDS_URI", LOOPBACK).stdout(Stdio::null());
        let mut ping = Command::new("ddsperf");
        ping.args(["-i", &dom, "-D5", "-Qminmatch:1", "-Qinitwait:5", "ping"])
            .args(rate)
            .args(waitset.then_some("waitset"))
            .args(["size", "80"])
            .env("CYCLONEDDS_URI", LOOPBACK);
        let out = ping_pong("ddsperf", pong, ping, cpus).context("apt-get install -y cyclonedds-tools")?;
        let mut p50s = Vec::new();
        let mut p99s = Vec::new();
        for line in out.lines().filter(|l| l.contains(" 50% ")) {
            let num = |key: &str| -> Option<f64> { line.split(key).nth(1)?.split("us").next()?.trim().parse().ok() };
            if let (Some(a), Some(b)) = (num(" 50% "), num(" 99% ")) {
                p50s.push(2.0 * a);
                p99s.push(2.0 * b);
            }
        }
        if p50s.is_empty() {
            bail!("no ddsperf output (apt-get install -y cyclonedds-tools)");
        }
        p50s.sort_by(f64::total_cmp);
        p99s.sort_by(f64::total_cmp);
        // The median of its per-second lines.
        Ok(Rtt { p50: nearest_rank(&p50s, 0.5), p99: nearest_rank(&p99s, 0.5), lost: 0 })
    }

    /// The Fast DDS ping-pong program, built on first use and kept next to `tutti`
    /// (`bench-cache/`, keyed by its source), else in the scratch directory.
    fn fastdds_program(&self) -> anyhow::Result<PathBuf> {
        let mut h = DefaultHasher::new();
        FASTDDS_SRC.hash(&mut h);
        let name = format!("fastdds_pingpong-{:016x}", h.finish());
        let cache = self
            .exe
            .parent()
            .map(|d| d.join("bench-cache"))
            .filter(|d| std::fs::create_dir_all(d).is_ok())
            .unwrap_or_else(|| self.dir.clone());
        let bin = cache.join(&name);
        if bin.exists() {
            return Ok(bin);
        }
        let src = self.dir.join("fastdds_pingpong.cpp");
        std::fs::write(&src, FASTDDS_SRC).context("writing the Fast DDS ping-pong")?;
        let tmp = cache.join(format!("{name}.{}", std::process::id()));
        let out = Command::new("g++")
            .args(["-std=c++11", "-O2", "-o"])
            .arg(&tmp)
            .arg(&src)
            .args(["-lfastrtps", "-lfastcdr"])
            .output();
        match out {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!("g++ not found: apt-get install -y g++"),
            Err(e) => return Err(e).context("running g++"),
            Ok(o) if !o.status.success() => {
                let err = String::from_utf8_lossy(&o.stderr);
                let first = err.lines().find(|l| l.contains("error")).unwrap_or("g++ failed");
                bail!("building against libfastrtps failed (apt-get install -y libfastrtps-dev): {first}");
            }
            Ok(_) => {}
        }
        std::fs::rename(&tmp, &bin).context("caching the Fast DDS ping-pong")?;
        Ok(bin)
    }

    /// The Fast DDS ping-pong (UDP on loopback, samples as large as the gateway's).
    fn fastdds(&mut self, bin: &Path, cpus: Cpus) -> anyhow::Result<Rtt> {
        let dom = self.slot().dom.to_string();
        let mut pong = Command::new(bin);
        pong.args([&dom, "pong"]).stdout(Stdio::null());
        let mut ping = Command::new(bin);
        ping.args([&dom, "ping", &self.args.samples.to_string()]);
        let out = ping_pong("fastdds", pong, ping, cpus)?;
        let line = out.lines().find(|l| l.starts_with("rtt_us")).context("no output from the Fast DDS ping")?;
        let num = |key: &str| -> Option<f64> {
            line.split_whitespace().find_map(|w| w.strip_prefix(key)).and_then(|v| v.parse().ok())
        };
        match (num("p50="), num("p99="), num("lost=")) {
            (Some(p50), Some(p99), Some(lost)) => Ok(Rtt { p50, p99, lost: lost as u32 }),
            _ => bail!("unexpected output from the Fast DDS ping: {line}"),
        }
    }

    /// The gateway on the large DDF, as its figure says: a framework hosts every domain of
    /// it, the gateway bridges them all, and a DDS peer (a Cyclone participant of this
    /// process) discovers every topic the gateway bridges. Returns the time until the gateway
    /// is up, the time until the peer has seen every topic, the topics bridged and the RSS.
    fn large(&self, e: EngineKind, slot: &Slot) -> anyhow::Result<Large> {
        let model = load_ddf(&self.args.large).map_err(|f| f.error)?;
        let opts = FrameworkOptions { namespace: slot.ns.clone(), ..Default::default() };
        let _framework = Framework::create(&model, &opts).context("hosting the large DDF's domains")?;
        let peer_cfg = tutti_gateway::engine::EngineConfig {
            domain_id: slot.dom,
            interfaces: vec![std::net::Ipv4Addr::LOCALHOST.into()],
            peers: Vec::new(),
            node_name: "bench_peer".into(),
            node_namespace: "/".into(),
            participant_lease: None,
        };
        let peer = tutti_gateway::engine::open(EngineKind::Cyclone, &peer_cfg).context("the DDS peer")?;
        let t = Instant::now();
        let ddf = self.args.large.to_string_lossy();
        let mut cmd = self.tutti(e, slot, &["gateway", &ddf, "--interface", "127.0.0.1", "--status-every", "1h"]);
        cmd.stderr(Stdio::piped());
        let mut kid = ChildProcess::spawn("the gateway on the large DDF", cmd, None)?
            .stop_on_drop(Some(SIGINT), Duration::from_secs(3));
        let stderr = kid.child.stderr.take();
        let mut up = None;
        if let Some(s) = stderr {
            let mut lines = BufReader::new(s).lines().map_while(Result::ok);
            for line in lines.by_ref() {
                if let Some(rest) = line.split("tutti gateway: up: ").nth(1) {
                    up = Some((t.elapsed(), rest.to_string()));
                    break;
                }
            }
            // Keep the pipe drained: a gateway blocked on stderr would stall.
            std::thread::spawn(move || for _ in lines {});
        }
        let (up, line) = up.context("the gateway on the large DDF did not start")?;
        // "B of D domains bridged, T topics, ..."
        let number = |after: &str| -> Option<usize> {
            let words: Vec<&str> = line.split([' ', ',']).filter(|w| !w.is_empty()).collect();
            let i = words.iter().position(|w| *w == after)?;
            words.get(i.checked_sub(1)?)?.parse().ok()
        };
        let bridged = line.split(' ').next().and_then(|w| w.parse::<usize>().ok()).unwrap_or(0);
        let topics = number("topics").context("the gateway's up line names no topic count")?;
        if bridged != model.domains.len() {
            bail!("the gateway bridged {bridged} of {} domains: {line}", model.domains.len());
        }
        // Every topic the gateway bridges, as a DDS peer discovers it.
        let deadline = Instant::now() + Duration::from_secs(300);
        let discovered = loop {
            let remote = peer.remote();
            let seen: std::collections::BTreeSet<&String> =
                remote.writers.keys().chain(remote.readers.keys()).filter(|t| t.starts_with("rt/")).collect();
            if seen.len() >= topics {
                break t.elapsed();
            }
            if Instant::now() > deadline {
                bail!("the DDS peer discovered {} of the gateway's {topics} topics in 300 s", seen.len());
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let rss = rss_kib(kid.pid()).context("the gateway's RSS")?;
        Ok(Large { up, discovered, topics, rss_kib: rss })
    }
}

impl EngineRun {
    fn not_run(engine: EngineKind, mode: GatewayMode, why: &str) -> EngineRun {
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

/// Runs `pong` in the background and `ping` to its end, on the placement's ping-pong CPUs;
/// returns what ping printed.
fn ping_pong(name: &str, mut pong: Command, mut ping: Command, cpus: Cpus) -> anyhow::Result<String> {
    let (ping_cpu, pong_cpu) = cpus.ping_pong();
    pong.stdin(Stdio::null()).stderr(Stdio::null());
    let _pong = start(&format!("{name} pong"), pong, pong_cpu)?;
    ping.stdin(Stdio::null()).stderr(Stdio::null());
    os::die_with_parent_on_spawn(&mut ping, Some(ping_cpu));
    let out = ping.output().with_context(|| format!("running {name}"))?;
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Samples per second of a sink's result.
fn rate(r: &Received) -> f64 {
    if r.secs > 0.0 {
        r.samples as f64 / r.secs
    } else {
        0.0
    }
}

/// The sink's "samples seconds lost misordered skipped-joining" line; waits for it to exit.
fn sink_result(kid: &mut ChildProcess) -> anyhow::Result<Received> {
    let mut line = String::new();
    if let Some(out) = kid.child.stdout.take() {
        BufReader::new(out).read_line(&mut line)?;
    }
    let v: Vec<f64> = line.split_whitespace().filter_map(|w| w.parse().ok()).collect();
    match v[..] {
        [samples, secs, lost, misordered, skipped_joining] if secs > 0.0 => Ok(Received {
            samples: samples as u64,
            secs,
            lost: lost as u64,
            misordered: misordered as u64,
            skipped_joining: skipped_joining as u64,
        }),
        _ => bail!("the sink received nothing"),
    }
}

// --- The hidden peer modes (child processes of the benchmark). ---

fn peer_opts(
    ddf: &Path,
    domain_id: u16,
    engine: EngineKind,
) -> anyhow::Result<(GatewayOptions, tutti_core::ddf::Domain)> {
    let model = load_ddf(ddf).map_err(|f| f.error)?;
    let mut opts = GatewayOptions::new(ddf, model.clone());
    opts.ros_domain_id = domain_id;
    opts.engine = engine;
    opts.interfaces = vec![std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)];
    let d = model.domains.first().context("the DDF has no domain")?.clone();
    Ok((opts, d))
}

fn echo(ddf: &Path, args: &Args) -> CliResult {
    let (opts, d) = peer_opts(ddf, args.ros_domain_id, args.dds)?;
    crate::peers::run(&opts, &d, tutti_exit::stop_flag()?).map_err(anyhow::Error::new)?;
    Ok(())
}

fn sink(ddf: &Path, role: &str, args: &Args) -> CliResult {
    let (opts, d) = peer_opts(ddf, args.ros_domain_id, args.dds)?;
    let role = if role == "publish" { Role::Publish } else { Role::Subscribe };
    let r = crate::peers::sink(&opts, &d, role, args.duration, PATIENCE, args.ordered).map_err(anyhow::Error::new)?;
    println!("{} {} {} {} {}", r.samples, r.secs, r.lost, r.misordered, r.skipped_joining);
    Ok(())
}

fn source(ddf: &Path, args: &Args) -> CliResult {
    let (opts, d) = peer_opts(ddf, args.ros_domain_id, args.dds)?;
    crate::peers::source(&opts, &d, Duration::from_millis(500), tutti_exit::stop_flag()?)
        .map_err(anyhow::Error::new)?;
    Ok(())
}

// --- Output. ---

/// The gateway on the large DDF: up, every topic discovered by a DDS peer, topics bridged.
#[derive(Debug, Clone)]
struct Large {
    up: Duration,
    discovered: Duration,
    topics: usize,
    rss_kib: u64,
}
type LargeFig = Fig<Large>;
type LargeRuns = Vec<(EngineKind, LargeFig)>;
/// Which figure of an engine's run a row shows.
type Get<T> = fn(&EngineRun) -> &Fig<T>;
/// The engine a target applies to and whether a figure meets it.
type Target = Option<(EngineKind, fn(f64) -> bool)>;

/// One row of a placement's table: a label and one cell per engine.
fn row(label: &str, cells: impl IntoIterator<Item = String>) {
    let cells: String = cells.into_iter().map(|c| format!(" {c:>17}")).collect();
    println!("  {label:<62}{cells}");
}

/// A figure's cell: `show` of it, "-" when not measured; "ok" or "MISSED" after the
/// Cyclone engine's figure where `target` says whether it met its target.
fn cell<T>(f: &Fig<T>, show: impl Fn(&T) -> f64, digits: usize, target: Target) -> String {
    match f {
        Ok(v) => {
            let x = show(v);
            let mark = match target {
                Some((EngineKind::Cyclone, met)) if met(x) => " ok",
                Some((EngineKind::Cyclone, _)) => " MISSED",
                _ => "",
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

fn print_tables(runs: &[PlacementRun], large: &[(EngineKind, LargeFig)], large_ddf: &Path) {
    println!(
        "gateway: shm -> gateway -> DDS -> echo -> DDS -> gateway -> shm, {ITEMS} x float64 sets (typed samples of 80 bytes)"
    );
    for run in runs {
        let engines = &run.engines;
        println!();
        println!("{}", run.cpus.name);
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
        let each = |label: &str, get: &dyn Fn(&EngineRun) -> String| row(label, engines.iter().map(get));
        let rtt_rows: [(&str, Get<Rtt>); 4] = [
            ("gateway round trip, back to back", |r| &r.rtt),
            ("gateway round trip, paced at 1 kHz", |r| &r.paced),
            ("engine ping -> echo, no gateway, back to back", |r| &r.ping),
            ("engine ping -> echo, answered on the receive thread", |r| &r.ping_rx),
        ];
        for (label, get) in rtt_rows {
            each(&format!("{label}, p50 µs"), &|r| cell(get(r), |t| t.p50, 1, None));
            each(&format!("{label}, p99 µs"), &|r| cell(get(r), |t| t.p99, 1, None));
            each(&format!("{label}, lost"), &|r| cell(get(r), |t| f64::from(t.lost), 0, None));
        }
        let peers = &run.peers;
        for (label, f) in [
            ("ddsperf ping-pong (80 B), back to back", &peers.ddsperf),
            ("ddsperf ping-pong (80 B), ping 1kHz", &peers.ddsperf_paced),
            ("ddsperf ping-pong (80 B), ping waits on a waitset", &peers.ddsperf_waitset),
            ("Fast DDS ping-pong (UDP, 80 B), back to back", &peers.fastdds),
        ] {
            match f {
                Ok(t) => row(&format!("{label}, p50 / p99 µs"), [format!("{:.1} / {:.1}", t.p50, t.p99)]),
                Err(why) => {
                    println!("  {}: not run ({why})", if label.starts_with("Fast") { "fastdds" } else { "ddsperf" })
                }
            }
        }
        let met_rtt: fn(f64) -> bool = |x| x <= TARGET_RTT_RATIO;
        each(&format!("ratio gateway / ddsperf p50, back to back (cyclone <= {TARGET_RTT_RATIO})"), &|r| {
            cell(&ratio(&r.rtt, &peers.ddsperf), |x| *x, 2, Some((r.engine, met_rtt)))
        });
        each("ratio gateway / ddsperf ping on a waitset p50, back to back", &|r| {
            cell(&ratio(&r.rtt, &peers.ddsperf_waitset), |x| *x, 2, None)
        });
        each("ratio gateway / ddsperf p50, paced at 1 kHz", &|r| {
            cell(&ratio(&r.paced, &peers.ddsperf_paced), |x| *x, 2, None)
        });
        each("ratio gateway / Fast DDS p50, back to back", &|r| cell(&ratio(&r.rtt, &peers.fastdds), |x| *x, 2, None));
        let met_rate: fn(f64) -> bool = |x| x >= TARGET_RATE;
        let rate_rows: [(&str, Get<f64>, bool); 3] = [
            ("async set shm -> gateway -> DDS sink, samples/s", |r| &r.to_dds, true),
            ("async set DDS source -> gateway -> shm, samples/s", |r| &r.from_dds, true),
            ("async set DDS source -> DDS sink, no gateway, samples/s", |r| &r.alone, false),
        ];
        for (label, get, targeted) in rate_rows {
            each(label, &|r| cell(get(r), |x| *x, 0, targeted.then_some((r.engine, met_rate))));
        }
        each("sync set shm -> gateway -> DDS sink, samples/s", &|r| cell(&r.sync, rate, 0, None));
        each("sync set steps lost (but for the start of the reader's stream)", &|r| {
            cell(&r.sync, |s| s.lost as f64, 0, None)
        });
        each("sync set steps skipped while the reader joined", &|r| {
            cell(&r.sync, |s| s.skipped_joining as f64, 0, None)
        });
        each("sync set steps duplicated or reordered", &|r| cell(&r.sync, |s| s.misordered as f64, 0, None));
        each("lock-step, DDS echo answering each step, steps/s", &|r| cell(&r.lock, |l| l.per_s, 0, None));
        each("lock-step steps not answered for themselves", &|r| cell(&r.lock, |l| l.unanswered as f64, 0, None));
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
    println!();
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
struct Json {
    runs: Vec<JsonRun>,
    large: Vec<JsonLarge>,
}

/// `x` rounded to one decimal.
fn tenths(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
}

fn to_json(runs: &[PlacementRun], large: &[(EngineKind, LargeFig)]) -> Json {
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
