//! What the gateway bridges under which names: the config file's rules (`allow`, `deny`,
//! `topics`: which sets, per-topic QoS overrides, rate limits, remapping), parsed here as the
//! file's [`PlanKeys`] section, and resolved once against the DDF into a [`Plan`] that the
//! manager and `tutti show --config` both use (a QoS that would break lock-step or the seed
//! of late joiners is refused, naming the key and the flag).

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};
use tutti_config::de::{Number, Parsed};
use tutti_config::sections::Section;
use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::{self, Durability, Endpoint, History, ItemTopic, Qos, Reliability};
use tutti_ros2::{names, TypeHash};

use super::values::{de_rate, de_remap};
use super::{ConfigError, ConfigFile, GatewayOptions};
use crate::engine::TopicType;

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
    /// The config file the rules come from, for messages (empty: none).
    pub source: String,
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
#[derive(Debug, Clone, PartialEq, Serialize)]
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
    /// Its ROS 2 type hash, which its endpoints announce (`tutti_ros2::idl::type_hashes`;
    /// None only for types that cannot be described, which a valid model never has).
    pub type_hash: Option<TypeHash>,
    pub writer_qos: Qos,
    pub reader_qos: Qos,
    /// At most this many samples a second to DDS.
    pub max_rate: Option<f64>,
}

impl PlannedSet {
    /// The type of its typed topic, with its hash.
    pub fn topic_type(&self) -> TopicType {
        TopicType { name: self.dds_type.clone(), hash: self.type_hash }
    }
}

/// A set the rules leave out, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LeftOut {
    /// Index of the domain in the model.
    pub domain: usize,
    pub role: Role,
    pub key: String,
    /// Which rule left it out (`matches deny pattern 'x'`, `matches no allow pattern`).
    pub reason: String,
}

/// Every set of the DDF: those bridged, in DDF order, and those left out.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plan {
    pub sets: Vec<PlannedSet>,
    pub left_out: Vec<LeftOut>,
}

/// The sets of `opts.model` that the gateway bridges, with their names and QoS after the
/// ROS namespace, remapping and overrides.
pub fn plan(opts: &GatewayOptions) -> Result<Vec<PlannedSet>, ConfigError> {
    Ok(resolve(opts)?.sets)
}

