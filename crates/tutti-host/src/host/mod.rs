//! [`Host`]: the framework of every domain of a model, stepped at a fixed period.

use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use tutti_core::ddf::{Domain, Model};
use tutti_core::shm::{DomainHost, Framework, FrameworkOptions, StepReport, WaitMode};

use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::connect::{ConnectionSpec, Connections, StepOrder};
use crate::control::{Components, ControlPort, Refusal, Reply, Request, RunState};
use crate::steps::{complete_all, publish_all, wait_for_writers};
use crate::{HostError, Tick, Ticker};

mod checkpoints;

/// What a run is.
#[derive(Debug, Clone)]
pub struct HostOptions {
    /// The simulated time of a step (> 0): step k is made at simulated time k × `step`.
    pub step: Duration,
    /// Simulated seconds per wall-clock second (> 0, default 1): a step is released every
    /// `step / speed` of wall time. Infinite: as fast as the participants go, not paced by
    /// the wall clock; event-driven domains then jump over the steps nobody is due at
    /// (docs/timing.md).
    pub speed: f64,
    /// Stop after this long (None: until stopped).
    pub duration: Option<Duration>,
    /// Stop after this many steps (None: until stopped); with `duration`, whichever comes first.
    pub steps: Option<u64>,
    /// Run late steps back to back instead of skipping them ([`Ticker::catching_up`]).
    pub catch_up: bool,
    /// Longest wait for the participants of a synchronous step, and for a seed.
    pub timeout: Duration,
    /// How the framework waits for participants.
    pub wait: WaitMode,
    /// The namespace of the segments (None: `TUTTI_NAMESPACE`, else the default).
    pub namespace: Option<String>,
    /// PUBLISH values, `DOMAIN/ITEM=VALUE` (arrays get it in every element).
    pub sets: Vec<String>,
    /// Hold participants in connect (wait-to-go) for this long after the start.
    pub hold: Option<Duration>,
    /// Before the first step, hold until each DOMAIN has N writers.
    pub wait_for: Vec<(String, usize)>,
    /// Hold participants in connect (wait-to-go) from the creation of the domains until
    /// [`Host::start`]: a launcher starts its components in between, and all are released
    /// together.
    pub hold_until_start: bool,
    /// Connections in the framework: outputs copied to inputs at every step
    /// ([`crate::connect`]).
    pub connections: Vec<ConnectionSpec>,
    /// How the connections are applied within a step ([`crate::connect`]).
    pub ordering: StepOrder,
    /// The DDF's name, for messages.
    pub ddf_name: String,
    /// Components (by connection name) that keep no state: a checkpoint leaves them out and
    /// says so (a launch file's `stateless: true`).
    pub stateless: Vec<String>,
    /// Save a checkpoint every so many steps (a launch file's `checkpoint:`).
    pub checkpoint: Option<Periodic>,
    /// Start from this checkpoint: put back once the components have connected, before the
    /// first step (`tutti run --restore`).
    pub restore: Option<Box<Checkpoint>>,
    /// Connection slots per domain: how many participants, recorders and gateways one domain
    /// takes at once (default 64, at most 4096; `tutti host --slots`).
    pub slots: u32,
}

/// Checkpoints saved as the run goes (docs/run.md, "Checkpoints").
#[derive(Debug, Clone, PartialEq)]
pub struct Periodic {
    /// Every this many steps (> 0).
    pub every: u64,
    /// Into this directory, as `step-NNNNNNNNN.tutti-checkpoint`.
    pub dir: std::path::PathBuf,
    /// Keeping the newest this many (0: all).
    pub keep: usize,
}

impl Default for HostOptions {
    fn default() -> Self {
        HostOptions {
            step: Duration::from_millis(10),
            speed: 1.0,
            duration: None,
            steps: None,
            catch_up: false,
            timeout: tutti_core::defaults::STEP_TIMEOUT,
            wait: WaitMode::adaptive(),
            namespace: None,
            sets: Vec::new(),
            hold: None,
            wait_for: Vec::new(),
            hold_until_start: false,
            connections: Vec::new(),
            ordering: StepOrder::Delayed,
            ddf_name: "the DDF".into(),
            stateless: Vec::new(),
            checkpoint: None,
            restore: None,
            slots: tutti_core::shm::DEFAULT_CONNECTIONS,
        }
    }
}

/// The step every domain just made, for a [`StepSink`].
#[derive(Debug, Clone, Copy)]
pub struct StepDone<'a> {
    /// What each domain's step did, in model order.
    pub reports: &'a [StepReport],
    /// The PUBLISH set each domain published.
    pub publish: &'a [Vec<u8>],
    /// Simulated time of the step, seconds.
    pub sim: f64,
    /// When the stepping started.
    pub run_start: Instant,
}

/// A step every domain has published and none has completed yet, for
/// [`StepSink::published`]: each domain's step number is its `current_step()`.
#[derive(Debug, Clone, Copy)]
pub struct Published<'a> {
    /// The PUBLISH set each domain published, in model order.
    pub publish: &'a [Vec<u8>],
    /// Simulated time of the step, seconds.
    pub sim: f64,
    /// Another step follows at once (the run is catching up, or making the steps of a
    /// `step N`): a sink may batch this one with it.
    pub more: bool,
}

/// Something that takes every step of a run (a recording: `tutti-record`'s recorders are
/// sinks; the gateway in the framework's process is one too).
pub trait StepSink {
    /// Takes the step every domain of `fw` has just published, before any of them waits
    /// for its participants: a sink that hands the PUBLISH sets on to where an answer to the
    /// step may come from (the gateway's DDS writers) does it here, since in a synchronous
    /// domain the step completes only once it is answered. Does nothing unless overridden.
    fn published(
        &mut self,
        fw: &Framework,
        step: &Published<'_>,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let _ = (fw, step);
        Ok(())
    }
    /// Takes the step `done` of `fw`.
    fn step(&mut self, fw: &Framework, done: &StepDone<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;
    /// The run is over: write what is buffered.
    fn finish(self: Box<Self>) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;
}

/// One domain's step in [`Host::step_domains`].
#[derive(Debug, Clone, Copy)]
pub struct DomainStep<'a> {
    /// The domain's index in the model.
    pub domain: usize,
    /// Its PUBLISH set for the step.
    pub publish: &'a [u8],
    /// Simulated time of the step, seconds.
    pub sim: f64,
}

