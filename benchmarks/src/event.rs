//! `tutti-bench event`: what an event-driven domain (`<synchronous>event</synchronous>`)
//! saves next to its lock-step twin. One participant is due at every step and `--slow`
//! participants every `--every`-th step (`Participant::set_period`); all are threads of this
//! process, each with its own connection, and each loops on `subscribe_lock`, a read of the
//! PUBLISH item, `publish_lock` and a commit of its own SUBSCRIBE item until the framework
//! stops. A `Host` in this process steps the domain as fast as the participants go
//! (`speed: inf`): once event-driven, once in lock-step (where `set_period` changes nothing,
//! so every participant is due at every step), and once event-driven without the every-step
//! participant, where the host jumps over the steps nobody is due at.
//!
//! Per run it prints the steps per second, the CPU time of the whole process (user + system,
//! every thread) per step, and the wall time of each `Host::step` call.

use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{bail, Context as _};
use serde_json::json;
use tutti_core::ddf;
use tutti_core::parse::{parse_duration, parse_wait};
use tutti_core::shm::{ConnectOptions, Participant, ShmError, WaitMode};
use tutti_host::{Host, HostOptions};

use crate::{nearest_rank, CliResult};

/// Steps per second and CPU time of an event-driven domain next to its lock-step twin.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:\n  tutti-bench event\n  tutti-bench event --steps 50000 --rounds 3 --json")]
pub struct Args {
    /// Simulated steps per run.
    #[arg(long, default_value_t = 20_000, value_parser = clap::value_parser!(u64).range(1..))]
    steps: u64,
    /// The framework's step (simulated time).
    #[arg(long, default_value = "1ms", value_parser = parse_duration)]
    step: Duration,
    /// Participants due every `--every`-th step, besides the one due at every step.
    #[arg(long, default_value_t = 20)]
    slow: usize,
    /// The slow participants' period, in steps.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(1..))]
    every: u64,
    /// Rounds of the four runs, one after the other, after a warm-up round that is shown but
    /// not counted (a fresh process's first runs pay for its threads and first page faults).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..))]
    rounds: u32,
    /// Leave out the warm-up round.
    #[arg(long)]
    no_warmup: bool,
    /// How the framework and every participant wait: adaptive (yield up to 50 µs, then block; the default), adaptive:DURATION, block (futex), spin or poll:DURATION.
    #[arg(long, default_value = "adaptive", value_parser = parse_wait)]
    wait: WaitMode,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

/// The ratio of event-driven to lock-step steps per second the benchmark asks for.
const TARGET: f64 = 5.0;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// Event-driven, the every-step participant and the slow ones.
    Event,
    /// The same participants in lock-step.
    LockStep,
    /// Event-driven, the slow participants only: the host jumps over idle steps.
    EventSlowOnly,
    /// Event-driven, the every-step participant only: the floor of the event run, what it
    /// would cost if the slow participants cost nothing at the steps they are not due at.
    EventEveryStepOnly,
}

impl Kind {
    const ALL: [Kind; 4] = [Kind::Event, Kind::LockStep, Kind::EventSlowOnly, Kind::EventEveryStepOnly];

    fn name(self) -> &'static str {
        match self {
            Kind::Event => "event",
            Kind::LockStep => "lock-step",
            Kind::EventSlowOnly => "event, slow only",
            Kind::EventEveryStepOnly => "event, every-step only",
        }
    }

    fn synchronous(self) -> &'static str {
        match self {
            Kind::LockStep => "yes",
            _ => "event",
        }
    }

    fn every_step_participant(self) -> bool {
        self != Kind::EventSlowOnly
    }

    /// The slow participants of this run.
    fn slow(self, args: &Args) -> usize {
        if self == Kind::EventEveryStepOnly {
            0
        } else {
            args.slow
        }
    }
}

/// One run's figures.
struct RunResult {
    kind: Kind,
    round: u32,
    /// Simulated steps (those jumped over included).
    steps: u64,
    /// `Host::step` calls (steps made).
    made: u64,
    wall: Duration,
    cpu: Duration,
    /// Wall time of each `Host::step` call, sorted.
    step_times: Vec<Duration>,
    step_timeouts: u64,
    /// What each participant did (index 0: the every-step one, if any).
    answered: Vec<Answered>,
}

impl RunResult {
    fn steps_per_s(&self) -> f64 {
        self.steps as f64 / self.wall.as_secs_f64()
    }

    fn cpu_per_step_us(&self) -> f64 {
        self.cpu.as_secs_f64() * 1e6 / self.steps as f64
    }

