//! How a domain appears in DDS and ROS 2 (`docs/gateway.md`): topic names, ROS 2-mangled type
//! names, field names and the QoS derived from the domain's flags. Plain data, no DDS crate:
//! `tutti show`, `tutti idl` and the gateway all take their names and QoS from here, so they
//! cannot disagree.

use std::collections::HashSet;
use std::path::Path;
use std::time::Duration;

use serde::Serialize;

use crate::ddf::model::join_path;
use crate::ddf::{Domain, Flags, Item, ItemKind, Role};

/// Words that cannot be field names: the two header fields of every set type, and the
/// keywords of IDL 4, C++ and Python that code generators trip on.
const RESERVED: &[&str] = &[
    "step",
    "sim_time",
    "abstract",
    "any",
    "alias",
    "attribute",
    "bitfield",
    "bitmask",
    "bitset",
    "boolean",
    "case",
    "char",
    "component",
    "connector",
    "const",
    "consumes",
    "context",
    "custom",
    "default",
    "double",
    "exception",
    "emits",
    "enum",
    "eventtype",
    "factory",
    "false",
    "finder",
    "fixed",
    "float",
    "getraises",
    "getter",
    "home",
    "import",
    "in",
    "inout",
    "interface",
    "local",
    "long",
    "manages",
    "map",
    "mirrorport",
    "module",
    "multiple",
    "native",
    "object",
    "octet",
    "oneway",
    "out",
    "primarykey",
    "private",
    "port",
    "porttype",
    "provides",
    "public",
    "publishes",
    "raises",
    "readonly",
    "setraises",
    "setter",
    "sequence",
    "short",
    "string",
    "struct",
    "supports",
    "switch",
    "true",
    "truncatable",
    "typedef",
    "typeid",
    "typename",
    "typeprefix",
    "unsigned",
    "union",
    "uses",
    "valuebase",
    "valuetype",
    "void",
    "wchar",
    "wstring",
    "int8",
    "uint8",
    "int16",
    "int32",
    "int64",
    "uint16",
    "uint32",
    "uint64",
    "and",
    "as",
    "assert",
    "break",
    "class",
    "continue",
    "def",
    "del",
    "elif",
    "else",
    "except",
    "finally",
    "for",
    "from",
    "global",
    "if",
    "is",
    "lambda",
    "none",
    "nonlocal",
    "not",
    "or",
    "pass",
    "raise",
    "return",
    "try",
    "while",
    "with",
    "yield",
    "auto",
    "bool",
    "delete",
    "do",
    "explicit",
    "extern",
    "friend",
    "goto",
    "inline",
    "int",
    "mutable",
    "namespace",
    "new",
    "operator",
    "protected",
    "register",
    "signed",
    "sizeof",
    "static",
    "template",
    "this",
    "throw",
    "virtual",
    "volatile",
];

/// `snake_case` of a name, made a valid ROS 2 field name (`[a-z][a-z0-9_]*`, no `__`, no
/// trailing `_`).
pub fn snake_case(name: &str) -> String {
    let mut out = String::new();
    let chars: Vec<char> = name.chars().collect();
    for (i, &c) in chars.iter().enumerate() {
        if c.is_ascii_uppercase() {
            let prev = i.checked_sub(1).map(|j| chars[j]);
            let next = chars.get(i + 1);
            let boundary = prev.is_some_and(|p| p.is_ascii_lowercase() || p.is_ascii_digit())
                || (prev.is_some_and(|p| p.is_ascii_uppercase()) && next.is_some_and(|n| n.is_ascii_lowercase()));
            if boundary {
                out.push('_');
            }
            out.push(c.to_ascii_lowercase());
        } else if c.is_ascii_alphanumeric() {
            out.push(c);
        } else {
            out.push('_');
        }
    }
    let mut cleaned = String::new();
    for c in out.chars() {
        if c == '_' && (cleaned.is_empty() || cleaned.ends_with('_')) {
            continue;
        }
        cleaned.push(c);
    }
    while cleaned.ends_with('_') {
        cleaned.pop();
    }
    if cleaned.is_empty() {
        cleaned.push('f');
    } else if cleaned.starts_with(|c: char| c.is_ascii_digit()) {
        cleaned.insert_str(0, "f_");
    }
    cleaned
}

