//! The simulation of `tutti-demo uav`: this process is the framework of `ddf/multiuav.ddf`
//! and of the FMU component's domain, stepped by a `tutti-host` ticker; it starts the UAV
//! components, the FMU component, the gateway, the monitoring script and the C components,
//! logs every step, and stops every child however the run ends.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::{ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use tutti_core::ddf::{Model, Role};
use tutti_core::shm::{Framework, FrameworkOptions, StepReport, WaitMode};
use tutti_host::{step_all, ChildProcess, StepDone, Tick, Ticker, SIGINT, SIGTERM};
use tutti_uav::scenario::Formation;

use crate::f64_at;
use crate::scenario::{Scenario, FMU_TAU, UAVS};

fn spawn(name: &str, cmd: Command) -> anyhow::Result<ChildProcess> {
    Ok(ChildProcess::spawn(name, cmd, None)?)
}

/// What `tutti-demo uav` asks of the simulation.
#[derive(Debug, Clone)]
pub struct SimOptions {
    /// Simulated seconds per wall-clock second.
    pub speed: f64,
    /// Simulated time of one framework step.
    pub step: Duration,
    /// Longest wall-clock wait of a step for the participants.
    pub timeout: Duration,
    /// A prebuilt C component.
    pub c_reader: Option<PathBuf>,
    pub no_gateway: bool,
    pub ros_domain_id: Option<u32>,
    pub rt: crate::RealtimeArgs,
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

impl DomainItems {
    /// The items of every domain of `model`: the formation commands, the altitude read and
    /// the clock in PUBLISH; the elevation and time in SUBSCRIBE, all float64.
    fn of(model: &Model) -> anyhow::Result<Vec<DomainItems>> {
        model
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
            .collect()
    }
}

/// What the run is made of, prepared before any process starts.
struct Setup {
    namespace: String,
    ddf_path: PathBuf,
    model: Model,
    /// This executable (the UAV components) and `tutti` (the FMU component, the gateway).
    exe: PathBuf,
    tutti: PathBuf,
    lib: PathBuf,
    c_reader: PathBuf,
    python: String,
    /// Simulated seconds of a step, and its wall-clock period.
    step: f64,
    period: Duration,
}

/// Writes the DDF, finds the executables, copies librtapi and builds the C component.
fn prepare(opts: &SimOptions, scenario: &Scenario, out: &Path) -> anyhow::Result<Setup> {
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
    let c_reader = match &opts.c_reader {
        Some(p) => p.clone(),
        None => build_c_reader(out, &lib)?,
    };
    let python = std::env::var("TUTTI_PYTHON").unwrap_or_else(|_| "python3".into());
    let (step, period) = (opts.step.as_secs_f64(), opts.step.div_f64(opts.speed));
    eprintln!(
        "demo: {} scenario, {:.0} s simulated at {}x (step {:.0} ms simulated, {:.1} ms wall), namespace {namespace}, results in {}",
        scenario.name,
        scenario.duration,
        opts.speed,
        step * 1e3,
        period.as_secs_f64() * 1e3,
        out.display()
    );
    Ok(Setup { namespace, ddf_path, model, exe, tutti, lib, c_reader, python, step, period })
}

impl Setup {
    /// A command of the run: in its namespace, with nothing on its standard input.
    fn command(&self, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut cmd = Command::new(program);
        cmd.env("TUTTI_NAMESPACE", &self.namespace).stdin(Stdio::null());
        cmd
    }
}

/// The FMU component's domain, hosted beside the UAVs' (its own DDF: multiuav.ddf is the
/// paper's, bridged to DDS as it is), with the ranges of its items.
struct FmuDomain {
    fw: Framework,
    ddf: PathBuf,
    publish: Vec<Vec<u8>>,
    elevation: Range<usize>,
    altitude: Range<usize>,
    climb: Range<usize>,
    steps: Range<usize>,
}

impl FmuDomain {
    fn create(out: &Path, opts: &FrameworkOptions) -> anyhow::Result<FmuDomain> {
        let ddf = out.join("altitude_filter.ddf");
        std::fs::write(&ddf, FMU_DDF_TEXT).with_context(|| format!("writing {}", ddf.display()))?;
        let model =
            tutti_core::ddf::parse_str(FMU_DDF_TEXT, &ddf.display().to_string()).map_err(|e| anyhow::anyhow!("{e}"))?;
        let fw = Framework::create(&model, opts).context("creating the FMU's domain")?;
        let leaf = |role: Role, p: &str| -> anyhow::Result<Range<usize>> {
            let leaf = model.domains[0].set(role).layout.leaf(p).with_context(|| format!("{FMU_DOMAIN}: no {p}"))?;
            Ok(leaf.range())
        };
        Ok(FmuDomain {
            publish: vec![model.domains[0].publish.layout.default_bytes()],
            elevation: leaf(Role::Publish, "elevation")?,
            altitude: leaf(Role::Subscribe, "altitude")?,
            climb: leaf(Role::Subscribe, "climb_rate")?,
            steps: leaf(Role::Subscribe, "steps")?,
            fw,
            ddf,
        })
    }
}

/// The processes of the run; each is stopped when this is dropped.
struct Children {
    uavs: Vec<ChildProcess>,
    fmu: ChildProcess,
    gateway: Option<ChildProcess>,
    monitor: Option<ChildProcess>,
    readers: Vec<ChildProcess>,
}

impl Children {
    /// The four UAV components and the FMU component (`tutti fmu run`, as a user would
    /// start it), connected before the first step.
    fn start(setup: &Setup, opts: &SimOptions, out: &Path, fmu: &FmuDomain) -> anyhow::Result<Children> {
        let fmu_path = build_fmu(out)?;
        let mut uavs = Vec::new();
        for i in 1..=UAVS {
            let mut cmd = setup.command(&setup.exe);
            cmd.args(["uav-node", "--index", &i.to_string(), "--speed", &opts.speed.to_string(), "--out"])
                .arg(out.join(format!("uav{i}.csv")));
            uavs.push(spawn(&format!("UAV {i}"), cmd)?);
        }
        let mut cmd = setup.command(&setup.tutti);
        cmd.args(["fmu", "run"])
            .arg(&fmu_path)
            .arg("--ddf")
            .arg(&fmu.ddf)
            .args(["--domain", FMU_DOMAIN, "--param", &format!("tau={FMU_TAU}"), "--name", "fmu:AltitudeFilter", "-q"])
            .env("TMPDIR", out.join("bin"));
        let fmu = spawn("FMU component (AltitudeFilter)", cmd)?;
        Ok(Children { uavs, fmu, gateway: None, monitor: None, readers: Vec::new() })
    }