/// Every set of `opts.model`: bridged (as [`plan`] returns them) or left out by `allow` /
/// `deny`, with the reason. Refuses `topics` that name no set, QoS overrides the domain's
/// flags forbid, a rate limit on a synchronous set and two topics of one name.
pub fn resolve(opts: &GatewayOptions) -> Result<Plan, ConfigError> {
    opts.lookahead.check(&opts.model, opts.types)?;
    let rules = &opts.rules;
    let at = |key: &str| in_source(&rules.source, key);
    super::entities::check_all(&opts.entities, &opts.model)
        .map_err(|error| ConfigError::Entity { at: at("entities"), error })?;
    let pkg = mapping::package_name(&opts.ddf_path);
    let hashes = tutti_ros2::idl::type_hashes(&opts.model, &pkg).unwrap_or_default();
    let ns = names::namespace(&opts.ros_namespace)?;
    let keys: Vec<String> = opts.model.domains.iter().flat_map(|d| Role::ALL.map(|r| set_key(&d.name, r))).collect();
    if let Some(k) = rules.topics.keys().find(|k| !keys.contains(k)) {
        return Err(ConfigError::NoSuchSet {
            at: at(&format!("topics.\"{k}\"")),
            set: k.clone(),
            sets: keys.join(", "),
        });
    }
    let mut plan = Plan { sets: Vec::new(), left_out: Vec::new() };
    // DDS topic -> the set that has it, to refuse two sets (or /clock) on one topic.
    let mut taken: BTreeMap<String, String> = BTreeMap::new();
    if opts.clock_domain()?.is_some() {
        // `/clock` is under the ROS namespace too (`rt/NS/clock`), as the manager names it.
        taken.insert(names::dds_topic(&ns, "clock"), "the gateway's /clock (see --clock)".into());
    }
    for (di, d) in opts.model.domains.iter().enumerate() {
        for role in Role::ALL {
            let key = set_key(&d.name, role);
            if let Some(reason) = rules.left_out(&key) {
                plan.left_out.push(LeftOut { domain: di, role, key, reason });
                continue;
            }
            let names = mapping::set_names(&pkg, &d.name, role);
            let settings = rules.topics.get(&key).cloned().unwrap_or_default();
            let topic_key = format!("topics.\"{key}\"");
            let (topic, ros2_topic) = match settings.remap.as_deref() {
                Some(abs) if abs.starts_with('/') => (format!("rt{abs}"), abs.to_string()),
                name => {
                    let rel = name.unwrap_or_else(|| names.ros2_topic.trim_start_matches('/'));
                    let topic = names::dds_topic(&ns, rel);
                    let ros2 = format!("/{}", topic.trim_start_matches("rt/"));
                    (topic, ros2)
                }
            };
            if let Some(other) = taken.insert(topic.clone(), format!("set '{key}'")) {
                return Err(topic_taken(rules, &key, &settings, other, ros2_topic));
            }
            check_flags(d, &settings, |what| at(&format!("{topic_key}.{what}")))?;
            let q = settings.qos;
            let qos = |endpoint| q.apply(mapping::qos(d.flags, opts.profile, endpoint, opts.strength));
            plan.sets.push(PlannedSet {
                domain: di,
                role,
                key,
                topic,
                ros2_topic,
                type_hash: hashes.get(&names.ros2_type).copied(),
                dds_type: names.dds_type,
                writer_qos: qos(Endpoint::Writer),
                reader_qos: qos(Endpoint::Reader),
                max_rate: settings.max_rate,
            });
        }
    }
    Ok(plan)
}

/// The error for set `key` whose topic `ros2_topic` set `other` has already: it blames the
/// remap that made the clash, this set's, else the other set's.
fn topic_taken(
    rules: &TopicRules,
    key: &str,
    settings: &TopicSettings,
    other: String,
    ros2_topic: String,
) -> ConfigError {
    let other_key = other.strip_prefix("set '").and_then(|o| o.strip_suffix('\''));
    let (blamed, other) = match other_key {
        Some(o) if settings.remap.is_none() && rules.topics.get(o).is_some_and(|t| t.remap.is_some()) => {
            (o.to_string(), format!("set '{key}'"))
        }
        _ => (key.to_string(), other),
    };
    ConfigError::TopicTaken {
        at: in_source(&rules.source, &format!("topics.\"{blamed}\".remap")),
        topic: ros2_topic,
        other,
    }
}

/// Refuses the settings of a set of domain `d` that its flags forbid: a QoS that would break
/// lock-step or the seed of late joiners, a rate limit on a synchronous set (`at` names a
/// settings key where it stands).
fn check_flags(d: &Domain, settings: &TopicSettings, at: impl Fn(&str) -> String) -> Result<(), ConfigError> {
    let refuse =
        |what: &str, term, flag, why| ConfigError::Refused { at: at(what), term, domain: d.name.clone(), flag, why };
    let q = settings.qos;
    if d.flags.synchronous {
        const LOCKSTEP: &str = "lock-step needs every step: RELIABLE, KEEP_ALL";
        if q.reliability == Some(Reliability::BestEffort) {
            return Err(refuse("qos.reliability", "best_effort", "synchronous=yes", LOCKSTEP));
        }
        if let Some(History::KeepLast(_)) = q.history {
            return Err(refuse("qos.history", "keep_last", "synchronous=yes", LOCKSTEP));
        }
        if settings.max_rate.is_some() {
            let why = "every step must reach DDS; only asynchronous sets are downsampled";
            return Err(refuse("max_rate", "a rate limit", "synchronous=yes", why));
        }
    }
    if d.flags.states && q.durability == Some(Durability::Volatile) {
        let why = "the seed must reach late joiners: TRANSIENT_LOCAL";
        return Err(refuse("qos.durability", "volatile", "states=yes", why));
    }
    Ok(())
}