/// `CamelCase` of a name (`multiuav_uav1` -> `MultiuavUav1`), made a valid type name.
pub fn camel_case(name: &str) -> String {
    let mut out = camel_parts(name);
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert(0, 'T');
    }
    out
}

/// The CamelCase words of a name, without making them a valid identifier on their own.
fn camel_parts(name: &str) -> String {
    let mut out = String::new();
    for part in name.split(|c: char| !c.is_ascii_alphanumeric()).filter(|p| !p.is_empty()) {
        let mut cs = part.chars();
        if let Some(first) = cs.next() {
            out.push(first.to_ascii_uppercase());
            out.extend(cs);
        }
    }
    out
}

/// A name made valid as one token of a ROS 2 topic name (`[A-Za-z_][A-Za-z0-9_]*`).
pub fn topic_token(name: &str) -> String {
    let mut out: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '_' }).collect();
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert(0, '_');
    }
    out
}

/// The ROS 2 package of a DDF: its file stem + `_msgs`, sanitised.
pub fn package_name(ddf_path: &Path) -> String {
    let stem = ddf_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut pkg = snake_case(&stem);
    if !pkg.starts_with(|c: char| c.is_ascii_lowercase()) {
        pkg.insert_str(0, "p_");
    }
    format!("{pkg}_msgs")
}

/// Field names for a list of sibling items, unique among themselves and never reserved.
pub fn field_names(items: &[Item]) -> Vec<String> {
    let mut used: HashSet<String> = HashSet::new();
    items
        .iter()
        .map(|item| {
            let base = snake_case(&item.name);
            let mut name = base.clone();
            let mut n = 1;
            while RESERVED.contains(&name.as_str()) || used.contains(&name) {
                n += 1;
                name = format!("{base}_{n}");
            }
            used.insert(name.clone());
            name
        })
        .collect()
}

/// The typed (one struct per set) names of one set of a domain.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SetNames {
    /// DDS topic, e.g. `rt/multiuav_uav1/publish`.
    pub topic: String,
    /// ROS 2 topic, e.g. `/multiuav_uav1/publish`.
    pub ros2_topic: String,
    /// Short type name, e.g. `MultiuavUav1Publish`.
    pub type_name: String,
    /// ROS 2-mangled DDS type name, e.g. `multiuav_msgs::msg::dds_::MultiuavUav1Publish_`.
    pub dds_type: String,
    /// ROS 2 interface name, e.g. `multiuav_msgs/msg/MultiuavUav1Publish`.
    pub ros2_type: String,
}

/// The names of one set, for DDF package `pkg`.
/// `DOMAIN/ROLE` of a set's topics (`rt/…` in DDS, `/…` in ROS 2).
fn topic_base(domain: &str, role: Role) -> String {
    format!("{}/{}", topic_token(domain), role.lower())
}

pub fn set_names(pkg: &str, domain: &str, role: Role) -> SetNames {
    let topic_base = topic_base(domain, role);
    let type_name = format!(
        "{}{}",
        camel_case(domain),
        match role {
            Role::Publish => "Publish",
            Role::Subscribe => "Subscribe",
        }
    );
    SetNames {
        topic: format!("rt/{topic_base}"),
        ros2_topic: format!("/{topic_base}"),
        dds_type: mangled(pkg, &type_name),
        ros2_type: format!("{pkg}/msg/{type_name}"),
        type_name,
    }
}

/// `PKG::msg::dds_::TYPE_`.
pub fn mangled(pkg: &str, type_name: &str) -> String {
    format!("{pkg}::msg::dds_::{type_name}_")
}

