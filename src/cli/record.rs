//! `tutti record DDF --out FILE`: records live domains of the namespace as a passive
//! observer, in the same formats as `tutti host --record` (by extension: MCAP or CSV). The
//! recorder is `tutti-record`'s [`LiveRecorder`]; this module parses, starts it and prints.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context as _;
use tutti_core::parse::parse_duration;
use tutti_core::shm::segment::namespace_from_env;
use tutti_record::live::LiveRecorder;

use super::{load_ddf, CliResult, Failure};

/// Record live domains without taking part in them (MCAP or CSV, by the file's extension).
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti record ddf/multiuav.ddf --out run.mcap --duration 60s\n  TUTTI_NAMESPACE=lab2 tutti record ddf/multiuav.ddf --domain multiuav_uav2 --out uav2.csv\n\nStop with Ctrl-C (the file is completed). Layouts: docs/recording.md."
)]
pub struct Args {
    /// The DDF of the co-simulation.
    #[arg(value_name = "DDF")]
    file: PathBuf,
    /// Record only this domain (repeatable; default: all of the DDF).
    #[arg(long = "domain", value_name = "NAME")]
    domains: Vec<String>,
    /// The recording: `.mcap` or CSV.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Stop after this long (default: until Ctrl-C).
    #[arg(long, value_parser = parse_duration)]
    duration: Option<Duration>,
}

pub fn run(args: Args) -> CliResult {
    let mut model = load_ddf(&args.file)?;
    tutti_record::keep_domains(&mut model, &args.domains, &args.file, "domain").map_err(Failure::invalid)?;
    let ns = namespace_from_env();
    let recorder = tutti_record::create(&args.out, &model, &args.file).context("starting the recording")?;
    let stop = super::stop_flag()?;
    eprintln!(
        "record: {} domain(s) of {} in namespace {ns} -> {}",
        model.domains.len(),
        args.file.display(),
        args.out.display()
    );
    let live = LiveRecorder::new(recorder, &model, ns);
    live.run(&stop, args.duration, |event| eprintln!("record: {event}")).context("writing the recording")?;
    Ok(())
}
