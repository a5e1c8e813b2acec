//! The framework half of `tutti replay`: acts as the framework of the recorded domains and
//! republishes each recorded step's PUBLISH set, with its simulated time, at the recorded
//! pace (scaled by the speed); synchronous domains wait for their participants as usual. With
//! `compare`, the SUBSCRIBE answers of each step of a synchronous domain are checked against
//! the recording, element by element, and every step that differs is reported.
//!
//! A step is compared only when the domain has as many connections as it had in the
//! recording at that step (a participant that joined or left at another step answers other
//! steps); those steps are counted, never silently passed. Asynchronous domains are replayed,
//! not compared: what their participants answer depends on timing.

use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use serde::Serialize;
use tutti_core::ddf::Domain;
use tutti_core::shm::WaitMode;

use tutti_host::control::{Refusal, Request, RunState};
use tutti_host::{DomainStep, Host, HostOptions, Report};

use super::{RecordedStep, Recording};
use crate::RecordError;

/// How to replay.
#[derive(Debug, Clone)]
pub struct ReplayOptions {
    /// Pace: 1 = as recorded, 2 = twice as fast, 0 = as fast as the participants answer.
    pub speed: f64,
    /// Check the participants' SUBSCRIBE answers against the recording.
    pub compare: bool,
    /// Longest wait for the participants of a synchronous step.
    pub timeout: Duration,
    pub wait: WaitMode,
    /// Before the first step, hold participants until each DOMAIN has N writers.
    pub wait_for: Vec<(String, usize)>,
    /// The namespace of the segments (None: `TUTTI_NAMESPACE`, else the default).
    pub namespace: Option<String>,
}

/// One element of a SUBSCRIBE set that differs from the recording.
#[derive(Debug, Clone, Serialize)]
pub struct Difference {
    pub item: String,
    pub recorded: String,
    pub replayed: String,
}

/// A step whose answers differ.
#[derive(Debug, Clone, Serialize)]
pub struct DifferingStep {
    pub domain: String,
    pub step: u64,
    pub sim_time: f64,
    pub items: Vec<Difference>,
}

/// What the comparison found.
#[derive(Debug, Default, Clone)]
pub struct Comparison {
    pub compared: u64,
    /// Steps not compared because the connection count differs from the recording's.
    pub other_connections: u64,
    /// Steps that differ; the first [`Comparison::KEEP`] of them in `kept`.
    pub differing: u64,
    pub kept: Vec<DifferingStep>,
}

impl Comparison {
    /// The most differing steps kept in full; the rest are counted.
    pub const KEEP: usize = 1000;

    /// A comparison fails when a step differs or when no step could be compared.
    pub fn failed(&self) -> bool {
        self.differing > 0 || self.compared == 0
    }
}

impl fmt::Display for Comparison {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let skipped = if self.other_connections > 0 {
            format!(", {} not compared (connections differ from the recording's)", self.other_connections)
        } else {
            String::new()
        };
        match self.kept.first() {
            _ if self.compared == 0 => write!(f, "compare: no step compared{skipped}"),
            None => write!(f, "compare: {} steps compared, no difference{skipped}", self.compared),
            Some(first) => {
                let d = first.items.first();
                write!(
                    f,
                    "compare: {} of {} compared steps differ{skipped}; the first is {} step {} (t={:.6} s): {}",
                    self.differing,
                    self.compared,
                    first.domain,
                    first.step,
                    first.sim_time,
                    d.map_or(String::new(), |d| format!("{} recorded {}, replayed {}", d.item, d.recorded, d.replayed))
                )
            }
        }
    }
}