    fn step_us(&self, q: f64) -> f64 {
        if self.step_times.is_empty() {
            return 0.0;
        }
        nearest_rank(&self.step_times, q).as_secs_f64() * 1e6
    }

    /// The mean sleeps of the slow participants' threads per simulated step (1: woken at
    /// every step).
    fn slow_sleeps_per_step(&self) -> Option<f64> {
        let first = usize::from(self.kind.every_step_participant());
        let slow = &self.answered[first.min(self.answered.len())..];
        if slow.is_empty() {
            return None;
        }
        let total: u64 = slow.iter().map(|a| a.sleeps).sum::<Option<u64>>()?;
        Some(total as f64 / slow.len() as f64 / self.steps as f64)
    }

    fn max_step_us(&self) -> f64 {
        self.step_times.last().map_or(0.0, |d| d.as_secs_f64() * 1e6)
    }
}

pub fn run(args: Args) -> CliResult {
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    if !args.json {
        print_header(&args, cpus);
    }
    let results = rounds(&args)?;
    let ratio = steps_per_s(&results, Kind::Event) / steps_per_s(&results, Kind::LockStep);
    let floor = steps_per_s(&results, Kind::EventEveryStepOnly) / steps_per_s(&results, Kind::LockStep);
    if args.json {
        print_json(&args, cpus, &results, ratio, floor)?;
    } else {
        let verdict = if ratio >= TARGET { "ok" } else { "MISSED" };
        println!(
            "event / lock-step steps/s: {ratio:.2} (target >= {TARGET}) {verdict}; CPU per step: event {:.2} µs, lock-step {:.2} µs",
            mean_cpu(&results, Kind::Event),
            mean_cpu(&results, Kind::LockStep)
        );
        println!(
            "the event run's floor (the every-step participant alone) / lock-step steps/s: {floor:.2}; slow wakes: sleeps per slow participant per step (due at 1/{})",
            args.every
        );
    }
    Ok(())
}

/// The table's title and head.
fn print_header(args: &Args, cpus: usize) {
    println!(
        "event-driven vs lock-step: 1 participant due every step + {} due every {} steps (threads of this process), step {:?}, {} steps per run, speed inf, wait {:?}, {} round(s), {cpus} CPUs, unpinned",
        args.slow, args.every, args.step, args.steps, args.wait, args.rounds
    );
    println!(
        "{:<26} {:>7} {:>11} {:>8} {:>11} {:>8} {:>8} {:>8} {:>9} {:>9} {:>11}",
        "run",
        "made",
        "steps/s",
        "wall s",
        "CPU µs/step",
        "p50 µs",
        "p90 µs",
        "p99 µs",
        "max µs",
        "timeouts",
        "slow wakes"
    );
}

/// Every round of the four runs, each checked and (but with `--json`) printed as it ends;
/// returns the counted ones (the warm-up round left out).
fn rounds(args: &Args) -> anyhow::Result<Vec<RunResult>> {
    let mut results = Vec::new();
    let first = if args.no_warmup { 1 } else { 0 };
    for round in first..=args.rounds {
        for kind in Kind::ALL {
            eprintln!("bench event: round {round}: {}", kind.name());
            let r = one_run(args, kind, round)?;
            check_answers(args, &r)?;
            let label =
                if round == 0 { format!("{} (warm-up)", kind.name()) } else { format!("{} #{round}", kind.name()) };
            if !args.json {
                print_row(&label, &r);
            }
            if round > 0 {
                results.push(r);
            }
        }
    }
    Ok(results)
}

/// One run's row of the table.
fn print_row(label: &str, r: &RunResult) {
    println!(
        "{:<26} {:>7} {:>11.0} {:>8.3} {:>11.2} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>9} {:>11}",
        label,
        r.made,
        r.steps_per_s(),
        r.wall.as_secs_f64(),
        r.cpu_per_step_us(),
        r.step_us(0.5),
        r.step_us(0.9),
        r.step_us(0.99),
        r.max_step_us(),
        r.step_timeouts,
        r.slow_sleeps_per_step().map_or("-".into(), |w| format!("{w:.3}"))
    );
}

/// Simulated steps per second of the runs of `kind`, over all rounds.
fn steps_per_s(results: &[RunResult], kind: Kind) -> f64 {
    let (steps, secs) = results
        .iter()
        .filter(|r| r.kind == kind)
        .fold((0u64, 0.0f64), |(s, w), r| (s + r.steps, w + r.wall.as_secs_f64()));
    steps as f64 / secs
}

