//! What the gateway bridges and under which names: the ROS namespace, and the config file's
//! rules (which sets, per-topic QoS overrides, rate limits, remapping), resolved once into a
//! [`plan`] that the manager and `tutti show --config` both use.

use std::collections::BTreeMap;

use tutti_core::ddf::Role;
use tutti_core::mapping::{self, Durability, Endpoint, History, Qos, Reliability};

use crate::{GatewayError, GatewayOptions};

/// Which sets are bridged and how (the config file's `allow`, `deny` and `topics`); the
/// default bridges every set as the DDF's flags say.
#[derive(Debug, Clone, Default)]
pub struct TopicRules {
    /// A set is bridged when its key (`DOMAIN/publish`, `DOMAIN/subscribe`) matches one of
    /// these (or the list is empty) …
    pub allow: Vec<regex::Regex>,
    /// … and none of these.
    pub deny: Vec<regex::Regex>,
    /// Per set key: QoS overrides, rate limit, new name.
    pub topics: BTreeMap<String, TopicSettings>,
}

/// The settings of one set's topic(s).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TopicSettings {
    pub qos: QosOverride,
    /// At most this many samples a second go out to DDS (asynchronous sets only).
    pub max_rate: Option<f64>,
    /// The topic's ROS name instead of `DOMAIN/ROLE` (relative to the ROS namespace unless it
    /// starts with `/`).
    pub remap: Option<String>,
}

/// QoS terms that replace the table's, for both the gateway's writer and reader of a topic.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QosOverride {
    pub reliability: Option<Reliability>,
    pub history: Option<History>,
    pub durability: Option<Durability>,
}

/// One bridged set as the gateway serves it.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedSet {
    /// Index of the domain in the model.
    pub domain: usize,
    pub role: Role,
    /// `DOMAIN/publish` or `DOMAIN/subscribe`: how rules and the stats name the set.
    pub key: String,
    /// DDS topic (`rt/NS/DOMAIN/publish`); per-item topics are `TOPIC/ITEM`.
    pub topic: String,
    /// ROS 2 name (`/NS/DOMAIN/publish`).
    pub ros2_topic: String,
    /// DDS type of the typed struct.
    pub dds_type: String,
    pub writer_qos: Qos,
    pub reader_qos: Qos,
    /// At most this many samples a second to DDS.
    pub max_rate: Option<f64>,
}

/// A ROS namespace as given (`sim1`, `/sim1/`, `a/b`) in canonical form without slashes
/// around it (`sim1`, `a/b`; empty for none); an invalid one is an error naming it.
pub fn ros_namespace(ns: &str) -> Result<String, GatewayError> {
    let t = ns.trim().trim_matches('/');
    for tok in t.split('/').filter(|_| !t.is_empty()) {
        let ok = !tok.is_empty()
            && !tok.starts_with(|c: char| c.is_ascii_digit())
            && tok.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !ok {
            return Err(GatewayError::Invalid(format!(
                "ROS namespace '{ns}': each part must be letters, digits and '_' and not start with a digit (e.g. sim1 or site_a/sim1)"
            )));
        }
    }
    Ok(t.to_string())
}

/// The ROS node namespace of a canonical ROS namespace (`/` for none).
pub fn node_namespace(ns: &str) -> String {
    format!("/{ns}")
}

/// `rt/NS/NAME` (`rt/NAME` without a namespace) for the relative ROS name `name`.
pub fn dds_topic(ns: &str, name: &str) -> String {
    if ns.is_empty() {
        format!("rt/{name}")
    } else {
        format!("rt/{ns}/{name}")
    }
}

/// The sets of `opts.model` that the gateway bridges, with their names and QoS after the
/// ROS namespace, remapping and overrides.
pub fn plan(opts: &GatewayOptions) -> Result<Vec<PlannedSet>, GatewayError> {
    let pkg = mapping::package_name(&opts.ddf_path);
    let ns = ros_namespace(&opts.ros_namespace)?;
    let mut out = Vec::new();
    for (di, d) in opts.model.domains.iter().enumerate() {
        for role in [Role::Publish, Role::Subscribe] {
            let names = mapping::set_names(&pkg, &d.name, role);
            let key = format!("{}/{}", d.name, role.lower());
            let rel = names.ros2_topic.trim_start_matches('/').to_string();
            out.push(PlannedSet {
                domain: di,
                role,
                key,
                topic: dds_topic(&ns, &rel),
                ros2_topic: format!("/{}", dds_topic(&ns, &rel).trim_start_matches("rt/")),
                dds_type: names.dds_type,
                writer_qos: mapping::qos(d.flags, opts.profile, Endpoint::Writer, opts.strength),
                reader_qos: mapping::qos(d.flags, opts.profile, Endpoint::Reader, opts.strength),
                max_rate: None,
            });
        }
    }
    Ok(out)
}
