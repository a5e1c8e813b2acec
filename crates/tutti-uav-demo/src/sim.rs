//! The run of `tutti-demo uav`: the scenario as a launch file (`examples/uav/uav-demo.json5`,
//! filled in for this run), run by `tutti run` as a child process. This module prepares the
//! output directory (the DDFs, librtapi, the C component, the FMU, the launch file), runs the
//! launch file, and draws `framework.csv` and `altitude_filter.csv` from the run's CSV
//! recording ([`crate::recording`]).
//!
//! `tutti run` is the framework: it steps the domains (`framework.step` at `framework.speed`),
//! writes the formation commands (`set`), each step's time and the republished altitude
//! (`connections`), records every step, and supervises the components: the four UAV
//! components, the FMU component, the gateway, the monitoring script, and the two C
//! components, declared with `autostart: false`, which the monitoring script starts through
//! the control plane at their times, as it sends the disconnect and connect requests
//! (`signal uavN USR1` / `USR2`).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{bail, Context};
use tutti_host::{ChildProcess, SIGINT};

use crate::scenario::{Action, Scenario};

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
    /// `--realtime [--cpu N] [--priority P]`, handed to `tutti run`.
    pub rt: crate::RealtimeArgs,
}

/// The DDF of the demo, built in: the demo runs from any directory.
const DDF_TEXT: &str = include_str!("../../../ddf/multiuav.ddf");
/// The scenario's launch file, with `${NAME}` values to fill in ([`launch_file`]).
pub const LAUNCH_TEMPLATE: &str = include_str!("../../../examples/uav/uav-demo.json5");
/// The gateway's config: the aircraft as ROS 2 entities.
pub const GATEWAY_CONFIG: &str = include_str!("../../../examples/uav/gateway.json5");
/// The source tree (C component, monitoring script, Python module, header).
const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
/// The domain of the demo's FMU component (examples/fmu/altitude_filter, docs/fmu.md): the
/// framework publishes UAV 1's elevation as it read it, the FMU answers with it filtered.
pub const FMU_DOMAIN: &str = "uav1_altitude_filter";
/// The FMU component's domain, added to the paper's four in the run's DDF (also the
/// checkpoint benchmark's: one file for both).
const FMU_DOMAIN_TEXT: &str = include_str!("../../../examples/uav/fmu-domain.xml");

