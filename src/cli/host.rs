//! `tutti host DDF`: a generic framework that creates every domain of a DDF and steps them
//! at a fixed period; optionally records both sets of every domain to CSV.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use tutti_core::ddf::Domain;
use tutti_core::shm::{Framework, FrameworkOptions, WaitMode};

use super::{load_ddf, CliResult, Failure};
use crate::rt::{self, Ticker};

/// Run the framework of every domain in a DDF: create the segments, step at a fixed period.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti host ddf/multiuav.ddf --step 10ms --duration 60s\n  tutti host ddf/product-sample.ddf --set grid_clock/tick=1 --record out/run.csv\n  tutti host ddf/multiuav.ddf --step 10ms --duration 60s --record out/run.mcap   # Foxglove, ros2 bag\n  TUTTI_NAMESPACE=lab2 tutti host ddf/large-1000.ddf --step 1ms\n  sudo tutti host ddf/multiuav.ddf --step 1ms --realtime --cpu 1 --priority 80\n  tutti host ddf/multiuav.ddf --wait-for multiuav_uav2=1 --record run.mcap   # replay later: tutti replay\n\nStop with Ctrl-C: the segments are removed on exit."
)]
pub struct Args {
    /// The DDF whose domains to host.
    #[arg(value_name = "DDF")]
    file: PathBuf,
    /// Step period (e.g. 1ms, 500us, 0.1s).
    #[arg(long, default_value = "10ms", value_parser = parse_duration)]
    step: Duration,
    /// Stop after this long (default: run until Ctrl-C).
    #[arg(long, value_parser = parse_duration)]
    duration: Option<Duration>,
    /// Record both sets of every domain at every step, by FILE's extension: `.mcap` (one
    /// file, ROS 2 CDR with schemas: Foxglove, ros2 bag) or CSV (one file per domain when
    /// there are several: FILE's stem + '-DOMAIN.csv'). Repeatable.
    #[arg(long, value_name = "FILE")]
    record: Vec<PathBuf>,
    /// When the loop falls behind, run the late steps back to back instead of skipping them:
    /// simulated time stays at one step per period (it then lags the wall clock), so a run's
    /// results do not depend on the machine's load.
    #[arg(long)]
    catch_up: bool,
    /// Longest wait for the participants of a synchronous step, and for a seed.
    #[arg(long, default_value = "1s", value_parser = parse_duration)]
    timeout: Duration,
    /// How the framework waits for participants: block, spin, or poll:DURATION.
    #[arg(long, default_value = "block", value_parser = parse_wait)]
    wait: WaitMode,
    /// Give a PUBLISH item a value: DOMAIN/ITEM=VALUE (repeatable; arrays get it in every element).
    #[arg(long = "set", value_name = "DOMAIN/ITEM=VALUE")]
    sets: Vec<String>,
    /// Hold participants in connect (wait-to-go) for this long after start.
    #[arg(long, value_parser = parse_duration)]
    hold: Option<Duration>,
    /// Before the first step, hold participants in wait-to-go until N writers (participants
    /// that have committed once) are connected to DOMAIN, so that they answer every step
    /// from the first; repeatable.
    #[arg(long = "wait-for", value_name = "DOMAIN=N", value_parser = rt::parse_wait_for)]
    wait_for: Vec<(String, usize)>,
    #[command(flatten)]
    rt: super::RealtimeArgs,
    /// Print no progress lines.
    #[arg(short, long)]
    quiet: bool,
}

// One parser for durations and wait modes across the CLI and the gateway's config file.
pub use tutti_gateway::config::{parse_duration, parse_wait};

/// Applies `--set DOMAIN/ITEM=VALUE` to the PUBLISH buffers.
fn apply_sets(sets: &[String], domains: &[Domain], buffers: &mut [Vec<u8>]) -> Result<(), Failure> {
    for s in sets {
        let (target, value) = s
            .split_once('=')
            .ok_or_else(|| Failure::invalid(anyhow::anyhow!("--set '{s}': expected DOMAIN/ITEM=VALUE")))?;
        let (domain, item) = target
            .split_once('/')
            .ok_or_else(|| Failure::invalid(anyhow::anyhow!("--set '{s}': expected DOMAIN/ITEM=VALUE")))?;
        let idx = domains
            .iter()
            .position(|d| d.name == domain)
            .ok_or_else(|| Failure::invalid(anyhow::anyhow!("--set '{s}': no domain '{domain}' in the DDF")))?;
        let leaf = domains[idx].publish.layout.leaf(item).ok_or_else(|| {
            Failure::invalid(anyhow::anyhow!("--set '{s}': no item '{item}' in the PUBLISH set of domain '{domain}'"))
        })?;
        let v = leaf.ty.parse_value(value).ok_or_else(|| {
            Failure::invalid(anyhow::anyhow!("--set '{s}': '{value}' is not a {} value", leaf.ty.canonical()))
        })?;
        let n = leaf.ty.size() as usize;
        for chunk in buffers[idx][leaf.range()].chunks_exact_mut(n) {
            leaf.ty.encode(v, chunk);
        }
    }
    Ok(())
}

