//! The entities' poses for viewers (docs/gateway.md, "Entities"): every entity's pose as a
//! transform on `/tf` (`tf2_msgs/msg/TFMessage`, from the entity's frame to the entity) and
//! as a `geometry_msgs/msg/PoseStamped` on `<entity>/pose`, once per step of the entities'
//! domains, or at most `pose_rate` times a second.
//!
//! The poller serves it, as it serves `/clock`: the entities' sets are read as a passive
//! observer ([`DomainEntities`]), so viewers never pace nor stall a domain, and nothing is
//! read while no reader of these topics is matched.

use std::sync::Arc;
use std::time::Instant;

use tutti_core::ddf::Model;
use tutti_core::shm::observer::Observer;
use tutti_ros2::simulation::entities::{self as ent, Entities};
use tutti_ros2::Message;

use super::to_dds::{look, min_interval, Activation, Outgoing, Polled, ServedBy};
use super::ShmConfig;
use crate::config::Entity;
use crate::engine::{Engine, TopicType, Writer};
use crate::entities::{DomainEntities, NewPoses};
use crate::stats::Stats;
use crate::GatewayError;

/// The poses route of `entities` (of DDF `model`) under the canonical ROS namespace `ns`:
/// `/tf` and a pose topic per entity, at most `rate` a second (None: every step).
pub fn route(
    dds: &dyn Engine,
    entities: &[Entity],
    model: &Model,
    cfg: &ShmConfig,
    ns: &str,
    rate: Option<f64>,
) -> Result<Outgoing, GatewayError> {
    let tf_topic = tutti_ros2::names::under(ns, ent::TF_TOPIC);
    let (tf, pose) = (ent::tf_message(), ent::pose_message());
    let ty = |m: &Message<'_>| TopicType::ros2(&m.name().dds(), m.hash());
    let tf_writer = dds.writer(&tf_topic, &ty(&tf), &ent::tf_qos())?;
    let mut topics = vec![tf_topic];
    let mut pose_writers = Vec::new();
    for e in entities {
        let topic = tutti_ros2::names::under(ns, &ent::pose_topic(&e.name));
        pose_writers.push(dds.writer(&topic, &ty(&pose), &tutti_ros2::simulation::services_qos())?);
        topics.push(topic);
    }
    let mut domains: Vec<String> = entities.iter().map(|e| e.domain.clone()).collect();
    domains.sort();
    domains.dedup();
    let activation = Arc::new(Activation::default());
    let pump = PosePump {
        source: DomainEntities::new(entities, model, &cfg.namespace, cfg.timeout),
        steps: domains.into_iter().map(Observer::new).collect(),
        new: NewPoses::default(),
        tf: (tf, tf_writer),
        poses: (pose, pose_writers),
        activation: activation.clone(),
        min_interval: min_interval(rate),
        next_allowed: Instant::now(),
    };
    Ok(Outgoing { topics, activation, served_by: ServedBy::Poller(Box::new(pump)) })
}

/// The poses' writers, fed from the entities' domains.
pub struct PosePump {
    source: DomainEntities,
    /// Each domain of the entities, followed for its steps.
    steps: Vec<Observer>,
    new: NewPoses,
    tf: (Message<'static>, Box<dyn Writer>),
    poses: (Message<'static>, Vec<Box<dyn Writer>>),
    activation: Arc<Activation>,
    min_interval: std::time::Duration,
    next_allowed: Instant,
}

impl std::fmt::Debug for PosePump {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PosePump").field("entities", &self.source).finish()
    }
}

impl Polled for PosePump {
    fn activation(&self) -> &Activation {
        &self.activation
    }

    fn poll(&mut self, cfg: &ShmConfig, stats: &Stats) -> bool {
        if !self.activation.is_active() {
            self.steps.iter_mut().for_each(Observer::close);
            self.new = NewPoses::default();
            return false;
        }
        let mut marks = Vec::with_capacity(self.steps.len());
        for o in &mut self.steps {
            marks.push(look(o, &cfg.namespace).map(|(seg, _)| (seg.step(), seg.time_resets())));
        }
        let now = Instant::now();
        if now < self.next_allowed {
            return false;
        }
        let Some(bodies) = self.new.take(marks, false, &mut self.source) else { return false };
        let list = self.source.list();
        let mut written = 0u64;
        let tf = ent::tf_value(list.iter().zip(&bodies));
        written += u64::from(write(&self.tf.0, &mut *self.tf.1, &tf, stats));
        for ((e, b), w) in list.iter().zip(&bodies).zip(&mut self.poses.1) {
            written += u64::from(write(&self.poses.0, &mut **w, &ent::pose_stamped(b, &e.frame), stats));
        }
        self.next_allowed = now + self.min_interval;
        written > 0
    }
}

/// Writes `v` as a `message` on `w`; whether it went out.
fn write(message: &Message<'_>, w: &mut dyn Writer, v: &tutti_ros2::Value, stats: &Stats) -> bool {
    let ok = match message.encode(v) {
        Ok(body) => {
            let ok = w.write(&body);
            w.flush();
            ok
        }
        Err(e) => {
            tracing::warn!("{}: {e}", message.name());
            false
        }
    };
    Stats::add(if ok { &stats.to_dds } else { &stats.errors }, 1);
    ok
}