/// Progress of a run, every second.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    pub elapsed: Duration,
    /// Steps released so far (the ticker's count, skipped deadlines included).
    pub step: u64,
    pub participants: u32,
    pub overruns: u64,
    pub max_late: Duration,
    pub step_timeouts: u64,
}

/// What a run reports while it goes; `Display` is the line a user reads.
#[derive(Debug, Clone)]
pub enum Report {
    /// Synchronous domains with states that got no seed within the timeout.
    Unseeded { domains: usize, timeout: Duration },
    /// Still waiting for writers (every 5 s).
    WaitingForWriters(crate::WriterWait),
    /// Every `wait_for` is met: stepping starts.
    WritersConnected(Vec<(String, usize)>),
    /// A domain's step timed out waiting for these connections.
    StepTimedOut { step: u64, domain: String, timeout: Duration, waiting_for: Vec<String> },
    /// Once a second.
    Progress(Progress),
    /// A periodic checkpoint was written.
    Saved { path: std::path::PathBuf, step: u64 },
    /// A checkpoint could not be taken or written (the run goes on).
    CheckpointFailed(String),
    /// No checkpoint of step 0 could be taken: `ResetSimulation` with `SCOPE_STATE` is not
    /// offered (the reason).
    NoStateReset(String),
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Report::Unseeded { domains, timeout } => write!(
                f,
                "{domains} domain(s) with states=yes got no seed within {timeout:?}; they start from their defaults"
            ),
            Report::WaitingForWriters(w) => write!(
                f,
                "waiting {:.0} s for {} writer(s) in {} ({} so far)",
                w.waited.as_secs_f64(),
                w.want,
                w.domain,
                w.seen
            ),
            Report::WritersConnected(wants) => {
                let list: Vec<String> = wants.iter().map(|(d, n)| format!("{d}={n}")).collect();
                write!(f, "writers connected ({}): stepping", list.join(", "))
            }
            Report::StepTimedOut { step, domain, timeout, waiting_for } => {
                write!(f, "step {step} of {domain} timed out after {timeout:?} waiting for {}", waiting_for.join(", "))
            }
            Report::Saved { path, step } => write!(f, "checkpoint of step {step}: {}", path.display()),
            Report::CheckpointFailed(why) => write!(f, "checkpoint: {why}"),
            Report::NoStateReset(why) => write!(f, "no state reset for this run: {why}"),
            Report::Progress(p) => write!(
                f,
                "t={:.1}s step {} participants {} overruns {} late max {:?} step timeouts {}",
                p.elapsed.as_secs_f64(),
                p.step,
                p.participants,
                p.overruns,
                p.max_late,
                p.step_timeouts
            ),
        }
    }
}

/// How a run ended.
#[derive(Debug, Clone, Copy)]
pub struct Summary {
    /// Whether stepping started (false: stopped while waiting for writers).
    pub started: bool,
    pub elapsed: Duration,
    pub steps: u64,
    pub overruns: u64,
    pub max_late: Duration,
    pub step_timeouts: u64,
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "stopped after {:.1}s, {} overruns, {} step timeouts",
            self.elapsed.as_secs_f64(),
            self.overruns,
            self.step_timeouts
        )
    }
}

/// A framework run: every domain of a model, created on [`Host::new`] (removed when dropped),
/// stepped by [`Host::step`] or [`Host::run`].
pub struct Host {
    fw: Framework,
    publish: Vec<Vec<u8>>,
    opts: HostOptions,
    namespace: String,
    sinks: Vec<Box<dyn StepSink>>,
    ticker: Ticker,
    run_start: Instant,
    held: bool,
    steps: u64,
    step_timeouts: u64,
    /// The control plane, once [`Host::serve_control`] was called.
    control: Option<ControlPort>,
    /// Time spent paused, which a `duration` does not count.
    paused_for: Duration,
    connections: Connections,
    /// The domains a [`StepOrder::Feedthrough`] step re-evaluates, in order (else none).
    reevaluate: Vec<usize>,
    /// The checkpoint of step 0 (`ResetState`), or why there is none; None until the run
    /// starts.
    initial: Option<Result<Checkpoint, CheckpointError>>,
}

impl fmt::Debug for Host {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Host").field("fw", &self.fw).field("opts", &self.opts).field("steps", &self.steps).finish()
    }
}

impl Host {
    /// Checks `opts` against `model` and creates every domain of it.
    pub fn new(model: &Model, opts: HostOptions) -> Result<Host, HostError> {
        if opts.step.is_zero() {
            return Err(HostError::ZeroStep);
        }
        if opts.speed.is_nan()
            || opts.speed <= 0.0
            || (opts.speed.is_finite() && opts.step.div_f64(opts.speed).is_zero())
        {
            return Err(HostError::Speed(opts.speed));
        }
        let mut publish: Vec<Vec<u8>> = model.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
        apply_sets(&opts.sets, &model.domains, &mut publish)?;
        for (d, n) in &opts.wait_for {
            if model.domain(d).is_none() {
                return Err(HostError::WaitForDomain { domain: d.clone(), writers: *n, ddf: opts.ddf_name.clone() });
            }
        }
        let connections = Connections::resolve(model, &opts.connections, &opts.sets)?;
        let mut fw_opts = FrameworkOptions {
            timeout: opts.timeout,
            wait: opts.wait,
            hold: opts.hold.is_some() || !opts.wait_for.is_empty() || opts.hold_until_start,
            connections: opts.slots,
            ..Default::default()
        };
        if let Some(ns) = &opts.namespace {
            fw_opts.namespace = ns.clone();
        }
        let fw = Framework::create(model, &fw_opts)
            .map_err(|source| HostError::Create { ddf: opts.ddf_name.clone(), source })?;
        for d in &fw.domains {
            // Known from the start: an event-driven participant turns the times it asks for
            // into steps with it.
            d.set_sim_step(opts.step.as_secs_f64());
        }
        let ticker = new_ticker(&opts);
        let reevaluate = match opts.ordering {
            StepOrder::Delayed => Vec::new(),
            StepOrder::Feedthrough => connections.reevaluation_order(|i| model.domains[i].flags.synchronous),
        };
        Ok(Host {
            fw,
            publish,
            namespace: fw_opts.namespace,
            held: opts.hold.is_some(),
            opts,
            sinks: Vec::new(),
            ticker,
            run_start: Instant::now(),
            steps: 0,
            step_timeouts: 0,
            control: None,
            paused_for: Duration::ZERO,
            connections,
            reevaluate,
            initial: None,
        })
    }

