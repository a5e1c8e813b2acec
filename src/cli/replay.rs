//! `tutti replay run.mcap`: acts as the framework of the recorded domains and republishes
//! each recorded step's PUBLISH set, with its simulated time, at the recorded pace (scaled by
//! `--speed`); synchronous domains wait for their participants as usual. With `--compare`,
//! the SUBSCRIBE answers of each step of a synchronous domain are checked against the
//! recording, element by element, and every step that differs is reported.
//!
//! A step is compared only when the domain has as many connections as it had in the
//! recording at that step (a participant that joined or left at another step answers other
//! steps); those steps are counted, never silently passed. Asynchronous domains are replayed,
//! not compared: what their participants answer depends on timing.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use serde_json::json;
use tutti_core::ddf::Domain;
use tutti_core::shm::{Framework, FrameworkOptions, WaitMode};
use tutti_record::replay::{RecordedStep, Recording};

use super::host::{parse_duration, parse_wait};
use super::{CliResult, Failure};
use crate::rt;

/// Replay a recording: be the framework of its domains and republish its PUBLISH sets.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti replay run.mcap\n  tutti replay run.mcap --domain multiuav_uav2 --speed 0 --compare\n  tutti replay run.mcap --wait-for multiuav_uav2=1 --compare --json\n\nThe recording is an MCAP file written by `tutti host --record` or `tutti record` (the DDF\nis inside). With --compare the exit status is 1 when a step differs. See docs/recording.md."
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
    #[arg(long = "wait-for", value_name = "DOMAIN=N", value_parser = rt::parse_wait_for)]
    wait_for: Vec<(String, usize)>,
    /// Longest wait for the participants of a synchronous step.
    #[arg(long, default_value = "1s", value_parser = parse_duration)]
    timeout: Duration,
    /// How the framework waits for participants: block, spin, or poll:DURATION.
    #[arg(long, default_value = "block", value_parser = parse_wait)]
    wait: WaitMode,
    /// Print the summary (and the differences) as one JSON object on stdout.
    #[arg(long)]
    json: bool,
    /// Print no progress lines.
    #[arg(short, long)]
    quiet: bool,
}

fn parse_speed(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a speed: a factor like 1, 0.5 or 10, or 0 for as fast as possible")),
    }
}

/// One element of a SUBSCRIBE set that differs from the recording.
#[derive(Debug, Clone, serde::Serialize)]
struct Difference {
    item: String,
    recorded: String,
    replayed: String,
}

/// A step whose answers differ.
#[derive(Debug, Clone, serde::Serialize)]
struct DifferingStep {
    domain: String,
    step: u64,
    sim_time: f64,
    items: Vec<Difference>,
}

/// What the comparison found.
#[derive(Debug, Default)]
struct Comparison {
    compared: u64,
    /// Steps not compared because the connection count differs from the recording's.
    other_connections: u64,
    /// Steps that differ; the first [`KEEP`] of them in `kept`.
    differing: u64,
    kept: Vec<DifferingStep>,
}

/// The most differing steps kept (and printed) in full; the rest are counted.
const KEEP: usize = 1000;
const PRINT: usize = 20;

/// The elements of `domain`'s SUBSCRIBE set that differ between `recorded` and `replayed`.
fn differences(domain: &Domain, recorded: &[u8], replayed: &[u8]) -> Vec<Difference> {
    let mut out = Vec::new();
    for leaf in &domain.subscribe.layout.leaves {
        let n = leaf.ty.size() as usize;
        let (Some(a), Some(b)) = (recorded.get(leaf.range()), replayed.get(leaf.range())) else { continue };
        for (e, (x, y)) in a.chunks_exact(n).zip(b.chunks_exact(n)).enumerate() {
            if x != y {
                let item = if leaf.length == 1 { leaf.path.clone() } else { format!("{}[{e}]", leaf.path) };
                out.push(Difference {
                    item,
                    recorded: leaf.ty.decode(x).to_string(),
                    replayed: leaf.ty.decode(y).to_string(),
                });
            }
        }
    }
    out
}

