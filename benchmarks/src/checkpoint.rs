//! `tutti-bench checkpoint`: what a checkpoint (docs/run.md, "Checkpoints") costs a run, next
//! to the time of one of its steps.
//!
//! Two runs, each hosted by a `Host` in this process with `speed` infinite (steps as fast as
//! the participants go):
//!
//! * **the large run**: a generated DDF of `--domains` synchronous domains (default 1,000) of
//!   `--items` items each (default 20: half PUBLISH, half SUBSCRIBE, 16 in 20 float64, the
//!   others int32 and boolean), no participants;
//! * **the UAV demo's run** (docs/uav-demo.md): its DDF (the four domains of
//!   `ddf/multiuav.ddf` and the FMU component's), its step (50 ms), its `framework.set`
//!   commands and its connections, with the four UAV components connected as participants:
//!   threads of this process that do what `tutti-demo uav-node` does at each step (read the
//!   commands and the step's time, fly the `tutti-uav` model to it, write the six outputs).
//!   The demo's components keep no state (no state handler), so its checkpoints are taken
//!   with `checkpoint(true)` (they are left out and named in the checkpoint), and the output
//!   says so. The FMU component (`tutti fmu run`, a process of its own), the gateway, the
//!   monitoring script, the C readers and the recording are not part of it: the FMU's
//!   domain is hosted, unconnected.
//!
//! Each run makes `--warmup-steps` steps, then `--warmup` untimed rounds, then
//! `--iterations` timed rounds of: one step (`Host::step`), a checkpoint alone
//! (`Host::checkpoint`), a save (a checkpoint written to a file: `Checkpoint::write`, which
//! syncs the file and renames it into place) and a restore (`Checkpoint::read` of that file
//! and `Host::restore`). Before the timed rounds it checks that a restore puts back what
//! was saved: a checkpoint taken after restoring an older one equals the older one.
//!
//! The files go to a directory made for the run in `--dir` (default: the system's
//! temporary directory) and removed at the end, whatever happened; the segments go with
//! each `Host`, and the benchmark checks that none is left.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{bail, ensure, Context as _};
use serde_json::json;
use tutti_core::ddf::{self, Role};
use tutti_core::shm::{ConnectOptions, Participant, ShmError};
use tutti_host::checkpoint::Checkpoint;
use tutti_host::{Host, HostOptions, Report};

use crate::{nearest_rank, CliResult};

/// Checkpoint save and restore of a 1,000-domain run and of the UAV demo's, next to a step.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti-bench checkpoint\n  tutti-bench checkpoint --iterations 200 --dir /dev/shm --json\n\nThe target (the issue's): save and restore of the 1,000-domain run each at most 50 ms (p99)."
)]
pub struct Args {
    /// Domains of the generated DDF (synchronous, no participants).
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..))]
    domains: u64,
    /// Items per domain of the generated DDF, half PUBLISH and half SUBSCRIBE.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(2..))]
    items: u64,
    /// Timed rounds (a step, a checkpoint, a save, a restore) per run.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32).range(1..))]
    iterations: u32,
    /// Untimed rounds before the timed ones (first page faults, the allocator, the file).
    #[arg(long, default_value_t = 3)]
    warmup: u32,
    /// Steps each run makes before anything is saved.
    #[arg(long, default_value_t = 10)]
    warmup_steps: u32,
    /// Where the checkpoint files go: a directory made in DIR for the run and removed at the
    /// end (default: the system's temporary directory). A save syncs its file, so the
    /// filesystem counts: the output names it.
    #[arg(long, value_name = "DIR")]
    dir: Option<PathBuf>,
    /// Leave out the UAV demo's run.
    #[arg(long)]
    no_uav: bool,
    /// Print one JSON object instead of the tables.
    #[arg(long)]
    json: bool,
}

/// The target for the 1,000-domain run: save and restore each at most this long.
const TARGET: Duration = Duration::from_millis(50);
/// The percentile the target is judged on.
const TARGET_Q: f64 = 0.99;

