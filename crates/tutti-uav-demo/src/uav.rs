//! `tutti-demo uav`: the UAV formation co-simulation of the paper's section 7, end to end.
//!
//! This process is the framework of `ddf/multiuav.ddf` (formation commands, the altitude it
//! read and its clock in PUBLISH; UAV states read from SUBSCRIBE), stepped by the real-time
//! loop of `tutti-host`. It starts four UAV components (`tutti-demo uav-node`), the monitoring script
//! (`launch-scripts/monitor.py`, Python over the RTAPI) that disconnects and reconnects UAV
//! components on schedule and logs the connection counts, two C components
//! (`examples/c/uav_altitude_log.c`) that connect to UAV2's domain on schedule, and the
//! DDS / ROS 2 gateway (loopback only). At the end it reads the CSV files back, draws
//! Figures 5 and 6 and prints the checks; exit status 1 when one fails.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use tutti_core::ddf::Role;
use tutti_core::shm::{Framework, FrameworkOptions, WaitMode};

use tutti_core::parse::parse_duration;
use tutti_host::{step_all, ChildProcess as Kid, StepDone, Ticker, SIGINT, SIGTERM};

use crate::analysis::{run_checks, Check, RunData};
use crate::f64_at;
use crate::plot;
use crate::scenario::{Scenario, FMU_TAU, UAVS};
use crate::{CliResult, Failure, EXIT_FAILURE};

fn spawn(name: &str, cmd: Command, cpu: Option<usize>) -> anyhow::Result<Kid> {
    Ok(Kid::spawn(name, cmd, cpu)?)
}

/// The DDF of the demo, built in: the demo runs from any directory.
const DDF_TEXT: &str = include_str!("../../../ddf/multiuav.ddf");
/// The source tree (C component, monitoring script, Python module, header).
const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
/// The domain of the demo's FMU component (examples/fmu/altitude_filter, docs/fmu.md): the
/// framework publishes UAV 1's elevation as it read it, the FMU answers with it filtered.
const FMU_DOMAIN: &str = "uav1_altitude_filter";
const FMU_DDF_TEXT: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<!-- The UAV demo's FMU component (AltitudeFilter, run with `tutti fmu run`). -->
<orchestra>
  <domain name="uav1_altitude_filter">
    <synchronous>yes</synchronous>
    <multiplePublishAllowed>no</multiplePublishAllowed>
    <states>no</states>
    <set name="PUBLISH">
      <item name="elevation"><type>float64</type><length>1</length></item>
    </set>
    <set name="SUBSCRIBE">
      <item name="altitude"><type>float64</type><length>1</length></item>
      <item name="climb_rate"><type>float64</type><length>1</length></item>
      <item name="steps"><type>int32</type><length>1</length></item>
    </set>
  </domain>
</orchestra>
"#;

#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti-demo uav\n  tutti-demo uav --out /tmp/uav --speed 8 --scenario short\n  tutti-demo uav-report --out out/uav      # re-check and re-draw a finished run\n\nEnvironment:\n  TUTTI_NAMESPACE   namespace of the segments (default: demo-PID)\n  TUTTI_PYTHON      Python 3 for the monitoring script (default: python3)\n  TUTTI_RTAPI_LIB   librtapi.so to use (default: next to this executable)\n  TUTTI_EXE         the tutti executable (default: next to this executable)\n  TUTTI_FONT        TrueType font for the figures (default: DejaVu Sans)\n  CC                C compiler for the C component and the FMU (default: gcc)"
)]
pub struct UavArgs {
    #[command(flatten)]
    run: RunArgs,
    /// Simulated seconds per wall-clock second.
    #[arg(long, default_value_t = 4.0)]
    speed: f64,
    /// Longest wall-clock wait of a step for the participants.
    #[arg(long, default_value = "1s", value_parser = parse_duration)]
    timeout: Duration,
    /// A prebuilt C component (default: compiled from examples/c/uav_altitude_log.c).
    #[arg(long, value_name = "PATH")]
    c_reader: Option<PathBuf>,
    /// Do not start the DDS / ROS 2 gateway.
    #[arg(long)]
    no_gateway: bool,
    /// DDS domain of the gateway (default: ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "N")]
    ros_domain_id: Option<u32>,
    #[command(flatten)]
    rt: crate::RealtimeArgs,
}

