//! `tutti-bench scale`: what a step costs as participants and domains grow, in the shapes of
//! HELICS's own benchmarks, next to HELICS federates in the same run.
//!
//! tutti's shapes, each participant a thread of this process with its own connection (with
//! `--processes`, a process of its own: this program as `scale-part`), the framework a `Host`
//! in this process stepping as fast as they go (`speed: inf`):
//!
//! * **barrier**: one synchronous domain, N participants that lock and commit nothing: the
//!   step's cost alone;
//! * **hub**: one synchronous domain, N participants each reading the framework's item and
//!   committing its own item of the one SUBSCRIBE set;
//! * **leaves**: N synchronous domains of one participant each, one framework;
//! * **ring**: N domains in a chain, participant i reading domain i's input and writing its
//!   output, which a connection copies to domain i+1's input (the last to the first).
//!
//! HELICS (`benchmarks/src/helics_scale.c`, compiled here against the C library of the
//! `helics` wheel from PyPI): barrier and hub (a hub federate, HELICS's framework, and N
//! federates depending on it; in the barrier nothing is published) and ring, one thread per
//! federate on one in-process core, time-stepped.
//!
//! * **fan-out** (`fanout.rs`): one writer, R readers of an asynchronous set, next to
//!   iceoryx2's publish-subscribe with as many subscribers.
//!
//! Every run's counts are checked (each participant or federate answered every step) before
//! its figures are printed.

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{bail, Context as _};
use serde_json::{json, Value};
use tutti_core::ddf;
use tutti_core::parse::parse_wait;
use tutti_core::shm::{ConnectOptions, Participant, ShmError, WaitMode};
use tutti_host::{ChildProcess, Host, HostOptions};

use crate::drive::{drive, process_cpu};
use crate::fanout::{self, FanOut};
use crate::scale_plot::Series;
use crate::{nearest_rank, CliResult};

const HELICS_SRC: &str = include_str!("helics_scale.c");

#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti-bench scale\n  tutti-bench scale --n 2,8,32,128 --steps 5000 --json\n  tutti-bench scale --shapes hub --wait spin --no-helics\n  tutti-bench scale --shapes barrier,hub --cpu 0   # everything on one core, HELICS too"
)]
pub struct Args {
    /// Participants (threads) per run, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "2,8,32")]
    n: Vec<usize>,
    /// Steps per run.
    #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..))]
    steps: u64,
    /// The shapes to run, comma-separated: barrier, hub, leaves, ring, fan-out.
    #[arg(long, value_delimiter = ',', default_value = "barrier,hub,leaves,ring,fan-out")]
    shapes: Vec<Shape>,
    /// Readers of the fan-out shape, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,10,100,200")]
    readers: Vec<usize>,
    /// Writes per fan-out run.
    #[arg(long, default_value_t = 20_000)]
    writes: usize,
    /// How the framework and every participant wait: adaptive (yield up to 50 µs, then block; the default), adaptive:DURATION, block (futex), spin or poll:DURATION.
    #[arg(long, default_value = "adaptive", value_parser = parse_wait)]
    wait: WaitMode,
    /// Participants are processes (this program again) instead of threads.
    #[arg(long)]
    processes: bool,
    /// Run everything on this one CPU: the framework, every participant (threads, or
    /// processes with --processes) and the HELICS program, which inherit this process's
    /// affinity. Default: the scheduler places them.
    #[arg(long, value_name = "CPU")]
    cpu: Option<usize>,
    /// Leave HELICS out (it is looked for in the repository's .venv, or HELICS_INSTALL).
    #[arg(long)]
    no_helics: bool,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
    /// Also draw the step's p50 against N, tutti and HELICS per shape, as this PNG (and an SVG
    /// beside it).
    #[arg(long, value_name = "FILE.png")]
    plot: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Shape {
    Barrier,
    Hub,
    Leaves,
    Ring,
    FanOut,
}

impl Shape {
    fn name(self) -> &'static str {
        match self {
            Shape::Barrier => "barrier",
            Shape::Hub => "hub",
            Shape::Leaves => "leaves",
            Shape::Ring => "ring",
            Shape::FanOut => "fan-out",
        }
    }