/// What a replay reports while it goes.
#[derive(Debug)]
pub enum ReplayEvent<'a> {
    /// The domains are created: their names and recorded step counts.
    Started { namespace: &'a str, domains: Vec<(String, usize)> },
    /// What the framework reports: waiting for writers (every 5 s), every `wait_for` met,
    /// seeds missing, a step that timed out.
    Host(Report),
    /// A compared step differs (the `nth` differing one, from 0).
    Differs { nth: u64, step: &'a DifferingStep },
    /// Once a second.
    Progress { elapsed: Duration, replayed: usize, total: usize, timeouts: u64, differing: Option<u64> },
}

impl fmt::Display for ReplayEvent<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayEvent::Started { namespace, domains } => {
                let names: Vec<String> = domains.iter().map(|(d, n)| format!("{d} ({n} steps)")).collect();
                write!(f, "in namespace {namespace}: {}", names.join(", "))
            }
            ReplayEvent::Host(report) => write!(f, "{report}"),
            ReplayEvent::Differs { step, .. } => {
                let items = &step.items;
                let list: Vec<String> = items
                    .iter()
                    .take(5)
                    .map(|d| format!("{}: recorded {}, replayed {}", d.item, d.recorded, d.replayed))
                    .collect();
                let more = if items.len() > 5 { format!(" (+{} more)", items.len() - 5) } else { String::new() };
                write!(
                    f,
                    "differs: {} step {} (t={:.6} s): {}{more}",
                    step.domain,
                    step.step,
                    step.sim_time,
                    list.join("; ")
                )
            }
            ReplayEvent::Progress { elapsed, replayed, total, timeouts, differing } => write!(
                f,
                "t={:.1}s {replayed}/{total} steps, step timeouts {timeouts}{}",
                elapsed.as_secs_f64(),
                differing.map_or(String::new(), |n| format!(", {n} differing"))
            ),
        }
    }
}

/// How a replay ended.
#[derive(Debug, Clone)]
pub struct ReplaySummary {
    /// Whether stepping started (false: stopped while waiting for writers).
    pub started: bool,
    pub replayed: usize,
    pub total: usize,
    pub timeouts: u64,
    pub elapsed: Duration,
    /// With `compare`: what it found.
    pub comparison: Option<Comparison>,
}

impl ReplaySummary {
    /// Fewer steps replayed than recorded.
    pub fn stopped_early(&self) -> bool {
        self.replayed < self.total
    }
}

/// A replay of a recording: its domains created, ready to run.
#[derive(Debug)]
pub struct Replay {
    recording: Recording,
    opts: ReplayOptions,
    host: Host,
}

/// How long the replay's loop waits at most before it looks at the control plane again.
const TURN: Duration = Duration::from_millis(10);

/// What the control plane has made of the replay: paused or playing, at which speed, paced from
/// where, a seek to make, and the simulated time of the last step replayed.
struct Play {
    paused: bool,
    speed: f64,
    /// The wall time and recorded log time the pacing counts from (None: from the next frame).
    anchor: Option<(Instant, u64)>,
    seek: Option<f64>,
    sim: f64,
}

impl Play {
    /// Answers a command of the control plane (`tutti ctl`, the Foxglove server's playback
    /// control): pause, resume, seek, speed and stop; a replay has no steps of its own to make.
    fn answer(&mut self, r: &Request, stop: &AtomicBool) -> Result<(), Refusal> {
        match r {
            Request::State => {}
            Request::Pause => self.paused = true,
            Request::Resume => (self.paused, self.anchor) = (false, None),
            Request::Seek { time } if time.is_finite() && *time >= 0.0 => {
                (self.seek, self.anchor) = (Some(*time), None)
            }
            Request::Seek { time } => return Err(Refusal(format!("seek {time}: a simulated time of 0 s or more"))),
            Request::Speed { factor } if factor.is_finite() && *factor > 0.0 => {
                (self.speed, self.anchor) = (*factor, None);
            }
            Request::Speed { factor } => return Err(Refusal(format!("speed {factor}: a factor above 0"))),
            Request::Stop => stop.store(true, Ordering::SeqCst),
            _ => {
                return Err(Refusal(
                    "a replay plays its recorded steps: pause, resume, seek, speed and stop apply to it".into(),
                ))
            }
        }
        Ok(())
    }
}

/// The replay's position: the next step of each domain, and the domains that have step `k`.
struct Cursor {
    next: Vec<usize>,
    frame: Vec<usize>,
}