/// The type name of a bus nested in a set type: the set type followed by the CamelCase of
/// each path segment (`GridFeederPublish` + `meter` -> `GridFeederPublishMeter`).
pub fn bus_type_name(set_type: &str, bus_path: &str) -> String {
    let mut out = set_type.to_string();
    for seg in bus_path.split('/') {
        out.push_str(&camel_parts(seg));
    }
    out
}

/// One per-item topic (`--ros2-types per-item`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ItemTopic {
    /// The leaf's item path in the DDF.
    pub path: String,
    /// DDS topic, e.g. `rt/multiuav_uav1/subscribe/elevation`.
    pub topic: String,
    /// Stock ROS 2 type, mangled, e.g. `std_msgs::msg::dds_::Float64_`.
    pub dds_type: String,
}

/// Stock type used for a leaf in per-item mode.
pub fn per_item_type(ty: crate::ddf::ScalarType, length: u16) -> &'static str {
    match (ty, length) {
        (crate::ddf::ScalarType::Boolean, 1) => "std_msgs::msg::dds_::Bool_",
        (_, 1) => "std_msgs::msg::dds_::Float64_",
        _ => "std_msgs::msg::dds_::Float64MultiArray_",
    }
}

/// The per-item topics of one set: one per leaf, the path's segments as snake_case field
/// names (so two items never share a topic).
pub fn item_topics(domain: &Domain, role: Role) -> Vec<ItemTopic> {
    item_topics_under(domain, role, &format!("rt/{}", topic_base(&domain.name, role)))
}

/// The per-item topics of one set under DDS topic `base` (a set's topic after a namespace or
/// a remapping): `BASE/ITEM`.
pub fn item_topics_under(domain: &Domain, role: Role, base: &str) -> Vec<ItemTopic> {
    let mut out = Vec::new();
    collect_item_topics(&domain.set(role).items, base, "", &mut out);
    out
}

fn collect_item_topics(items: &[Item], topic_prefix: &str, path_prefix: &str, out: &mut Vec<ItemTopic>) {
    for (item, field) in items.iter().zip(field_names(items)) {
        let path = join_path(path_prefix, &item.name);
        let topic = format!("{topic_prefix}/{field}");
        match &item.kind {
            ItemKind::Scalar { ty, length, .. } => {
                out.push(ItemTopic { path, topic, dds_type: per_item_type(*ty, *length).to_string() })
            }
            ItemKind::Bus { items } => collect_item_topics(items, &topic, &path, out),
        }
    }
}

/// DDS QoS profile for the gateway (`docs/gateway.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Every reader and writer SHARED, so rclpy nodes match; exclusivity enforced by the gateway.
    #[default]
    Ros2,
    /// Exclusive ownership on the wire for `multiplePublishAllowed=no`.
    Dds,
}