/// `tutti-demo uav-report`: the checks and figures of a finished run, again.
#[derive(Debug, clap::Args)]
pub struct ReportArgs {
    #[command(flatten)]
    run: RunArgs,
}

/// What a run is (`uav-report` must be given the values of the run it re-checks).
#[derive(Debug, clap::Args)]
struct RunArgs {
    /// Directory of the results (CSV files, figure5.png/.svg, figure6.png/.svg, summary.txt
    /// and summary.json).
    #[arg(long, default_value = "out/uav")]
    out: PathBuf,
    /// The script: paper (120 s, the paper's times) or short (40 s).
    #[arg(long, default_value = "paper", value_parser = ["paper", "short"])]
    scenario: String,
    /// Simulated length in seconds (default: the scenario's); events after it are dropped.
    #[arg(long, value_parser = parse_seconds)]
    duration: Option<f64>,
    /// Simulated time of one framework step.
    #[arg(long, default_value = "50ms", value_parser = parse_duration)]
    step: Duration,
}

impl RunArgs {
    fn scenario(&self) -> Scenario {
        let s = Scenario::by_name(&self.scenario).unwrap_or_else(Scenario::paper);
        match self.duration {
            Some(d) => s.with_duration(d),
            None => s,
        }
    }
}

/// Seconds as a plain number (`40`, `12.5`) or a duration (`40s`, `2min`).
pub fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        Ok(_) => Err(format!("'{s}' must be a positive number of seconds")),
        Err(_) => parse_duration(s).map(|d| d.as_secs_f64()).map_err(|e| e.to_string()),
    }
}

/// librtapi.so: `TUTTI_RTAPI_LIB`, else next to this executable (or in its deps/).
fn find_rtapi() -> anyhow::Result<PathBuf> {
    if let Some(p) = std::env::var_os("TUTTI_RTAPI_LIB") {
        return Ok(PathBuf::from(p));
    }
    let exe = std::env::current_exe().context("locating this executable")?;
    let dir = exe.parent().unwrap_or(Path::new("."));
    for cand in [dir.join("librtapi.so"), dir.join("deps/librtapi.so"), dir.join("../librtapi.so")] {
        if cand.is_file() {
            return Ok(cand.canonicalize().unwrap_or(cand));
        }
    }
    bail!(
        "librtapi.so not found next to {}: build it with `cargo build --release -p tutti-rtapi` (or set TUTTI_RTAPI_LIB)",
        exe.display()
    )
}

/// Compiles the C component against include/RTAPI.h and librtapi.
fn build_c_reader(out: &Path, lib: &Path) -> anyhow::Result<PathBuf> {
    let src = Path::new(ROOT).join("examples/c/uav_altitude_log.c");
    let bin = out.join("bin/uav_altitude_log");
    std::fs::create_dir_all(bin.parent().unwrap_or(out))?;
    let libdir = lib.parent().unwrap_or(Path::new("."));
    let cc = std::env::var("CC").unwrap_or_else(|_| "gcc".into());
    let status = Command::new(&cc)
        .args(["-std=c99", "-O2", "-Wall", "-Wextra"])
        .arg(format!("-I{ROOT}/include"))
        .arg(&src)
        .arg(format!("-L{}", libdir.display()))
        .arg("-lrtapi")
        .arg(format!("-Wl,-rpath,{}", libdir.display()))
        .arg("-o")
        .arg(&bin)
        .status()
        .with_context(|| format!("running the C compiler '{cc}' (install gcc, or pass --c-reader)"))?;
    anyhow::ensure!(status.success(), "compiling {} failed ({status})", src.display());
    Ok(bin)
}

