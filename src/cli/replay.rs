//! `tutti replay run.mcap`: acts as the framework of the recorded domains and republishes
//! each recorded step's PUBLISH set at the recorded pace; with `--compare`, checks the
//! participants' SUBSCRIBE answers against the recording. The replay is `tutti-record`'s
//! [`Replay`]; this module parses, runs it and prints (the JSON summary included).

use std::path::PathBuf;
use std::time::Duration;

use serde_json::json;
use tutti_core::parse::{parse_duration, parse_wait};
use tutti_core::shm::WaitMode;
use tutti_record::replay::{Recording, Replay, ReplayEvent, ReplayOptions, ReplaySummary};
use tutti_record::RecordError;

use super::{CliResult, Failure};

/// Replay a recording: be the framework of its domains and republish its PUBLISH sets.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti replay run.mcap\n  tutti replay run.mcap --domain multiuav_uav2 --speed 0 --compare\n  tutti replay run.mcap --wait-for multiuav_uav2=1 --compare --json\n  tutti replay run.mcap --gateway=foxglove.json5   # Foxglove plays, pauses and seeks it\n\nThe recording is an MCAP file written by `tutti host --record` or `tutti record` (the DDF\nis inside). With --compare the exit status is 1 when a step differs. See docs/recording.md."
)]
pub struct Args {
    /// The recording (`.mcap`).
    #[arg(value_name = "RUN.mcap")]
    file: PathBuf,
    /// Replay only this domain (repeatable; default: every recorded domain).
    #[arg(long = "domain", value_name = "NAME")]
    domains: Vec<String>,
    /// Pace: 1 = as recorded, 2 = twice as fast, 0 = as fast as the participants answer.
    #[arg(long, default_value = "1", value_parser = parse_speed)]
    speed: f64,
    /// Check the participants' SUBSCRIBE answers against the recording, step by step.
    #[arg(long)]
    compare: bool,
    /// The DDF of the recorded domains, instead of the one inside the recording.
    #[arg(long, value_name = "DDF")]
    ddf: Option<PathBuf>,
    /// Before the first step, hold participants in wait-to-go until N writers are connected
    /// to DOMAIN (as `tutti host --wait-for`); repeatable.
    #[arg(long = "wait-for", value_name = "DOMAIN=N", value_parser = tutti_host::parse_wait_for)]
    wait_for: Vec<(String, usize)>,
    /// Longest wait for the participants of a synchronous step.
    #[arg(long, default_value = tutti_core::defaults::STEP_TIMEOUT_TEXT, value_parser = parse_duration)]
    timeout: Duration,
    /// How the framework waits for participants: adaptive (yield up to 50 µs, then block; the default), adaptive:DURATION, block, spin or poll:DURATION.
    #[arg(long, default_value = "adaptive", value_parser = parse_wait)]
    wait: WaitMode,
    /// Print the summary (and the differences) as one JSON object on stdout.
    #[arg(long)]
    json: bool,
    /// Run the DDS / ROS 2 gateway in this process, as `tutti host --gateway` does (the config
    /// file is optional): the replayed sets go to DDS and to Foxglove, whose playback controls
    /// pause, play, seek and set the speed of the replay. Give CONFIG as --gateway=CONFIG.
    #[arg(long, value_name = "CONFIG", num_args = 0..=1, require_equals = true)]
    gateway: Option<Option<PathBuf>>,
    /// Print no progress lines.
    #[arg(short, long)]
    quiet: bool,
}

fn parse_speed(s: &str) -> anyhow::Result<f64> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => anyhow::bail!("'{s}' is not a speed: a factor like 1, 0.5 or 10, or 0 for as fast as possible"),
    }
}

/// The differing steps printed in full; the rest are counted.
const PRINT: u64 = 20;

/// A replay's error with its exit status: 2 for a recording or options that cannot apply, else 1.
fn record_failure(e: RecordError) -> Failure {
    Failure::classed(e.is_invalid(), e)
}