/// The run's DDF: the paper's four domains and the FMU component's.
pub fn run_ddf() -> anyhow::Result<String> {
    let end = DDF_TEXT.rfind("</orchestra>").context("ddf/multiuav.ddf has no </orchestra>")?;
    Ok(format!("{}{FMU_DOMAIN_TEXT}{}", &DDF_TEXT[..end], &DDF_TEXT[end..]))
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

/// What the launch file is filled in with.
#[derive(Debug, Clone)]
pub struct Filled {
    pub out: PathBuf,
    pub tutti: PathBuf,
    pub tutti_demo: PathBuf,
    pub python: String,
    pub c_reader: PathBuf,
    pub ros_domain_id: String,
    pub gateway: bool,
}

/// The scenario's launch file for this run: [`LAUNCH_TEMPLATE`] with its `${NAME}` values
/// filled in. Every value must be known: one left over is an error.
pub fn launch_file(opts: &SimOptions, scenario: &Scenario, f: &Filled) -> anyhow::Result<String> {
    let step = opts.step.as_secs_f64();
    // Steps at 0, step, …, duration: the old loop's count, the last one at `duration`.
    let steps = (scenario.duration / step + 1e-9).floor() as u64 + 1;
    let starts: Vec<String> =
        scenario.c_readers.iter().enumerate().map(|(j, t)| format!("{t}:c_reader{}", j + 1)).collect();
    let path = |p: &Path| p.display().to_string();
    let values = [
        ("STEP", format!("{}us", opts.step.as_micros())),
        ("SPEED", opts.speed.to_string()),
        ("STEPS", steps.to_string()),
        ("TIMEOUT", format!("{}ms", opts.timeout.as_millis())),
        ("DURATION", scenario.duration.to_string()),
        ("EVENTS", scenario.events_arg()),
        ("STARTS", starts.join(",")),
        ("OUT", path(&f.out)),
        ("ROOT", path(&Path::new(ROOT).canonicalize().unwrap_or_else(|_| PathBuf::from(ROOT)))),
        ("TUTTI", path(&f.tutti)),
        ("TUTTI_DEMO", path(&f.tutti_demo)),
        ("PYTHON", f.python.clone()),
        ("C_READER", path(&f.c_reader)),
        ("ROS_DOMAIN_ID", f.ros_domain_id.clone()),
        ("GATEWAY", f.gateway.to_string()),
    ];
    let mut text = LAUNCH_TEMPLATE.to_string();
    for (name, value) in values {
        // JSON string contents: a path with a quote or a backslash stays one string.
        let value = value.replace('\\', "\\\\").replace('"', "\\\"");
        text = text.replace(&format!("${{{name}}}"), &value);
    }
    if let Some(at) = text.find("${") {
        let name: String = text[at..].chars().take_while(|c| *c != '}').collect();
        bail!("the launch file template has a value the demo does not fill: {name}}}");
    }
    Ok(text)
}

/// What [`prepare`] made.
#[derive(Debug)]
pub struct Prepared {
    pub namespace: String,
    pub launch: PathBuf,
    tutti: PathBuf,
}

/// Writes the DDFs, copies librtapi, builds the C component and the FMU, and writes the
/// launch file `uav-demo.json5` in `out`.
pub fn prepare(opts: &SimOptions, scenario: &Scenario, out: &Path) -> anyhow::Result<Prepared> {
    let namespace = std::env::var("TUTTI_NAMESPACE")
        .ok()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| format!("demo-{}", std::process::id()));
    let ddf = run_ddf()?;
    let ddf_path = out.join("multiuav.ddf");
    // Checked here too: a mistake is the demo's, not the user's launch file's.
    tutti_core::ddf::parse_str(&ddf, &ddf_path.display().to_string()).map_err(|e| anyhow::anyhow!("{e}"))?;
    std::fs::write(&ddf_path, &ddf).with_context(|| format!("writing {}", ddf_path.display()))?;
    // The gateway bridges the paper's domains, as it did before the FMU's was added.
    std::fs::create_dir_all(out.join("gateway"))?;
    std::fs::write(out.join("gateway/multiuav.ddf"), DDF_TEXT).context("writing gateway/multiuav.ddf")?;
    // The four aircraft as ROS 2 entities (examples/uav/gateway.json5).
    std::fs::write(out.join("gateway/uav.json5"), GATEWAY_CONFIG).context("writing gateway/uav.json5")?;
    let tutti_demo = std::env::current_exe().context("locating this executable")?;
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
        Some(p) => std::path::absolute(p).unwrap_or(p.clone()),
        None => build_c_reader(out, &lib)?,
    };
    build_fmu(out)?;
    let ros_domain_id = match opts.ros_domain_id {
        Some(id) => id.to_string(),
        // The gateway's own reader: a bad value is refused here, naming the variable.
        None => tutti_gateway::config::env::domain_id()?.unwrap_or(0).to_string(),
    };
    let filled = Filled {
        out: out.to_path_buf(),
        tutti: tutti.clone(),
        tutti_demo,
        python: std::env::var("TUTTI_PYTHON").unwrap_or_else(|_| "python3".into()),
        c_reader,
        ros_domain_id,
        gateway: !opts.no_gateway,
    };
    let launch = out.join("uav-demo.json5");
    std::fs::write(&launch, launch_file(opts, scenario, &filled)?)
        .with_context(|| format!("writing {}", launch.display()))?;
    Ok(Prepared { namespace, launch, tutti })
}