/// Builds the demo's FMU from examples/fmu/altitude_filter: the C source compiled into a
/// shared library, packed with its modelDescription.xml into bin/AltitudeFilter.fmu.
fn build_fmu(out: &Path) -> anyhow::Result<PathBuf> {
    let src = Path::new(ROOT).join("examples/fmu/altitude_filter");
    let so = out.join("bin/AltitudeFilter.so");
    std::fs::create_dir_all(so.parent().unwrap_or(out))?;
    let cc = std::env::var("CC").unwrap_or_else(|_| "gcc".into());
    let status = Command::new(&cc)
        .args(["-std=c99", "-O2", "-Wall", "-Wextra", "-shared", "-fPIC"])
        .arg(src.join("AltitudeFilter.c"))
        .arg("-o")
        .arg(&so)
        .status()
        .with_context(|| format!("running the C compiler '{cc}' for the FMU"))?;
    anyhow::ensure!(status.success(), "compiling {} failed ({status})", src.join("AltitudeFilter.c").display());
    let md_path = src.join("modelDescription.xml");
    let md = std::fs::read(&md_path).with_context(|| format!("reading {}", md_path.display()))?;
    let lib = std::fs::read(&so).with_context(|| format!("reading {}", so.display()))?;
    let fmu = out.join("bin/AltitudeFilter.fmu");
    tutti_fmu::pack::write_fmu(
        &fmu,
        &[("modelDescription.xml", &md), ("binaries/x86_64-linux/AltitudeFilter.so", &lib)],
    )
    .with_context(|| format!("writing {}", fmu.display()))?;
    Ok(fmu)
}

/// Offsets of the items the framework writes and reads in one domain.
struct DomainItems {
    publish: [usize; 7],
    elevation: usize,
    time: usize,
}

pub fn run(args: UavArgs) -> CliResult {
    if !(args.speed > 0.0 && args.speed.is_finite()) {
        return Err(Failure::invalid(anyhow::anyhow!("--speed must be a positive number")));
    }
    if args.run.step.is_zero() {
        return Err(Failure::invalid(anyhow::anyhow!("--step must be longer than 0")));
    }
    let scenario = args.run.scenario();
    let dir = &args.run.out;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let out = dir.canonicalize().unwrap_or(dir.clone());
    let interrupted = tutti_host::stop_on_ctrl_c().context("installing the signal handler")?;
    let started = Instant::now();
    let ran = simulate(&args, &scenario, &out, &interrupted);
    if interrupted.load(Ordering::SeqCst) {
        eprintln!("demo: interrupted; every process stopped");
        return Err(Failure { code: EXIT_FAILURE, error: anyhow::anyhow!("interrupted") });
    }
    ran?;
    eprintln!("demo: simulation done in {:.1} s of wall time", started.elapsed().as_secs_f64());
    report(&out, &scenario, args.run.step.as_secs_f64())
}

/// `tutti-demo uav-report`.
pub fn run_report(args: ReportArgs) -> CliResult {
    report(&args.run.out, &args.run.scenario(), args.run.step.as_secs_f64())
}

/// Checks and figures of the run in `out`; prints the summary (also to summary.txt).
fn report(out: &Path, scenario: &Scenario, step: f64) -> CliResult {
    let data = RunData::load(out, scenario);
    let mut checks = run_checks(scenario, &data, step);
    for (name, f) in [
        ("figure5.png", plot::figure5 as fn(&Path, &Scenario, &RunData) -> anyhow::Result<()>),
        ("figure6.png", plot::figure6),
    ] {
        let path = out.join(name);
        let r = f(&path, scenario, &data);
        checks.push(Check {
            name: format!("{name} drawn"),
            pass: r.is_ok(),
            detail: match r {
                Ok(()) => path.display().to_string(),
                Err(e) => format!("{e:#}"),
            },
        });
    }
    let mut text = format!("UAV demo summary ({} scenario, {:.0} s simulated)\n", scenario.name, scenario.duration);
    for c in &checks {
        text.push_str(&format!("  [{}] {}\n         {}\n", if c.pass { "PASS" } else { "FAIL" }, c.name, c.detail));
    }
    let failed = checks.iter().filter(|c| !c.pass).count();
    text.push_str(&format!("{} passed, {} failed\n", checks.len() - failed, failed));
    let _ = std::fs::write(out.join("summary.txt"), &text);
    // The same for programs: one object, every check with its verdict.
    let json = serde_json::json!({
        "scenario": scenario.name,
        "simulated_s": scenario.duration,
        "passed": checks.len() - failed,
        "failed": failed,
        "checks": checks.iter().map(|c| serde_json::json!({ "name": c.name, "pass": c.pass, "detail": c.detail })).collect::<Vec<_>>(),
    });
    let _ = std::fs::write(out.join("summary.json"), format!("{json:#}\n"));
    eprint!("{text}");
    eprintln!("results in {}", out.display());
    if failed > 0 {
        return Err(Failure { code: EXIT_FAILURE, error: anyhow::anyhow!("{failed} check(s) of the UAV demo failed") });
    }
    Ok(())
}