    /// Waits until every domain has a connection (30 s at most).
    fn wait_connected(&mut self, fws: [&Framework; 2], interrupted: &AtomicBool) -> anyhow::Result<()> {
        let deadline = Instant::now() + Duration::from_secs(30);
        while fws.iter().flat_map(|fw| &fw.domains).any(|d| d.connection_count() == 0) {
            for k in self.uavs.iter_mut().chain(std::iter::once(&mut self.fmu)) {
                if let Some(st) = k.poll() {
                    bail!("{} exited before connecting ({st})", k.name);
                }
            }
            anyhow::ensure!(!interrupted.load(Ordering::SeqCst), "interrupted");
            anyhow::ensure!(Instant::now() < deadline, "the UAV and FMU components did not connect within 30 s");
            std::thread::sleep(Duration::from_millis(20));
        }
        eprintln!("demo: 4 UAV components and the FMU component (AltitudeFilter, tutti fmu run) connected");
        Ok(())
    }

    /// The DDS / ROS 2 gateway on loopback, its log in gateway.log.
    fn start_gateway(&mut self, setup: &Setup, opts: &SimOptions, out: &Path) -> anyhow::Result<()> {
        let mut cmd = setup.command(&setup.tutti);
        cmd.arg("gateway").arg(&setup.ddf_path).args(["--interface", "127.0.0.1", "--status-every", "3600s"]);
        if let Some(id) = opts.ros_domain_id {
            cmd.args(["--ros-domain-id", &id.to_string()]);
        }
        let log = File::create(out.join("gateway.log")).context("creating gateway.log")?;
        cmd.stderr(log);
        self.gateway = Some(spawn("gateway", cmd)?);
        eprintln!("demo: DDS / ROS 2 gateway on loopback (log in gateway.log)");
        Ok(())
    }

