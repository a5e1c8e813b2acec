//! `tutti-demo uav`: the UAV formation co-simulation of the paper's section 7, end to end:
//! its options, the run ([`crate::sim`]) and its report (the checks and the figures).
//!
//! The scenario is a launch file (`examples/uav/uav-demo.json5`), run by `tutti run`
//! ([`crate::sim`]): the framework of `ddf/multiuav.ddf` and the FMU's domain (formation
//! commands, the altitude it read and its clock in PUBLISH; UAV states read from SUBSCRIBE),
//! four UAV components (`tutti-demo uav-node`), the FMU component, the DDS / ROS 2 gateway
//! (loopback only), the monitoring script (`launch-scripts/monitor.py`) that sends the
//! disconnect and connect requests and starts the two C components
//! (`examples/c/uav_altitude_log.c`) through the run's control plane, and logs the
//! connection counts. At the end this reads the CSV files back, draws Figures 5 and 6 and
//! prints the checks; exit status 1 when one fails.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::Context;
use tutti_core::parse::parse_duration;

use crate::analysis::{run_checks, Check, RunData};
use crate::plot;
use crate::scenario::Scenario;
use crate::sim::SimOptions;
use crate::{CliResult, Failure, EXIT_FAILURE};

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
    #[arg(long, default_value = tutti_core::defaults::STEP_TIMEOUT_TEXT, value_parser = parse_duration)]
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
    /// Only prepare --out (the DDFs, the C component, the FMU, the launch file
    /// uav-demo.json5) and say how to run it with `tutti run` and `tutti ctl`.
    #[arg(long)]
    prepare: bool,
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

impl UavArgs {
    fn sim_options(&self) -> SimOptions {
        SimOptions {
            speed: self.speed,
            step: self.run.step,
            timeout: self.timeout,
            c_reader: self.c_reader.clone(),
            no_gateway: self.no_gateway,
            ros_domain_id: self.ros_domain_id,
            rt: self.rt.clone(),
        }
    }
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
pub fn parse_seconds(s: &str) -> anyhow::Result<f64> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        Ok(_) => anyhow::bail!("'{s}' must be a positive number of seconds"),
        Err(_) => Ok(parse_duration(s)?.as_secs_f64()),
    }
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
    if args.prepare {
        let p = crate::sim::prepare(&args.sim_options(), &scenario, &out)?;
        eprintln!("demo: prepared {}; run the scenario with", p.launch.display());
        eprintln!("  TUTTI_NAMESPACE={} tutti run {}", p.namespace, p.launch.display());
        eprintln!("then check and draw it with");
        eprintln!(
            "  tutti-demo uav-report --out {} --scenario {}{}",
            out.display(),
            scenario.name,
            args.run.duration.map(|d| format!(" --duration {d}")).unwrap_or_default()
        );
        eprintln!("(uav-report draws framework.csv and altitude_filter.csv from the run's recording)");
        return Ok(());
    }
    let interrupted = tutti_exit::stop_flag()?;
    let started = Instant::now();
    let ran = crate::sim::simulate(&args.sim_options(), &scenario, &out, &interrupted);
    if interrupted.load(Ordering::SeqCst) {
        eprintln!("demo: interrupted; every process stopped");
        return Err(Failure { code: EXIT_FAILURE, error: anyhow::anyhow!("interrupted") });
    }
    ran?;
    eprintln!("demo: simulation done in {:.1} s of wall time", started.elapsed().as_secs_f64());
    report(&out, &scenario, args.run.step.as_secs_f64())
}

/// `tutti-demo uav-report`: from the recording of a run made by hand (`tutti run`) too.
pub fn run_report(args: ReportArgs) -> CliResult {
    // The recording is the run's truth: the tables are drawn from it again, whoever ran it.
    if args.run.out.join("run-multiuav_uav1.csv").exists() {
        crate::recording::demo_tables(&args.run.out).context("drawing framework.csv from the run's recording")?;
    }
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
                Err(e) => tutti_exit::said_once(&e),
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
