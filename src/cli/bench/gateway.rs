//! `tutti bench gateway`: the round trip shared memory -> gateway -> DDS -> echo peer ->
//! DDS -> gateway -> shared memory, against Cyclone's `ddsperf` ping-pong in the same run
//! and with the same core placement; the rate of an 8-item asynchronous set through the
//! gateway each way, next to rustdds alone on the same cores; and the start-up and memory
//! of a gateway serving ddf/large-1000.ddf.
//!
//! The framework is this process; the gateway and the DDS peers (`--echo`, `--sink`,
//! `--source`: separate DDS participants using the gateway's codec) are child processes,
//! each pinned to its CPU.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context as _};
use tutti_core::ddf::Role;
use tutti_core::shm::{os, Framework, FrameworkOptions, WaitMode};
use tutti_gateway::GatewayOptions;

use super::super::child::{self, Kid, SIGINT};
use super::super::{load_ddf, CliResult};

const ITEMS: usize = 8;
/// The log filter of the benchmark's children: errors only, nothing from the DDS stack.
const QUIET_LOG: &str = "error,rustdds=off,ros2_client=off";
const LOOPBACK: &str = "<CycloneDDS xmlns=\"https://cdds.io/config\"><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><Peers><Peer address=\"127.0.0.1\"/></Peers><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex></Discovery></Domain></CycloneDDS>";

/// Round trip and throughput through the gateway, next to Cyclone's ddsperf.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  cargo build --release && target/release/tutti bench gateway\n\nNeeds ddsperf (apt-get install -y cyclonedds-tools) for the comparison; figures go to docs/benchmarks.md."
)]
pub struct Args {
    /// Round trips timed per placement.
    #[arg(long, default_value_t = 2000)]
    samples: u32,
    /// How long the throughput run lasts.
    #[arg(long, default_value = "3s", value_parser = super::super::host::parse_duration)]
    duration: Duration,
    /// Core placements to run: same (everything on CPU 0), split (the gateway alone on CPU 1),
    /// apart (the DDS peer alone on CPU 1), both (same and split), all.
    #[arg(long, default_value = "all")]
    placement: String,
    /// DDS domain id of the runs.
    #[arg(long, default_value_t = 230)]
    ros_domain_id: u16,
    /// Also start a gateway on this DDF and record its start-up time and memory.
    #[arg(long, default_value = "ddf/large-1000.ddf")]
    large: PathBuf,
    /// Internal: run the echo peer for DDF (used by the benchmark itself).
    #[arg(long, hide = true, value_name = "DDF")]
    echo: Option<PathBuf>,
    /// Internal: count the samples on DDF's PUBLISH (`publish`) or SUBSCRIBE topic.
    #[arg(long, hide = true, num_args = 2, value_names = ["DDF", "ROLE"])]
    sink: Vec<String>,
    /// Internal: write SUBSCRIBE samples of DDF flat out.
    #[arg(long, hide = true, value_name = "DDF")]
    source: Option<PathBuf>,
}

fn ddf_text() -> String {
    let items: String = (0..ITEMS).map(|i| format!("<item name=\"v{i}\"><type>double</type></item>")).collect();
    format!(
        "<orchestra><domain name=\"gwbench\"><synchronous>no</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>\
         <block name=\"gwbench/Publish\">{items}</block><block name=\"gwbench/Subscribe\">{items}</block></domain></orchestra>"
    )
}