    /// The monitoring script: loaded before the clock starts, then fed the simulated time of
    /// every step on its standard input (returned).
    fn start_monitor(&mut self, setup: &Setup, scenario: &Scenario, out: &Path) -> anyhow::Result<ChildStdin> {
        let mut cmd = setup.command(&setup.python);
        let pids: Vec<String> = self.uavs.iter().enumerate().map(|(i, k)| format!("{}:{}", i + 1, k.pid())).collect();
        let domains: Vec<&str> = setup.model.domains.iter().map(|d| d.name.as_str()).collect();
        cmd.arg(Path::new(ROOT).join("launch-scripts/monitor.py"))
            .args(["--clock", "stdin"])
            .args(["--duration", &scenario.duration.to_string(), "--events", &scenario.events_arg()])
            .args(["--pids", &pids.join(","), "--domains", &domains.join(",")])
            .arg("--out")
            .arg(out.join("connections.csv"))
            .arg("--events-out")
            .arg(out.join("events.csv"))
            .env("PYTHONPATH", Path::new(ROOT).join("python"))
            .env("TUTTI_RTAPI_LIB", &setup.lib)
            .env("PYTHONUNBUFFERED", "1");
        cmd.stdin(Stdio::piped()).stdout(Stdio::piped());
        let monitor = self.monitor.insert(spawn("monitoring script", cmd)?);
        let monitor_in = monitor.child.stdin.take().context("the monitoring script's stdin")?;
        let stdout = monitor.child.stdout.take().context("the monitoring script's stdout")?;
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line);
            let _ = tx.send(line);
        });
        let python = &setup.python;
        match rx.recv_timeout(Duration::from_secs(60)) {
            Ok(line) if line.trim() == "ready" => Ok(monitor_in),
            Ok(line) => bail!("the monitoring script did not start ({python}): {:?}", line.trim()),
            Err(_) => bail!("the monitoring script ({python}) was not ready within 60 s"),
        }
    }

    /// Fails when a child ended during the run (the monitoring script may end at the end).
    fn check(&mut self, sim: f64, scenario: &Scenario) -> anyhow::Result<()> {
        let others = self.uavs.iter_mut().chain(self.readers.iter_mut()).chain(self.gateway.iter_mut());
        for k in others.chain(std::iter::once(&mut self.fmu)) {
            if let Some(st) = k.poll() {
                bail!("{} exited during the run ({st})", k.name);
            }
        }
        if let Some(st) = self.monitor.as_mut().and_then(ChildProcess::poll) {
            if !st.success() || sim < scenario.duration - 2.0 {
                bail!("the monitoring script exited at t={sim:.1}s ({st})");
            }
        }
        Ok(())
    }
}

/// The run's logs: the framework's view of every step, and the FMU's.
struct Logs {
    csv: BufWriter<File>,
    fmu_csv: BufWriter<File>,
}

impl Logs {
    fn create(out: &Path) -> anyhow::Result<Logs> {
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
        Ok(Logs { csv, fmu_csv })
    }
}

/// The stepping loop's state.
struct Stepper<'a> {
    setup: &'a Setup,
    scenario: &'a Scenario,
    out: &'a Path,
    fw: Framework,
    fmu: FmuDomain,
    items: Vec<DomainItems>,
    formation: Formation,
    publish: Vec<Vec<u8>>,
    read_elevation: [f64; UAVS],
    logs: Logs,
    recording: Box<dyn tutti_record::Recorder>,
    wall0: Instant,
}