    /// Domains of the shape's DDF for N participants.
    fn domains(self, n: usize) -> usize {
        match self {
            Shape::Barrier | Shape::Hub | Shape::FanOut => 1,
            Shape::Leaves | Shape::Ring => n,
        }
    }

    /// Whether HELICS has the shape (leaves are N federates that exchange nothing: its barrier).
    fn helics(self) -> bool {
        !matches!(self, Shape::Leaves | Shape::FanOut)
    }
}

/// One run's figures, tutti's or HELICS's.
#[derive(Debug, Clone)]
struct Figures {
    system: &'static str,
    shape: Shape,
    n: usize,
    steps: u64,
    wall_s: f64,
    cpu_s: f64,
    p50_us: f64,
    p99_us: f64,
}

impl Figures {
    fn steps_per_s(&self) -> f64 {
        self.steps as f64 / self.wall_s
    }

    fn cpu_us_per_step(&self) -> f64 {
        self.cpu_s * 1e6 / self.steps as f64
    }

    fn to_json(&self) -> Value {
        json!({
            "system": self.system, "shape": self.shape.name(), "n": self.n, "steps": self.steps,
            "steps_per_s": self.steps_per_s(), "wall_s": self.wall_s, "cpu_us_per_step": self.cpu_us_per_step(),
            "step_us": { "p50": self.p50_us, "p99": self.p99_us },
        })
    }
}