impl Profile {
    /// The name `--qos-profile` takes.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Ros2 => "ros2",
            Profile::Dds => "dds",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum Reliability {
    Reliable,
    BestEffort,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum History {
    KeepAll,
    KeepLast(u32),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum Durability {
    Volatile,
    /// Late joiners get the last `depth` samples.
    TransientLocal {
        depth: u32,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "SCREAMING_SNAKE_CASE")]
pub enum Ownership {
    Shared,
    Exclusive { strength: i32 },
}

/// The QoS of one gateway reader or writer, in tutti's own terms: each engine maps them to
/// its middleware's (a DDS engine to the DDS policies of the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Qos {
    pub reliability: Reliability,
    pub history: History,
    pub durability: Durability,
    /// Exclusivity and its strength.
    pub ownership: Ownership,
    /// How long a sample stays valid after it was written (None: for ever, the default);
    /// an expired sample is no longer delivered nor kept for late joiners.
    #[serde(skip_serializing_if = "Option::is_none", serialize_with = "seconds")]
    pub lifespan: Option<Duration>,
}

/// A lifespan as seconds.
fn seconds<S: serde::Serializer>(d: &Option<Duration>, s: S) -> Result<S::Ok, S::Error> {
    match d {
        Some(d) => s.serialize_f64(d.as_secs_f64()),
        None => s.serialize_none(),
    }
}

/// Whether the QoS is for a gateway writer or reader.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Endpoint {
    Writer,
    Reader,
}

/// The QoS table of `docs/gateway.md` ("QoS"): writers offer the strongest terms the flags allow,
/// readers ask the weakest, so rclpy's default, sensor-data and latched profiles all match.
pub fn qos(flags: Flags, profile: Profile, endpoint: Endpoint, strength: i32) -> Qos {
    let (reliability, history) = match (flags.synchronous, endpoint) {
        (true, _) => (Reliability::Reliable, History::KeepAll),
        (false, Endpoint::Writer) => (Reliability::Reliable, History::KeepLast(1)),
        (false, Endpoint::Reader) => (Reliability::BestEffort, History::KeepLast(1)),
    };
    let durability = match (flags.states, endpoint) {
        (true, Endpoint::Writer) => Durability::TransientLocal { depth: 1 },
        _ => Durability::Volatile,
    };
    let ownership = match (flags.multiple_publish_allowed, profile) {
        (false, Profile::Dds) => Ownership::Exclusive { strength },
        _ => Ownership::Shared,
    };
    Qos { reliability, history, durability, ownership, lifespan: None }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_ros2_conventions() {
        assert_eq!(snake_case("Latitude"), "latitude");
        assert_eq!(snake_case("powerKW"), "power_kw");
        assert_eq!(snake_case("HTTPServer2"), "http_server2");
        assert_eq!(snake_case("a--b_"), "a_b");
        assert_eq!(snake_case("9lives"), "f_9lives");
        assert_eq!(camel_case("multiuav_uav1"), "MultiuavUav1");
        assert_eq!(camel_case("grid-feeder"), "GridFeeder");
        assert_eq!(package_name(Path::new("ddf/multiuav.ddf")), "multiuav_msgs");
        assert_eq!(package_name(Path::new("x/My-File.ddf")), "my_file_msgs");
        let n = set_names("multiuav_msgs", "multiuav_uav1", Role::Publish);
        assert_eq!(n.topic, "rt/multiuav_uav1/publish");
        assert_eq!(n.dds_type, "multiuav_msgs::msg::dds_::MultiuavUav1Publish_");
    }

    #[test]
    fn field_names_avoid_reserved_words_and_collisions() {
        let item = |n: &str| Item {
            name: n.into(),
            kind: ItemKind::Scalar { ty: crate::ddf::ScalarType::Float64, length: 1, default: None },
            pos: Default::default(),
        };
        let names = field_names(&[item("Step"), item("X"), item("x"), item("module")]);
        assert_eq!(names, vec!["step_2", "x", "x_2", "module_2"]);
    }

    #[test]
    fn qos_table() {
        let f = |s, m, st| Flags { synchronous: s, event: false, multiple_publish_allowed: m, states: st };
        let w = qos(f(false, false, true), Profile::Ros2, Endpoint::Writer, 0);
        assert_eq!(w.reliability, Reliability::Reliable);
        assert_eq!(w.history, History::KeepLast(1));
        assert_eq!(w.durability, Durability::TransientLocal { depth: 1 });
        assert_eq!(w.ownership, Ownership::Shared);
        let r = qos(f(false, false, true), Profile::Dds, Endpoint::Reader, 7);
        assert_eq!(r.reliability, Reliability::BestEffort);
        assert_eq!(r.durability, Durability::Volatile);
        assert_eq!(r.ownership, Ownership::Exclusive { strength: 7 });
        let s = qos(f(true, true, false), Profile::Dds, Endpoint::Reader, 0);
        assert_eq!(
            (s.reliability, s.history, s.ownership),
            (Reliability::Reliable, History::KeepAll, Ownership::Shared)
        );
    }
}