impl Stepper<'_> {
    /// The formation commands, the elevation each UAV's domain last read and the clock.
    fn set_commands(&mut self, sim: f64) {
        for (i, (buf, it)) in self.publish.iter_mut().zip(&self.items).enumerate() {
            let off = self.formation.offsets[i];
            let airspeed = self.formation.route[1].airspeed;
            let values = [1.0, off.along, off.cross, off.up, airspeed, self.read_elevation[i], sim];
            for (o, v) in it.publish.iter().zip(values) {
                buf[*o..*o + 8].copy_from_slice(&v.to_ne_bytes());
            }
        }
    }

    /// One step of the UAVs' domains and of the FMU's, logged and recorded.
    fn step(&mut self, sim: f64, tick: &Tick) -> anyhow::Result<()> {
        self.set_commands(sim);
        let period = self.setup.period;
        let reports = step_all(&mut self.fw, &self.publish, sim, period, tick)?;
        self.log_step(&reports, sim)?;
        // The FMU's step: UAV 1's elevation as just read in, its filter out.
        let fmu = &mut self.fmu;
        fmu.publish[0][fmu.elevation.clone()].copy_from_slice(&self.read_elevation[0].to_ne_bytes());
        let fmu_reports = step_all(&mut fmu.fw, &fmu.publish, sim, period, tick)?;
        let host = &fmu.fw.domains[0];
        let sub = host.subscribe();
        let steps_done = i32::from_ne_bytes(sub[fmu.steps.clone()].try_into().unwrap_or_default());
        writeln!(
            self.logs.fmu_csv,
            "{},{sim:.6},{},{},{},{steps_done},{}",
            fmu_reports.first().map_or(0, |r| r.step),
            self.read_elevation[0],
            f64_at(sub, fmu.altitude.start),
            f64_at(sub, fmu.climb.start),
            host.connection_count()
        )?;
        let done = StepDone { reports: &reports, publish: &self.publish, sim, run_start: self.wall0 };
        tutti_record::record_step(self.recording.as_mut(), &self.fw, &done).context("writing the recording")?;
        Ok(())
    }

    /// The framework's row of the step: what each domain read and published, its connections.
    fn log_step(&mut self, reports: &[StepReport], sim: f64) -> anyhow::Result<()> {
        let step = reports.first().map_or(0, |r| r.step);
        let mut row = format!("{step},{sim:.6},{:.6}", self.wall0.elapsed().as_secs_f64());
        for (i, (host, it)) in self.fw.domains.iter().zip(&self.items).enumerate() {
            let sub = host.subscribe();
            let (e, t) = (f64_at(sub, it.elevation), f64_at(sub, it.time));
            let published = f64_at(&self.publish[i], it.publish[5]);
            self.read_elevation[i] = e;
            // Full precision: the C components' reads are compared with these values.
            row.push_str(&format!(",{e},{t},{published},{}", host.connection_count()));
        }
        writeln!(self.logs.csv, "{row}")?;
        Ok(())
    }

    /// The C components, on schedule.
    fn start_readers(&self, children: &mut Children, sim: f64) -> anyhow::Result<()> {
        let readers = &self.scenario.c_readers;
        while children.readers.len() < readers.len() && sim >= readers[children.readers.len()] {
            let j = children.readers.len() + 1;
            let uav = self.scenario.c_domain_uav;
            let mut cmd = self.setup.command(&self.setup.c_reader);
            cmd.arg(&self.setup.model.domains[uav - 1].name).arg(self.out.join(format!("c_reader{j}.csv")));
            eprintln!("demo: t={sim:.1}s C component {j} connects to multiuav_uav{uav}");
            children.readers.push(spawn(&format!("C component {j}"), cmd)?);
        }
        Ok(())
    }

    /// Steps until the scenario's end or an interruption; returns the ticker.
    fn run(
        &mut self,
        children: &mut Children,
        mut monitor_in: Option<ChildStdin>,
        interrupted: &AtomicBool,
    ) -> anyhow::Result<Ticker> {
        let mut ticker = Ticker::new(self.setup.period);
        self.wall0 = Instant::now();
        let (mut last_progress, mut overruns_seen, mut steps) = (-10.0f64, 0, 0u64);
        while !interrupted.load(Ordering::SeqCst) {
            let tick = ticker.wait();
            // Simulated time counts steps: on a machine too loaded for real time the
            // simulation slows down (overruns are counted) instead of skipping steps; every
            // participant, the monitoring script included, follows this clock.
            let sim = steps as f64 * self.setup.step;
            if sim > self.scenario.duration + 1e-9 {
                break;
            }
            steps += 1;
            if monitor_in.as_mut().is_some_and(|pipe| writeln!(pipe, "{sim:.6}").is_err()) {
                monitor_in = None;
            }
            self.step(sim, &tick)?;
            self.start_readers(children, sim)?;
            if tick.k % 20 == 0 {
                children.check(sim, self.scenario)?;
            }
            if sim - last_progress >= 10.0 - 1e-9 {
                last_progress = sim;
                let counts: Vec<String> = self.fw.domains.iter().map(|d| d.connection_count().to_string()).collect();
                let late = if ticker.overruns > overruns_seen {
                    format!(", {} overruns", ticker.overruns)
                } else {
                    String::new()
                };
                overruns_seen = ticker.overruns;
                eprintln!("demo: t={sim:5.1}s connections per domain [{}]{late}", counts.join(" "));
            }
        }
        Ok(ticker)
    }

    /// Writes what the logs and the recording buffer.
    fn finish_logs(&mut self) -> anyhow::Result<()> {
        self.logs.csv.flush().context("writing framework.csv")?;
        self.logs.fmu_csv.flush().context("writing altitude_filter.csv")?;
        Ok(())
    }
}