impl Replay {
    /// Checks `opts` against `recording` (at `path`, for messages) and creates the domains:
    /// the framework is a [`Host`], whose steps the replay paces by the recording's.
    pub fn new(recording: Recording, opts: ReplayOptions, path: &std::path::Path) -> Result<Replay, RecordError> {
        if recording.model.domains.is_empty() {
            let detail = "no recorded step to replay".into();
            return Err(RecordError::Format { path: path.display().to_string(), detail });
        }
        let host_opts = HostOptions {
            timeout: opts.timeout,
            wait: opts.wait,
            namespace: opts.namespace.clone(),
            wait_for: opts.wait_for.clone(),
            ddf_name: format!("the domains replayed from {}", path.display()),
            ..HostOptions::default()
        };
        let host = Host::new(&recording.model, host_opts)?;
        Ok(Replay { recording, opts, host })
    }

    /// Its framework, to serve the control plane on and to give sinks (a gateway) before
    /// [`run`](Self::run).
    pub fn host_mut(&mut self) -> &mut Host {
        &mut self.host
    }

    /// Recorded steps, all domains together.
    pub fn total(&self) -> usize {
        self.recording.domains.iter().map(|d| d.steps.len()).sum()
    }

    /// Waits for the writers (and seeds), then replays until the end or `stop`.
    pub fn run(
        mut self,
        stop: &AtomicBool,
        mut on_event: impl FnMut(ReplayEvent<'_>),
    ) -> Result<ReplaySummary, RecordError> {
        let domains = self.recording.domains.iter().map(|d| (d.name.clone(), d.steps.len())).collect();
        on_event(ReplayEvent::Started { namespace: self.host.namespace(), domains });
        let mut summary = ReplaySummary {
            started: false,
            replayed: 0,
            total: self.total(),
            timeouts: 0,
            elapsed: Duration::ZERO,
            comparison: self.opts.compare.then(Comparison::default),
        };
        if !self.host.start(stop, &mut |report| on_event(ReplayEvent::Host(report)))? {
            return Ok(summary);
        }
        summary.started = true;
        self.replay_steps(stop, &mut summary, &mut on_event)?;
        Ok(summary)
    }

    fn replay_steps(
        &mut self,
        stop: &AtomicBool,
        summary: &mut ReplaySummary,
        on_event: &mut impl FnMut(ReplayEvent<'_>),
    ) -> Result<(), RecordError> {
        let recorded = &self.recording.domains;
        let mut cursor = Cursor { next: vec![0; recorded.len()], frame: Vec::with_capacity(recorded.len()) };
        let end = recorded.iter().filter_map(|d| d.steps.last()).map(|s| s.sim_time).fold(0.0, f64::max);
        self.host.set_playback(self.opts.speed, end);
        let start = Instant::now();
        let mut last_report = Instant::now();
        let mut play = Play { paused: false, speed: self.opts.speed, anchor: None, seek: None, sim: 0.0 };
        while !stop.load(Ordering::SeqCst) {
            self.host.take_requests(|r, host| {
                let answer = play.answer(r, stop);
                if let Some(t) = play.seek.take() {
                    play.sim = self.seek(&mut cursor, t);
                }
                // Said before the answer goes: a `state` after a pause, a resume or a seek
                // reads what it did.
                if !stop.load(Ordering::SeqCst) {
                    host.set_run_state(if play.paused { RunState::Paused } else { RunState::Playing }, play.sim);
                }
                answer
            });
            if play.paused {
                self.host.set_run_state(RunState::Paused, play.sim);
                std::thread::sleep(TURN);
                continue;
            }
            if !self.next_frame(&mut cursor) {
                break;
            }
            if play.speed > 0.0 {
                // Paced from the first frame after the start, a resume, a seek or a new speed.
                let log = cursor.frame.iter().map(|&i| self.step_of(&cursor, i).log_time).min().unwrap_or(0);
                let (t0, log0) = *play.anchor.get_or_insert((Instant::now(), log));
                let due = Duration::from_secs_f64(log.saturating_sub(log0) as f64 / 1e9 / play.speed);
                if let Some(wait) = due.checked_sub(t0.elapsed()) {
                    // In turns, so that a pause or a seek is taken within one.
                    std::thread::sleep(wait.min(TURN));
                    continue;
                }
            }
            self.step_frame(&cursor, summary, on_event)?;
            play.sim = cursor.frame.iter().map(|&i| self.step_of(&cursor, i).sim_time).fold(0.0, f64::max);
            self.host.set_run_state(RunState::Playing, play.sim);
            for &i in &cursor.frame {
                cursor.next[i] += 1;
            }
            summary.replayed += cursor.frame.len();
            summary.elapsed = start.elapsed();
            if last_report.elapsed() >= Duration::from_secs(1) {
                last_report = Instant::now();
                on_event(ReplayEvent::Progress {
                    elapsed: start.elapsed(),
                    replayed: summary.replayed,
                    total: summary.total,
                    timeouts: summary.timeouts,
                    differing: summary.comparison.as_ref().map(|c| c.differing),
                });
            }
        }
        self.host.set_run_state(RunState::Stopped, play.sim);
        summary.elapsed = start.elapsed();
        Ok(())
    }

    /// Moves `cursor` to the first recorded step of each domain at or after simulated time `t`;
    /// the earliest of their times (`t` past the end).
    fn seek(&self, cursor: &mut Cursor, t: f64) -> f64 {
        let mut at = f64::INFINITY;
        for (next, d) in cursor.next.iter_mut().zip(&self.recording.domains) {
            *next = d.steps.iter().position(|s| s.sim_time >= t - 1e-9).unwrap_or(d.steps.len());
            at = d.steps.get(*next).map_or(at, |s| at.min(s.sim_time));
        }
        if at.is_finite() {
            at
        } else {
            t
        }
    }

    /// Finds the next recorded step number and the domains that have it; false at the end.
    fn next_frame(&self, cursor: &mut Cursor) -> bool {
        let recorded = &self.recording.domains;
        let next = recorded.iter().zip(&cursor.next).filter_map(|(d, &c)| d.steps.get(c)).map(|s| s.step).min();
        let Some(k) = next else { return false };
        cursor.frame.clear();
        cursor.frame.extend(
            (0..recorded.len()).filter(|&i| recorded[i].steps.get(cursor.next[i]).is_some_and(|s| s.step == k)),
        );
        true
    }

    fn step_of(&self, cursor: &Cursor, i: usize) -> &RecordedStep {
        &self.recording.domains[i].steps[cursor.next[i]]
    }

    /// Steps the frame's domains with their recorded sets, then compares their answers.
    fn step_frame(
        &mut self,
        cursor: &Cursor,
        summary: &mut ReplaySummary,
        on_event: &mut impl FnMut(ReplayEvent<'_>),
    ) -> Result<(), RecordError> {
        let recorded = &self.recording.domains;
        let step_of = |i: usize| &recorded[i].steps[cursor.next[i]];
        let steps: Vec<DomainStep<'_>> = cursor
            .frame
            .iter()
            .map(|&i| DomainStep { domain: i, publish: &step_of(i).publish, sim: step_of(i).sim_time })
            .collect();
        let reports = self.host.step_domains(&steps, &mut |report| on_event(ReplayEvent::Host(report)))?;
        summary.timeouts += reports.iter().filter(|r| r.timed_out > 0).count() as u64;
        let Some(cmp) = summary.comparison.as_mut() else { return Ok(()) };
        for &i in &cursor.frame {
            let (s, domain) = (step_of(i), &self.recording.model.domains[i]);
            let Some(want) = s.subscribe.as_deref().filter(|_| domain.flags.synchronous) else { continue };
            let host = &self.host.framework().domains[i];
            if host.connection_count() != s.connections {
                cmp.other_connections += 1;
                continue;
            }
            cmp.compared += 1;
            let items = differences(domain, want, host.subscribe());
            if !items.is_empty() {
                let differing =
                    DifferingStep { domain: domain.name.clone(), step: s.step, sim_time: s.sim_time, items };
                on_event(ReplayEvent::Differs { nth: cmp.differing, step: &differing });
                cmp.differing += 1;
                if cmp.kept.len() < Comparison::KEEP {
                    cmp.kept.push(differing);
                }
            }
        }
        Ok(())
    }
}

/// The elements of `domain`'s SUBSCRIBE set that differ between `recorded` and `replayed`.
pub fn differences(domain: &Domain, recorded: &[u8], replayed: &[u8]) -> Vec<Difference> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_name_the_item_and_element() {
        let ddf = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../ddf/multiuav.ddf");
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
    }
}