    /// Checks `DOMAIN/ITEM=VALUE` settings (as [`HostOptions::sets`] takes them) against
    /// `model` without creating anything: a launcher refuses a bad one before it starts.
    pub fn check_sets(model: &Model, sets: &[String]) -> Result<(), HostError> {
        let mut publish: Vec<Vec<u8>> = model.domains.iter().map(|d| d.publish.layout.default_bytes()).collect();
        apply_sets(sets, &model.domains, &mut publish)
    }

    /// The framework: its domains, their connections and sets.
    pub fn framework(&self) -> &Framework {
        &self.fw
    }

    /// The namespace of the segments.
    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    /// Adds a sink that takes every step from now on.
    pub fn add_sink(&mut self, sink: Box<dyn StepSink>) {
        self.sinks.push(sink);
    }

    /// Serves this run's control plane (`tutti ctl`) from now on, on the namespace's control
    /// socket ([`crate::control::socket_path`]); `stop` is the flag the run stops on, which
    /// a `stop` command raises. `components` answers the commands on the components of a
    /// launched run. The socket is removed with the host.
    pub fn serve_control(
        &mut self,
        stop: Arc<AtomicBool>,
        components: Option<Arc<dyn Components>>,
    ) -> Result<(), HostError> {
        let port = ControlPort::serve(&self.namespace, stop, components)?;
        port.shared.set_speed(self.opts.speed, self.opts.end_time());
        self.control = Some(port);
        Ok(())
    }

    /// The run's state now.
    pub fn state(&self) -> RunState {
        self.control.as_ref().map_or(RunState::Ready, |c| c.shared.state())
    }

    fn publish_state(&self, state: RunState, sim: f64) {
        if let Some(c) = &self.control {
            c.shared.set(state, self.ticker.next_k(), sim);
        }
    }

    /// Waits for the writers, lets the participants go, waits for their seeds, and starts
    /// the clock. Returns false when `stop` was set while waiting.
    ///
    /// The seeds come after the release: a participant held in connect cannot commit its
    /// seed, so waiting for it first would only spend the timeout.
    pub fn start(&mut self, stop: &AtomicBool, on_report: &mut dyn FnMut(Report)) -> Result<bool, HostError> {
        let wants = self.opts.wait_for.clone();
        let waited = wait_for_writers(&mut self.fw, &wants, stop, |w| on_report(Report::WaitingForWriters(w.clone())))?;
        if !waited {
            return Ok(false);
        }
        if !wants.is_empty() {
            on_report(Report::WritersConnected(wants));
        }
        if self.opts.hold.is_none() {
            self.fw.domains.iter().for_each(|d| d.set_hold(false));
        }
        let unseeded = self.fw.wait_for_seeds();
        if unseeded > 0 {
            on_report(Report::Unseeded { domains: unseeded, timeout: self.opts.timeout });
        }
        if !self.connections.is_empty() {
            // The initial exchange: the outputs as they stand before the first step (the
            // seeds, else the DDF's defaults) are the inputs of the first step.
            for d in &mut self.fw.domains {
                let domain = d.info().name.clone();
                d.read_subscribe().map_err(|source| HostError::Domain { domain, source })?;
            }
            let domains = &self.fw.domains;
            self.connections.apply(|i| domains.get(i).map(|d| d.subscribe()), &mut self.publish);
        }
        self.ticker = new_ticker(&self.opts);
        self.take_initial(on_report);
        if let Some(c) = self.opts.restore.take() {
            self.restore(&c).map_err(HostError::Checkpoint)?;
        }
        self.run_start = Instant::now();
        self.publish_state(RunState::Playing, self.last_sim());
        Ok(true)
    }

    /// Waits for the next deadline and makes one step of every domain; its sinks take it.
    pub fn step(&mut self, on_report: &mut dyn FnMut(Report)) -> Result<Tick, HostError> {
        self.skip_idle_steps();
        let tick = self.ticker.wait();
        // Released a whole period late: the next deadline is already due.
        let more = tick.late >= self.opts.period();
        self.make_step(tick, more, on_report)?;
        Ok(tick)
    }

    /// Discrete-event advance: in a run not paced by the wall clock, leaves out the next
    /// steps when nobody in any domain would be due at them (event-driven domains whose
    /// participants are due later and whose inputs do not change), so that the next step made
    /// is the next one somebody is due at. Its simulated time shows the jump.
    fn skip_idle_steps(&mut self) {
        if self.opts.speed.is_finite() || self.connections.has_clock() {
            return;
        }
        if !self.fw.domains.iter().any(|d| d.info().flags.event) {
            return;
        }
        let next = self.ticker.next_k();
        let mut idle: Option<u64> = None;
        for (d, publish) in self.fw.domains.iter().zip(&self.publish) {
            if let Some(n) = d.idle_steps(publish, next) {
                idle = Some(idle.map_or(n, |m| m.min(n)));
            }
        }
        // Nobody due at all (or only when an input changes, which nothing makes happen):
        // step as usual.
        let Some(mut n) = idle.filter(|&n| n > 0) else { return };
        if let Some(limit) = self.opts.steps {
            n = n.min(limit.saturating_sub(self.steps + 1));
        }
        if n == 0 {
            return;
        }
        // The steps' simulated time (the ticker's index) jumps; their numbers go on by one.
        self.ticker.skip(n);
        self.steps += n;
    }

    /// The period the domains are told: the wall-clock period, or the step when the run is
    /// not paced by the wall clock (a participant sizes its step by it: tutti fmu run).
    fn told_period(&self) -> Duration {
        if self.opts.speed.is_finite() {
            self.opts.period()
        } else {
            self.opts.step
        }
    }