/// Orderly end: the UAVs flush their logs, the framework stops (the C components see it and
/// exit), the FMU component terminates its FMU, the monitoring script finishes its log, the
/// gateway stops.
fn shut_down(children: &mut Children, fw: Framework, fmu_fw: Framework) {
    for k in &mut children.uavs {
        k.stop(Some(SIGTERM), Duration::from_secs(3));
    }
    drop(fw);
    // Its framework gone, the FMU component terminates its FMU and exits.
    drop(fmu_fw);
    let ending = std::iter::once(&mut children.fmu).chain(children.readers.iter_mut()).chain(children.monitor.as_mut());
    for k in ending {
        if k.wait(Duration::from_secs(3)).is_none() {
            k.stop(Some(SIGTERM), Duration::from_secs(1));
        }
    }
    if let Some(g) = &mut children.gateway {
        g.stop(Some(SIGINT), Duration::from_secs(3));
    }
    let all = children.uavs.iter_mut().chain(children.readers.iter_mut()).chain(children.monitor.as_mut());
    for k in all.chain(std::iter::once(&mut children.fmu)) {
        if let Some(st) = k.poll().filter(|st| !st.success() && st.code().is_some()) {
            eprintln!("demo: warning: {} ended with {st}", k.name);
        }
    }
}

/// Runs the co-simulation; every child is stopped when this returns, however it returns.
pub fn simulate(opts: &SimOptions, scenario: &Scenario, out: &Path, interrupted: &AtomicBool) -> anyhow::Result<()> {
    let setup = prepare(opts, scenario, out)?;
    let fw_opts = FrameworkOptions {
        namespace: setup.namespace.clone(),
        timeout: opts.timeout,
        wait: WaitMode::Block,
        ..Default::default()
    };
    let fw = Framework::create(&setup.model, &fw_opts).context("creating the domains of multiuav.ddf")?;
    let fmu = FmuDomain::create(out, &fw_opts)?;
    // The whole run as ROS 2 tools read it (Foxglove, ros2 bag): docs/recording.md.
    let recording =
        tutti_record::create(&out.join("run.mcap"), &setup.model, &setup.ddf_path).context("starting run.mcap")?;
    let items = DomainItems::of(&setup.model)?;
    let mut children = Children::start(&setup, opts, out, &fmu)?;
    children.wait_connected([&fw, &fmu.fw], interrupted)?;
    if !opts.no_gateway {
        children.start_gateway(&setup, opts, out)?;
    }
    let logs = Logs::create(out)?;
    let monitor_in = children.start_monitor(&setup, scenario, out)?;
    crate::enter_realtime(&opts.rt, "demo", false);
    let mut stepper = Stepper {
        publish: setup.model.domains.iter().map(|d| d.publish.layout.default_bytes()).collect(),
        setup: &setup,
        scenario,
        out,
        fw,
        fmu,
        items,
        formation: tutti_uav::scenario::default_formation(),
        read_elevation: [0.0; UAVS],
        logs,
        recording,
        wall0: Instant::now(),
    };
    let ticker = stepper.run(&mut children, Some(monitor_in), interrupted)?;
    stepper.finish_logs()?;
    let Stepper { fw, fmu, recording, .. } = stepper;
    recording.finish().context("writing run.mcap")?;
    if interrupted.load(Ordering::SeqCst) {
        return Ok(());
    }
    eprintln!(
        "demo: stepping done: {} overruns, max lateness {:.2} ms",
        ticker.overruns,
        ticker.max_late.as_secs_f64() * 1e3
    );
    shut_down(&mut children, fw, fmu.fw);
    Ok(())
}