/// What one run measured: each operation's timings, sorted.
struct Figures {
    name: String,
    /// One line on what ran.
    what: String,
    domains: usize,
    items: usize,
    /// Components whose states a checkpoint holds, and those it leaves out (name and why).
    saved: usize,
    skipped: Vec<String>,
    skip_stateless: bool,
    /// The size of the checkpoint file.
    file_bytes: u64,
    /// (label, JSON key, timings).
    ops: Vec<(&'static str, &'static str, Vec<Duration>)>,
}

impl Figures {
    fn op(&self, key: &str) -> &[Duration] {
        self.ops.iter().find(|(_, k, _)| *k == key).map_or(&[], |(_, _, v)| v)
    }
}

/// A directory of the benchmark's own, removed with everything in it when dropped.
struct Scratch(PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub fn run(args: Args) -> CliResult {
    let stop = tutti_exit::stop_flag()?;
    let base = args.dir.clone().unwrap_or_else(std::env::temp_dir);
    let scratch = Scratch(base.join(format!("tutti-bench-checkpoint-{}", std::process::id())));
    std::fs::create_dir(&scratch.0).with_context(|| format!("creating {}", scratch.0.display()))?;
    let fs = filesystem(&scratch.0);
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    let mut runs = Vec::new();
    runs.push(large_run(&args, &scratch.0, &stop)?);
    if !args.no_uav {
        runs.push(uav_run(&args, &scratch.0, &stop)?);
    }
    let dir = scratch.0.clone();
    drop(scratch);
    if dir.exists() {
        return Err(anyhow::anyhow!("the scratch directory {} is still there", dir.display()).into());
    }
    let large = &runs[0];
    let save = q(large.op("save"), TARGET_Q);
    let restore = q(large.op("restore"), TARGET_Q);
    let ok = save <= TARGET && restore <= TARGET;
    if args.json {
        print_json(&args, cpus, &fs, &runs, ok)?;
        return Ok(());
    }
    println!(
        "checkpoints: {} timed rounds per run after {} warm-up round(s) and {} steps; files in {} ({fs}); {cpus} CPUs in the process's affinity, the benchmark pins nothing",
        args.iterations,
        args.warmup,
        args.warmup_steps,
        base.display()
    );
    for r in &runs {
        print_table(r);
    }
    let verdict = if ok { "ok" } else { "MISSED" };
    let of = if large.domains == 1000 { String::new() } else { format!(" (this run: {} domains)", large.domains) };
    println!(
        "target: save and restore of the 1,000-domain run each <= {} ms (p99){of}: save p99 {:.3} ms (max {:.3}), read + restore p99 {:.3} ms (max {:.3}) {verdict}",
        TARGET.as_millis(),
        ms(save),
        ms(q(large.op("save"), 1.0)),
        ms(restore),
        ms(q(large.op("restore"), 1.0)),
    );
    Ok(())
}

/// The nearest-rank quantile of sorted timings (zero when there are none).
fn q(sorted: &[Duration], p: f64) -> Duration {
    if sorted.is_empty() {
        return Duration::ZERO;
    }
    nearest_rank(sorted, p)
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// The table of one run.
fn print_table(r: &Figures) {
    println!();
    println!("{}: {}", r.name, r.what);
    let components = if r.skip_stateless {
        format!(
            "checkpoint(true): {} component(s) keep no state and are left out ({}), {} saved",
            r.skipped.len(),
            r.skipped.join(", "),
            r.saved
        )
    } else {
        format!("checkpoint(false): {} component state(s) saved", r.saved)
    };
    println!("  checkpoint file {} bytes; {components}", r.file_bytes);
    println!("  {:<48} {:>9} {:>9} {:>9} {:>9}", "operation (ms)", "p50", "p90", "p99", "max");
    for (label, _, v) in &r.ops {
        println!(
            "  {label:<48} {:>9.3} {:>9.3} {:>9.3} {:>9.3}",
            ms(q(v, 0.5)),
            ms(q(v, 0.9)),
            ms(q(v, 0.99)),
            ms(q(v, 1.0))
        );
    }
}

/// `--json`: every run and the verdict as one object.
fn print_json(args: &Args, cpus: usize, fs: &str, runs: &[Figures], ok: bool) -> anyhow::Result<()> {
    let runs: Vec<_> = runs
        .iter()
        .map(|r| {
            let ops: serde_json::Map<String, serde_json::Value> = r
                .ops
                .iter()
                .map(|(_, key, v)| {
                    let p = |x: f64| ms(q(v, x));
                    (format!("{key}_ms"), json!({ "p50": p(0.5), "p90": p(0.9), "p99": p(0.99), "max": p(1.0) }))
                })
                .collect();
            json!({
                "run": r.name,
                "what": r.what,
                "domains": r.domains,
                "items": r.items,
                "skip_stateless": r.skip_stateless,
                "components_saved": r.saved,
                "components_skipped": r.skipped,
                "file_bytes": r.file_bytes,
                "timings": ops,
            })
        })
        .collect();
    let out = json!({
        "benchmark": "checkpoint",
        "iterations": args.iterations,
        "warmup": args.warmup,
        "warmup_steps": args.warmup_steps,
        "filesystem": fs,
        "cpus": cpus,
        "runs": runs,
        "target_ms": ms(TARGET),
        "target_percentile": TARGET_Q,
        "ok": ok,
    });
    println!("{}", serde_json::to_string(&out).context("writing JSON")?);
    Ok(())
}

/// The type of the filesystem `dir` is on, as `/proc/self/mounts` names it (the longest mount
/// point above it), with the mount point.
fn filesystem(dir: &Path) -> String {
    let dir = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    let Ok(mounts) = std::fs::read_to_string("/proc/self/mounts") else { return "filesystem unknown".into() };
    let best = mounts
        .lines()
        .filter_map(|l| {
            let mut f = l.split_whitespace();
            let (_, at, ty) = (f.next()?, f.next()?, f.next()?);
            dir.starts_with(at).then(|| (at.to_string(), ty.to_string()))
        })
        .max_by_key(|(at, _)| at.len());
    best.map_or_else(|| "filesystem unknown".into(), |(at, ty)| format!("{ty} on {at}"))
}

/// The generated DDF: `domains` synchronous domains of `items` items.
fn large_ddf(domains: usize, items: usize) -> String {
    use std::fmt::Write as _;
    let ty = |i: usize| match i % 10 {
        4 => "int32",
        9 => "boolean",
        _ => "float64",
    };
    let publish = items.div_ceil(2);
    let mut out = String::with_capacity(domains * (250 + items * 60));
    out.push_str("<orchestra>\n");
    for d in 0..domains {
        let _ = writeln!(
            out,
            "<domain name=\"ckpt_{d:04}\"><synchronous>yes</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>"
        );
        out.push_str("<set name=\"PUBLISH\">");
        for i in 0..publish {
            let _ = write!(out, "<item name=\"p{i}\"><type>{}</type></item>", ty(i));
        }
        out.push_str("</set>\n<set name=\"SUBSCRIBE\">");
        for i in publish..items {
            let _ = write!(out, "<item name=\"s{i}\"><type>{}</type></item>", ty(i));
        }
        out.push_str("</set></domain>\n");
    }
    out.push_str("</orchestra>\n");
    out
}

/// Counts the step timeouts a run reports (there must be none) and prints the other reports
/// but the expected one: the demo's components keep no state, so the host can take no
/// checkpoint of step 0.
fn reporter<'a>(tag: &'static str, timeouts: &'a mut u64) -> impl FnMut(Report) + 'a {
    move |r: Report| match r {
        Report::StepTimedOut { .. } => {
            *timeouts += 1;
            eprintln!("bench checkpoint: {tag}: {r}");
        }
        Report::NoStateReset(_) => {}
        r => eprintln!("bench checkpoint: {tag}: {r}"),
    }
}

/// The large run: the generated DDF, no participants.
fn large_run(args: &Args, dir: &Path, stop: &AtomicBool) -> anyhow::Result<Figures> {
    let (domains, items) = (args.domains as usize, args.items as usize);
    let model = ddf::parse_str(&large_ddf(domains, items), "checkpoint-bench.ddf").context("the benchmark's DDF")?;
    let namespace = format!("benchckpt{}x1", std::process::id());
    let opts = HostOptions {
        step: Duration::from_millis(10),
        speed: f64::INFINITY,
        timeout: Duration::from_secs(5),
        namespace: Some(namespace.clone()),
        ddf_name: format!("the benchmark's DDF ({domains} domains)"),
        ..Default::default()
    };
    eprintln!("bench checkpoint: creating {domains} domains");
    let result = (|| {
        let mut host = Host::new(&model, opts).context("creating the domains")?;
        let mut timeouts = 0;
        let mut on_report = reporter("large run", &mut timeouts);
        if !host.start(stop, &mut on_report).context("starting the run")? {
            bail!("interrupted");
        }
        let what = format!(
            "{domains} domains x {items} items (generated: synchronous, {} PUBLISH + {} SUBSCRIBE items each, float64 mostly), no participants, step 10ms, speed inf",
            items.div_ceil(2),
            items / 2
        );
        let figures = measure(&mut host, args, dir, "large", false, stop, &mut on_report)?;
        drop(on_report);
        ensure!(timeouts == 0, "the large run: {timeouts} step(s) timed out");
        let name = if domains == 1000 { "1,000-domain run".to_string() } else { format!("{domains}-domain run") };
        Ok(Figures { name, what, domains, items, ..figures })
    })();
    check_removed(&namespace)?;
    result
}

/// The UAV demo's run DDF: `ddf/multiuav.ddf` and the FMU component's domain, as
/// `tutti-demo uav` writes it (crates/tutti-uav-demo/src/sim.rs, `run_ddf`).
fn uav_ddf() -> anyhow::Result<String> {
    const PAPER: &str = include_str!("../../ddf/multiuav.ddf");
    const FMU_DOMAIN: &str = include_str!("../../examples/uav/fmu-domain.xml");
    let end = PAPER.rfind("</orchestra>").context("ddf/multiuav.ddf has no </orchestra>")?;
    Ok(format!("{}{FMU_DOMAIN}{}", &PAPER[..end], &PAPER[end..]))
}

/// The UAVs of the demo.
const UAVS: usize = 4;

/// The UAV demo's run: its framework as `examples/uav/uav-demo.json5` sets it up, and its
/// four UAV components as threads.
fn uav_run(args: &Args, dir: &Path, stop: &AtomicBool) -> anyhow::Result<Figures> {
    let model = ddf::parse_str(&uav_ddf()?, "multiuav.ddf").context("the UAV demo's DDF")?;
    let namespace = format!("benchckpt{}x2", std::process::id());
    // The launch file's `framework.set` and `connections`.
    let slots = [(0, 0, 0), (-60, -60, 20), (-60, 60, -20), (-120, 0, 40)];
    let mut sets = Vec::new();
    for (i, (x, y, z)) in slots.iter().enumerate() {
        let d = format!("multiuav_uav{}", i + 1);
        sets.extend([
            format!("{d}/Autopilot=1"),
            format!("{d}/X={x}"),
            format!("{d}/Y={y}"),
            format!("{d}/Z={z}"),
            format!("{d}/Airspeed=25"),
        ]);
    }
    let mut connections = Vec::new();
    for i in 1..=UAVS {
        connections.push(format!("@sim_time -> multiuav_uav{i}/publish/Time"));
        connections.push(format!("multiuav_uav{i}/subscribe/Elevation -> multiuav_uav{i}/publish/Altitude"));
    }
    connections.push("multiuav_uav1/subscribe/Elevation -> uav1_altitude_filter/publish/elevation".into());
    let connections = connections
        .iter()
        .map(|c| tutti_host::connect::parse_connection(c).with_context(|| format!("the connection {c}")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let opts = HostOptions {
        step: Duration::from_millis(50),
        speed: f64::INFINITY,
        timeout: Duration::from_secs(5),
        namespace: Some(namespace.clone()),
        sets,
        connections,
        hold_until_start: true,
        ddf_name: "multiuav.ddf (the UAV demo's run)".into(),
        ..Default::default()
    };
    eprintln!("bench checkpoint: the UAV demo's run");
    let quit = Arc::new(AtomicBool::new(false));
    let mut threads: Vec<JoinHandle<anyhow::Result<u64>>> = Vec::new();
    let result = (|| {
        // Dropped on every way out: the segments go with it, and the components' next call
        // returns "framework stopped".
        let mut host = Host::new(&model, opts).context("creating the domains")?;
        for i in 1..=UAVS {
            let (ns, quit) = (namespace.clone(), quit.clone());
            threads.push(std::thread::spawn(move || uav_component(&ns, i, &quit)));
        }
        wait_connected(&host, &threads, stop)?;
        let mut timeouts = 0;
        let mut on_report = reporter("UAV run", &mut timeouts);
        if !host.start(stop, &mut on_report).context("starting the run")? {
            bail!("interrupted");
        }
        let what = "the UAV demo's DDF (multiuav_uav1..4 + uav1_altitude_filter), its sets and 9 connections, step 50ms, speed inf; uav1..uav4 connected (threads flying the tutti-uav model as tutti-demo uav-node does); the FMU component, gateway, monitor, C readers and recording not run".to_string();
        let figures = measure(&mut host, args, dir, "uav", true, stop, &mut on_report)?;
        drop(on_report);
        ensure!(timeouts == 0, "the UAV run: {timeouts} step(s) timed out");
        let domains = host.framework().domains.len();
        let items = host
            .framework()
            .domains
            .iter()
            .map(|d| d.info().publish.leaves.len() + d.info().subscribe.leaves.len())
            .sum::<usize>()
            / domains;
        Ok(Figures { name: "UAV demo's run".into(), what, domains, items, ..figures })
    })();
    quit.store(true, Ordering::SeqCst);
    let mut failed = None;
    for (i, t) in threads.into_iter().enumerate() {
        match t.join() {
            Ok(Ok(_)) => {}
            Ok(Err(e)) => {
                failed.get_or_insert(e.context(format!("uav{}", i + 1)));
            }
            Err(_) => {
                failed.get_or_insert_with(|| anyhow::anyhow!("uav{} panicked", i + 1));
            }
        }
    }
    check_removed(&namespace)?;
    let figures = result?;
    match failed {
        Some(e) => Err(e),
        None => Ok(figures),
    }
}

/// Waits until each UAV domain has its component.
fn wait_connected(host: &Host, threads: &[JoinHandle<anyhow::Result<u64>>], stop: &AtomicBool) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(30);
    let count =
        |d: &str| host.framework().domains.iter().find(|x| x.info().name == d).map_or(0, |x| x.connection_count());
    while (1..=UAVS).any(|i| count(&format!("multiuav_uav{i}")) == 0) {
        if threads.iter().any(|t| t.is_finished()) {
            bail!("a UAV component ended before the run started");
        }
        if stop.load(Ordering::SeqCst) {
            bail!("interrupted");
        }
        if Instant::now() >= deadline {
            bail!("the UAV components did not all connect within 30 s");
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    Ok(())
}

fn f64_at(buf: &[u8], off: usize) -> f64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&buf[off..off + 8]);
    f64::from_ne_bytes(b)
}

/// UAV component `index` (1..=4), as `tutti-demo uav-node --index N` flies it while connected
/// (crates/tutti-uav-demo/src/node.rs): at each step, read the formation commands and the
/// step's time, fly the model to that time in steps of at most `DEFAULT_DT`, and write
/// Latitude, Longitude, Elevation, Airspeed, Heading and Time. Returns the steps answered once
/// the framework stops.
fn uav_component(namespace: &str, index: usize, quit: &AtomicBool) -> anyhow::Result<u64> {
    let mut uav = tutti_uav::scenario::default_formation()
        .build_uav(index - 1)
        .map_err(|e| anyhow::anyhow!("UAV {index}: {e}"))?;
    let domain = format!("multiuav_uav{index}");
    let opts = ConnectOptions {
        namespace: namespace.to_string(),
        name: format!("uav{index}"),
        connect_timeout: Duration::from_secs(30),
        ..Default::default()
    };
    let mut p = Participant::connect(&domain, opts).with_context(|| format!("connecting to {domain}"))?;
    // Short lock timeouts, as the node's: the quit flag is looked at between locks.
    p.set_timeout(Duration::from_millis(250));
    let off = |p: &Participant, role: Role, name: &str| -> anyhow::Result<usize> {
        let (_, leaf) = p.leaf(role, name)?;
        ensure!(leaf.size == 8 && leaf.length == 1, "{name} must be a float64 scalar");
        Ok(leaf.offset as usize)
    };
    let mut commands = [0usize; 5];
    for (c, name) in commands.iter_mut().zip(["Autopilot", "X", "Y", "Z", "Airspeed"]) {
        *c = off(&p, Role::Publish, name)?;
    }
    let time = off(&p, Role::Publish, "Time")?;
    let outputs = ["Latitude", "Longitude", "Elevation", "Airspeed", "Heading", "Time"];
    let mut answered = 0u64;
    while !quit.load(Ordering::SeqCst) {
        match p.subscribe_lock() {
            Ok(_) => {}
            Err(ShmError::Timeout { .. }) => continue,
            Err(ShmError::FrameworkStopped { .. }) => break,
            Err(e) => return Err(e).context("reading the commands"),
        }
        let snap = p.snapshot();
        let c = commands.map(|o| f64_at(snap, o));
        let t = f64_at(snap, time);
        uav.apply_command(&tutti_uav::FormationCommand::from_ddf(c[0], c[1], c[2], c[3], c[4]));
        while uav.time() + 1e-9 < t {
            let dt = (t - uav.time()).min(tutti_uav::DEFAULT_DT);
            uav.step(dt);
        }
        let o = uav.outputs();
        let values = [o.lat_deg, o.lon_deg, o.elevation_m, o.airspeed, o.heading_deg, o.time];
        let step = (|| -> Result<(), ShmError> {
            p.publish_lock()?;
            for (name, v) in outputs.iter().zip(values) {
                p.stage(name, &v.to_ne_bytes())?;
            }
            p.commit()
        })();
        match step {
            Ok(()) => answered += 1,
            Err(ShmError::Timeout { .. }) => {}
            Err(ShmError::FrameworkStopped { .. }) => break,
            Err(e) => return Err(e).context("writing the state"),
        }
    }
    Ok(answered)
}

/// The timed rounds of one run (see the module's documentation), after its warm-up; `tag`
/// names the checkpoint file.
fn measure(
    host: &mut Host,
    args: &Args,
    dir: &Path,
    tag: &str,
    skip_stateless: bool,
    stop: &AtomicBool,
    on_report: &mut dyn FnMut(Report),
) -> anyhow::Result<Figures> {
    let path = dir.join(format!("{tag}.{}", tutti_host::checkpoint::EXTENSION));
    let interrupted = || if stop.load(Ordering::SeqCst) { Err(anyhow::anyhow!("interrupted")) } else { Ok(()) };
    for _ in 0..args.warmup_steps {
        interrupted()?;
        host.step(on_report).context("a step")?;
    }
    check_restore(host, &path, skip_stateless, on_report)?;
    let n = args.iterations as usize;
    let mut t: [Vec<Duration>; 7] = std::array::from_fn(|_| Vec::with_capacity(n));
    let [step, checkpoint, save, write, restore, read, put_back] = &mut t;
    let mut file_bytes = 0;
    let mut last = None;
    for round in 0..args.warmup as usize + n {
        interrupted()?;
        let timed = round >= args.warmup as usize;
        let s = Instant::now();
        host.step(on_report).context("a step")?;
        let step_t = s.elapsed();

        let s = Instant::now();
        let c = host.checkpoint(skip_stateless).context("a checkpoint")?;
        let checkpoint_t = s.elapsed();
        drop(c);

        let s = Instant::now();
        let c = host.checkpoint(skip_stateless).context("a checkpoint")?;
        let m = Instant::now();
        c.write(&path).context("writing the checkpoint")?;
        let (save_t, write_t) = (s.elapsed(), m.elapsed());

        let s = Instant::now();
        let back = Checkpoint::read(&path).context("reading the checkpoint")?;
        let m = Instant::now();
        host.restore(&back).context("restoring the checkpoint")?;
        let (restore_t, put_back_t, read_t) = (s.elapsed(), m.elapsed(), m - s);
        file_bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        last = Some(c);
        if timed {
            step.push(step_t);
            checkpoint.push(checkpoint_t);
            save.push(save_t);
            write.push(write_t);
            restore.push(restore_t);
            read.push(read_t);
            put_back.push(put_back_t);
        }
    }
    t.iter_mut().for_each(|v| v.sort_unstable());
    let [step, checkpoint, save, write, restore, read, put_back] = t;
    let last = last.context("no round was made")?;
    let skipped = last.skipped.iter().map(|s| format!("{} in {}: {}", s.name, s.domain, s.why)).collect();
    Ok(Figures {
        name: String::new(),
        what: String::new(),
        domains: 0,
        items: 0,
        saved: last.components.len(),
        skipped,
        skip_stateless,
        file_bytes,
        ops: vec![
            ("save (checkpoint + write)", "save", save),
            ("  checkpoint alone (Host::checkpoint)", "checkpoint", checkpoint),
            ("  write alone (to_bytes, write, fsync, rename)", "write", write),
            ("read + restore", "restore", restore),
            ("  read alone (Checkpoint::read)", "read", read),
            ("  restore alone (Host::restore)", "restore_only", put_back),
            ("one step (Host::step)", "step", step),
        ],
    })
}

/// A restore puts back what was saved: a checkpoint, written and read back, equals itself;
/// restored after three more steps, the run's checkpoint equals it again.
fn check_restore(
    host: &mut Host,
    path: &Path,
    skip_stateless: bool,
    on_report: &mut dyn FnMut(Report),
) -> anyhow::Result<()> {
    let before = host.checkpoint(skip_stateless).context("a checkpoint")?;
    before.write(path).context("writing the checkpoint")?;
    let read = Checkpoint::read(path).context("reading the checkpoint")?;
    ensure!(read == before, "the checkpoint read back differs from the one written");
    for _ in 0..3 {
        host.step(on_report).context("a step")?;
    }
    let moved = host.checkpoint(skip_stateless).context("a checkpoint")?;
    ensure!(
        moved.steps == before.steps + 3,
        "three steps after the checkpoint, the run counts {} for {}",
        moved.steps,
        before.steps
    );
    host.restore(&read).context("restoring the checkpoint")?;
    let after = host.checkpoint(skip_stateless).context("a checkpoint")?;
    ensure!(after == before, "the run after a restore is not the checkpoint it restored");
    Ok(())
}

/// Nothing of namespace `ns` is left in /dev/shm (segments, state files).
fn check_removed(ns: &str) -> anyhow::Result<()> {
    let prefix = format!("tutti.{ns}.");
    let left: Vec<String> = std::fs::read_dir("/dev/shm")
        .context("listing /dev/shm")?
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.starts_with(&prefix))
        .collect();
    ensure!(left.is_empty(), "{} file(s) of the run left in /dev/shm, e.g. {}", left.len(), left[0]);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_generated_ddf_is_synchronous_float64_mostly_and_split_between_the_sets() {
        let model = ddf::parse_str(&large_ddf(3, 20), "t.ddf").unwrap();
        assert_eq!(model.domains.len(), 3);
        for d in &model.domains {
            assert!(d.flags.synchronous);
            assert_eq!((d.publish.layout.leaves.len(), d.subscribe.layout.leaves.len()), (10, 10));
            let float64 = d.leaves().filter(|(_, l)| l.ty == ddf::ScalarType::Float64).count();
            assert_eq!(float64, 16);
        }
    }

    #[test]
    fn the_uav_ddf_is_the_demos_four_domains_and_the_fmus() {
        let model = ddf::parse_str(&uav_ddf().unwrap(), "multiuav.ddf").unwrap();
        let names: Vec<&str> = model.domains.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(names, ["multiuav_uav1", "multiuav_uav2", "multiuav_uav3", "multiuav_uav4", "uav1_altitude_filter"]);
    }
}
