//! The framework's own PUBLISH set -> DDS, written from the framework's step itself: the
//! route of a gateway that runs in the framework's process ([`crate::in_process`]).
//!
//! No poller and no pump follow the set in shared memory: the framework hands each step's
//! set to [`StepRoute::send`] right after publishing it (`tutti_host::StepSink::published`),
//! before a synchronous step waits for its participants, so a DDS peer that answers the step
//! has it in time. The set is encoded and written on the framework's thread, into buffers
//! the route keeps (nothing is allocated per step), and only while a DDS reader is matched
//! ([`Activation`], kept by the manager's discovery).
//!
//! * A **synchronous** set is written and sent at every step, once and in order: the DDS
//!   writer has the domain's QoS (reliable, keep-all), so a reader that cannot keep up
//!   slows the framework's writes rather than losing steps: a step the DDS writer refuses
//!   (its history full until the readers acknowledge) is tried again on the framework's
//!   thread for up to the step timeout ([`Patience`]), and only then counted `lost` and
//!   logged.
//! * An **asynchronous** set is written at every step (at most `max_rate` a second where the
//!   config file says so). When the framework says another step follows at once (it is
//!   catching up, or a caller steps flat out: [`StepRoute::send`]'s `more`), the sample is
//!   left in a batch of at most [`FLUSH_EVERY`], which goes out with the first step sent
//!   without `more`, when full, when the run ends ([`StepRoute::flush`]), and at the latest
//!   [`HOLD_AT_MOST`] after its first sample: the gateway's flush thread ([`Held`]) sends it
//!   then, so a held sample never waits long for a step that waits for an answer to it. No
//!   timing guess decides it: on one core an answer can come back through DDS while the
//!   write that caused it is still being sent, so a short gap between two steps does not mean
//!   that nothing waits.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::ItemTopic;

use super::per_item::ItemWriters;
use super::to_dds::{self, min_interval, Activation, Outbound, Outgoing, ServedBy};
use super::{Counters, Patience};
use crate::config::PlannedSet;
use crate::engine::{Engine, Flusher};
use crate::GatewayError;

/// Samples of an asynchronous set that go out in one batch at most.
pub const FLUSH_EVERY: u32 = 32;
/// The longest a batched sample waits: then the flush thread sends its batch.
pub const HOLD_AT_MOST: Duration = Duration::from_micros(50);

/// A route's batch as the flush thread sees it: since when its first sample waits (ns on
/// this process's clock, 0: nothing waits), and how to send it from another thread.
pub struct Held {
    since_ns: AtomicU64,
    flush: Flusher,
    /// The flush thread, woken when a batch starts.
    thread: OnceLock<Thread>,
}

impl std::fmt::Debug for Held {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Held").field("since_ns", &self.since_ns).finish()
    }
}

impl Held {
    /// The flush thread to wake when a batch starts.
    pub fn watched_by(&self, thread: Thread) {
        let _ = self.thread.set(thread);
    }
}

/// Nanoseconds since the first call in this process: a monotonic clock as an integer.
fn now_ns() -> u64 {
    static START: OnceLock<Instant> = OnceLock::new();
    START.get_or_init(Instant::now).elapsed().as_nanos() as u64 | 1
}

/// The flush thread of an in-process gateway: sends each batch that has waited
/// [`HOLD_AT_MOST`], until `stop`; sleeps while nothing waits.
pub fn spawn_flusher(held: Vec<Arc<Held>>, stop: Arc<AtomicBool>) -> std::io::Result<Option<JoinHandle<()>>> {
    if held.is_empty() {
        return Ok(None);
    }
    let thread = std::thread::Builder::new().name("tutti-gw-flush".into()).spawn(move || {
        let limit = HOLD_AT_MOST.as_nanos() as u64;
        while !stop.load(Ordering::Acquire) {
            let now = now_ns();
            let mut waiting = false;
            for h in &held {
                let since = h.since_ns.load(Ordering::Acquire);
                if since == 0 {
                    continue;
                }
                if now.saturating_sub(since) >= limit && h.since_ns.swap(0, Ordering::AcqRel) != 0 {
                    (h.flush)();
                } else {
                    waiting = true;
                }
            }
            if waiting {
                std::thread::sleep(HOLD_AT_MOST / 2);
            } else {
                std::thread::park_timeout(Duration::from_millis(100));
            }
        }
    })?;
    Ok(Some(thread))
}