pub fn run(args: Args) -> CliResult {
    let mut recording = Recording::read_with(&args.file, args.ddf.as_deref()).map_err(Failure::invalid)?;
    tutti_record::keep_domains(&mut recording.model, &args.domains, &args.file, "recorded domain")
        .map_err(Failure::invalid)?;
    recording.domains.retain(|d| recording.model.domain(&d.name).is_some());
    let ddf_name = recording.ddf_name.clone();
    let opts = ReplayOptions {
        speed: args.speed,
        compare: args.compare,
        timeout: args.timeout,
        wait: args.wait,
        wait_for: args.wait_for.clone(),
        namespace: None,
    };
    let model = recording.model.clone();
    let mut replay = Replay::new(recording, opts, &args.file).map_err(record_failure)?;
    let stop = super::stop_flag()?;
    // `tutti ctl` and the gateway's playback controls: pause, resume, seek, speed, stop.
    replay.host_mut().serve_control(stop.clone(), None).map_err(|e| Failure::invalid(anyhow::Error::new(e)))?;
    let gateway = match &args.gateway {
        Some(config) => Some(super::host::start_gateway(
            &args.file,
            &model,
            config.as_deref(),
            args.quiet,
            "replay",
            replay.host_mut(),
        )?),
        None => None,
    };
    let (quiet, shown) = (args.quiet, args.file.display().to_string());
    let summary = replay
        .run(&stop, |event| match &event {
            ReplayEvent::Started { .. } if !quiet => eprintln!("replay: {shown} (DDF {ddf_name}) {event}"),
            ReplayEvent::Differs { nth, .. } if !quiet && !args.json && *nth < PRINT => eprintln!("{event}"),
            ReplayEvent::Progress { .. } | ReplayEvent::Host(_) if !quiet => eprintln!("replay: {event}"),
            _ => {}
        })
        .map_err(|e| anyhow::Error::new(e).context(format!("replaying {shown}")))?;
    if let Some(gw) = gateway {
        let stats = gw.stop();
        if !quiet {
            eprintln!("replay: gateway: stopped | {stats}");
        }
    }
    if !summary.started {
        return Ok(());
    }
    finish(&args, &summary)
}

/// Prints the summary (and with `--json` the object); with `--compare`, fails when a step differs.
fn finish(args: &Args, summary: &ReplaySummary) -> CliResult {
    let elapsed = summary.elapsed.as_secs_f64();
    let (replayed, total, timeouts) = (summary.replayed, summary.total, summary.timeouts);
    if args.json {
        let mut v = json!({
            "recording": args.file.display().to_string(),
            "steps": replayed,
            "recorded_steps": total,
            "step_timeouts": timeouts,
            "seconds": elapsed,
            "stopped_early": summary.stopped_early(),
        });
        if let Some(cmp) = &summary.comparison {
            v["compared"] = cmp.compared.into();
            v["not_compared_other_connections"] = cmp.other_connections.into();
            v["differing_steps"] = cmp.differing.into();
            v["first"] = serde_json::to_value(cmp.kept.first()).unwrap_or_default();
            v["differences"] = serde_json::to_value(&cmp.kept).unwrap_or_default();
        }
        println!("{v}");
    }
    if !args.quiet {
        eprintln!(
            "replay: {replayed} of {total} recorded steps in {elapsed:.1} s{}, {timeouts} step timeouts",
            if summary.stopped_early() { " (stopped early)" } else { "" }
        );
    }
    let Some(cmp) = &summary.comparison else { return Ok(()) };
    if cmp.failed() {
        return Err(anyhow::anyhow!("{cmp}").into());
    }
    if !args.quiet {
        eprintln!("{cmp}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speeds_are_factors_of_zero_or_more() {
        assert!(parse_speed("-1").is_err() && parse_speed("nan").is_err() && parse_speed("0").is_ok());
    }
}