pub fn run(args: Args) -> CliResult {
    let recording = Recording::read_with(&args.file, args.ddf.as_deref()).map_err(Failure::invalid)?;
    let Recording { ddf_name, mut model, domains: mut recorded } = recording;
    for d in &args.domains {
        if model.domain(d).is_none() {
            return Err(Failure::invalid(anyhow::anyhow!(
                "{}: no recorded domain '{d}' (recorded: {})",
                args.file.display(),
                model.domains.iter().map(|d| d.name.as_str()).collect::<Vec<_>>().join(", ")
            )));
        }
    }
    if !args.domains.is_empty() {
        model.domains.retain(|d| args.domains.contains(&d.name));
        recorded.retain(|d| args.domains.contains(&d.name));
    }
    if model.domains.is_empty() {
        return Err(Failure::invalid(anyhow::anyhow!("{}: no recorded step to replay", args.file.display())));
    }
    for (d, n) in &args.wait_for {
        if model.domain(d).is_none() {
            return Err(Failure::invalid(anyhow::anyhow!("--wait-for {d}={n}: no domain '{d}' replayed")));
        }
    }
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)).context("installing the signal handler")?;
    }
    let opts = FrameworkOptions {
        timeout: args.timeout,
        wait: args.wait,
        hold: !args.wait_for.is_empty(),
        ..Default::default()
    };
    let mut fw = Framework::create(&model, &opts).with_context(|| format!("replaying {}", args.file.display()))?;
    let total: usize = recorded.iter().map(|d| d.steps.len()).sum();
    if !args.quiet {
        let names: Vec<String> = recorded.iter().map(|d| format!("{} ({} steps)", d.name, d.steps.len())).collect();
        eprintln!(
            "replay: {} (DDF {ddf_name}) in namespace {}: {}",
            args.file.display(),
            opts.namespace,
            names.join(", ")
        );
    }
    if !rt::wait_for_writers(&mut fw, &args.wait_for, &stop, "replay", args.quiet)? {
        return Ok(());
    }
    fw.domains.iter().for_each(|d| d.set_hold(false));

    let mut cursors = vec![0usize; recorded.len()];
    let mut cmp = Comparison::default();
    let mut timeouts = 0u64;
    let mut replayed = 0usize;
    let first_log = recorded.iter().filter_map(|d| d.steps.first()).map(|s| s.log_time).min().unwrap_or(0);
    let start = Instant::now();
    let mut last_report = Instant::now();
    let mut frame: Vec<usize> = Vec::with_capacity(recorded.len());
    while !stop.load(Ordering::SeqCst) {
        // The next recorded step number, and the domains that have it.
        let Some(k) = recorded.iter().zip(&cursors).filter_map(|(d, &c)| d.steps.get(c)).map(|s| s.step).min() else {
            break;
        };
        frame.clear();
        frame.extend((0..recorded.len()).filter(|&i| recorded[i].steps.get(cursors[i]).is_some_and(|s| s.step == k)));
        let step_of = |i: usize| -> &RecordedStep { &recorded[i].steps[cursors[i]] };
        if args.speed > 0.0 {
            let log = frame.iter().map(|&i| step_of(i).log_time).min().unwrap_or(first_log);
            let due = Duration::from_secs_f64(log.saturating_sub(first_log) as f64 / 1e9 / args.speed);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        for &i in &frame {
            let s = step_of(i);
            let host = &mut fw.domains[i];
            host.publish_step(&s.publish, s.sim_time).with_context(|| format!("domain '{}'", recorded[i].name))?;
        }
        for &i in &frame {
            let s = step_of(i);
            let host = &mut fw.domains[i];
            let report = host.complete_step().with_context(|| format!("domain '{}'", recorded[i].name))?;
            if report.timed_out > 0 {
                timeouts += 1;
            }
            let domain = &model.domains[i];
            let Some(want) = s.subscribe.as_deref().filter(|_| args.compare && domain.flags.synchronous) else {
                continue;
            };
            if host.connection_count() != s.connections {
                cmp.other_connections += 1;
                continue;
            }
            cmp.compared += 1;
            let items = differences(domain, want, host.subscribe());
            if !items.is_empty() {
                if !args.quiet && !args.json && cmp.differing < PRINT as u64 {
                    print_difference(&domain.name, s, &items);
                }
                cmp.differing += 1;
                if cmp.kept.len() < KEEP {
                    cmp.kept.push(DifferingStep {
                        domain: domain.name.clone(),
                        step: s.step,
                        sim_time: s.sim_time,
                        items,
                    });
                }
            }
        }
        for &i in &frame {
            cursors[i] += 1;
        }
        replayed += frame.len();
        if !args.quiet && last_report.elapsed() >= Duration::from_secs(1) {
            last_report = Instant::now();
            eprintln!(
                "replay: t={:.1}s {replayed}/{total} steps, step timeouts {timeouts}{}",
                start.elapsed().as_secs_f64(),
                if args.compare { format!(", {} differing", cmp.differing) } else { String::new() }
            );
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let stopped = replayed < total;
    if args.json {
        let mut v = json!({
            "recording": args.file.display().to_string(),
            "steps": replayed,
            "recorded_steps": total,
            "step_timeouts": timeouts,
            "seconds": elapsed,
            "stopped_early": stopped,
        });
        if args.compare {
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
            if stopped { " (stopped early)" } else { "" }
        );
    }
    let failed = args.compare && (cmp.differing > 0 || cmp.compared == 0);
    if args.compare && !args.quiet && !failed {
        eprintln!("{}", compare_summary(&cmp));
    }
    if failed {
        return Err(anyhow::anyhow!("{}", compare_summary(&cmp)).into());
    }
    Ok(())
}

fn print_difference(domain: &str, s: &RecordedStep, items: &[Difference]) {
    let list: Vec<String> =
        items.iter().take(5).map(|d| format!("{}: recorded {}, replayed {}", d.item, d.recorded, d.replayed)).collect();
    let more = if items.len() > 5 { format!(" (+{} more)", items.len() - 5) } else { String::new() };
    eprintln!("differs: {domain} step {} (t={:.6} s): {}{more}", s.step, s.sim_time, list.join("; "));
}

fn compare_summary(cmp: &Comparison) -> String {
    let skipped = if cmp.other_connections > 0 {
        format!(", {} not compared (connections differ from the recording's)", cmp.other_connections)
    } else {
        String::new()
    };
    match cmp.kept.first() {
        _ if cmp.compared == 0 => format!("compare: no step compared{skipped}"),
        None => format!("compare: {} steps compared, no difference{skipped}", cmp.compared),
        Some(first) => {
            let d = &first.items.first();
            format!(
                "compare: {} of {} compared steps differ{skipped}; the first is {} step {} (t={:.6} s): {}",
                cmp.differing,
                cmp.compared,
                first.domain,
                first.step,
                first.sim_time,
                d.map_or(String::new(), |d| format!("{} recorded {}, replayed {}", d.item, d.recorded, d.replayed))
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_name_the_item_and_element() {
        let ddf = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("ddf/multiuav.ddf");
        let m = tutti_core::ddf::load(ddf).unwrap();
        let d = &m.domains[0];
        let a = d.subscribe.layout.default_bytes();
        let mut b = a.clone();
        let leaf = d.subscribe.layout.leaves.iter().find(|l| l.ty.size() == 8).unwrap();
        b[leaf.range()][..8].copy_from_slice(&2.5f64.to_ne_bytes());
        let diffs = differences(d, &a, &b);
        assert_eq!(diffs.len(), 1);
        assert!(diffs[0].item.starts_with(&leaf.path), "{diffs:?}");
        assert_eq!(diffs[0].replayed, "2.5");
        assert!(differences(d, &a, &a).is_empty());
        assert!(parse_speed("-1").is_err() && parse_speed("nan").is_err() && parse_speed("0").is_ok());
    }
}