/// One domain's PUBLISH set, written to DDS from the framework's step.
#[derive(Debug)]
pub struct StepRoute {
    domain: String,
    out: Outbound,
    activation: Arc<Activation>,
    counters: Counters,
    /// `activation.joined()` as last acted on (per-item writers send every item again).
    joined: u64,
    /// Shortest time between two samples of an asynchronous set (zero: no limit).
    min_interval: Duration,
    next_allowed: Instant,
    /// The samples written but not yet sent.
    unflushed: u32,
    /// The batch as the flush thread sees it (asynchronous sets of a batching engine).
    held: Option<Arc<Held>>,
    /// A synchronous set's: how long a step DDS refuses is tried again (None: asynchronous,
    /// where the next step's value replaces a refused one).
    patience: Option<Patience>,
}

/// The typed route of planned PUBLISH set `p` of domain `d`, written from the step (a step of
/// a synchronous set that DDS refuses is tried again as `patience` says).
pub fn typed(
    dds: &dyn Engine,
    d: &Domain,
    p: &PlannedSet,
    counters: Counters,
    patience: Patience,
) -> Result<Outgoing, GatewayError> {
    let out = to_dds::set_writer(dds, d, p)?;
    Ok(route(d, p, out, vec![p.ros2_topic.clone()], counters, patience))
}

/// The per-item route of planned PUBLISH set `p` of domain `d` (a topic for each of `items`),
/// written from the step.
pub fn items(
    dds: &dyn Engine,
    d: &Domain,
    p: &PlannedSet,
    items: &[ItemTopic],
    counters: Counters,
    patience: Patience,
) -> Result<Outgoing, GatewayError> {
    let out = Outbound::Items(ItemWriters::create(dds, items, &d.set(Role::Publish).layout, &p.writer_qos)?);
    Ok(route(d, p, out, items.iter().map(|t| t.topic.clone()).collect(), counters, patience))
}

fn route(
    d: &Domain,
    p: &PlannedSet,
    out: Outbound,
    topics: Vec<String>,
    counters: Counters,
    patience: Patience,
) -> Outgoing {
    let activation = Arc::new(Activation::default());
    let now = Instant::now();
    let held = match (d.flags.synchronous, out.flusher()) {
        (false, Some(flush)) => Some(Arc::new(Held { since_ns: AtomicU64::new(0), flush, thread: OnceLock::new() })),
        _ => None,
    };
    let r = StepRoute {
        domain: d.name.clone(),
        out,
        activation: activation.clone(),
        counters,
        joined: 0,
        min_interval: if d.flags.synchronous { Duration::ZERO } else { min_interval(p.max_rate) },
        next_allowed: now,
        unflushed: 0,
        held,
        patience: d.flags.synchronous.then_some(patience),
    };
    Outgoing { topics, activation, served_by: ServedBy::Step(Box::new(r)) }
}

impl StepRoute {
    /// The domain whose PUBLISH set this is.
    pub fn domain(&self) -> &str {
        &self.domain
    }

    /// Writes step `step` (simulated time `sim`), whose PUBLISH set is `set`, to DDS if a
    /// reader wants it; returns whether it was written. `more`: another step follows at once,
    /// so an asynchronous set may wait in a batch (see the module).
    pub fn send(&mut self, step: u64, sim: f64, set: &[u8], more: bool) -> bool {
        if !self.activation.is_active() {
            self.flush();
            return false;
        }
        let joined = self.activation.joined();
        if joined != self.joined {
            self.joined = joined;
            self.out.reset();
        }
        if !self.min_interval.is_zero() {
            let now = Instant::now();
            if now < self.next_allowed {
                return false;
            }
            self.next_allowed = now + self.min_interval;
        }
        let Counters { total, set: counts } = &self.counters;
        let written = match &self.patience {
            // The framework's thread waits here while DDS refuses the step: back-pressure.
            Some(patience) => self.out.write_step(step, sim, set, total, Some(counts), patience) > 0,
            None => self.out.write(step, sim, set, total, Some(counts)) > 0,
        };
        self.unflushed += 1;
        match &self.held {
            Some(h) if more && self.unflushed < FLUSH_EVERY => {
                if h.since_ns.compare_exchange(0, now_ns(), Ordering::AcqRel, Ordering::Acquire).is_ok() {
                    if let Some(t) = h.thread.get() {
                        t.unpark();
                    }
                }
            }
            _ => self.flush(),
        }
        written
    }

    /// Sends what the last steps left in the writers' batches.
    pub fn flush(&mut self) {
        if self.unflushed > 0 {
            if let Some(h) = &self.held {
                h.since_ns.store(0, Ordering::Release);
            }
            self.out.flush();
            self.unflushed = 0;
        }
    }

    /// The batch the flush thread watches, if this route batches.
    pub fn held(&self) -> Option<Arc<Held>> {
        self.held.clone()
    }
}
