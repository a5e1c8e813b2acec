//! The live recorder of `tutti record`: it records live domains of a namespace as a passive
//! observer. It opens their segments read-only in effect (no connection, so it never counts
//! as a participant and never paces a step), and writes each step it sees to a [`Recorder`].
//!
//! A step is written when the next one is published: its PUBLISH set as read when it was
//! published, and the SUBSCRIBE set as it stands when the framework moves on (in a
//! synchronous domain, the answers the framework read for that step). Steps published
//! faster than it looks (every 100 µs) are counted as missed, never invented. Following a
//! domain (opening it, noticing its framework stop or come back) is the core's
//! [`Observer`], as for the gateway's poller.

use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use tutti_core::ddf::{Model, Role};
use tutti_core::shm::observer::{Look, Observer};

use crate::{now_ns, RecordError, Recorder, Step};

/// Attempts at a consistent copy of the PUBLISH set before the step is left to the next look.
const READ_TRIES: u32 = 64;

/// One domain as the recorder follows it.
#[derive(Debug)]
struct Followed {
    obs: Observer,
    /// The step last seen published, with its simulated time; its PUBLISH set is `publish`.
    pending: Option<(u64, f64)>,
    publish: Vec<u8>,
    subscribe: Vec<u8>,
    recorded: u64,
    missed: u64,
}

/// What the live recorder reports; `Display` is the line a user reads.
#[derive(Debug, Clone)]
pub enum LiveEvent {
    /// A domain's framework appeared (or came back).
    Following(String),
    /// A domain's framework stopped.
    Stopped(String),
    /// A domain's segment could not be opened.
    Refused { domain: String, reason: String },
    /// Every 5 s and at the end: steps recorded and missed per domain.
    Progress { elapsed: Duration, domains: Vec<(String, u64, u64)> },
}

impl fmt::Display for LiveEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LiveEvent::Following(d) => write!(f, "{d}: following its framework"),
            LiveEvent::Stopped(d) => write!(f, "{d}: the framework stopped"),
            LiveEvent::Refused { domain, reason } => write!(f, "{domain}: {reason}"),
            LiveEvent::Progress { elapsed, domains } => {
                let parts: Vec<String> =
                    domains.iter().map(|(d, n, missed)| format!("{d} {n} steps ({missed} missed)")).collect();
                write!(f, "t={:.1}s {}", elapsed.as_secs_f64(), parts.join(", "))
            }
        }
    }
}

/// A passive recorder of the live domains of a model in one namespace.
pub struct LiveRecorder {
    recorder: Box<dyn Recorder>,
    followed: Vec<Followed>,
    namespace: String,
    start: Instant,
}

impl fmt::Debug for LiveRecorder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LiveRecorder").field("followed", &self.followed).field("namespace", &self.namespace).finish()
    }
}

impl LiveRecorder {
    /// Follows every domain of `model` in `namespace`, writing to `recorder` (made for `model`).
    pub fn new(recorder: Box<dyn Recorder>, model: &Model, namespace: String) -> LiveRecorder {
        let followed = model
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
        LiveRecorder { recorder, followed, namespace, start: Instant::now() }
    }

    /// Records until `stop` is set or `duration` is over, looking every 100 µs; reports its
    /// counts every 5 s and at the end. Finishes the recording.
    pub fn run(
        mut self,
        stop: &AtomicBool,
        duration: Option<Duration>,
        mut on_event: impl FnMut(LiveEvent),
    ) -> Result<(), RecordError> {
        self.start = Instant::now();
        let mut last_report = Instant::now();
        while !stop.load(Ordering::SeqCst) && duration.map_or(true, |d| self.start.elapsed() < d) {
            self.look(&mut on_event)?;
            if last_report.elapsed() >= Duration::from_secs(5) {
                last_report = Instant::now();
                on_event(self.progress());
            }
            std::thread::sleep(Duration::from_micros(100));
        }
        let progress = self.progress();
        self.recorder.finish()?;
        on_event(progress);
        Ok(())
    }

    /// Steps recorded and missed so far, per domain.
    pub fn progress(&self) -> LiveEvent {
        LiveEvent::Progress {
            elapsed: self.start.elapsed(),
            domains: self.followed.iter().map(|f| (f.obs.domain.clone(), f.recorded, f.missed)).collect(),
        }
    }

    /// One look at every domain: records the steps completed since the last look.
    pub fn look(&mut self, on_event: &mut impl FnMut(LiveEvent)) -> Result<(), RecordError> {
        for (i, f) in self.followed.iter_mut().enumerate() {
            match f.obs.look(&self.namespace) {
                Look::Fresh => {
                    on_event(LiveEvent::Following(f.obs.domain.clone()));
                    f.pending = None;
                }
                Look::Same => {}
                Look::Gone => continue,
                Look::Stopped => {
                    on_event(LiveEvent::Stopped(f.obs.domain.clone()));
                    f.pending = None;
                    continue;
                }
                Look::Refused(e) => {
                    on_event(LiveEvent::Refused { domain: f.obs.domain.clone(), reason: e.to_string() });
                    continue;
                }
            }
            follow(f, i, self.recorder.as_mut(), self.start)?;
        }
        Ok(())
    }
}

/// Records `f`'s pending step when its framework has moved on, and takes the new one.
fn follow(f: &mut Followed, i: usize, recorder: &mut dyn Recorder, start: Instant) -> Result<(), RecordError> {
    let Some(seg) = f.obs.segment() else { return Ok(()) };
    let step = seg.step();
    if step == 0 || f.pending.is_some_and(|(k, _)| k == step) {
        return Ok(());
    }
    // The framework moved on: the pending step is complete.
    if let Some((k, sim)) = f.pending.take() {
        if seg.read_set(Role::Subscribe, &mut f.subscribe).is_ok() {
            let s = Step {
                step: k,
                sim_time: sim,
                wall_ns: now_ns(),
                elapsed_s: start.elapsed().as_secs_f64(),
                connections: seg.connection_count(),
                owner_pid: seg.exclusive_owner_pid(),
                publish: &f.publish,
                subscribe: &f.subscribe,
            };
            recorder.step(i, &s)?;
            f.recorded += 1;
            f.missed += step.saturating_sub(k + 1);
        }
    }
    // The PUBLISH set with its step and that step's time, read as one (the framework's latest
    // time, read apart, may already be the next step's); still step `step`, else it is caught
    // at the next look.
    if let Some((_, stamp)) = seg.try_read_set_stamped(Role::Publish, &mut f.publish, READ_TRIES) {
        if stamp.step == step {
            f.pending = Some((step, stamp.sim_time));
        }
    }
    Ok(())
}
