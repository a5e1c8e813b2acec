//! `tutti run FILE`: a whole co-simulation from one launch file (the `tutti-launch` crate:
//! the file, its checks, the supervisor of the components and the run; docs/run.md). This
//! module parses the flags, calls it and prints: the components' output as `[NAME] line`,
//! the run's own lines as `run: …`.

use std::io::Write as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context as _;
use tutti_core::parse::parse_duration;
use tutti_launch::{Event, RunOptions};

use super::{CliResult, Failure};

/// Run a co-simulation described by a launch file (or an SSP archive): the framework, the components, the gateway.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti run cosim.json5\n  tutti run system.ssp --record run.csv --step 10ms\n  tutti run cosim.json5 --logs /tmp/cosim-logs --check\n  sudo tutti run cosim.json5 --realtime --cpu 1 --priority 80\n  tutti run cosim.json5 --restore checkpoints/step-000000500.tutti-checkpoint\n\nThe launch file's keys, restart policies and logs: docs/run.md. Exit status: 0 when every component \
                  ended well (exit status 0, or stopped by the run), 1 otherwise, 2 for a launch file that is refused."
)]
pub struct Args {
    /// The launch file (JSON5), or an SSP archive (`.ssp`: docs/ssp.md).
    #[arg(value_name = "FILE")]
    file: PathBuf,
    /// An SSP archive: extract it and write its DDF and launch file here (kept), instead of a
    /// temporary directory removed at the end.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// An SSP archive: how it steps and what is recorded.
    #[command(flatten)]
    ssp: super::ssp::PlanArgs,
    /// Where each component's output goes, as NAME.log (default: `logs/` beside the launch file).
    #[arg(long, value_name = "DIR")]
    logs: Option<PathBuf>,
    /// Only check the launch file, start nothing.
    #[arg(long)]
    check: bool,
    /// How long a component has to exit after SIGTERM before it is killed.
    #[arg(long, default_value = "3s", value_parser = parse_duration)]
    grace: Duration,
    /// Print no framework progress lines (the components' output and the run's events stay).
    #[arg(short, long)]
    quiet: bool,
    /// Start from this checkpoint (`tutti ctl save`, or a launch file's `checkpoint:`): put
    /// back once the components have connected, before the first step. One of another DDF,
    /// or a damaged one, is refused before anything starts (exit 2).
    #[arg(long, value_name = "CHECKPOINT")]
    restore: Option<PathBuf>,
    #[command(flatten)]
    rt: super::RealtimeArgs,
}

pub fn run(args: Args) -> CliResult {
    let is_ssp = args.file.extension().is_some_and(|e| e.eq_ignore_ascii_case("ssp"));
    // An SSP archive becomes a launch file first (and its directory goes when this does).
    let (launch, _prepared) = if is_ssp {
        let p = tutti_ssp::prepare(&args.file, args.out.as_deref(), &args.ssp.options()).map_err(Failure::invalid)?;
        eprintln!("run: {} is {}", args.file.display(), p.launch_file.display());
        (p.launch.clone(), Some(p))
    } else {
        (tutti_launch::load(&args.file).map_err(Failure::invalid)?, None)
    };
    let restore = match &args.restore {
        Some(path) => {
            let c = tutti_host::checkpoint::Checkpoint::read(path).map_err(Failure::invalid)?;
            c.check_model(&launch.model, &path.display().to_string()).map_err(Failure::invalid)?;
            Some(Box::new(c))
        }
        None => None,
    };
    if args.check {
        eprintln!(
            "run: {} is valid: {} component(s) over {}",
            args.file.display(),
            launch.components.len(),
            launch.ddf.display()
        );
        return Ok(());
    }
    if launch.gateway.is_some() {
        // The gateway's own log (its Foxglove and HTTP addresses, DDS trouble), as with
        // `tutti host --gateway`.
        super::gateway::init_logging();
    }
    let stop = super::stop_flag()?;
    let tutti_exe = std::env::current_exe().context("locating the tutti executable")?;
    let opts = RunOptions {
        log_dir: args.logs.clone().unwrap_or_else(|| launch.dir.join("logs")),
        tutti_exe,
        namespace: None,
        grace: args.grace,
        realtime: args.rt.request(),
        restore,
    };
    let quiet = args.quiet;
    let print = Arc::new(move |e: Event| match &e {
        Event::Line { component, line, stderr: false } => {
            let _ = writeln!(std::io::stdout().lock(), "[{component}] {line}");
        }
        Event::Line { component, line, stderr: true } => eprintln!("[{component}] {line}"),
        Event::Host(tutti_host::Report::Progress(_)) if quiet => {}
        _ => eprintln!("run: {e}"),
    });
    eprintln!("run: {} component(s), logs in {}", launch.components.len(), opts.log_dir.display());
    let outcome =
        tutti_launch::run(&launch, opts, stop, print, |_| {}).map_err(|e| Failure::classed(e.is_invalid(), e))?;
    if let Some(s) = &outcome.summary {
        eprintln!("run: framework {s} ({} steps)", s.steps);
    }
    let failed: Vec<String> = outcome
        .components
        .iter()
        .filter(|c| !c.ended_well())
        .map(|c| format!("{} ({:?}, log {})", c.name, c.state, c.log.display()))
        .collect();
    if let Some(e) = &outcome.start_error {
        if !outcome.all_well() {
            return Err(anyhow::anyhow!("run: {e}").into());
        }
    }
    if !failed.is_empty() {
        return Err(anyhow::anyhow!("run: not every component ended well: {}", failed.join(", ")).into());
    }
    eprintln!("run: every component ended well");
    Ok(())
}