/// `--json`: the runs and the ratios as one object.
fn print_json(args: &Args, cpus: usize, results: &[RunResult], ratio: f64, floor: f64) -> anyhow::Result<()> {
    let runs: Vec<_> = results
        .iter()
        .map(|r| {
            json!({
                "run": r.kind.name(),
                "round": r.round,
                "steps": r.steps,
                "steps_made": r.made,
                "steps_per_s": r.steps_per_s(),
                "wall_s": r.wall.as_secs_f64(),
                "cpu_s": r.cpu.as_secs_f64(),
                "cpu_us_per_step": r.cpu_per_step_us(),
                "step_us": { "p50": r.step_us(0.5), "p90": r.step_us(0.9), "p99": r.step_us(0.99), "max": r.max_step_us() },
                "step_timeouts": r.step_timeouts,
                "answered": r.answered.iter().map(|a| a.steps).collect::<Vec<_>>(),
                "sleeps": r.answered.iter().map(|a| a.sleeps).collect::<Vec<_>>(),
                "slow_wakes_per_step": r.slow_sleeps_per_step(),
            })
        })
        .collect();
    let out = json!({
        "benchmark": "event",
        "steps": args.steps,
        "step_s": args.step.as_secs_f64(),
        "slow": args.slow,
        "every": args.every,
        "wait": format!("{:?}", args.wait),
        "cpus": cpus,
        "runs": runs,
        "ratio_event_to_lock_step": ratio,
        "ratio_every_step_only_to_lock_step": floor,
        "target": TARGET,
        "ok": ratio >= TARGET,
    });
    println!("{}", serde_json::to_string(&out).context("writing JSON")?);
    Ok(())
}

/// CPU µs per simulated step of the runs of `kind`, over all rounds.
fn mean_cpu(results: &[RunResult], kind: Kind) -> f64 {
    let (cpu, steps) = results
        .iter()
        .filter(|r| r.kind == kind)
        .fold((0.0f64, 0u64), |(c, s), r| (c + r.cpu.as_secs_f64(), s + r.steps));
    cpu * 1e6 / steps as f64
}

/// Each participant answered exactly the steps it is due at: a wrong count is a fault of the
/// framework or the participant, not a figure.
fn check_answers(args: &Args, r: &RunResult) -> anyhow::Result<()> {
    let slow_due = match r.kind {
        Kind::LockStep => args.steps,
        // Due at the steps whose simulated time is a multiple of the period: 0, every, …
        Kind::Event | Kind::EventSlowOnly | Kind::EventEveryStepOnly => args.steps.div_ceil(args.every),
    };
    let first_slow = usize::from(r.kind.every_step_participant());
    let every = r.answered.first().map(|a| a.steps);
    if r.kind.every_step_participant() && every != Some(args.steps) {
        bail!("{} run: the every-step participant answered {every:?} of {} steps", r.kind.name(), args.steps);
    }
    if let Some((i, a)) = r.answered.iter().enumerate().skip(first_slow).find(|(_, a)| a.steps != slow_due) {
        bail!("{} run: slow participant {} answered {} steps, due at {slow_due}", r.kind.name(), i, a.steps);
    }
    if r.step_timeouts > 0 {
        bail!("{} run: {} step(s) timed out", r.kind.name(), r.step_timeouts);
    }
    Ok(())
}