/// Starts a child pinned to `cpu`; dropped, it gets SIGINT and 3 s to leave (a gateway
/// says goodbye on DDS), then SIGKILL.
fn start(name: &str, cmd: Command, cpu: usize) -> anyhow::Result<Kid> {
    Ok(child::spawn(name, cmd, Some(cpu))?.stop_on_drop(Some(SIGINT), Duration::from_secs(3)))
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

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn rss_kib(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    s.lines().find_map(|l| l.strip_prefix("VmRSS:")).and_then(|v| v.split_whitespace().next()?.parse().ok())
}

pub fn run(args: Args) -> CliResult {
    if let Some(ddf) = &args.echo {
        return echo(ddf, args.ros_domain_id);
    }
    if let [ddf, role] = &args.sink[..] {
        return sink(Path::new(ddf), role, args.ros_domain_id, args.duration);
    }
    if let Some(ddf) = &args.source {
        return source(ddf, args.ros_domain_id);
    }
    let exe = std::env::current_exe().context("locating tutti")?;
    let dir = std::env::temp_dir().join(format!("tutti-bench-gw-{}", std::process::id()));
    std::fs::create_dir_all(&dir).context("creating a scratch directory")?;
    let ddf = dir.join("gwbench.ddf");
    std::fs::write(&ddf, ddf_text()).context("writing the benchmark DDF")?;
    let same = Cpus { name: "same core (all on CPU 0)", fw: 0, gw: 0, peer: 0 };
    let split = Cpus { name: "two cores (gateway CPU 1; framework and DDS peer CPU 0)", fw: 0, gw: 1, peer: 0 };
    let apart = Cpus { name: "two cores (framework and gateway CPU 0; DDS peer CPU 1)", fw: 0, gw: 0, peer: 1 };
    let placements = match args.placement.as_str() {
        "same" => vec![same],
        "split" => vec![split],
        "apart" => vec![apart],
        "both" => vec![same, split],
        _ => vec![same, split, apart],
    };
    println!("gateway round trip: shm -> gateway -> DDS -> echo -> DDS -> gateway -> shm, {ITEMS} x float64 async set");
    println!("{:<58} {:>10} {:>10} {:>10}", "placement / path", "p50 µs", "p99 µs", "lost");
    for cpus in placements {
        let name = cpus.name;
        let (r, paced) = round_trip(&exe, &ddf, &args, cpus).with_context(|| format!("placement {name}"))?;
        println!("{name}");
        println!(
            "  {:<56} {:>10.1} {:>10.1} {:>10}",
            "gateway (rustdds) round trip, back to back", r.p50, r.p99, r.lost
        );
        match rustdds_ping(&exe, &ddf, &args, cpus) {
            Ok(mut t) => {
                t.sort_by(f64::total_cmp);
                let lost = args.samples as usize - t.len();
                let (p50, p99) = (percentile(&t, 0.5), percentile(&t, 0.99));
                println!(
                    "  {:<56} {:>10.1} {:>10.1} {:>10}",
                    "rustdds ping -> echo round trip (no gateway)", p50, p99, lost
                );
            }
            Err(e) => println!("  rustdds ping: not run ({e:#})"),
        }
        // ddsperf's two processes: one per core when the DDS sides are on two cores.
        let (lo, hi) = (cpus.gw.min(cpus.peer), cpus.gw.max(cpus.peer));
        match ddsperf(lo, hi, None) {
            Ok((p50, p99)) => {
                println!("  {:<56} {:>10.1} {:>10.1}", "ddsperf ping-pong round trip, back to back", p50, p99);
                println!(
                    "  {:<56} {:>10.2}",
                    "ratio gateway / ddsperf, back to back, p50 (target <= 1.5)",
                    r.p50 / p50
                );
            }
            Err(e) => println!("  ddsperf: not run ({e:#})"),
        }
        println!(
            "  {:<56} {:>10.1} {:>10.1} {:>10}",
            "gateway (rustdds) round trip, paced at 1 kHz", paced.p50, paced.p99, paced.lost
        );
        match ddsperf(lo, hi, Some("1kHz")) {
            Ok((p50, p99)) => {
                println!("  {:<56} {:>10.1} {:>10.1}", "ddsperf ping-pong round trip, ping 1kHz", p50, p99);
                println!("  {:<56} {:>10.2}", "ratio gateway / ddsperf, paced at 1 kHz, p50", paced.p50 / p50);
            }
            Err(e) => println!("  ddsperf: not run ({e:#})"),
        }
        let t = throughput(&exe, &ddf, &args, cpus).with_context(|| format!("placement {name}"))?;
        println!("  {:<56} {:>10.0}", "shm -> gateway -> DDS sink, samples/s", t.to_dds);
        println!("  {:<56} {:>10.0}", "DDS source -> gateway -> shm, samples/s", t.from_dds);
        println!("  {:<56} {:>10.0}", "DDS source -> DDS sink (rustdds alone), samples/s", t.direct);
    }
    if args.large.exists() {
        let (up, rss) = large(&exe, &args)?;
        println!(
            "gateway on {}: up in {:.2} s, RSS {:.1} MiB",
            args.large.display(),
            up.as_secs_f64(),
            rss as f64 / 1024.0
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

struct RoundTrip {
    p50: f64,
    p99: f64,
    lost: u32,
}

/// Where the framework (this process), the gateway and the DDS peer run.
#[derive(Debug, Clone, Copy)]
struct Cpus {
    name: &'static str,
    fw: usize,
    gw: usize,
    peer: usize,
}

/// The gateway round trip back to back, then paced at 1 kHz (same processes).
fn round_trip(exe: &Path, ddf: &Path, args: &Args, cpus: Cpus) -> anyhow::Result<(RoundTrip, RoundTrip)> {
    let ns = format!("gwbench{}", std::process::id());
    let model = load_ddf(ddf).map_err(|f| f.error)?;
    let opts = FrameworkOptions { namespace: ns.clone(), wait: WaitMode::Spin, ..Default::default() };
    let mut fw = Framework::create(&model, &opts).context("creating the benchmark domain")?;
    let host = &mut fw.domains[0];
    let dom = args.ros_domain_id.to_string();
    let _gw = gateway(exe, ddf, cpus.gw, &dom, &ns)?;
    let _echo = echo_peer(exe, ddf, cpus.peer, &dom)?;
    pin_self(cpus.fw);
    let mut data = vec![0u8; ITEMS * 8];
    let mut seq = 0f64;
    let mut send = |host: &mut tutti_core::shm::DomainHost, seq: f64| {
        fill(&mut data, seq);
        host.publish_step(&data, seq).map(|_| ())
    };
    let back = |host: &mut tutti_core::shm::DomainHost| -> f64 {
        host.read_subscribe().map(|b| f64::from_ne_bytes(b[0..8].try_into().unwrap_or_default())).unwrap_or(f64::NAN)
    };
    // Until the echo path works end to end.
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        seq += 1.0;
        send(host, seq)?;
        let t = Instant::now();
        while t.elapsed() < Duration::from_millis(100) && back(host) != seq {
            std::hint::spin_loop();
        }
        if back(host) == seq {
            break;
        }
        if Instant::now() > end {
            bail!("no echo within 30 s (is the loopback interface up?)");
        }
    }
    let mut measure = |paced: bool| -> anyhow::Result<RoundTrip> {
        let mut times = Vec::with_capacity(args.samples as usize);
        let mut lost = 0;
        let start = Instant::now();
        for k in 0..args.samples {
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
            send(host, seq)?;
            let mut spins = 0u32;
            while back(host) != seq && t.elapsed() < Duration::from_secs(1) {
                // Spin, but give the core away between looks: the echo and the gateway may
                // share it (a pure spinner is only preempted at the end of its time slice).
                spins += 1;
                if spins < 16 {
                    std::hint::spin_loop();
                } else {
                    std::thread::yield_now();
                }
            }
            if back(host) == seq {
                times.push(t.elapsed().as_secs_f64() * 1e6);
            } else {
                lost += 1;
            }
        }
        times.sort_by(f64::total_cmp);
        Ok(RoundTrip { p50: percentile(&times, 0.5), p99: percentile(&times, 0.99), lost })
    };
    let hot = measure(false)?;
    let paced = measure(true)?;
    Ok((hot, paced))
}

/// ddsperf ping-pong with the same placement, back to back (`rate` None: a ping as soon as
/// the pong is in) or at a rate ("1kHz"); returns (p50, p99) of the round trip in µs.
fn ddsperf(main_cpu: usize, other_cpu: usize, rate: Option<&str>) -> anyhow::Result<(f64, f64)> {
    let domain = "229";
    let mut pong = Command::new("ddsperf");
    pong.args(["-i", domain, "-D8", "pong"])
        .env("CYCLONEDDS_URI", LOOPBACK)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    let _pong = start("ddsperf pong", pong, other_cpu)?;
    let mut ping = Command::new("ddsperf");
    ping.args(["-i", domain, "-D5", "-Qminmatch:1", "-Qinitwait:5", "ping"])
        .args(rate)
        .env("CYCLONEDDS_URI", LOOPBACK)
        .stderr(Stdio::null());
    child::prepare(&mut ping, Some(main_cpu));
    let out = ping.output().context("running ddsperf ping")?;
    let mut p50s = Vec::new();
    let mut p99s = Vec::new();
    for line in String::from_utf8_lossy(&out.stdout).lines().filter(|l| l.contains(" 50% ")) {
        let num = |key: &str| -> Option<f64> { line.split(key).nth(1)?.split("us").next()?.trim().parse().ok() };
        if let (Some(a), Some(b)) = (num(" 50% "), num(" 99% ")) {
            p50s.push(a);
            p99s.push(b);
        }
    }
    if p50s.is_empty() {
        bail!("no ddsperf output (apt-get install -y cyclonedds-tools)");
    }
    p50s.sort_by(f64::total_cmp);
    p99s.sort_by(f64::total_cmp);
    // ddsperf prints half the round trip.
    Ok((2.0 * percentile(&p50s, 0.5), 2.0 * percentile(&p99s, 0.5)))
}

/// Starts a gateway on the large DDF; returns its start-up time and RSS (KiB) once up.
fn large(exe: &Path, args: &Args) -> anyhow::Result<(Duration, u64)> {
    let t = Instant::now();
    let mut cmd = Command::new(exe);
    cmd.args(["gateway", &args.large.to_string_lossy(), "--ros-domain-id", &(args.ros_domain_id - 1).to_string()])
        .args(["--interface", "127.0.0.1", "--status-every", "1h"])
        .env("TUTTI_NAMESPACE", format!("gwbenchlarge{}", std::process::id()))
        .env("RUST_LOG", QUIET_LOG)
        .stdin(Stdio::null())
        .stderr(Stdio::piped());
    let mut kid =
        child::spawn("the gateway on the large DDF", cmd, None)?.stop_on_drop(Some(SIGINT), Duration::from_secs(3));
    let stderr = kid.child.stderr.take();
    let mut up = None;
    if let Some(s) = stderr {
        for line in BufReader::new(s).lines().map_while(Result::ok) {
            if line.contains("tutti gateway: up") {
                up = Some(t.elapsed());
                break;
            }
        }
    }
    let up = up.context("the gateway on the large DDF did not start")?;
    std::thread::sleep(Duration::from_millis(500));
    let rss = rss_kib(kid.pid()).unwrap_or(0);
    Ok((up, rss))
}

fn echo(ddf: &Path, domain_id: u16) -> CliResult {
    let (opts, d) = peer_opts(ddf, domain_id)?;
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    ctrlc::set_handler(move || s.store(true, Ordering::SeqCst)).context("installing the signal handler")?;
    tutti_gateway::echo::run(&opts, &d, stop).map_err(anyhow::Error::new)?;
    Ok(())
}

struct Throughput {
    to_dds: f64,
    from_dds: f64,
    direct: f64,
}

fn gateway(exe: &Path, ddf: &Path, cpu: usize, dom: &str, ns: &str) -> anyhow::Result<Kid> {
    let mut cmd = Command::new(exe);
    cmd.args(["gateway", &ddf.to_string_lossy(), "--ros-domain-id", dom, "--interface", "127.0.0.1"])
        .args(["--poll", "0", "--wait", "spin", "-q"])
        .env("TUTTI_NAMESPACE", ns)
        .env("RUST_LOG", QUIET_LOG)
        .stdin(Stdio::null());
    start("the gateway", cmd, cpu)
}

/// The echo peer (`--echo`) on `cpu`.
fn echo_peer(exe: &Path, ddf: &Path, cpu: usize, dom: &str) -> anyhow::Result<Kid> {
    let mut cmd = Command::new(exe);
    cmd.args(["bench", "gateway", "--echo", &ddf.to_string_lossy(), "--ros-domain-id", dom]).stdin(Stdio::null());
    start("the echo peer", cmd, cpu)
}

fn peer(exe: &Path, cpu: usize, dom: &str, duration: Duration, what: &[&str]) -> anyhow::Result<Kid> {
    let mut cmd = Command::new(exe);
    cmd.args(["bench", "gateway", "--ros-domain-id", dom, "--duration"])
        .arg(format!("{}ms", duration.as_millis()))
        .args(what)
        .env("RUST_LOG", QUIET_LOG)
        .stdin(Stdio::null())
        .stdout(Stdio::piped());
    start("a benchmark peer", cmd, cpu)
}

/// The sink's "samples seconds" line; waits for it to exit.
fn sink_rate(kid: &mut Kid) -> anyhow::Result<f64> {
    let mut line = String::new();
    if let Some(out) = kid.child.stdout.take() {
        BufReader::new(out).read_line(&mut line)?;
    }
    let mut it = line.split_whitespace().map(str::parse::<f64>);
    match (it.next(), it.next()) {
        (Some(Ok(n)), Some(Ok(secs))) if secs > 0.0 => Ok(n / secs),
        _ => bail!("the sink received nothing"),
    }
}

/// Samples per second, each way, of the 8-item asynchronous set, and rustdds alone.
///
/// * shm -> DDS: this process commits PUBLISH values flat out (yielding between commits,
///   so a peer on the same core runs); the gateway sends each new value it sees; a rustdds
///   sink in another process counts what arrives over `duration`.
/// * DDS -> shm: a rustdds source writes SUBSCRIBE samples flat out; the commits the
///   gateway makes in shared memory are counted over `duration`.
/// * rustdds alone: the same source and sink on the same cores, without the gateway.
fn throughput(exe: &Path, ddf: &Path, args: &Args, cpus: Cpus) -> anyhow::Result<Throughput> {
    let ns = format!("gwbenchtp{}", std::process::id());
    let model = load_ddf(ddf).map_err(|f| f.error)?;
    let opts = FrameworkOptions { namespace: ns.clone(), wait: WaitMode::Spin, ..Default::default() };
    let mut fw = Framework::create(&model, &opts).context("creating the benchmark domain")?;
    let host = &mut fw.domains[0];
    let dom = (args.ros_domain_id + 2).to_string();
    let ddfs = ddf.to_string_lossy().into_owned();
    pin_self(cpus.fw);
    let _gw = gateway(exe, ddf, cpus.gw, &dom, &ns)?;

    // shm -> DDS.
    let mut sink = peer(exe, cpus.peer, &dom, args.duration, &["--sink", &ddfs, "publish"])?;
    let mut data = vec![0u8; ITEMS * 8];
    let mut seq = 0f64;
    let end = Instant::now() + args.duration + Duration::from_secs(40);
    while sink.poll().is_none() && Instant::now() < end {
        seq += 1.0;
        fill(&mut data, seq);
        host.publish_step(&data, seq)?;
        std::thread::yield_now();
    }
    let to_dds = sink_rate(&mut sink)?;

    // DDS -> shm.
    let source = peer(exe, cpus.peer, &dom, args.duration, &["--source", &ddfs])?;
    let commits = |host: &tutti_core::shm::DomainHost| host.status().subscribe_commits;
    let c0 = commits(host);
    let end = Instant::now() + Duration::from_secs(40);
    while commits(host) < c0 + 100 && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(1));
    }
    let (c1, t) = (commits(host), Instant::now());
    std::thread::sleep(args.duration);
    let from_dds = (commits(host) - c1) as f64 / t.elapsed().as_secs_f64();
    drop(source);
    drop(_gw);

    // rustdds alone, on the same cores.
    let mut sink = peer(exe, cpus.gw, &dom, args.duration, &["--sink", &ddfs, "subscribe"])?;
    let _source = peer(exe, cpus.peer, &dom, args.duration, &["--source", &ddfs])?;
    let direct = sink_rate(&mut sink)?;
    Ok(Throughput { to_dds, from_dds, direct })
}

fn peer_opts(ddf: &Path, domain_id: u16) -> anyhow::Result<(GatewayOptions, tutti_core::ddf::Domain)> {
    let model = load_ddf(ddf).map_err(|f| f.error)?;
    let mut opts = GatewayOptions::new(ddf, model.clone());
    opts.ros_domain_id = domain_id;
    opts.interfaces = vec![std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)];
    let d = model.domains.first().context("the DDF has no domain")?.clone();
    Ok((opts, d))
}

