//! `tutti-bench record`: what recording costs a real-time host. The framework of a DDF steps
//! every domain at a fixed rate (as `tutti host` does, with values that change every step)
//! for `--duration`, without a recording, with `--record run.mcap` and with CSV, in
//! alternating rounds; it prints the step lateness (how late each step woke after its
//! deadline) and overruns of each, and the size of each recording per minute of run.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use tutti_core::ddf::ScalarType;
use tutti_core::shm::{Framework, FrameworkOptions};

use crate::nearest_rank;
use crate::{load_ddf, CliResult};
use tutti_core::parse::parse_duration;
use tutti_host::{step_all, StepDone, Ticker};

/// The host every stepping benchmark runs: a DDF, its period, each run's length.
#[derive(Debug, clap::Args)]
pub struct Stepping {
    /// The DDF whose domains are hosted.
    #[arg(long, value_name = "DDF", default_value = "ddf/multiuav.ddf")]
    pub file: PathBuf,
    /// Step period.
    #[arg(long, default_value = "1ms", value_parser = parse_duration)]
    pub step: Duration,
    /// Length of each run.
    #[arg(long, default_value = "10s", value_parser = parse_duration)]
    pub duration: Duration,
}

/// Step lateness at a fixed rate with and without a recording, and MB per minute.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  cargo run --release -p tutti-bench -- record --duration 20s --rounds 2")]
pub struct Args {
    #[command(flatten)]
    run: Stepping,
    /// Rounds of the three runs (none, MCAP, CSV), interleaved.
    #[arg(long, default_value_t = 2)]
    rounds: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    None,
    Mcap,
    Csv,
}

impl Mode {
    fn name(self) -> &'static str {
        match self {
            Mode::None => "no recording",
            Mode::Mcap => "--record run.mcap",
            Mode::Csv => "--record run.csv",
        }
    }
}

struct RunResult {
    late: Vec<Duration>,
    overruns: u64,
    bytes: u64,
    secs: f64,
}

pub fn run(args: Args) -> CliResult {
    let model = load_ddf(&args.run.file)?;
    let dir = std::env::temp_dir().join(format!("tutti-bench-record-{}", std::process::id()));
    std::fs::create_dir_all(&dir).context("creating a scratch directory")?;
    let items: usize = model.domains.iter().map(|d| d.leaves().count()).sum();
    println!(
        "recording cost: {} ({} domains, {items} items), step {:?}, {:?} per run, {} round(s), interleaved",
        args.run.file.display(),
        model.domains.len(),
        args.run.step,
        args.run.duration,
        args.rounds
    );
    println!(
        "{:<24} {:>12} {:>12} {:>12} {:>9} {:>10}",
        "run", "late p50 µs", "late p99 µs", "late max µs", "overruns", "MB/min"
    );
    let result = (|| -> anyhow::Result<()> {
        for round in 1..=args.rounds {
            for mode in [Mode::None, Mode::Mcap, Mode::Csv] {
                eprintln!("bench record: round {round}: {}", mode.name());
                let r = one_run(&args, &model, mode, &dir, round)?;
                let mut late = r.late;
                late.sort();
                let us = |d: Duration| d.as_secs_f64() * 1e6;
                let mb_min = r.bytes as f64 / 1e6 / (r.secs / 60.0);
                println!(
                    "{:<24} {:>12.1} {:>12.1} {:>12.1} {:>9} {:>10}",
                    format!("{} #{round}", mode.name()),
                    us(nearest_rank(&late, 0.5)),
                    us(nearest_rank(&late, 0.99)),
                    us(late[late.len() - 1]),
                    r.overruns,
                    if mode == Mode::None { "-".to_string() } else { format!("{mb_min:.1}") }
                );
            }
        }
        Ok(())
    })();
    let _ = std::fs::remove_dir_all(&dir);
    result.map_err(Into::into)
}

fn one_run(
    args: &Args,
    model: &tutti_core::ddf::Model,
    mode: Mode,
    dir: &std::path::Path,
    round: u32,
) -> anyhow::Result<RunResult> {
    let opts = FrameworkOptions {
        namespace: format!("benchrec{}x{round}x{}", std::process::id(), mode as u8),
        timeout: Duration::from_millis(50),
        ..Default::default()
    };
    let mut fw = Framework::create(model, &opts).context("creating the domains")?;
    let path = dir.join(match mode {
        Mode::Mcap => "run.mcap",
        _ => "run.csv",
    });
    let mut recorder = match mode {
        Mode::None => None,
        _ => Some(tutti_record::create(&path, model, &args.run.file)?),
    };
    let (late, overruns, secs) =
        step_run(model, &mut fw, args.run.step, args.run.duration, |fw, done| match recorder.as_mut() {
            Some(rec) => tutti_record::record_step(rec.as_mut(), fw, done).context("writing the recording"),
            None => Ok(()),
        })?;
    if let Some(rec) = recorder {
        rec.finish()?;
    }
    let bytes = match mode {
        Mode::None => 0,
        Mode::Mcap => std::fs::metadata(&path).with_context(|| format!("the recording {}", path.display()))?.len(),
        Mode::Csv => std::fs::read_dir(dir)?
            .filter_map(Result::ok)
            .filter(|e| e.file_name().to_string_lossy().ends_with(".csv"))
            .filter_map(|e| e.metadata().ok())
            .map(|m| m.len())
            .sum(),
    };
    for e in std::fs::read_dir(dir)?.filter_map(Result::ok) {
        let _ = std::fs::remove_file(e.path());
    }
    Ok(RunResult { late, overruns, bytes, secs })
}

/// Steps every domain of `fw` at period `step` for `duration`, as `tutti host` does but with
/// float64 PUBLISH values that change every step, as a simulation's would; `after` runs after
/// each step (a recording, or nothing). Returns each step's lateness, the overruns and the
/// seconds run. Shared by the benchmarks that measure what something beside the framework
/// costs it (`bench record`, `bench studio`).
pub(crate) fn step_run(
    model: &tutti_core::ddf::Model,
    fw: &mut Framework,
    step: Duration,
    duration: Duration,
    mut after: impl FnMut(&Framework, &StepDone<'_>) -> anyhow::Result<()>,
) -> anyhow::Result<(Vec<Duration>, u64, f64)> {
    let mut publish: Vec<Vec<u8>> = model.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
    let mut late = Vec::with_capacity((duration.as_secs_f64() / step.as_secs_f64()) as usize + 16);
    let mut ticker = Ticker::new(step);
    let start = Instant::now();
    while start.elapsed() < duration {
        let tick = ticker.wait();
        late.push(tick.late);
        let sim = tick.k as f64 * step.as_secs_f64();
        for (buf, d) in publish.iter_mut().zip(&model.domains) {
            for leaf in d.publish.layout.leaves.iter().filter(|l| l.ty == ScalarType::Float64) {
                for c in buf[leaf.range()].chunks_exact_mut(8) {
                    c.copy_from_slice(&(sim * 1.5 + leaf.offset as f64).to_ne_bytes());
                }
            }
        }
        let reports = step_all(fw, &publish, sim, step, &tick)?;
        after(fw, &StepDone { reports: &reports, publish: &publish, sim, run_start: start })?;
    }
    Ok((late, ticker.overruns, start.elapsed().as_secs_f64()))
}