fn model(kind: Kind, outputs: usize) -> anyhow::Result<ddf::Model> {
    let items: String = (0..outputs).map(|i| format!(r#"<item name="y{i}"><type>float64</type></item>"#)).collect();
    let text = format!(
        r#"<orchestra><domain name="ev"><synchronous>{}</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
        <set name="PUBLISH"><item name="x"><type>float64</type></item></set>
        <set name="SUBSCRIBE">{items}</set></domain></orchestra>"#,
        kind.synchronous()
    );
    ddf::parse_str(&text, "event-bench.ddf").context("the benchmark's DDF")
}

/// What one participant did in a run.
#[derive(Debug, Clone, Copy)]
struct Answered {
    /// Steps it answered.
    steps: u64,
    /// Times its thread went to sleep (voluntary context switches) from its first step to the
    /// end of the run: a participant woken at a step it is not due at sleeps again, so this
    /// counts the wake-ups that cost CPU, useful or not.
    sleeps: Option<u64>,
}

/// The voluntary context switches of the calling thread so far (Linux, `/proc`).
fn thread_sleeps() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/thread-self/status").ok()?;
    status.lines().find_map(|l| l.strip_prefix("voluntary_ctxt_switches:")).and_then(|v| v.trim().parse().ok())
}

/// One participant: connects, says its period (if any), and answers every step it is due at
/// until the framework stops.
fn participant(namespace: String, index: usize, period: Option<f64>, wait: WaitMode) -> Result<Answered, ShmError> {
    let opts = ConnectOptions {
        namespace,
        wait,
        name: format!("p{index}"),
        connect_timeout: Duration::from_secs(30),
        timeout: Duration::from_secs(10),
        ..Default::default()
    };
    let mut p = Participant::connect("ev", opts)?;
    if let Some(seconds) = period {
        p.set_period(seconds)?;
    }
    let (x, _) = p.leaf(ddf::Role::Publish, "x")?;
    let (y, _) = p.leaf(ddf::Role::Subscribe, &format!("y{index}"))?;
    let mut answered = 0u64;
    let mut slept_before = None;
    loop {
        match p.subscribe_lock() {
            Ok(_) => {}
            Err(ShmError::FrameworkStopped { .. }) => {
                let sleeps = slept_before.zip(thread_sleeps()).map(|(a, b): (u64, u64)| b.saturating_sub(a));
                return Ok(Answered { steps: answered, sleeps });
            }
            Err(e) => return Err(e),
        }
        if answered == 0 {
            slept_before = thread_sleeps();
        }
        let read = p.snapshot_item(x).and_then(|b| b.try_into().ok()).map_or(0.0, f64::from_ne_bytes);
        p.publish_lock()?;
        p.stage_at(y, &(read + 1.0).to_ne_bytes())?;
        p.commit()?;
        answered += 1;
    }
}

fn one_run(args: &Args, kind: Kind, round: u32) -> anyhow::Result<RunResult> {
    let every_step = kind.every_step_participant();
    let count = kind.slow(args) + usize::from(every_step);
    // Outputs y0 (the every-step participant) and y1..=y{slow}.
    let model = model(kind, args.slow + 1)?;
    let namespace = format!("benchev{}x{round}x{}", std::process::id(), kind as u8);
    let opts = HostOptions {
        step: args.step,
        speed: f64::INFINITY,
        steps: Some(args.steps),
        timeout: Duration::from_secs(5),
        wait: args.wait,
        namespace: Some(namespace.clone()),
        hold_until_start: true,
        connections: vec![tutti_host::connect::parse_connection("ev/subscribe/y0 -> ev/publish/x")
            .context("the benchmark's connection")?],
        ddf_name: "the benchmark's DDF".into(),
        ..Default::default()
    };
    // Dropped on every way out of this function: the segments go with it, and the
    // participants' next call returns "framework stopped".
    let mut host = Host::new(&model, opts).context("creating the domain")?;
    let period = args.step.as_secs_f64() * args.every as f64;
    let first = usize::from(!every_step);
    let threads: Vec<JoinHandle<Result<Answered, ShmError>>> = (first..first + count)
        .map(|i| {
            let ns = namespace.clone();
            let period = (i > 0).then_some(period);
            let wait = args.wait;
            std::thread::spawn(move || participant(ns, i, period, wait))
        })
        .collect();
    let stepped = drive(&mut host, args, count);
    drop(host);
    let mut answered = Vec::with_capacity(threads.len());
    let mut failed = None;
    for (i, t) in threads.into_iter().enumerate() {
        match t.join() {
            Ok(Ok(n)) => answered.push(n),
            Ok(Err(e)) => {
                failed.get_or_insert_with(|| anyhow::Error::new(e).context(format!("participant {}", i + first)));
            }
            Err(_) => {
                failed.get_or_insert_with(|| anyhow::anyhow!("participant {} panicked", i + first));
            }
        }
    }
    let stepped = stepped?;
    if let Some(e) = failed {
        return Err(e);
    }
    Ok(RunResult { kind, round, answered, ..stepped })
}

/// The host's run, as [`crate::drive::drive`] makes it, in this benchmark's figures.
fn drive(host: &mut Host, args: &Args, count: usize) -> anyhow::Result<RunResult> {
    let d = crate::drive::drive(host, args.steps, count, "event")?;
    Ok(RunResult {
        kind: Kind::Event,
        round: 0,
        steps: d.steps,
        made: d.step_times.len() as u64,
        wall: d.wall,
        cpu: d.cpu,
        step_times: d.step_times,
        step_timeouts: d.timeouts,
        answered: Vec::new(),
    })
}
