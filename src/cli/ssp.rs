//! `tutti ssp inspect|ddf SYSTEM.ssp`: a system of FMUs from an SSP archive (the work is in
//! the `tutti-ssp` crate; docs/ssp.md). `tutti run SYSTEM.ssp` runs one (src/cli/run.rs).
//!
//! Exit status: 2 for an archive that cannot be used (not an SSP archive, a refused element
//! with its FILE:LINE:COL, an FMU that does not fit its connectors).

use std::path::PathBuf;
use std::time::Duration;

use tutti_core::parse::parse_duration;
use tutti_host::connect::StepOrder;
use tutti_ssp::{Archive, PlanOptions, System};

use super::{CliResult, Failure};

/// SSP archives: inspect a system of FMUs, or make a DDF and a launch file of it.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti ssp inspect system.ssp\n  tutti ssp ddf system.ssp --out run/ --step 10ms --record run.csv\n  tutti run run/system.json5\n  tutti run system.ssp --record run.csv\n\nThe mapping from SSP to a DDF and a launch file, and what is supported: docs/ssp.md."
)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    Inspect(InspectArgs),
    Ddf(DdfArgs),
}

/// List a system's components, connectors, connections, units and parameter values.
#[derive(Debug, clap::Args)]
struct InspectArgs {
    #[arg(value_name = "SYSTEM.ssp")]
    ssp: PathBuf,
}

/// Extract the archive into DIR and write the DDF (a domain per component) and one launch file.
#[derive(Debug, clap::Args)]
struct DdfArgs {
    #[arg(value_name = "SYSTEM.ssp")]
    ssp: PathBuf,
    /// The directory to write into (the FMUs are extracted there too).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    #[command(flatten)]
    plan: PlanArgs,
}

/// How an SSP system is run (shared with `tutti run SYSTEM.ssp`).
#[derive(Debug, Clone, clap::Args)]
pub struct PlanArgs {
    /// The communication step.
    #[arg(long, value_parser = parse_duration, default_value = "10ms")]
    pub step: Duration,
    /// How many steps (default: the DefaultExperiment's stopTime over the step).
    #[arg(long, value_name = "N")]
    pub steps: Option<u64>,
    /// Record every step (CSV, or MCAP by extension; repeatable).
    #[arg(long, value_name = "FILE")]
    pub record: Vec<PathBuf>,
    /// The framework's wait for a step's answers.
    #[arg(long, value_parser = parse_duration, default_value = tutti_core::defaults::SSP_STEP_TIMEOUT_TEXT)]
    pub timeout: Duration,
    /// How the connections are applied within a step: 'delayed' (libcosim's ordering) or
    /// 'feedthrough' (OMSimulator's: direct-feedthrough outputs evaluated again after the
    /// exchange; docs/ssp.md).
    #[arg(long, value_name = "ORDERING", default_value = "delayed")]
    pub ordering: StepOrder,
}

impl PlanArgs {
    /// The plan's options; recordings absolute, since the launch file is elsewhere.
    pub fn options(&self) -> PlanOptions {
        let record = self.record.iter().map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone())).collect();
        PlanOptions { step: self.step, steps: self.steps, record, timeout: self.timeout, ordering: self.ordering }
    }
}

pub fn run(args: Args) -> CliResult {
    match args.command {
        Command::Inspect(a) => inspect(a),
        Command::Ddf(a) => ddf(a),
    }
}

fn inspect(a: InspectArgs) -> CliResult {
    let mut archive = Archive::open(&a.ssp).map_err(Failure::invalid)?;
    let s = System::load(&mut archive).map_err(Failure::invalid)?;
    let version = match s.version {
        tutti_ssp::SspVersion::V1 => "1.0",
        tutti_ssp::SspVersion::V2 => "2.0",
    };
    println!("system:      {} (SSP {version}, {})", s.name, s.file);
    if let Some(t) = s.stop_time {
        println!("experiment:  0 to {t} s");
    }
    println!("\ncomponents:");
    for c in &s.components {
        println!("  {}  {}", c.name, c.source);
        for k in &c.connectors {
            let ty = k.ty.map_or("(the FMU's type)", |t| t.as_str());
            let unit = k.unit.as_deref().map(|u| format!(" [{u}]")).unwrap_or_default();
            println!("    {:<8} {} {ty}{unit}", k.kind.as_str(), k.name);
        }
    }
    println!("\nconnections:");
    if s.connections.is_empty() {
        println!("  none");
    }
    for c in &s.connections {
        let mut line = format!("  {}.{} -> {}.{}", c.from.0, c.from.1, c.to.0, c.to.1);
        if c.factor != 1.0 || c.offset != 0.0 {
            line.push_str(&format!("  (× {} + {})", c.factor, c.offset));
        }
        if c.suppress_unit_conversion {
            line.push_str("  (no unit conversion)");
        }
        println!("{line}");
    }
    if !s.units.is_empty() {
        println!("\nunits:");
        for (u, _) in &s.units {
            println!("  {u}");
        }
    }
    println!("\nparameters:");
    let mut any = false;
    for c in &s.components {
        for p in &c.params {
            any = true;
            println!("  {}.{} = {}  ({}, component level, {})", c.name, p.name, p.value, p.ty.as_str(), p.at);
        }
    }
    for p in &s.system_params {
        any = true;
        println!("  {} = {}  ({}, system level, {})", p.name, p.value, p.ty.as_str(), p.at);
    }
    if !any {
        println!("  none");
    }
    Ok(())
}

fn ddf(a: DdfArgs) -> CliResult {
    let prepared = tutti_ssp::prepare(&a.ssp, Some(&a.out), &a.plan.options()).map_err(Failure::invalid)?;
    let p = &prepared.plan;
    eprintln!(
        "ssp: wrote {} and {} in {}: {} component(s), {} connection(s), {}",
        p.ddf_file,
        p.launch_file,
        a.out.display(),
        p.members.len(),
        p.connections.len(),
        p.steps.map_or("no step limit (no stopTime; give --steps)".to_string(), |n| format!("{n} steps"))
    );
    println!("{}", prepared.launch_file.display());
    Ok(())
}