    /// Makes the step of `tick`: every domain, then the sinks.
    fn make_step(&mut self, tick: Tick, more: bool, on_report: &mut dyn FnMut(Report)) -> Result<(), HostError> {
        if self.held && self.opts.hold.is_some_and(|h| self.run_start.elapsed() >= h) {
            self.held = false;
            self.fw.domains.iter().for_each(|d| d.set_hold(false));
        }
        let sim = tick.k as f64 * self.opts.step.as_secs_f64();
        // `@sim_time` connections: the time of the step they are published in.
        self.connections.apply_clock(sim, &mut self.publish);
        let period = self.told_period();
        publish_all(&mut self.fw, &self.publish, sim, period)?;
        let published = Published { publish: &self.publish, sim, more };
        for sink in &mut self.sinks {
            sink.published(&self.fw, &published)
                .map_err(|source| HostError::Sink { what: "handing the published step on", source })?;
        }
        let reports = complete_all(&mut self.fw, period, &tick)?;
        self.steps += 1;
        for (i, r) in reports.iter().enumerate() {
            self.count_timeout(i, r, on_report);
        }
        self.reevaluate(sim, on_report)?;
        let done = StepDone { reports: &reports, publish: &self.publish, sim, run_start: self.run_start };
        for sink in &mut self.sinks {
            sink.step(&self.fw, &done).map_err(|source| HostError::Sink { what: "writing the recording", source })?;
        }
        if !self.connections.is_empty() {
            // The outputs of this step are the inputs of the next.
            let domains = &self.fw.domains;
            self.connections.apply(|i| domains.get(i).map(|d| d.subscribe()), &mut self.publish);
        }
        if let Some(c) = &self.control {
            c.shared.set(c.shared.state(), tick.k + 1, sim);
        }
        Ok(())
    }

    /// [`StepOrder::Feedthrough`]: after the step's answers, each fed domain in graph order
    /// gets its inputs from the outputs as they now stand and is published again with the
    /// step's simulated time (a repeated step: its participants answer without advancing),
    /// so that its new outputs reach the domains after it within the step.
    fn reevaluate(&mut self, sim: f64, on_report: &mut dyn FnMut(Report)) -> Result<(), HostError> {
        for k in 0..self.reevaluate.len() {
            let d = self.reevaluate[k];
            let domains = &self.fw.domains;
            self.connections.apply(|i| domains.get(i).map(|x| x.subscribe()), &mut self.publish);
            let host = &mut self.fw.domains[d];
            let report = host
                .step(&self.publish[d], sim)
                .map_err(|source| HostError::Domain { domain: host.info().name.clone(), source })?;
            self.count_timeout(d, &report, on_report);
        }
        Ok(())
    }

