//! What `tutti show --json` prints (schema `tutti-show/1`, documented in `docs/ddf.md`):
//! domains, flags, sets, items with their layout, DDS topics and QoS, built once for the
//! CLI and `tutti studio`.

use std::path::Path;

use serde::Serialize;

use crate::ddf::{Domain, Leaf, Model, Role};
use crate::mapping::{self, Endpoint, ItemTopic, Profile, Qos, SetNames};

/// `tutti show --json` output, version 1.
#[derive(Debug, Serialize)]
pub struct ShowJson<'a> {
    pub schema: &'static str,
    pub source: &'a str,
    pub package: String,
    pub qos_profile: Profile,
    /// The gateway's DDS engine: "cyclone" or "rustdds".
    pub dds_engine: &'static str,
    pub domains: Vec<DomainJson<'a>>,
}

/// One domain of [`ShowJson`].
#[derive(Debug, Serialize)]
pub struct DomainJson<'a> {
    pub name: &'a str,
    pub synchronous: bool,
    /// `<synchronous>event</synchronous>`: event-driven (docs/timing.md).
    pub event: bool,
    pub multiple_publish_allowed: bool,
    pub states: bool,
    pub connection: Option<&'a crate::ddf::Connection>,
    pub layout_hash: String,
    /// How writer exclusivity is enforced: null, "gateway" (the core's first-writer rule,
    /// over DDS too) or "gateway+dds" (also EXCLUSIVE ownership matched on the wire).
    pub exclusive_writer: Option<&'static str>,
    pub sets: Vec<SetJson<'a>>,
}

/// One set of a [`DomainJson`].
#[derive(Debug, Serialize)]
pub struct SetJson<'a> {
    pub role: Role,
    pub size: u32,
    pub align: u32,
    pub items: &'a [Leaf],
    pub dds: SetNames,
    pub per_item_topics: Vec<ItemTopic>,
    pub writer_qos: Qos,
    pub reader_qos: Qos,
}

/// The view of `model` (read from `path`, which names the ROS 2 package) for QoS profile
/// `profile` and the gateway's DDS engine named `dds_engine`.
pub fn show<'a>(model: &'a Model, path: &Path, profile: Profile, dds_engine: &'static str) -> ShowJson<'a> {
    let package = mapping::package_name(path);
    let domains = model.domains.iter().map(|d| domain_json(d, &package, profile)).collect();
    ShowJson { schema: "tutti-show/1", source: &model.source, package, qos_profile: profile, dds_engine, domains }
}

fn domain_json<'a>(d: &'a Domain, package: &str, profile: Profile) -> DomainJson<'a> {
    let sets = Role::ALL
        .iter()
        .map(|&role| {
            let set = d.set(role);
            SetJson {
                role,
                size: set.layout.size,
                align: set.layout.align,
                items: &set.layout.leaves,
                dds: mapping::set_names(package, &d.name, role),
                per_item_topics: mapping::item_topics(d, role),
                writer_qos: mapping::qos(d.flags, profile, Endpoint::Writer, 100),
                reader_qos: mapping::qos(d.flags, profile, Endpoint::Reader, 100),
            }
        })
        .collect();
    let exclusive_writer = match (d.flags.multiple_publish_allowed, profile) {
        (true, _) => None,
        (false, Profile::Ros2) => Some("gateway"),
        (false, Profile::Dds) => Some("gateway+dds"),
    };
    DomainJson {
        name: &d.name,
        synchronous: d.flags.synchronous,
        event: d.flags.event,
        multiple_publish_allowed: d.flags.multiple_publish_allowed,
        states: d.flags.states,
        connection: d.connection.as_ref(),
        layout_hash: format!("{:016x}", d.layout_hash),
        exclusive_writer,
        sets,
    }
}
