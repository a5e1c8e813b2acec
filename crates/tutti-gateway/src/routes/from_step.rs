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
//!   slows the framework's writes rather than losing steps.
//! * An **asynchronous** set is written at every step (at most `max_rate` a second where the
//!   config file says so). Steps that follow each other closer than [`BACK_TO_BACK`] (a
//!   framework stepping flat out, or catching up) are sent in batches of at most
//!   [`FLUSH_EVERY`]: the batch goes out with the first step that comes after a pause, or
//!   when full, or when the run ends ([`StepRoute::flush`]). A step after a pause is sent at
//!   once, so a framework stepping at its period adds no latency.

use std::sync::Arc;
use std::time::{Duration, Instant};

use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::ItemTopic;

use super::per_item::ItemWriters;
use super::to_dds::{self, min_interval, Activation, Outbound, Outgoing, ServedBy};
use super::Counters;
use crate::config::PlannedSet;
use crate::engine::Engine;
use crate::GatewayError;

/// Steps of an asynchronous set closer together than this are batched. It is below the
/// shortest DDS round trip on loopback (ddsperf: 7.5 µs), so a step that follows the answer
/// to its predecessor through DDS is never held: a held sample waits for the next step (a
/// host makes one within its period; the end of the run flushes), never for an answer to it.
pub const BACK_TO_BACK: Duration = Duration::from_micros(3);
/// Samples of an asynchronous set that go out in one batch at most.
pub const FLUSH_EVERY: u32 = 32;

/// One domain's PUBLISH set, written to DDS from the framework's step.
#[derive(Debug)]
pub struct StepRoute {
    domain: String,
    synchronous: bool,
    out: Outbound,
    activation: Arc<Activation>,
    counters: Counters,
    /// `activation.joined()` as last acted on (per-item writers send every item again).
    joined: u64,
    /// Shortest time between two samples of an asynchronous set (zero: no limit).
    min_interval: Duration,
    next_allowed: Instant,
    /// When the last sample was written, and the samples written but not yet sent.
    last_write: Instant,
    unflushed: u32,
}

/// The typed route of planned PUBLISH set `p` of domain `d`, written from the step.
pub fn typed(dds: &dyn Engine, d: &Domain, p: &PlannedSet, counters: Counters) -> Result<Outgoing, GatewayError> {
    let out = to_dds::set_writer(dds, d, p)?;
    Ok(route(d, p, out, vec![p.topic.clone()], counters))
}

/// The per-item route of planned PUBLISH set `p` of domain `d` (a topic for each of `items`),
/// written from the step.
pub fn items(
    dds: &dyn Engine,
    d: &Domain,
    p: &PlannedSet,
    items: &[ItemTopic],
    counters: Counters,
) -> Result<Outgoing, GatewayError> {
    let out = Outbound::Items(ItemWriters::create(dds, items, &d.set(Role::Publish).layout, &p.writer_qos)?);
    Ok(route(d, p, out, items.iter().map(|t| t.topic.clone()).collect(), counters))
}

fn route(d: &Domain, p: &PlannedSet, out: Outbound, topics: Vec<String>, counters: Counters) -> Outgoing {
    let activation = Arc::new(Activation::default());
    let now = Instant::now();
    let r = StepRoute {
        domain: d.name.clone(),
        synchronous: d.flags.synchronous,
        out,
        activation: activation.clone(),
        counters,
        joined: 0,
        min_interval: if d.flags.synchronous { Duration::ZERO } else { min_interval(p.max_rate) },
        next_allowed: now,
        last_write: now,
        unflushed: 0,
    };
    Outgoing { topics, activation, served_by: ServedBy::Step(Box::new(r)) }
}

impl StepRoute {
    /// The domain whose PUBLISH set this is.
    pub fn domain(&self) -> &str {
        &self.domain
    }

    /// Writes step `step` (simulated time `sim`), whose PUBLISH set is `set`, to DDS if a
    /// reader wants it; returns whether it was written.
    pub fn send(&mut self, step: u64, sim: f64, set: &[u8]) -> bool {
        if !self.activation.is_active() {
            self.flush();
            return false;
        }
        let joined = self.activation.joined();
        if joined != self.joined {
            self.joined = joined;
            self.out.reset();
        }
        let now = Instant::now();
        if !self.min_interval.is_zero() {
            if now < self.next_allowed {
                return false;
            }
            self.next_allowed = now + self.min_interval;
        }
        let Counters { total, set: counts } = &self.counters;
        let written = self.out.write(step, sim, set, total, Some(counts)) > 0;
        self.unflushed += 1;
        let back_to_back = now.saturating_duration_since(self.last_write) < BACK_TO_BACK;
        self.last_write = now;
        if self.synchronous || !back_to_back || self.unflushed >= FLUSH_EVERY {
            self.flush();
        }
        written
    }

    /// Sends what the last steps left in the writers' batches.
    pub fn flush(&mut self) {
        if self.unflushed > 0 {
            self.out.flush();
            self.unflushed = 0;
        }
    }
}