    /// Makes one step of the domains in `steps` now, each with its own PUBLISH set and
    /// simulated time, the caller keeping the pace (a replay follows its recording's):
    /// publishes to all, then completes all, so their participants work in parallel. Returns
    /// each domain's report in the order of `steps`. Step timeouts are reported and counted
    /// as in [`Host::step`]; the sinks, which take steps of every domain, are not given these.
    pub fn step_domains(
        &mut self,
        steps: &[DomainStep<'_>],
        on_report: &mut dyn FnMut(Report),
    ) -> Result<Vec<StepReport>, HostError> {
        let failed = |host: &DomainHost| {
            let domain = host.info().name.clone();
            move |source| HostError::Domain { domain, source }
        };
        for s in steps {
            let host = self.fw.domains.get_mut(s.domain).ok_or(HostError::NoDomain { index: s.domain })?;
            let on_error = failed(host);
            host.publish_step(s.publish, s.sim).map_err(on_error)?;
        }
        let mut reports = Vec::with_capacity(steps.len());
        for s in steps {
            let host = &mut self.fw.domains[s.domain];
            let on_error = failed(host);
            let report = host.complete_step().map_err(on_error)?;
            self.count_timeout(s.domain, &report, on_report);
            reports.push(report);
        }
        self.steps += 1;
        Ok(reports)
    }

    /// Counts and reports domain `i`'s step if it timed out.
    fn count_timeout(&mut self, i: usize, r: &StepReport, on_report: &mut dyn FnMut(Report)) {
        if r.timed_out == 0 {
            return;
        }
        self.step_timeouts += 1;
        let d = &self.fw.domains[i];
        on_report(Report::StepTimedOut {
            step: r.step,
            domain: d.info().name.clone(),
            timeout: self.opts.timeout,
            waiting_for: d.timed_out_on().to_vec(),
        });
    }

    /// Steps whose participants did not all answer within the timeout, so far.
    pub fn step_timeouts(&self) -> u64 {
        self.step_timeouts
    }

    /// How the run stands now.
    pub fn progress(&self, step: u64) -> Progress {
        Progress {
            elapsed: self.run_start.elapsed(),
            step,
            participants: self.fw.domains.iter().map(|d| d.connection_count()).sum(),
            overruns: self.ticker.overruns,
            max_late: self.ticker.max_late,
            step_timeouts: self.step_timeouts,
        }
    }

    /// The whole run: [`Host::start`], then steps until `stop` is set or the duration is
    /// over, with a [`Report::Progress`] every second; the sinks are finished at the end.
    pub fn run(mut self, stop: &AtomicBool, on_report: impl FnMut(Report)) -> Result<Summary, HostError> {
        self.run_and_keep(stop, on_report)
    }

    /// [`Host::run`], keeping the domains afterwards (they go when the host is dropped): a
    /// launcher stops its components first, while the domains they are connected to remain.
    pub fn run_and_keep(&mut self, stop: &AtomicBool, mut on_report: impl FnMut(Report)) -> Result<Summary, HostError> {
        let started = self.start(stop, &mut on_report)?;
        let mut last_report = Instant::now();
        while started && !stop.load(Ordering::SeqCst) {
            if self.opts.duration.is_some_and(|d| self.run_start.elapsed().saturating_sub(self.paused_for) >= d)
                || self.opts.steps.is_some_and(|n| self.steps >= n)
            {
                break;
            }
            self.take_commands(stop, &mut on_report)?;
            if stop.load(Ordering::SeqCst) {
                break;
            }
            let tick = self.step(&mut on_report)?;
            self.periodic_checkpoint(&mut on_report);
            if last_report.elapsed() >= Duration::from_secs(1) {
                last_report = Instant::now();
                on_report(Report::Progress(self.progress(tick.k + 1)));
            }
        }
        let summary = Summary {
            started,
            elapsed: self.run_start.elapsed(),
            steps: self.steps,
            overruns: self.ticker.overruns,
            max_late: self.ticker.max_late,
            step_timeouts: self.step_timeouts,
        };
        self.publish_state(RunState::Stopped, self.ticker.next_k() as f64 * self.opts.step.as_secs_f64());
        for sink in std::mem::take(&mut self.sinks) {
            sink.finish().map_err(|source| HostError::Sink { what: "writing the recording", source })?;
        }
        Ok(summary)
    }

    /// Carries out the commands that came since the last step; a pause holds here until
    /// resumed or stopped.
    fn take_commands(&mut self, stop: &AtomicBool, on_report: &mut dyn FnMut(Report)) -> Result<(), HostError> {
        loop {
            let Some(c) = &self.control else { return Ok(()) };
            let Ok(cmd) = c.commands.try_recv() else { return Ok(()) };
            match cmd.request {
                Request::Pause => self.pause(cmd.reply, stop, on_report)?,
                Request::Reset => {
                    self.reset(RunState::Playing);
                    let _ = cmd.reply.send(Ok(()));
                }
                Request::Step { .. } => {
                    let _ = cmd.reply.send(Err(Refusal("step: the run is playing; pause it first".into())));
                }
                Request::Speed { factor } => {
                    let _ = cmd.reply.send(self.set_speed(factor));
                }
                Request::Seek { .. } => {
                    let _ = cmd.reply.send(Err(no_seek()));
                }
                // Between two steps is a step boundary: the run goes on playing afterwards.
                ref r @ (Request::Save { .. } | Request::Restore { .. } | Request::ResetState) => {
                    let _ = cmd.reply.send(self.checkpoint_command(r));
                }
                _ => {
                    let _ = cmd.reply.send(Ok(()));
                }
            }
        }
    }

    /// Holds every domain at this step boundary until resumed or stopped, making the steps
    /// asked for meanwhile.
    /// `reply` is answered once paused; a resume is answered once playing again.
    fn pause(&mut self, reply: Reply, stop: &AtomicBool, on_report: &mut dyn FnMut(Report)) -> Result<(), HostError> {
        let since = Instant::now();
        self.fw.domains.iter().for_each(|d| d.set_paused(true));
        self.publish_state(RunState::Paused, self.last_sim());
        let _ = reply.send(Ok(()));
        let result = self.paused(stop, on_report);
        self.fw.domains.iter().for_each(|d| d.set_paused(false));
        self.ticker.restart_at(self.ticker.next_k());
        self.paused_for += since.elapsed();
        if !stop.load(Ordering::SeqCst) {
            self.publish_state(RunState::Playing, self.last_sim());
        }
        let resumed = result?;
        if let Some(reply) = resumed {
            let _ = reply.send(Ok(()));
        }
        Ok(())
    }

    /// Serves the commands of a pause until a resume (returned, to be answered once playing)
    /// or a stop.
    fn paused(&mut self, stop: &AtomicBool, on_report: &mut dyn FnMut(Report)) -> Result<Option<Reply>, HostError> {
        while !stop.load(Ordering::SeqCst) {
            let Some(c) = &self.control else { return Ok(None) };
            let Ok(cmd) = c.commands.recv_timeout(Duration::from_millis(50)) else { continue };
            let done = match cmd.request {
                Request::Resume => return Ok(Some(cmd.reply)),
                Request::Step { n } => self.steps_while_paused(n, on_report),
                Request::Speed { factor } => Ok(self.set_speed(factor)),
                Request::Seek { .. } => Ok(Err(no_seek())),
                Request::Reset => {
                    self.reset(RunState::Paused);
                    Ok(Ok(()))
                }
                ref r @ (Request::Save { .. } | Request::Restore { .. } | Request::ResetState) => {
                    Ok(self.checkpoint_command(r))
                }
                _ => Ok(Ok(())),
            };
            match done {
                Ok(answer) => {
                    let _ = cmd.reply.send(answer);
                }
                Err(e) => {
                    let _ = cmd.reply.send(Err(Refusal(format!("the step failed: {e}"))));
                    return Err(e);
                }
            }
        }
        Ok(None)
    }

    /// `step n` while paused: exactly `n` steps, one after the other, then paused again.
    fn steps_while_paused(
        &mut self,
        n: u64,
        on_report: &mut dyn FnMut(Report),
    ) -> Result<Result<(), Refusal>, HostError> {
        if let Some(refusal) = self.step_refusal() {
            return Ok(Err(refusal));
        }
        for i in 0..n {
            let tick = self.ticker.release_now();
            self.make_step(tick, i + 1 < n, on_report)?;
        }
        Ok(Ok(()))
    }

    /// Why `step` cannot apply to this run, if it cannot.
    fn step_refusal(&self) -> Option<Refusal> {
        let domains = &self.fw.domains;
        if domains.iter().any(|d| d.info().flags.synchronous) {
            return None;
        }
        let names: Vec<&str> = domains.iter().map(|d| d.info().name.as_str()).collect();
        Some(Refusal(format!(
            "step: every domain of this run is asynchronous ({}): their participants do not step with the framework, so there is no step to count; use resume and pause",
            names.join(", ")
        )))
    }

    /// For a loop of its own that steps this host (a replay, through
    /// [`step_domains`](Self::step_domains)): answers the control plane's commands that came,
    /// each with `answer`; how many there were.
    /// The answer is sent once `answer` returns, so what it says of the run
    /// ([`set_run_state`](Self::set_run_state)) is what the next `state` reads.
    pub fn take_requests(&self, mut answer: impl FnMut(&Request, &Host) -> Result<(), Refusal>) -> usize {
        let Some(c) = &self.control else { return 0 };
        let mut n = 0;
        while let Ok(cmd) = c.commands.try_recv() {
            let _ = cmd.reply.send(answer(&cmd.request, self));
            n += 1;
        }
        n
    }

    /// For a loop of its own: says the run's state and simulated time to the control plane.
    pub fn set_run_state(&self, state: RunState, sim: f64) {
        self.publish_state(state, sim);
    }

    /// For a replay: the control plane says the run can seek, ends at `end_time` (simulated
    /// seconds) and plays at `speed`.
    pub fn set_playback(&self, speed: f64, end_time: f64) {
        if let Some(c) = &self.control {
            c.shared.set_speed(speed, Some(end_time));
            c.shared.seekable.store(true, Ordering::Relaxed);
        }
    }

    /// Steps at `factor` times real time from the next step on (the deadlines start again
    /// from now, as after a pause).
    fn set_speed(&mut self, factor: f64) -> Result<(), Refusal> {
        if !(factor.is_finite() && factor > 0.0) || self.opts.step.div_f64(factor).is_zero() {
            return Err(Refusal(format!(
                "speed {factor}: a factor above 0 (1 = real time, 2 = twice as fast) whose period is not zero"
            )));
        }
        if !self.opts.speed.is_finite() {
            return Err(Refusal("speed: this run is not paced by the wall clock (it steps as fast as it can)".into()));
        }
        self.opts.speed = factor;
        let mut ticker = new_ticker(&self.opts);
        ticker.overruns = self.ticker.overruns;
        ticker.max_late = self.ticker.max_late;
        ticker.restart_at(self.ticker.next_k());
        self.ticker = ticker;
        if let Some(c) = &self.control {
            c.shared.set_speed(factor, self.opts.end_time());
        }
        Ok(())
    }

    /// Step count and simulated time back to zero; the run stays in `state`.
    fn reset(&mut self, state: RunState) {
        self.ticker.restart_at(0);
        // Event-driven participants: each says anew, at the first step of the new time,
        // when it is next due.
        self.fw.domains.iter().for_each(|d| {
            d.all_due_next();
            // A clock that follows a domain says 0 at once, even while the run stays paused.
            d.reset_time(0.0);
        });
        self.publish_state(state, 0.0);
    }

    /// Simulated time of the last step made.
    fn last_sim(&self) -> f64 {
        self.ticker.next_k().saturating_sub(1) as f64 * self.opts.step.as_secs_f64()
    }
}

/// Why a live run refuses `seek`.
fn no_seek() -> Refusal {
    Refusal("seek: a live run cannot go to another time (a recording can: tutti replay)".into())
}

impl HostOptions {
    /// The simulated time the run ends at, when it has an end: after `steps`, or after
    /// `duration` of wall time at `speed`, whichever comes first.
    pub fn end_time(&self) -> Option<f64> {
        let by_steps = self.steps.map(|n| n as f64 * self.step.as_secs_f64());
        let by_time = self.duration.filter(|_| self.speed.is_finite()).map(|d| d.as_secs_f64() * self.speed);
        match (by_steps, by_time) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The wall-clock period of a step: `step / speed`.
    pub fn period(&self) -> Duration {
        if self.speed.is_infinite() {
            return Duration::ZERO;
        }
        self.step.div_f64(self.speed)
    }
}

fn new_ticker(opts: &HostOptions) -> Ticker {
    if opts.catch_up {
        Ticker::catching_up(opts.period())
    } else {
        Ticker::new(opts.period())
    }
}

/// Applies `DOMAIN/ITEM=VALUE` settings to the PUBLISH buffers.
fn apply_sets(sets: &[String], domains: &[Domain], buffers: &mut [Vec<u8>]) -> Result<(), HostError> {
    for s in sets {
        let invalid = |reason: String| HostError::Set { set: s.clone(), reason };
        let form = || invalid("expected DOMAIN/ITEM=VALUE".into());
        let (target, value) = s.split_once('=').ok_or_else(form)?;
        let (domain, item) = target.split_once('/').ok_or_else(form)?;
        let idx = domains
            .iter()
            .position(|d| d.name == domain)
            .ok_or_else(|| invalid(format!("no domain '{domain}' in the DDF")))?;
        let leaf = domains[idx]
            .publish
            .layout
            .leaf(item)
            .ok_or_else(|| invalid(format!("no item '{item}' in the PUBLISH set of domain '{domain}'")))?;
        let v = leaf
            .ty
            .parse_value(value)
            .ok_or_else(|| invalid(format!("'{value}' is not a {} value", leaf.ty.canonical())))?;
        let n = leaf.ty.size() as usize;
        for chunk in buffers[idx][leaf.range()].chunks_exact_mut(n) {
            leaf.ty.encode(v, chunk);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use tutti_test_support::wait_until;

    /// The probe's DDF: one asynchronous domain, an int32 out and a float64 in.
    fn probe_ddf() -> String {
        tutti_test_support::ddf::one_domain("probe").publish("tick", "int32").subscribe("value", "float64").text()
    }

    /// Counts the steps it is given, published and done, and keeps the last PUBLISH set.
    struct Count(std::rc::Rc<std::cell::RefCell<(u64, Vec<u8>, u64)>>);

    impl StepSink for Count {
        fn published(
            &mut self,
            fw: &Framework,
            p: &Published<'_>,
        ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            let mut c = self.0.borrow_mut();
            // Published and not yet taken as a done step.
            assert_eq!(fw.domains[0].current_step(), c.0 + 1);
            assert_eq!(p.publish.len(), 1);
            c.2 += 1;
            Ok(())
        }
        fn step(&mut self, _: &Framework, done: &StepDone<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            let mut c = self.0.borrow_mut();
            c.0 += 1;
            c.1 = done.publish[0].clone();
            Ok(())
        }
        fn finish(self: Box<Self>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            Ok(())
        }
    }

    fn options(ns: &str) -> HostOptions {
        HostOptions {
            step: Duration::from_millis(1),
            duration: Some(Duration::from_millis(30)),
            namespace: Some(ns.into()),
            sets: vec!["probe/tick=7".into()],
            ..HostOptions::default()
        }
    }

    #[test]
    fn a_host_is_a_value_driven_in_process_and_its_sinks_see_every_step() {
        let model = tutti_core::ddf::parse_str(&probe_ddf(), "probe.ddf").unwrap();
        let ns = format!("hostlib{}", std::process::id());
        let mut host = Host::new(&model, options(&ns)).unwrap();
        assert_eq!(host.namespace(), ns);
        assert_eq!(host.framework().domains.len(), 1);
        let seen = std::rc::Rc::new(std::cell::RefCell::new((0, Vec::new(), 0)));
        host.add_sink(Box::new(Count(seen.clone())));
        let stop = AtomicBool::new(false);
        let summary = host.run(&stop, |_| {}).unwrap();
        assert!(summary.started);
        assert!(summary.steps > 0);
        let (steps, publish, published) = seen.borrow().clone();
        assert_eq!(steps, summary.steps, "the sink took every step");
        assert_eq!(published, summary.steps, "and each one first as published");
        assert_eq!(publish, 7i32.to_ne_bytes(), "--set reached the PUBLISH set");
    }

    #[test]
    fn held_until_start_participants_wait_to_go_until_the_host_starts() {
        let model = tutti_core::ddf::parse_str(&probe_ddf(), "probe.ddf").unwrap();
        let ns = format!("hostlibh{}", std::process::id());
        let mut host = Host::new(&model, HostOptions { hold_until_start: true, ..options(&ns) }).unwrap();
        let seg = tutti_core::shm::Segment::open(&ns, "probe").unwrap();
        assert!(seg.status().waiting_to_go, "held from the creation of the domain");
        assert!(host.start(&AtomicBool::new(false), &mut |_| {}).unwrap());
        assert!(!seg.status().waiting_to_go, "released by the start");
    }

    #[test]
    fn settings_are_checked_without_creating_anything() {
        let model = tutti_core::ddf::parse_str(&probe_ddf(), "probe.ddf").unwrap();
        assert!(Host::check_sets(&model, &["probe/tick=3".into()]).is_ok());
        let e = Host::check_sets(&model, &["probe/tick=x".into()]).unwrap_err();
        assert!(e.is_invalid() && e.to_string().contains("'x' is not a int32"), "{e}");
    }

    #[test]
    fn a_run_with_a_step_limit_makes_exactly_that_many_steps() {
        let model = tutti_core::ddf::parse_str(&probe_ddf(), "probe.ddf").unwrap();
        let ns = format!("hostlibn{}", std::process::id());
        let opts = HostOptions { duration: None, steps: Some(25), ..options(&ns) };
        let host = Host::new(&model, opts).unwrap();
        let mut host = host;
        let summary = host.run_and_keep(&AtomicBool::new(false), |_| {}).unwrap();
        assert_eq!(summary.steps, 25);
        assert_eq!(tutti_core::shm::Segment::open(&ns, "probe").unwrap().status().step, 25, "kept after the run");
        drop(host);
        let seg = tutti_core::shm::Segment::open(&ns, "probe");
        assert!(seg.is_err(), "the domain is removed with the host");
    }

    #[test]
    fn a_checkpoint_puts_the_run_back_and_refuses_a_domain_with_a_lookahead() {
        use tutti_core::shm::{ConnKind, ConnectOptions, LinkInfo, Participant};
        let model = tutti_core::ddf::parse_str(&probe_ddf(), "probe.ddf").unwrap();
        let ns = format!("hostlibc{}", std::process::id());
        let mut host = Host::new(&model, HostOptions { duration: None, steps: Some(5), ..options(&ns) }).unwrap();
        host.run_and_keep(&AtomicBool::new(false), |_| {}).unwrap();
        let c = host.checkpoint(false).unwrap();
        // Late steps are skipped: the index may be ahead of the count.
        assert!(c.next_index >= 5 && (c.steps, c.components.len()) == (5, 0), "{c:?}");
        assert_eq!(c.domains[0].publish, 7i32.to_ne_bytes(), "the --set value");
        host.publish[0] = 9i32.to_ne_bytes().to_vec();
        host.restore(&c).unwrap();
        assert_eq!(
            (host.publish[0].as_slice(), host.ticker.next_k(), host.steps),
            (&7i32.to_ne_bytes()[..], c.next_index, 5)
        );
        let other = tutti_core::ddf::parse_str(&probe_ddf().replace("tick", "tock"), "other.ddf").unwrap();
        let e = c.check_model(&other, "c").unwrap_err();
        assert!(e.is_invalid() && e.to_string().contains("another DDF"), "{e}");

        // A remote writer across a link with a lookahead that keeps no state of the link (a
        // gateway older than this one keeps none): its answers on their way would be missing.
        let opts = ConnectOptions {
            namespace: ns.clone(),
            kind: ConnKind::Remote,
            skip_wait_to_go: true,
            ..ConnectOptions::default()
        };
        let remote = Participant::connect("probe", opts).unwrap();
        remote.set_link(&LinkInfo { lookahead: 4, ..LinkInfo::default() });
        let e = host.checkpoint(false).unwrap_err();
        assert!(e.to_string().contains("lookahead of 4 steps"), "{e}");
        drop(remote);
    }

    /// An event-driven participant due every 7 steps: a checkpoint keeps when it is next due,
    /// and after a restore the run makes the steps it made after the checkpoint again, no
    /// others (without the due index, the participant would be due where it last said, ahead).
    #[test]
    fn a_restore_puts_back_when_each_event_driven_connection_is_next_due() {
        use tutti_core::shm::{ConnectOptions, Participant, ShmError};
        let model = tutti_core::ddf::parse_str(
            r#"<orchestra><domain name="ev"><synchronous>event</synchronous>
            <set name="PUBLISH"><item name="x"><type>float64</type></item></set>
            <set name="SUBSCRIBE"><item name="a"><type>float64</type></item></set>
            </domain></orchestra>"#,
            "event.ddf",
        )
        .unwrap();
        let ns = format!("hostlibev{}", std::process::id());
        let opts = HostOptions {
            speed: f64::INFINITY,
            duration: None,
            sets: Vec::new(),
            timeout: Duration::from_secs(20),
            ..options(&ns)
        };
        let mut host = Host::new(&model, opts).unwrap();
        let copts = ConnectOptions { namespace: ns.clone(), name: "b".into(), ..ConnectOptions::default() };
        let mut p = Participant::connect("ev", copts).unwrap();
        let b = std::thread::spawn(move || {
            let mut seen = Vec::new();
            loop {
                p.request_time(p.simulation_time() + 0.007).unwrap();
                match p.subscribe_lock() {
                    Ok(_) => seen.push((p.simulation_time() * 1000.0).round() as u64),
                    Err(ShmError::FrameworkStopped { .. }) => return seen,
                    Err(e) => panic!("{e}"),
                }
            }
        });
        assert!(host.start(&AtomicBool::new(false), &mut |_| {}).unwrap());
        let mut made = Vec::new();
        let step = |host: &mut Host, made: &mut Vec<u64>| made.push(host.step(&mut |_| {}).unwrap().k);
        while made.last().is_none_or(|&k| k < 20) {
            step(&mut host, &mut made);
        }
        let c = host.checkpoint(true).unwrap();
        assert_eq!(c.skipped.len(), 1, "b keeps no state: {c:?}");
        let due = c.domains[0].due.clone();
        assert_eq!(due.len(), 1, "{due:?}");
        let before = made.len();
        while made.last().is_some_and(|&k| k < 60) {
            step(&mut host, &mut made);
        }
        host.restore(&c).unwrap();
        let after = made.len();
        for _ in 0..4 {
            step(&mut host, &mut made);
        }
        drop(host);
        let seen = b.join().unwrap();
        assert!(made[..before].iter().all(|k| k % 7 == 0), "due every 7 steps: {made:?}");
        let again: Vec<u64> = made[before..].iter().copied().take(4).collect();
        assert_eq!(&made[after..], &again[..], "after the restore, the steps made after the checkpoint again");
        assert_eq!(again[0], due[0].1, "the first of them is where the checkpoint said b is due");
        assert!(seen.windows(2).filter(|w| w[1] < w[0]).count() == 1, "b went back once: {seen:?}");
    }

    #[test]
    fn a_caller_paced_step_publishes_its_own_set_and_time_and_is_counted() {
        let model = tutti_core::ddf::parse_str(&probe_ddf(), "probe.ddf").unwrap();
        let ns = format!("hostlibd{}", std::process::id());
        let mut host = Host::new(&model, HostOptions { sets: Vec::new(), ..options(&ns) }).unwrap();
        assert!(host.start(&AtomicBool::new(false), &mut |_| {}).unwrap());
        let set = 41i32.to_ne_bytes();
        let steps = [DomainStep { domain: 0, publish: &set, sim: 2.5 }];
        let reports = host.step_domains(&steps, &mut |_| {}).unwrap();
        assert_eq!((reports.len(), reports[0].step, reports[0].timed_out), (1, 1, 0));
        let s = host.framework().domains[0].status();
        assert_eq!((s.step, s.sim_time), (1, 2.5), "the step carries the caller's simulated time");
        let mut seen = [0u8; 4];
        let seg = tutti_core::shm::Segment::open(&ns, "probe").unwrap();
        seg.read_set(tutti_core::ddf::Role::Publish, &mut seen).unwrap();
        assert_eq!(seen, set, "the step carries the caller's PUBLISH set");
        let missing = [DomainStep { domain: 3, publish: &set, sim: 0.0 }];
        assert!(matches!(host.step_domains(&missing, &mut |_| {}), Err(HostError::NoDomain { index: 3 })));
    }

    #[test]
    fn a_run_is_paused_stepped_reset_and_stopped_through_its_control_plane() {
        use crate::control::{ControlClient, ControlError, RunState};
        let model = tutti_core::ddf::parse_str(&probe_ddf(), "probe.ddf").unwrap();
        let ns = format!("hostlibc{}", std::process::id());
        let stop = Arc::new(AtomicBool::new(false));
        let runner = std::thread::spawn({
            let (stop, ns) = (stop.clone(), ns.clone());
            move || {
                let mut host = Host::new(&model, HostOptions { duration: None, ..options(&ns) }).unwrap();
                host.serve_control(stop.clone(), None).unwrap();
                host.run(&stop, |_| {})
            }
        });
        let serving = || {
            assert!(!runner.is_finished(), "the run never served its control plane");
            crate::control::socket_path(&ns).exists()
        };
        wait_until("the run never served its control plane", Duration::from_secs(30), serving);
        let mut c = ControlClient::connect(&ns, Duration::from_secs(30)).unwrap();
        wait_until("the run never started", Duration::from_secs(30), || c.state().unwrap().state == RunState::Playing);
        // Every domain of the probe is asynchronous: stepping is refused with the reason.
        let refused = |r: Result<_, ControlError>| matches!(r, Err(ControlError::Refused(_)));
        assert!(refused(c.step(1)), "step while playing");
        let paused = c.pause().unwrap();
        assert_eq!(paused.state, RunState::Paused);
        let e = c.step(3).unwrap_err().to_string();
        assert!(e.contains("every domain of this run is asynchronous (probe)"), "{e}");
        assert_eq!(c.state().unwrap().step, paused.step, "no step while paused");
        let reset = c.reset().unwrap();
        assert_eq!((reset.state, reset.step, reset.sim_time), (RunState::Paused, 0, 0.0));
        assert_eq!(c.resume().unwrap().state, RunState::Playing);
        assert!(matches!(
            c.component(crate::control::ComponentAction::Restart, "x"),
            Err(ControlError::Refused(r)) if r.0.contains("no components")
        ));
        c.stop().unwrap();
        let summary = runner.join().unwrap().unwrap();
        assert!(summary.started && stop.load(Ordering::SeqCst));
        assert!(!crate::control::socket_path(&ns).exists(), "the socket goes with the run");
        assert!(matches!(ControlClient::connect(&ns, Duration::from_secs(1)), Err(ControlError::NoRun { .. })));
    }

    #[test]
    fn options_that_cannot_apply_are_refused_before_anything_is_created() {
        let model = tutti_core::ddf::parse_str(&probe_ddf(), "probe.ddf").unwrap();
        let ns = format!("hostlibx{}", std::process::id());
        let bad = |opts: HostOptions| Host::new(&model, opts).unwrap_err();
        assert!(bad(HostOptions { step: Duration::ZERO, ..options(&ns) }).is_invalid());
        let e = bad(HostOptions { sets: vec!["probe/nothing=1".into()], ..options(&ns) });
        assert!(e.is_invalid() && e.to_string().contains("no item 'nothing'"), "{e}");
        let e = bad(HostOptions { wait_for: vec![("elsewhere".into(), 1)], ..options(&ns) });
        assert!(e.is_invalid() && e.to_string().contains("no domain 'elsewhere'"), "{e}");
    }
}
