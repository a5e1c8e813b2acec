//! `/clock`: the simulated time of one domain as `rosgraph_msgs/msg/Clock` on `rt/clock`, so
//! that ROS 2 nodes started with `use_sim_time:=true` follow the co-simulation.
//!
//! The poller thread reads the domain's header as a passive observer (no connection, so the
//! clock never paces or stalls the domain): each new step's simulated time is written once,
//! at most every `1 / --clock-rate` seconds (the latest time goes out when the cap allows).
//! Each time is its step's, read with it from the stamp of the framework's PUBLISH set; it
//! goes back only when the run is reset or restored (docs/run.md, "reset"), and then at once,
//! paused or not: the framework's word of a time set back (`Segment::time_resets`) puts its
//! new time out without waiting for a step, as Gazebo's clock does. When the framework pauses
//! or stops, nothing is written, so ROS 2 time stops too. The writer is RELIABLE, KEEP_LAST 1,
//! VOLATILE: it matches rclcpp's `ClockQoS` subscriptions (BEST_EFFORT, KEEP_LAST 1) and
//! reliable ones.

use std::sync::Arc;
use std::time::{Duration, Instant};

use tracing::info;

use tutti_core::ddf::Role;
use tutti_core::shm::observer::Observer;
use tutti_core::shm::Stamp;
use tutti_ros2::clock;

use super::to_dds::{look, Activation, Outgoing, Polled, ServedBy};
use super::ShmConfig;
use crate::engine::{Engine, TopicType, Writer};
use crate::stats::Stats;
use crate::GatewayError;

/// The `/clock` route of `domain` under the canonical ROS namespace `ns`: its writer,
/// watched by the poller, at most `rate` samples a second (None: one per step).
pub fn route(dds: &dyn Engine, domain: &str, ns: &str, rate: Option<f64>) -> Result<Outgoing, GatewayError> {
    let topic = tutti_ros2::names::under(ns, clock::TOPIC);
    let m = clock::message();
    let writer = dds.writer(&topic, &TopicType::ros2(&m.name().dds(), m.hash()), &clock::qos())?;
    let activation = Arc::new(Activation::default());
    let pump = ClockPump::new(domain.to_string(), writer, activation.clone(), rate);
    Ok(Outgoing { topics: vec![topic], activation, served_by: ServedBy::Poller(Box::new(pump)) })
}

/// Attempts at a consistent read of the PUBLISH set's stamp before the poll looks again later.
const STAMP_TRIES: u32 = 8;

/// The `/clock` publisher of one domain.
pub struct ClockPump {
    live: Observer,
    message: tutti_ros2::Message<'static>,
    writer: Box<dyn Writer>,
    activation: Arc<Activation>,
    /// Shortest time between two samples (zero: one per step).
    min_interval: Duration,
    last_step: Option<u64>,
    /// The framework's count of time resets as last seen.
    last_reset: Option<u32>,
    next_allowed: Instant,
}

impl std::fmt::Debug for ClockPump {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClockPump").field("domain", &self.live.domain).finish()
    }
}

impl ClockPump {
    /// The clock of `domain`, written by `writer` while `activation` is on, at most `rate`
    /// times a second (None: every step).
    pub fn new(domain: String, writer: Box<dyn Writer>, activation: Arc<Activation>, rate: Option<f64>) -> Self {
        let min_interval = super::to_dds::min_interval(rate);
        ClockPump {
            live: Observer::new(domain),
            message: clock::message(),
            writer,
            activation,
            min_interval,
            last_step: None,
            last_reset: None,
            next_allowed: Instant::now(),
        }
    }
}

impl Polled for ClockPump {
    fn activation(&self) -> &Activation {
        &self.activation
    }

    fn poll(&mut self, cfg: &ShmConfig, stats: &Stats) -> bool {
        if !self.activation.is_active() {
            self.live.close();
            return false;
        }
        let Some((seg, fresh)) = look(&mut self.live, &cfg.namespace) else { return false };
        if fresh {
            if self.last_step.is_some() {
                info!("/clock follows a new framework of its domain from its start");
            }
            self.last_step = None;
            self.last_reset = None;
        }
        let resets = seg.time_resets();
        if self.last_reset.replace(resets).is_some_and(|seen| seen != resets) {
            // Set back between two steps: its new time now, whatever the rate cap.
            let t = seg.sim_time();
            info!(domain = %self.live.domain, "/clock goes back to {t} s with its run's reset");
            return self.write(t, Instant::now(), stats);
        }
        // The step and its time, read as one: the framework's latest step and latest time
        // are two words, and a step published between the two loads paired a step with the
        // next one's time (and that time went out twice).
        let Some(Stamp { step, sim_time: t }) = seg.stamp(Role::Publish, STAMP_TRIES) else { return false };
        if step == 0 || self.last_step == Some(step) {
            return false;
        }
        let now = Instant::now();
        if now < self.next_allowed {
            return false;
        }
        self.last_step = Some(step);
        // While paused nothing moves, and the header's time is the run's now: a reset made
        // before this clock began to follow the domain (its first reader came later) has set
        // it back since the step.
        let t = if seg.paused() { seg.sim_time() } else { t };
        self.write(t, now, stats)
    }
}

impl ClockPump {
    /// Writes time `t` (seconds) at `now`.
    fn write(&mut self, t: f64, now: Instant, stats: &Stats) -> bool {
        let body = clock::encode(&self.message, t);
        let ok = self.writer.write(&body);
        self.writer.flush();
        if ok {
            self.next_allowed = now + self.min_interval;
            Stats::add(&stats.to_dds, 1);
        } else {
            Stats::add(&stats.errors, 1);
        }
        ok
    }
}