pub fn run(args: Args) -> CliResult {
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    // Before any thread or process starts: they all inherit it.
    if let Some(cpu) = args.cpu {
        tutti_core::shm::os::pin_to_cpu(cpu).with_context(|| format!("pinning the benchmark to CPU {cpu} (--cpu)"))?;
    }
    let placement = args.cpu.map_or("unpinned".to_string(), |c| format!("all on CPU {c}"));
    let helics = if args.no_helics { None } else { Some(Helics::build()?) };
    let steps = args.shapes.iter().any(|&s| s != Shape::FanOut);
    if !args.json && steps {
        println!(
            "scale: {} steps per run, speed inf, wait {:?}, one {} per participant (a thread per federate), {cpus} CPUs, {placement}; HELICS {}",
            args.steps,
            args.wait,
            if args.processes { "process" } else { "thread" },
            helics.as_ref().map_or("left out".to_string(), |h| format!("{} (inproc core, C federates)", h.version))
        );
        println!(
            "{:<8} {:>4}  {:>11} {:>9} {:>9} {:>11}  {:>11} {:>9} {:>9} {:>11}  {:>8}",
            "shape",
            "N",
            "tutti st/s",
            "p50 µs",
            "p99 µs",
            "CPU µs/st",
            "HELICS st/s",
            "p50 µs",
            "p99 µs",
            "CPU µs/st",
            "ratio"
        );
    }
    let mut all = Vec::new();
    for &shape in args.shapes.iter().filter(|&&s| s != Shape::FanOut) {
        for &n in &args.n {
            eprintln!("bench scale: {} N={n}: tutti", shape.name());
            let ours = tutti_run(&args, shape, n)?;
            let theirs = match (&helics, shape.helics()) {
                (Some(h), true) => {
                    eprintln!("bench scale: {} N={n}: HELICS", shape.name());
                    Some(h.run(shape, n, args.steps)?)
                }
                _ => None,
            };
            if !args.json {
                print_row(&ours, theirs.as_ref());
            }
            all.push(ours);
            all.extend(theirs);
        }
    }
    let fanout = if args.shapes.contains(&Shape::FanOut) { fan_out(&args)? } else { Vec::new() };
    if let Some(path) = &args.plot {
        plot(path, &all, cpus)?;
        eprintln!("bench scale: drew {} and its SVG", path.display());
    }
    if args.json {
        let out = json!({
            "benchmark": "scale",
            "steps": args.steps,
            "wait": format!("{:?}", args.wait),
            "cpus": cpus,
            "cpu": args.cpu,
            "helics": helics.as_ref().map(|h| h.version.clone()),
            "runs": all.iter().map(Figures::to_json).collect::<Vec<_>>(),
            "fan_out": fanout.iter().map(FanOut::to_json).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string(&out).context("writing JSON")?);
    }
    Ok(())
}

/// `--plot`: each system's p50 step time against N, a line per shape (HELICS dashed).
fn plot(path: &std::path::Path, runs: &[Figures], cpus: usize) -> anyhow::Result<()> {
    let mut series: Vec<Series> = Vec::new();
    for r in runs {
        let point = (r.n as f64, r.p50_us);
        match series.iter_mut().find(|s| s.system == r.system && s.shape == r.shape.name()) {
            Some(s) => s.points.push(point),
            None => series.push(Series {
                system: r.system,
                shape: r.shape.name(),
                dashed: r.system == "HELICS",
                points: vec![point],
            }),
        }
    }
    crate::scale_plot::plot(path, &series, cpus)
}

/// The fan-out runs, tutti's and iceoryx2's for each reader count (a table but with --json).
fn fan_out(args: &Args) -> anyhow::Result<Vec<FanOut>> {
    if !args.json {
        println!("\nfan-out: one writer, R readers, {} writes of 8 bytes, one thread; the writer's call", args.writes);
        println!(
            "{:>8}  {:>14} {:>14}  {:>17} {:>17}",
            "readers", "tutti p50 ns", "p99 ns", "iceoryx2 p50 ns", "p99 ns"
        );
    }
    let mut out = Vec::new();
    for &r in &args.readers {
        eprintln!("bench scale: fan-out R={r}");
        let ours = fanout::tutti(&format!("{}fanoutx{r}", namespace_prefix()), r, args.writes)?;
        let theirs = fanout::iceoryx2(r, args.writes)?;
        if !args.json {
            println!(
                "{r:>8}  {:>14.0} {:>14.0}  {:>17.0} {:>17.0}",
                ours.p50_ns, ours.p99_ns, theirs.p50_ns, theirs.p99_ns
            );
        }
        out.extend([ours, theirs]);
    }
    Ok(out)
}

fn print_row(ours: &Figures, theirs: Option<&Figures>) {
    let peer = theirs.map_or(format!("{:>11} {:>9} {:>9} {:>11}  {:>8}", "-", "-", "-", "-", "-"), |t| {
        format!(
            "{:>11.0} {:>9.1} {:>9.1} {:>11.1}  {:>7.1}x",
            t.steps_per_s(),
            t.p50_us,
            t.p99_us,
            t.cpu_us_per_step(),
            ours.steps_per_s() / t.steps_per_s()
        )
    });
    println!(
        "{:<8} {:>4}  {:>11.0} {:>9.1} {:>9.1} {:>11.1}  {peer}",
        ours.shape.name(),
        ours.n,
        ours.steps_per_s(),
        ours.p50_us,
        ours.p99_us,
        ours.cpu_us_per_step()
    );
}

/// The shape's DDF: domains `d0..`, each with an input `x` (PUBLISH) and, for N participants
/// of one domain, outputs `y0..y{N-1}` (SUBSCRIBE; one `y0` per domain otherwise).
fn model(shape: Shape, n: usize) -> anyhow::Result<ddf::Model> {
    let outputs = if shape.domains(n) == 1 { n } else { 1 };
    let items: String = (0..outputs).map(|i| format!(r#"<item name="y{i}"><type>float64</type></item>"#)).collect();
    let domains: String = (0..shape.domains(n))
        .map(|d| {
            format!(
                r#"<domain name="d{d}"><synchronous>yes</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
                <set name="PUBLISH"><item name="x"><type>float64</type></item></set><set name="SUBSCRIBE">{items}</set></domain>"#
            )
        })
        .collect();
    ddf::parse_str(&format!("<orchestra>{domains}</orchestra>"), "scale-bench.ddf").context("the benchmark's DDF")
}

/// Participant `i`: which domain it joins and which output it writes (none in a barrier).
fn place(shape: Shape, i: usize) -> (String, Option<String>) {
    match shape {
        Shape::Barrier | Shape::FanOut => ("d0".into(), None),
        Shape::Hub => ("d0".into(), Some(format!("y{i}"))),
        Shape::Leaves | Shape::Ring => (format!("d{i}"), Some("y0".into())),
    }
}

/// Hidden: one participant of `tutti-bench scale --processes`, as a process of its own.
#[derive(Debug, clap::Args)]
pub struct PartArgs {
    namespace: String,
    #[arg(value_enum)]
    shape: Shape,
    index: usize,
    #[arg(value_parser = parse_wait)]
    wait: WaitMode,
}

/// `tutti-bench scale-part`: answers every step until the framework stops, then prints the
/// steps answered and the CPU time spent from the first of them, in ns.
pub fn part(a: PartArgs) -> CliResult {
    let (answered, cpu) = participant(a.namespace, a.shape, a.index, a.wait).context("the participant")?;
    println!("{answered} {}", cpu.as_nanos());
    Ok(())
}

/// Answers every step until the framework stops; returns the steps answered and the CPU time
/// of this process from the first of them (of every thread: a process's figure).
fn participant(namespace: String, shape: Shape, i: usize, wait: WaitMode) -> Result<(u64, Duration), ShmError> {
    let (domain, output) = place(shape, i);
    let opts = ConnectOptions {
        namespace,
        wait,
        name: format!("p{i}"),
        connect_timeout: Duration::from_secs(60),
        timeout: Duration::from_secs(30),
        ..Default::default()
    };
    let mut p = Participant::connect(&domain, opts)?;
    let x = p.leaf(ddf::Role::Publish, "x")?.0;
    let y = output.map(|o| p.leaf(ddf::Role::Subscribe, &o)).transpose()?.map(|l| l.0);
    let mut answered = 0u64;
    let mut cpu0 = None;
    loop {
        match p.subscribe_lock() {
            Ok(_) => {}
            Err(ShmError::FrameworkStopped { .. }) => {
                return Ok((answered, cpu0.map_or(Duration::ZERO, |c| process_cpu().saturating_sub(c))));
            }
            Err(e) => return Err(e),
        }
        cpu0.get_or_insert_with(process_cpu);
        let read = match y {
            Some(_) => p.snapshot_item(x).and_then(|b| b.try_into().ok()).map_or(0.0, f64::from_ne_bytes),
            None => 0.0,
        };
        p.publish_lock()?;
        if let Some(y) = y {
            p.stage_at(y, &(read + 1.0).to_ne_bytes())?;
        }
        p.commit()?;
        answered += 1;
    }
}

fn tutti_run(args: &Args, shape: Shape, n: usize) -> anyhow::Result<Figures> {
    let model = model(shape, n)?;
    let namespace = format!("{}{}x{n}", namespace_prefix(), shape.name());
    let connections = match shape {
        Shape::Ring => (0..n)
            .map(|i| tutti_host::connect::parse_connection(&format!("d{i}/subscribe/y0 -> d{}/publish/x", (i + 1) % n)))
            .collect::<Result<Vec<_>, _>>()
            .context("the ring's connections")?,
        _ => Vec::new(),
    };
    let opts = HostOptions {
        step: Duration::from_millis(1),
        speed: f64::INFINITY,
        steps: Some(args.steps),
        timeout: Duration::from_secs(30),
        wait: args.wait,
        namespace: Some(namespace.clone()),
        hold_until_start: true,
        connections,
        ddf_name: "the benchmark's DDF".into(),
        slots: n as u32 + 1,
        ..Default::default()
    };
    // Dropped on every way out: the segments go with it and the participants' next call
    // returns "framework stopped".
    let mut host = Host::new(&model, opts).context("creating the domains")?;
    let participants = Participants::start(args, &namespace, shape, n)?;
    let stepped = drive(&mut host, args.steps, n, "scale");
    drop(host);
    let ended = participants.finish(args.steps);
    let d = stepped?;
    if d.timeouts > 0 {
        bail!("{} N={n}: {} step(s) timed out", shape.name(), d.timeouts);
    }
    let children_cpu = ended.map_err(|e| e.context(format!("{} N={n}", shape.name())))?;
    let (wall, cpu) = (d.wall, d.cpu + children_cpu);
    let us = |q: f64| nearest_rank(&d.step_times, q).as_secs_f64() * 1e6;
    Ok(Figures {
        system: if args.processes { "tutti (processes)" } else { "tutti" },
        shape,
        n,
        steps: args.steps,
        wall_s: wall.as_secs_f64(),
        cpu_s: cpu.as_secs_f64(),
        p50_us: us(0.5),
        p99_us: us(0.99),
    })
}

/// A run's participants: threads of this process, or processes of their own.
enum Participants {
    Threads(Vec<JoinHandle<Result<(u64, Duration), ShmError>>>),
    Processes(Vec<ChildProcess>),
}

impl Participants {
    fn start(args: &Args, namespace: &str, shape: Shape, n: usize) -> anyhow::Result<Participants> {
        if !args.processes {
            let threads = (0..n)
                .map(|i| {
                    let (ns, wait) = (namespace.to_string(), args.wait);
                    std::thread::spawn(move || participant(ns, shape, i, wait))
                })
                .collect();
            return Ok(Participants::Threads(threads));
        }
        let exe = std::env::current_exe().context("this program's path")?;
        let wait = match args.wait {
            WaitMode::Block => "block".to_string(),
            WaitMode::Spin => "spin".to_string(),
            WaitMode::Poll(d) => format!("poll:{}ns", d.as_nanos()),
            WaitMode::Adaptive(d) => format!("adaptive:{}ns", d.as_nanos()),
        };
        let children = (0..n)
            .map(|i| {
                let mut cmd = Command::new(&exe);
                cmd.args(["scale-part", namespace, shape.name(), &i.to_string(), &wait])
                    .stdin(Stdio::null())
                    .stdout(Stdio::piped());
                let child = ChildProcess::spawn(&format!("participant {i}"), cmd, None)?;
                Ok(child.stop_on_drop(Some(tutti_host::SIGTERM), Duration::from_secs(2)))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        Ok(Participants::Processes(children))
    }

    /// Waits for every participant's end and checks that each answered `steps` steps;
    /// returns the CPU time the processes spent (zero for threads: this process's counts it).
    fn finish(self, steps: u64) -> anyhow::Result<Duration> {
        let mut failed = None;
        let mut cpu = Duration::ZERO;
        let mut check = |i: usize, r: anyhow::Result<(u64, Duration)>| match r {
            Ok((answered, _)) if answered != steps => {
                failed.get_or_insert(anyhow::anyhow!("participant {i} answered {answered} of {steps} steps"));
            }
            Ok((_, c)) => cpu += c,
            Err(e) => {
                failed.get_or_insert(e.context(format!("participant {i}")));
            }
        };
        match self {
            Participants::Threads(threads) => {
                for (i, t) in threads.into_iter().enumerate() {
                    let r = t.join().map_err(|_| anyhow::anyhow!("panicked")).and_then(|r| Ok(r?));
                    check(i, r.map(|(a, _)| (a, Duration::ZERO)));
                }
            }
            Participants::Processes(children) => {
                for (i, mut c) in children.into_iter().enumerate() {
                    check(i, process_result(&mut c));
                }
            }
        }
        failed.map_or(Ok(cpu), Err)
    }
}

/// A participant process's answer (its exit and the line it printed).
fn process_result(c: &mut ChildProcess) -> anyhow::Result<(u64, Duration)> {
    let status = c.wait(Duration::from_secs(30)).context("still running 30 s after the run")?;
    let mut out = String::new();
    if let Some(mut stdout) = c.child.stdout.take() {
        std::io::Read::read_to_string(&mut stdout, &mut out).context("reading its output")?;
    }
    if !status.success() {
        bail!("exited with {status}");
    }
    let mut words = out.split_whitespace().map(str::parse::<u64>);
    match (words.next(), words.next()) {
        (Some(Ok(answered)), Some(Ok(ns))) => Ok((answered, Duration::from_nanos(ns))),
        _ => bail!("printed '{}', not its count", out.trim()),
    }
}

/// The runs' namespaces begin with TUTTI_NAMESPACE when set (a test's own), else with one of
/// this process's; each run's is `PREFIXSHAPExN`.
pub(crate) fn namespace_prefix() -> String {
    std::env::var("TUTTI_NAMESPACE").unwrap_or_else(|_| format!("benchscale{}x", std::process::id()))
}

/// The HELICS federates' program, compiled against the `helics` wheel's C library.
struct Helics {
    exe: PathBuf,
    version: String,
    _dir: tempfile::TempDir,
}

impl Helics {
    /// HELICS's install tree: HELICS_INSTALL, else the `helics` package of the repository's
    /// .venv (launch-scripts/test.sh installs it).
    fn install() -> anyhow::Result<PathBuf> {
        if let Some(dir) = std::env::var_os("HELICS_INSTALL") {
            return Ok(dir.into());
        }
        let py = tutti_test_support::repo_root().join(".venv/bin/python");
        let out = Command::new(&py)
            .args(["-c", "import helics, os; print(os.path.join(os.path.dirname(helics.__file__), 'install'))"])
            .output()
            .with_context(|| format!("running {}", py.display()))?;
        if !out.status.success() {
            bail!(
                "no HELICS: {} cannot import helics (pip install helics==3.6.1, or set HELICS_INSTALL, or --no-helics)",
                py.display()
            );
        }
        Ok(PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()))
    }

    fn build() -> anyhow::Result<Helics> {
        let install = Self::install()?;
        let (include, lib) = (install.join("include"), install.join("lib64"));
        if !include.join("helics/helics.h").is_file() {
            bail!("{} has no include/helics/helics.h", install.display());
        }
        let dir = tempfile::tempdir().context("a temporary directory")?;
        let src = dir.path().join("helics_scale.c");
        std::fs::write(&src, HELICS_SRC).context("writing the HELICS program")?;
        let exe = dir.path().join("helics_scale");
        let out = Command::new("cc")
            .args(["-O2", "-std=gnu11", "-Wall", "-Wextra", "-Werror"])
            .arg(&src)
            .arg(format!("-I{}", include.display()))
            .arg(format!("-L{}", lib.display()))
            .arg("-lhelics")
            .arg(format!("-Wl,-rpath,{}", lib.display()))
            .arg("-lpthread")
            .arg("-o")
            .arg(&exe)
            .output()
            .context("running cc")?;
        if !out.status.success() {
            bail!("compiling the HELICS federates failed:\n{}", String::from_utf8_lossy(&out.stderr));
        }
        let mut h = Helics { exe, version: String::new(), _dir: dir };
        let probe = h.output(Shape::Barrier, 1, 1)?;
        h.version = probe["version"].as_str().unwrap_or("?").to_string();
        Ok(h)
    }

    fn output(&self, shape: Shape, n: usize, steps: u64) -> anyhow::Result<Value> {
        let out = tutti_test_support::run_with_timeout(
            {
                let mut c = Command::new(&self.exe);
                c.args([shape.name(), &n.to_string(), &steps.to_string()]);
                c
            },
            Duration::from_secs(900),
        );
        let (status, stdout, stderr) = out;
        if !status.success() {
            bail!("HELICS {} N={n} failed ({status}): {stderr}", shape.name());
        }
        // HELICS logs on stdout too: the figures are the last line, one JSON object.
        let line = stdout.lines().rev().find(|l| l.starts_with('{')).unwrap_or_default();
        serde_json::from_str(line).with_context(|| format!("HELICS's output: {stdout}"))
    }

    fn run(&self, shape: Shape, n: usize, steps: u64) -> anyhow::Result<Figures> {
        let v = self.output(shape, n, steps)?;
        let granted: Vec<u64> = v["granted"].as_array().into_iter().flatten().filter_map(Value::as_u64).collect();
        let federates = v["federates"].as_u64().unwrap_or(0) as usize;
        if granted.len() != federates || granted.iter().any(|&g| g != steps) {
            bail!("HELICS {} N={n}: federates granted {granted:?} of {steps} steps", shape.name());
        }
        let f = |k: &str| v[k].as_f64().with_context(|| format!("HELICS's {k}: {v}"));
        Ok(Figures {
            system: "HELICS",
            shape,
            n,
            steps,
            wall_s: f("wall_s")?,
            cpu_s: f("cpu_s")?,
            p50_us: f("p50_us")?,
            p99_us: f("p99_us")?,
        })
    }
}