pub fn run(args: Args) -> CliResult {
    let model = load_ddf(&args.file)?;
    if args.step.is_zero() {
        return Err(Failure::invalid(anyhow::anyhow!("--step must be longer than 0")));
    }
    let mut publish: Vec<Vec<u8>> = model.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
    apply_sets(&args.sets, &model.domains, &mut publish)?;
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)).context("installing the signal handler")?;
    }
    for (d, n) in &args.wait_for {
        if model.domain(d).is_none() {
            return Err(Failure::invalid(anyhow::anyhow!(
                "--wait-for {d}={n}: no domain '{d}' in {}",
                args.file.display()
            )));
        }
    }
    let hold = args.hold.is_some() || !args.wait_for.is_empty();
    let opts = FrameworkOptions { timeout: args.timeout, wait: args.wait, hold, ..Default::default() };
    let started = Instant::now();
    let mut fw = Framework::create(&model, &opts).with_context(|| format!("hosting {}", args.file.display()))?;
    let mut recorders = args
        .record
        .iter()
        .map(|path| tutti_record::create(path, &model, &args.file))
        .collect::<Result<Vec<_>, _>>()
        .context("starting the recording")?;
    if !args.quiet {
        eprintln!(
            "host: {} domain(s) of {} created in {:.1} ms (namespace {}), step {:?}",
            fw.domains.len(),
            args.file.display(),
            started.elapsed().as_secs_f64() * 1e3,
            opts.namespace,
            args.step
        );
    }
    if let Some(req) = args.rt.request() {
        if args.quiet {
            rt::enter_realtime(&req);
        } else {
            rt::enter_realtime_verbose("host", &req);
        }
    }
    let unseeded = fw.wait_for_seeds();
    if unseeded > 0 && !args.quiet {
        eprintln!(
            "host: {unseeded} domain(s) with states=yes got no seed within {:?}; they start from their defaults",
            args.timeout
        );
    }
    if !rt::wait_for_writers(&mut fw, &args.wait_for, &stop, "host", args.quiet)? {
        return Ok(());
    }
    if args.hold.is_none() {
        fw.domains.iter().for_each(|d| d.set_hold(false));
    }
    let mut ticker = if args.catch_up { Ticker::catching_up(args.step) } else { Ticker::new(args.step) };
    let run_start = Instant::now();
    let mut last_report = Instant::now();
    let mut held = args.hold.is_some();
    let mut timeouts = 0u64;
    while !stop.load(Ordering::SeqCst) {
        if args.duration.is_some_and(|d| run_start.elapsed() >= d) {
            break;
        }
        let tick = ticker.wait();
        if held && args.hold.is_some_and(|h| run_start.elapsed() >= h) {
            held = false;
            fw.domains.iter().for_each(|d| d.set_hold(false));
        }
        let sim = tick.k as f64 * args.step.as_secs_f64();
        let reports = rt::step_all(&mut fw, &publish, sim, args.step, &tick)?;
        timeouts += reports.iter().filter(|r| r.timed_out > 0).count() as u64;
        if !args.quiet {
            for (d, r) in fw.domains.iter().zip(&reports) {
                if r.timed_out > 0 {
                    eprintln!(
                        "host: step {} of {} timed out after {:?} waiting for {}",
                        r.step,
                        d.info().name,
                        args.timeout,
                        d.timed_out_on().join(", ")
                    );
                }
            }
        }
        rt::record_step(&mut recorders, &fw, &reports, &publish, sim, run_start)?;
        if !args.quiet && last_report.elapsed() >= Duration::from_secs(1) {
            last_report = Instant::now();
            let conns: u32 = fw.domains.iter().map(|d| d.connection_count()).sum();
            eprintln!(
                "host: t={:.1}s step {} participants {} overruns {} late max {:?} step timeouts {}",
                run_start.elapsed().as_secs_f64(),
                tick.k + 1,
                conns,
                ticker.overruns,
                ticker.max_late,
                timeouts
            );
        }
    }
    for rec in recorders {
        rec.finish().context("writing the recording")?;
    }
    if !args.quiet {
        eprintln!(
            "host: stopped after {:.1}s, {} overruns, {} step timeouts",
            run_start.elapsed().as_secs_f64(),
            ticker.overruns,
            timeouts
        );
    }
    Ok(())
}