/// Where a message points: `FILE: KEY`, or `KEY` for rules from no file.
fn in_source(source: &str, key: &str) -> String {
    if source.is_empty() {
        key.to_string()
    } else {
        format!("{source}: {key}")
    }
}

/// The per-item topics (`--ros2-types per-item`) of a planned set, under its DDS topic.
pub fn item_topics(opts: &GatewayOptions, set: &PlannedSet) -> Vec<ItemTopic> {
    mapping::item_topics_under(&opts.model.domains[set.domain], set.role, &set.topic)
}

/// The per-item topics of `set` by their ROS 2 names (`/NS/DOMAIN/publish/ITEM`), as the
/// engine takes them.
pub fn item_ros2_topics(opts: &GatewayOptions, set: &PlannedSet) -> Vec<ItemTopic> {
    mapping::item_topics_under(&opts.model.domains[set.domain], set.role, &set.ros2_topic)
}

/// `DOMAIN/publish` or `DOMAIN/subscribe`.
pub fn set_key(domain: &str, role: Role) -> String {
    format!("{domain}/{}", role.lower())
}

impl QosOverride {
    /// `base` with the overridden terms replaced. A transient-local writer keeps as many
    /// samples for late joiners as an overridden KEEP_LAST depth says (the durability service
    /// replays the history).
    pub fn apply(&self, base: Qos) -> Qos {
        let mut q = base;
        q.reliability = self.reliability.unwrap_or(q.reliability);
        q.history = self.history.unwrap_or(q.history);
        q.durability = self.durability.unwrap_or(q.durability);
        if let (Durability::TransientLocal { .. }, Some(History::KeepLast(n))) = (q.durability, self.history) {
            q.durability = Durability::TransientLocal { depth: n };
        }
        q
    }
}

impl TopicRules {
    /// The rules of a config file (`allow`, `deny`, `topics`); none without those keys.
    pub fn from_config(cfg: &ConfigFile) -> Result<TopicRules, ConfigError> {
        let (source, cfg) = (cfg.source.clone().unwrap_or_default(), &cfg.plan);
        let at = |key: &str| in_source(&source, key);
        let compile = |key: &str, pats: &Option<Vec<String>>| -> Result<Vec<regex::Regex>, ConfigError> {
            pats.iter()
                .flatten()
                .map(|p| anchored(p).map_err(|e| ConfigError::PatternAt { at: at(key), error: Box::new(e) }))
                .collect()
        };
        let mut topics = BTreeMap::new();
        for (key, t) in cfg.topics.iter().flatten() {
            let q = &t.qos;
            let history = match (q.history, q.depth) {
                (Some(HistoryKey::KeepLast), depth) => Some(History::KeepLast(depth.unwrap_or(1))),
                (Some(HistoryKey::KeepAll), None) => Some(History::KeepAll),
                (None, None) => None,
                (_, Some(_)) => {
                    return Err(ConfigError::DepthWithoutKeepLast { at: at(&format!("topics.\"{key}\".qos.depth")) })
                }
            };
            let qos = QosOverride {
                reliability: q.reliability.map(|r| match r {
                    ReliabilityKey::Reliable => Reliability::Reliable,
                    ReliabilityKey::BestEffort => Reliability::BestEffort,
                }),
                history,
                durability: q.durability.map(|d| match d {
                    DurabilityKey::Volatile => Durability::Volatile,
                    DurabilityKey::TransientLocal => Durability::TransientLocal { depth: 1 },
                }),
            };
            topics.insert(key.clone(), TopicSettings { qos, max_rate: t.max_rate, remap: t.remap.clone() });
        }
        Ok(TopicRules { allow: compile("allow", &cfg.allow)?, deny: compile("deny", &cfg.deny)?, topics, source })
    }