/// Runs the co-simulation; every child is stopped when this returns, however it returns.
fn simulate(args: &UavArgs, scenario: &Scenario, out: &Path, interrupted: &AtomicBool) -> anyhow::Result<()> {
    let namespace = std::env::var("TUTTI_NAMESPACE")
        .ok()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| format!("demo-{}", std::process::id()));
    let ddf_path = out.join("multiuav.ddf");
    std::fs::write(&ddf_path, DDF_TEXT).with_context(|| format!("writing {}", ddf_path.display()))?;
    let model =
        tutti_core::ddf::parse_str(DDF_TEXT, &ddf_path.display().to_string()).map_err(|e| anyhow::anyhow!("{e}"))?;
    anyhow::ensure!(model.domains.len() == UAVS, "the demo's DDF has {} domains, not {UAVS}", model.domains.len());
    let exe = std::env::current_exe().context("locating this executable")?;
    let tutti = crate::tutti_exe()?;
    // A private copy of librtapi: a rebuild during the run cannot pull it away.
    let found = find_rtapi()?;
    let lib = out.join("bin/librtapi.so");
    std::fs::create_dir_all(out.join("bin"))?;
    std::fs::copy(&found, &lib).with_context(|| format!("copying {}", found.display()))?;
    // The name the library's SONAME gives, which programs linked against it load.
    let soname = out.join("bin/librtapi.so.0");
    let _ = std::fs::remove_file(&soname);
    std::os::unix::fs::symlink("librtapi.so", &soname).with_context(|| format!("linking {}", soname.display()))?;
    let c_reader = match &args.c_reader {
        Some(p) => p.clone(),
        None => build_c_reader(out, &lib)?,
    };
    let python = std::env::var("TUTTI_PYTHON").unwrap_or_else(|_| "python3".into());
    let step = args.run.step.as_secs_f64();
    let period = args.run.step.div_f64(args.speed);
    eprintln!(
        "demo: {} scenario, {:.0} s simulated at {}x (step {:.0} ms simulated, {:.1} ms wall), namespace {namespace}, results in {}",
        scenario.name,
        scenario.duration,
        args.speed,
        step * 1e3,
        period.as_secs_f64() * 1e3,
        out.display()
    );

    let opts = FrameworkOptions {
        namespace: namespace.clone(),
        timeout: args.timeout,
        wait: WaitMode::Block,
        ..Default::default()
    };
    let mut fw = Framework::create(&model, &opts).context("creating the domains of multiuav.ddf")?;
    // The FMU component's domain, hosted beside the UAVs' (its own DDF: multiuav.ddf is the
    // paper's, bridged to DDS as it is).
    let fmu_ddf = out.join("altitude_filter.ddf");
    std::fs::write(&fmu_ddf, FMU_DDF_TEXT).with_context(|| format!("writing {}", fmu_ddf.display()))?;
    let fmu_model =
        tutti_core::ddf::parse_str(FMU_DDF_TEXT, &fmu_ddf.display().to_string()).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut fw_fmu = Framework::create(&fmu_model, &opts).context("creating the FMU's domain")?;
    let fmu_leaf = |role: Role, p: &str| -> anyhow::Result<std::ops::Range<usize>> {
        let leaf = fmu_model.domains[0].set(role).layout.leaf(p).with_context(|| format!("{FMU_DOMAIN}: no {p}"))?;
        Ok(leaf.range())
    };
    let (fmu_elevation, fmu_altitude, fmu_climb, fmu_steps) = (
        fmu_leaf(Role::Publish, "elevation")?,
        fmu_leaf(Role::Subscribe, "altitude")?,
        fmu_leaf(Role::Subscribe, "climb_rate")?,
        fmu_leaf(Role::Subscribe, "steps")?,
    );
    let fmu_path = build_fmu(out)?;
    // The whole run as ROS 2 tools read it (Foxglove, ros2 bag): docs/recording.md.
    let mut recording = tutti_record::create(&out.join("run.mcap"), &model, &ddf_path).context("starting run.mcap")?;
    let items: Vec<DomainItems> = model
        .domains
        .iter()
        .map(|d| {
            let off = |role: Role, p: &str| -> anyhow::Result<usize> {
                let leaf = d.set(role).layout.leaf(p).with_context(|| format!("{}: no item {p}", d.name))?;
                anyhow::ensure!(leaf.size == 8, "{}: {p} is not a float64", d.name);
                Ok(leaf.offset as usize)
            };
            let mut publish = [0; 7];
            for (o, p) in publish.iter_mut().zip(["Autopilot", "X", "Y", "Z", "Airspeed", "Altitude", "Time"]) {
                *o = off(Role::Publish, p)?;
            }
            Ok(DomainItems {
                publish,
                elevation: off(Role::Subscribe, "Elevation")?,
                time: off(Role::Subscribe, "Time")?,
            })
        })
        .collect::<anyhow::Result<_>>()?;
    let formation = tutti_uav::scenario::default_formation();

    let env = |cmd: &mut Command| {
        cmd.env("TUTTI_NAMESPACE", &namespace).stdin(Stdio::null());
    };
    // The UAV components: connected before the first step.
    let mut uavs = Vec::new();
    for i in 1..=UAVS {
        let mut cmd = Command::new(&exe);
        cmd.args(["uav-node", "--index", &i.to_string(), "--speed", &args.speed.to_string(), "--out"])
            .arg(out.join(format!("uav{i}.csv")));
        env(&mut cmd);
        uavs.push(spawn(&format!("UAV {i}"), cmd, None)?);
    }
    // The FMU component: `tutti fmu run`, as a user would start it.
    let mut fmu_kid = {
        let mut cmd = Command::new(&tutti);
        cmd.args(["fmu", "run"])
            .arg(&fmu_path)
            .arg("--ddf")
            .arg(&fmu_ddf)
            .args(["--domain", FMU_DOMAIN, "--param", &format!("tau={FMU_TAU}"), "--name", "fmu:AltitudeFilter", "-q"])
            .env("TMPDIR", out.join("bin"));
        env(&mut cmd);
        spawn("FMU component (AltitudeFilter)", cmd, None)?
    };
    let connect_deadline = Instant::now() + Duration::from_secs(30);
    while fw.domains.iter().chain(&fw_fmu.domains).any(|d| d.connection_count() == 0) {
        for k in uavs.iter_mut().chain(std::iter::once(&mut fmu_kid)) {
            if let Some(st) = k.poll() {
                bail!("{} exited before connecting ({st})", k.name);
            }
        }
        anyhow::ensure!(!interrupted.load(Ordering::SeqCst), "interrupted");
        anyhow::ensure!(Instant::now() < connect_deadline, "the UAV and FMU components did not connect within 30 s");
        std::thread::sleep(Duration::from_millis(20));
    }
    eprintln!("demo: 4 UAV components and the FMU component (AltitudeFilter, tutti fmu run) connected");
    let mut gateway = None;
    if !args.no_gateway {
        let mut cmd = Command::new(&tutti);
        cmd.arg("gateway").arg(&ddf_path).args(["--interface", "127.0.0.1", "--status-every", "3600s"]);
        if let Some(id) = args.ros_domain_id {
            cmd.args(["--ros-domain-id", &id.to_string()]);
        }
        let log = File::create(out.join("gateway.log")).context("creating gateway.log")?;
        cmd.stderr(log);
        env(&mut cmd);
        gateway = Some(spawn("gateway", cmd, None)?);
        eprintln!("demo: DDS / ROS 2 gateway on loopback (log in gateway.log)");
    }

    let mut csv = BufWriter::new(File::create(out.join("framework.csv")).context("creating framework.csv")?);
    let mut header = vec!["step".to_string(), "sim_time".into(), "wall_s".into()];
    for i in 1..=UAVS {
        for c in ["elevation", "time", "altitude_pub", "connections"] {
            header.push(format!("uav{i}_{c}"));
        }
    }
    writeln!(csv, "{}", header.join(","))?;
    let mut fmu_csv =
        BufWriter::new(File::create(out.join("altitude_filter.csv")).context("creating altitude_filter.csv")?);
    writeln!(fmu_csv, "step,sim_time,elevation,altitude,climb_rate,steps,connections")?;
    let mut fmu_publish = vec![fmu_model.domains[0].publish.layout.default_bytes()];
    let mut publish: Vec<Vec<u8>> = model.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
    let mut read_elevation = [0.0f64; UAVS];

    // The monitoring script: loaded before the clock starts, then fed the simulated time of
    // every step on its standard input.
    let mut monitor = {
        let mut cmd = Command::new(&python);
        let pids: Vec<String> = uavs.iter().enumerate().map(|(i, k)| format!("{}:{}", i + 1, k.pid())).collect();
        let domains: Vec<&str> = model.domains.iter().map(|d| d.name.as_str()).collect();
        cmd.arg(Path::new(ROOT).join("launch-scripts/monitor.py"))
            .args(["--clock", "stdin"])
            .args(["--duration", &scenario.duration.to_string(), "--events", &scenario.events_arg()])
            .args(["--pids", &pids.join(","), "--domains", &domains.join(",")])
            .arg("--out")
            .arg(out.join("connections.csv"))
            .arg("--events-out")
            .arg(out.join("events.csv"))
            .env("PYTHONPATH", Path::new(ROOT).join("python"))
            .env("TUTTI_RTAPI_LIB", &lib)
            .env("PYTHONUNBUFFERED", "1");
        env(&mut cmd);
        cmd.stdin(Stdio::piped()).stdout(Stdio::piped());
        spawn("monitoring script", cmd, None)?
    };
    let monitor_in = monitor.child.stdin.take().context("the monitoring script's stdin")?;
    {
        let stdout = monitor.child.stdout.take().context("the monitoring script's stdout")?;
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line);
            let _ = tx.send(line);
        });
        match rx.recv_timeout(Duration::from_secs(60)) {
            Ok(line) if line.trim() == "ready" => {}
            Ok(line) => bail!("the monitoring script did not start ({python}): {:?}", line.trim()),
            Err(_) => bail!("the monitoring script ({python}) was not ready within 60 s"),
        }
    }
    crate::enter_realtime(&args.rt, "demo");
    let mut ticker = Ticker::new(period);
    let wall0 = Instant::now();
    let mut monitor_in = Some(monitor_in);
    let mut readers: Vec<Kid> = Vec::new();
    let mut last_progress = -10.0f64;
    let mut overruns_seen = 0;
    let mut steps = 0u64;
    loop {
        if interrupted.load(Ordering::SeqCst) {
            break;
        }
        let tick = ticker.wait();
        // Simulated time counts steps: on a machine too loaded for real time the simulation
        // slows down (overruns are counted) instead of skipping steps; every participant,
        // the monitoring script included, follows this clock.
        let sim = steps as f64 * step;
        if sim > scenario.duration + 1e-9 {
            break;
        }
        steps += 1;
        if let Some(pipe) = monitor_in.as_mut() {
            if writeln!(pipe, "{sim:.6}").is_err() {
                monitor_in = None;
            }
        }
        for (i, (buf, it)) in publish.iter_mut().zip(&items).enumerate() {
            let off = formation.offsets[i];
            let values = [1.0, off.along, off.cross, off.up, formation.route[1].airspeed, read_elevation[i], sim];
            for (o, v) in it.publish.iter().zip(values) {
                buf[*o..*o + 8].copy_from_slice(&v.to_ne_bytes());
            }
        }
        let reports = step_all(&mut fw, &publish, sim, period, &tick)?;
        let mut row =
            format!("{},{sim:.6},{:.6}", reports.first().map_or(0, |r| r.step), wall0.elapsed().as_secs_f64());
        for (i, (host, it)) in fw.domains.iter().zip(&items).enumerate() {
            let sub = host.subscribe();
            let (e, t) = (f64_at(sub, it.elevation), f64_at(sub, it.time));
            let published = f64_at(&publish[i], it.publish[5]);
            read_elevation[i] = e;
            // Full precision: the C components' reads are compared with these values.
            row.push_str(&format!(",{e},{t},{published},{}", host.connection_count()));
        }
        writeln!(csv, "{row}")?;
        // The FMU's step: UAV 1's elevation as just read in, its filter out.
        fmu_publish[0][fmu_elevation.clone()].copy_from_slice(&read_elevation[0].to_ne_bytes());
        let fmu_reports = step_all(&mut fw_fmu, &fmu_publish, sim, period, &tick)?;
        {
            let host = &fw_fmu.domains[0];
            let sub = host.subscribe();
            let steps_done = i32::from_ne_bytes(sub[fmu_steps.clone()].try_into().unwrap_or_default());
            writeln!(
                fmu_csv,
                "{},{sim:.6},{},{},{},{steps_done},{}",
                fmu_reports.first().map_or(0, |r| r.step),
                read_elevation[0],
                f64_at(sub, fmu_altitude.start),
                f64_at(sub, fmu_climb.start),
                host.connection_count()
            )?;
        }
        let done = StepDone { reports: &reports, publish: &publish, sim, run_start: wall0 };
        tutti_record::record_step(recording.as_mut(), &fw, &done).context("writing the recording")?;
        // The C components, on schedule.
        while readers.len() < scenario.c_readers.len() && sim >= scenario.c_readers[readers.len()] {
            let j = readers.len() + 1;
            let mut cmd = Command::new(&c_reader);
            cmd.arg(&model.domains[scenario.c_domain_uav - 1].name).arg(out.join(format!("c_reader{j}.csv")));
            env(&mut cmd);
            eprintln!("demo: t={sim:.1}s C component {j} connects to multiuav_uav{}", scenario.c_domain_uav);
            readers.push(spawn(&format!("C component {j}"), cmd, None)?);
        }
        if tick.k % 20 == 0 {
            for k in
                uavs.iter_mut().chain(readers.iter_mut()).chain(gateway.iter_mut()).chain(std::iter::once(&mut fmu_kid))
            {
                if let Some(st) = k.poll() {
                    bail!("{} exited during the run ({st})", k.name);
                }
            }
            if let Some(st) = monitor.poll() {
                if !st.success() || sim < scenario.duration - 2.0 {
                    bail!("the monitoring script exited at t={sim:.1}s ({st})");
                }
            }
        }
        if sim - last_progress >= 10.0 - 1e-9 {
            last_progress = sim;
            let counts: Vec<String> = fw.domains.iter().map(|d| d.connection_count().to_string()).collect();
            let late =
                if ticker.overruns > overruns_seen { format!(", {} overruns", ticker.overruns) } else { String::new() };
            overruns_seen = ticker.overruns;
            eprintln!("demo: t={sim:5.1}s connections per domain [{}]{late}", counts.join(" "));
        }
    }
    drop(monitor_in.take());
    csv.flush().context("writing framework.csv")?;
    fmu_csv.flush().context("writing altitude_filter.csv")?;
    recording.finish().context("writing run.mcap")?;
    if interrupted.load(Ordering::SeqCst) {
        return Ok(());
    }
    eprintln!(
        "demo: stepping done: {} overruns, max lateness {:.2} ms",
        ticker.overruns,
        ticker.max_late.as_secs_f64() * 1e3
    );
    // Orderly end: the UAVs flush their logs, the framework stops (the C components see it
    // and exit), the monitoring script finishes its log, the gateway stops.
    for k in &mut uavs {
        k.stop(Some(SIGTERM), Duration::from_secs(3));
    }
    drop(fw);
    // Its framework gone, the FMU component terminates its FMU and exits.
    drop(fw_fmu);
    if fmu_kid.wait(Duration::from_secs(3)).is_none() {
        fmu_kid.stop(Some(SIGTERM), Duration::from_secs(1));
    }
    for k in &mut readers {
        if k.wait(Duration::from_secs(3)).is_none() {
            k.stop(Some(SIGTERM), Duration::from_secs(1));
        }
    }
    if monitor.wait(Duration::from_secs(3)).is_none() {
        monitor.stop(Some(SIGTERM), Duration::from_secs(1));
    }
    if let Some(g) = &mut gateway {
        g.stop(Some(SIGINT), Duration::from_secs(3));
    }
    for k in uavs.iter_mut().chain(readers.iter_mut()).chain([&mut monitor, &mut fmu_kid]) {
        if let Some(st) = k.poll().filter(|st| !st.success() && st.code().is_some()) {
            eprintln!("demo: warning: {} ended with {st}", k.name);
        }
    }
    Ok(())
}
