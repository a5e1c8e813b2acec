//! `tutti record DDF --out FILE`: records live domains of the namespace as a passive
//! observer: it opens their segments read-only in effect (no connection, so it never counts
//! as a participant and never paces a step), and writes each step it sees, in the same
//! formats as `tutti host --record` (by extension: MCAP or CSV).
//!
//! A step is written when the next one is published: its PUBLISH set as read when it was
//! published, and the SUBSCRIBE set as it stands when the framework moves on (in a
//! synchronous domain, the answers the framework read for that step). Steps published
//! faster than it looks (every 100 µs) are counted as missed, never invented. Following a
//! domain (opening it, noticing its framework stop or come back) is the core's
//! [`Observer`], as for the gateway's poller.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use tutti_core::ddf::Role;
use tutti_core::shm::observer::{Look, Observer};
use tutti_core::shm::segment::namespace_from_env;

use super::host::parse_duration;
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

/// One domain as the recorder follows it.
struct Followed {
    obs: Observer,
    /// The step last seen published, with its simulated time; its PUBLISH set is `publish`.
    pending: Option<(u64, f64)>,
    publish: Vec<u8>,
    subscribe: Vec<u8>,
    recorded: u64,
    missed: u64,
}

pub fn run(args: Args) -> CliResult {
    let mut model = load_ddf(&args.file)?;
    for d in &args.domains {
        if model.domain(d).is_none() {
            return Err(Failure::invalid(anyhow::anyhow!("{}: no domain '{d}'", args.file.display())));
        }
    }
    if !args.domains.is_empty() {
        model.domains.retain(|d| args.domains.contains(&d.name));
    }
    let ns = namespace_from_env();
    let mut recorder = tutti_record::create(&args.out, &model, &args.file).context("starting the recording")?;
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)).context("installing the signal handler")?;
    }
    let mut followed: Vec<Followed> = model
        .domains
        .iter()
        .map(|d| Followed {
            obs: Observer::new(d.name.clone()),
            pending: None,
            publish: vec![0; d.publish.layout.size as usize],
            subscribe: vec![0; d.subscribe.layout.size as usize],
            recorded: 0,
            missed: 0,
        })
        .collect();
    eprintln!(
        "record: {} domain(s) of {} in namespace {ns} -> {}",
        followed.len(),
        args.file.display(),
        args.out.display()
    );
    let start = Instant::now();
    let mut last_report = Instant::now();
    while !stop.load(Ordering::SeqCst) && args.duration.map_or(true, |d| start.elapsed() < d) {
        for (i, f) in followed.iter_mut().enumerate() {
            match f.obs.look(&ns) {
                Look::Fresh => {
                    eprintln!("record: {}: following its framework", f.obs.domain);
                    f.pending = None;
                }
                Look::Same => {}
                Look::Gone => continue,
                Look::Stopped => {
                    eprintln!("record: {}: the framework stopped", f.obs.domain);
                    f.pending = None;
                    continue;
                }
                Look::Refused(e) => {
                    eprintln!("record: {}: {e}", f.obs.domain);
                    continue;
                }
            }
            let Some(seg) = f.obs.segment() else { continue };
            let step = seg.step();
            if step == 0 || f.pending.is_some_and(|(k, _)| k == step) {
                continue;
            }
            // The framework moved on: the pending step is complete.
            if let Some((k, sim)) = f.pending.take() {
                if seg.read_set(Role::Subscribe, &mut f.subscribe).is_ok() {
                    let s = tutti_record::Step {
                        step: k,
                        sim_time: sim,
                        wall_ns: tutti_record::now_ns(),
                        elapsed_s: start.elapsed().as_secs_f64(),
                        connections: seg.connection_count(),
                        owner_pid: seg.exclusive_owner_pid(),
                        publish: &f.publish,
                        subscribe: &f.subscribe,
                    };
                    recorder.step(i, &s).context("writing the recording")?;
                    f.recorded += 1;
                    f.missed += step.saturating_sub(k + 1);
                }
            }
            let sim = seg.sim_time();
            // Still step `step` after the copy: else it is caught at the next look.
            if seg.read_set(Role::Publish, &mut f.publish).is_ok() && seg.step() == step {
                f.pending = Some((step, sim));
            }
        }
        if last_report.elapsed() >= Duration::from_secs(5) {
            last_report = Instant::now();
            report(&followed, start);
        }
        std::thread::sleep(Duration::from_micros(100));
    }
    recorder.finish().context("writing the recording")?;
    report(&followed, start);
    Ok(())
}

fn report(followed: &[Followed], start: Instant) {
    let parts: Vec<String> =
        followed.iter().map(|f| format!("{} {} steps ({} missed)", f.obs.domain, f.recorded, f.missed)).collect();
    eprintln!("record: t={:.1}s {}", start.elapsed().as_secs_f64(), parts.join(", "));
}