    /// Why the set `key` is not bridged, if it is not.
    fn left_out(&self, key: &str) -> Option<String> {
        let shown = |r: &regex::Regex| unanchored(r.as_str()).to_string();
        if let Some(d) = self.deny.iter().find(|r| r.is_match(key)) {
            return Some(format!("matches deny pattern '{}'", shown(d)));
        }
        if !self.allow.is_empty() && !self.allow.iter().any(|r| r.is_match(key)) {
            let pats: Vec<String> = self.allow.iter().map(|r| format!("'{}'", shown(r))).collect();
            return Some(format!("matches no allow pattern ({})", pats.join(", ")));
        }
        None
    }
}

/// A pattern of `allow` / `deny`, which must match the whole set key (`uav1/.*`, not `uav`).
/// A bad pattern is an error naming it.
pub fn anchored(pattern: &str) -> Result<regex::Regex, ConfigError> {
    let bad = |error| ConfigError::Pattern { pattern: pattern.to_string(), error };
    // Compiled alone first, so that the error shows the pattern as written.
    regex::Regex::new(pattern).map_err(bad)?;
    regex::Regex::new(&format!("^(?:{pattern})$")).map_err(bad)
}

fn unanchored(s: &str) -> &str {
    s.strip_prefix("^(?:").and_then(|s| s.strip_suffix(")$")).unwrap_or(s)
}

/// The plan's keys of the config file: which sets are bridged, and how.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanKeys {
    /// Regexes over set keys (`DOMAIN/publish`), checked when read.
    #[serde(default, deserialize_with = "de_patterns")]
    pub allow: Option<Vec<String>>,
    #[serde(default, deserialize_with = "de_patterns")]
    pub deny: Option<Vec<String>>,
    /// Per set key (`DOMAIN/publish`, `DOMAIN/subscribe`).
    pub topics: Option<BTreeMap<String, TopicEntry>>,
}

impl Section for PlanKeys {
    const KEYS: &'static [&'static str] = &["allow", "deny", "topics"];

    fn over(self, lower: Self) -> Self {
        PlanKeys {
            allow: self.allow.or(lower.allow),
            deny: self.deny.or(lower.deny),
            topics: self.topics.or(lower.topics),
        }
    }
}

#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TopicEntry {
    #[serde(default)]
    pub qos: QosEntry,
    /// Hz, positive.
    #[serde(default, deserialize_with = "de_rate")]
    pub max_rate: Option<f64>,
    /// A ROS topic name, relative to the ROS namespace or absolute (`/…`).
    #[serde(default, deserialize_with = "de_remap")]
    pub remap: Option<String>,
}

/// `topics.KEY.qos`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QosEntry {
    pub reliability: Option<ReliabilityKey>,
    pub history: Option<HistoryKey>,
    /// KEEP_LAST's depth, 1 or more (with `history: "keep_last"` only).
    #[serde(default, deserialize_with = "de_depth")]
    pub depth: Option<u32>,
    pub durability: Option<DurabilityKey>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReliabilityKey {
    Reliable,
    BestEffort,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HistoryKey {
    KeepAll,
    KeepLast,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DurabilityKey {
    Volatile,
    TransientLocal,
}

fn parse_pattern(s: &str) -> Result<String, ConfigError> {
    anchored(s).map(|_| s.to_string())
}

fn de_depth<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    let ok = |v: f64| v.fract() == 0.0 && (1.0..=f64::from(u32::MAX)).contains(&v);
    d.deserialize_any(Number { expecting: "a depth of 1 or more", ok }).map(|v| Some(v as u32))
}

fn de_patterns<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<String>>, D::Error> {
    struct Patterns;
    impl<'de> Visitor<'de> for Patterns {
        type Value = Vec<String>;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a list of regular expressions over set keys, like [\"uav1/.*\"]")
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<String>, A::Error> {
            let mut out = Vec::new();
            while let Some(p) =
                seq.next_element_seed(Parsed { expecting: "a regular expression", parse: parse_pattern })?
            {
                out.push(p);
            }
            Ok(out)
        }
    }
    d.deserialize_any(Patterns).map(Some)
}