/// Runs the co-simulation: `tutti run` of the prepared launch file, its components' logs in
/// `out/logs`; then `framework.csv` and `altitude_filter.csv` from its recording. `tutti run`
/// is stopped (and its components with it) however this returns.
pub fn simulate(opts: &SimOptions, scenario: &Scenario, out: &Path, interrupted: &AtomicBool) -> anyhow::Result<()> {
    let p = prepare(opts, scenario, out)?;
    let period = opts.step.div_f64(opts.speed);
    eprintln!(
        "demo: {} scenario, {:.0} s simulated at {}x (step {:.0} ms simulated, {:.1} ms wall), namespace {}, results in {}",
        scenario.name,
        scenario.duration,
        opts.speed,
        opts.step.as_secs_f64() * 1e3,
        period.as_secs_f64() * 1e3,
        p.namespace,
        out.display()
    );
    for e in &scenario.events {
        let sig = if e.action == Action::Disconnect { "USR1" } else { "USR2" };
        eprintln!("demo: at {:>5.1} s: tutti ctl signal uav{} {sig}   ({})", e.t, e.uav, e.action.name());
    }
    for (j, t) in scenario.c_readers.iter().enumerate() {
        eprintln!("demo: at {t:>5.1} s: tutti ctl start c_reader{}", j + 1);
    }
    eprintln!("demo: tutti run {} (the components' output in {})", p.launch.display(), out.join("logs").display());
    for old in
        ["framework.csv", "altitude_filter.csv", "connections.csv", "events.csv", "c_reader1.csv", "c_reader2.csv"]
    {
        let _ = std::fs::remove_file(out.join(old));
    }
    let mut cmd = Command::new(&p.tutti);
    cmd.arg("run").arg(&p.launch).arg("--logs").arg(out.join("logs"));
    if opts.rt.realtime {
        cmd.arg("--realtime");
        opts.rt.cpu.map(|c| cmd.args(["--cpu", &c.to_string()]));
        opts.rt.priority.map(|p| cmd.args(["--priority", &p.to_string()]));
    }
    cmd.env("TUTTI_NAMESPACE", &p.namespace).stdin(Stdio::null());
    let mut run = ChildProcess::spawn("tutti run", cmd, None)?.stop_on_drop(Some(SIGINT), Duration::from_secs(15));
    let status = loop {
        if let Some(st) = run.poll() {
            break st;
        }
        if interrupted.load(Ordering::SeqCst) {
            // Ctrl-C reached `tutti run` too; it tears the components down in order.
            run.stop(Some(SIGINT), Duration::from_secs(15));
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    if !status.success() {
        bail!(
            "tutti run {} ended with {status}: see its lines above and the logs in {}",
            p.launch.display(),
            out.join("logs").display()
        );
    }
    crate::recording::demo_tables(out).context("drawing framework.csv and altitude_filter.csv from run.csv")?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gateway's config names the four aircraft, each item one of its domain's.
    #[test]
    fn the_gateway_config_declares_the_four_aircraft_as_entities() {
        let model = tutti_core::ddf::parse_str(DDF_TEXT, "gateway/multiuav.ddf").unwrap();
        let config = tutti_gateway::config::with_model(&model, || {
            tutti_gateway::config::parse(GATEWAY_CONFIG, "gateway/uav.json5")
        })
        .unwrap();
        let entities = config.entities.entities.unwrap_or_default();
        let names: Vec<&str> = entities.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["uav1", "uav2", "uav3", "uav4"]);
        assert!(entities.iter().zip(1..).all(|(e, n)| e.domain == format!("multiuav_uav{n}") && e.frame == "map"));
    }

    fn opts() -> SimOptions {
        SimOptions {
            speed: 4.0,
            step: Duration::from_millis(50),
            timeout: Duration::from_secs(1),
            c_reader: None,
            no_gateway: false,
            ros_domain_id: None,
            rt: crate::RealtimeArgs { realtime: false, cpu: None, priority: None },
        }
    }

    fn filled() -> Filled {
        Filled {
            out: "/o".into(),
            tutti: "/b/tutti".into(),
            tutti_demo: "/b/tutti-demo".into(),
            python: "python3".into(),
            c_reader: "/o/bin/uav_altitude_log".into(),
            ros_domain_id: "7".into(),
            gateway: true,
        }
    }

    /// The filled launch file is what `tutti run` checks: every value in, the scenario's
    /// steps and events, the formation of tutti-uav in `set`.
    #[test]
    fn the_launch_file_is_filled_with_the_scenario() {
        let text = launch_file(&opts(), &Scenario::paper(), &filled()).unwrap();
        assert!(!text.contains("${"), "{text}");
        assert!(text.contains("steps: 2401,") && text.contains("step: \"50000us\"") && text.contains("speed: 4,"));
        assert!(text.contains("\"30:3:disconnect,40:4:disconnect,50:3:connect,70:4:connect\""), "{text}");
        assert!(text.contains("\"60:c_reader1,80:c_reader2\""), "{text}");
        let short = launch_file(&opts(), &Scenario::short().with_duration(12.0), &filled()).unwrap();
        assert!(short.contains("steps: 241,") && short.contains("\"10:3:disconnect\""), "{short}");
        let f = tutti_uav::scenario::default_formation();
        for (i, off) in f.offsets.iter().enumerate() {
            let d = format!("multiuav_uav{}", i + 1);
            for (item, v) in [("X", off.along), ("Y", off.cross), ("Z", off.up), ("Airspeed", f.route[1].airspeed)] {
                assert!(text.contains(&format!("\"{d}/{item}={v}\"")), "{d}/{item}={v} is not in the launch file");
            }
        }
    }

    #[test]
    fn the_run_ddf_adds_the_fmu_domain_to_the_papers_and_the_fmu_filters_with_the_checks_tau() {
        let model = tutti_core::ddf::parse_str(&run_ddf().unwrap(), "multiuav.ddf").unwrap();
        let names: Vec<&str> = model.domains.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(names, ["multiuav_uav1", "multiuav_uav2", "multiuav_uav3", "multiuav_uav4", FMU_DOMAIN]);
        let md =
            std::fs::read_to_string(Path::new(ROOT).join("examples/fmu/altitude_filter/modelDescription.xml")).unwrap();
        let tau = md.lines().find(|l| l.contains("name=\"tau\"")).unwrap();
        let start = tau.split("start=\"").nth(1).unwrap().split('"').next().unwrap();
        assert_eq!(
            start.parse::<f64>().unwrap(),
            crate::scenario::FMU_TAU,
            "the launch file runs the FMU's default tau"
        );
    }
}