fn sink(ddf: &Path, role: &str, domain_id: u16, window: Duration) -> CliResult {
    let (opts, d) = peer_opts(ddf, domain_id)?;
    let role = if role == "publish" { Role::Publish } else { Role::Subscribe };
    let (n, secs) =
        tutti_gateway::echo::sink(&opts, &d, role, window, Duration::from_secs(30)).map_err(anyhow::Error::new)?;
    println!("{n} {secs}");
    Ok(())
}

fn source(ddf: &Path, domain_id: u16) -> CliResult {
    let (opts, d) = peer_opts(ddf, domain_id)?;
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    ctrlc::set_handler(move || s.store(true, Ordering::SeqCst)).context("installing the signal handler")?;
    tutti_gateway::echo::source(&opts, &d, Duration::from_millis(500), stop).map_err(anyhow::Error::new)?;
    Ok(())
}

/// The echo pinged by a rustdds participant in this process (where the gateway was), with
/// no gateway and no shared memory: what rustdds itself costs on this path.
fn rustdds_ping(exe: &Path, ddf: &Path, args: &Args, cpus: Cpus) -> anyhow::Result<Vec<f64>> {
    let dom = (args.ros_domain_id + 4).to_string();
    let _echo = echo_peer(exe, ddf, cpus.peer, &dom)?;
    pin_self(cpus.gw);
    let (mut opts, d) = peer_opts(ddf, args.ros_domain_id + 4)?;
    opts.node_name = "tutti_bench_ping".into();
    let t = tutti_gateway::echo::ping(&opts, &d, args.samples, Duration::from_secs(30));
    pin_self(cpus.fw);
    t.map_err(anyhow::Error::new)
}
