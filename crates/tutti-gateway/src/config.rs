//! What the gateway serves and how ([`GatewayOptions`]), and what it bridges under which
//! names: the ROS namespace, and the config file's rules (which sets, per-topic QoS overrides, rate limits, remapping), resolved once into a
//! [`plan`] that the manager and `tutti show --config` both use.
//!
//! The config file (`tutti gateway --config gateway.json5`) is parsed, then validated, in two
//! steps: [`load`] reads it into a [`ConfigFile`] (JSON5, unknown keys refused, every value
//! checked where it stands, so errors carry the file, line and column), [`ConfigFile::apply`]
//! puts it into [`GatewayOptions`], and [`resolve`] checks the `topics` against the DDF's
//! flags (a QoS that would break lock-step or the seed of late joiners is refused, naming the
//! key and the flag). Its keys are the CLI's long flags with `_` for `-`; the CLI builds a
//! [`ConfigFile`] from the flags it was given and lays it [`over`](ConfigFile::over) the
//! file's, so flags win over the file and the file over the defaults.

use std::collections::BTreeMap;
use std::fmt;
use std::net::{IpAddr, SocketAddr};
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::de::{Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};
use tutti_config::de::{Number, Parsed};
use tutti_core::ddf::{Domain, Model, Role};
use tutti_core::mapping::{self, Durability, Endpoint, History, ItemTopic, Profile, Qos, Reliability};
use tutti_core::parse::{parse_duration, parse_wait};
use tutti_core::shm::WaitMode;
use tutti_ros2::TypeHash;

use crate::engine::TopicType;

use crate::engine::{EngineConfig, EngineKind};

/// The shortest lease the gateway's DDS participant announces, whatever `--lease` says: the
/// participant renews it every 4/5 of the lease, and a peer that misses a renewal on a
/// loaded machine would drop every route of a gateway that is still there.
pub const MIN_PARTICIPANT_LEASE: Duration = Duration::from_secs(2);
pub use crate::error::ConfigError;

// ---------------------------------------------------------------------------------------
// The options.

/// The two type mappings of `docs/gateway.md` ("Mapping").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TypeMode {
    /// One struct per set (`tutti idl`'s types), with `step` and `sim_time`.
    #[default]
    Typed,
    /// One topic per item with stock `std_msgs` types.
    PerItem,
}

/// Everything the gateway needs.
#[derive(Debug, Clone)]
pub struct GatewayOptions {
    /// The DDF the model was read from (its stem names the ROS 2 package).
    pub ddf_path: PathBuf,
    pub model: Model,
    /// DDS domain (ROS_DOMAIN_ID).
    pub ros_domain_id: u16,
    pub types: TypeMode,
    pub profile: Profile,
    /// OWNERSHIP_STRENGTH of the gateway's writers in the `dds` profile.
    pub strength: i32,
    /// Be the framework of local segments fed from DDS.
    pub mirror: bool,
    /// ROS 2 node name.
    pub node_name: String,
    /// Shared-memory namespace.
    pub namespace: String,
    /// Addresses DDS may use; empty: all interfaces.
    pub interfaces: Vec<IpAddr>,
    /// Longest shared-memory wait (a step, a commit's step, connecting); in mirror mode the
    /// framework's step timeout.
    pub timeout: Duration,
    /// How shared-memory waits wait (spin for lowest latency, block for no CPU).
    pub wait: WaitMode,
    /// How often idle asynchronous sets are looked at for changes.
    pub poll: Duration,
    /// How often discovery data is compared with the routes' connections.
    pub discovery_every: Duration,
    /// The DDS engine.
    pub engine: EngineKind,
    /// Unicast discovery peers (Cyclone engine).
    pub peers: Vec<String>,
    /// Which domain's simulated time goes out on `/clock`.
    pub clock: ClockSource,
    /// At most this many `/clock` samples a second (None: one per step).
    pub clock_rate: Option<f64>,
    /// ROS namespace of every topic and of the node (empty: none): `rt/NS/DOMAIN/publish`,
    /// node `/NS/NODE`.
    pub ros_namespace: String,
    /// Bridge a domain only while a framework hosts it in `namespace` (the default; a
    /// mirror hosts its domains itself); false: every domain of the DDF from the start.
    pub hosted_only: bool,
    /// How long a DDS writer of a synchronous domain may owe its answer to a step before
    /// the gateway releases its lock-step share (a killed writer; it joins again with its
    /// next sample); also the lease the gateway's own DDS participant announces (at least
    /// [`MIN_PARTICIPANT_LEASE`]), after which the other participants forget a killed gateway.
    pub lease: Duration,
    /// DDS readers of a synchronous PUBLISH set get every step: the gateway reads the set in
    /// lock-step through an observer connection that the framework waits for (a copy and a
    /// DDS write a step), instead of following it passively.
    pub every_step: bool,
    /// Serve the counters over HTTP (JSON at `/stats`, Prometheus text at `/metrics`).
    pub http: Option<SocketAddr>,
    /// Serve the bridged sets over the Foxglove WebSocket protocol (`crate::foxglove`).
    pub foxglove: Option<SocketAddr>,
    /// Offer no `simulation_interfaces` services (`crate::services`): the gateway bridges
    /// data and never controls the run.
    pub passive: bool,
    /// Which sets are bridged, and per-topic QoS, rate and name (the config file's
    /// `allow`, `deny` and `topics`).
    pub rules: TopicRules,
}

/// The domain whose simulated time the gateway publishes on `/clock`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ClockSource {
    /// The first synchronous domain of the DDF (none if it has none).
    #[default]
    FirstSynchronous,
    Domain(String),
    Off,
}

impl GatewayOptions {
    /// Defaults for `model` read from `ddf_path`.
    pub fn new(ddf_path: impl Into<PathBuf>, model: Model) -> Self {
        GatewayOptions {
            ddf_path: ddf_path.into(),
            model,
            ros_domain_id: 0,
            types: TypeMode::Typed,
            profile: Profile::Ros2,
            strength: 0,
            mirror: false,
            node_name: "tutti_gateway".into(),
            namespace: tutti_core::shm::segment::namespace_from_env(),
            interfaces: Vec::new(),
            timeout: Duration::from_secs(1),
            wait: WaitMode::Block,
            poll: Duration::from_micros(500),
            discovery_every: Duration::from_millis(200),
            engine: EngineKind::default(),
            peers: Vec::new(),
            clock: ClockSource::default(),
            clock_rate: None,
            ros_namespace: String::new(),
            hosted_only: true,
            lease: Duration::from_secs(1),
            every_step: false,
            passive: false,
            http: None,
            foxglove: None,
            rules: TopicRules::default(),
        }
    }

    /// The index of the domain whose time goes out on `/clock`, if any; an unknown name is
    /// an error. A mirror publishes no clock (the home gateway does).
    pub fn clock_domain(&self) -> Result<Option<usize>, ConfigError> {
        if self.mirror {
            return Ok(None);
        }
        match &self.clock {
            ClockSource::Off => Ok(None),
            ClockSource::FirstSynchronous => Ok(self.model.domains.iter().position(|d| d.flags.synchronous)),
            ClockSource::Domain(name) => match self.model.domains.iter().position(|d| &d.name == name) {
                Some(i) => Ok(Some(i)),
                None => Err(ConfigError::NoSuchClockDomain {
                    name: name.clone(),
                    domains: self.model.domains.iter().map(|d| d.name.as_str()).collect::<Vec<_>>().join(", "),
                }),
            },
        }
    }

    /// How the engine's participant joins DDS.
    pub fn engine_config(&self) -> EngineConfig {
        EngineConfig {
            domain_id: self.ros_domain_id,
            interfaces: self.interfaces.clone(),
            peers: self.peers.clone(),
            node_name: self.node_name.clone(),
            node_namespace: node_namespace(self.ros_namespace.trim().trim_matches('/')),
            participant_lease: Some(self.lease.max(MIN_PARTICIPANT_LEASE)),
        }
    }
}

// ---------------------------------------------------------------------------------------
// The rules and the plan.

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

/// A ROS namespace as given (`sim1`, `/sim1/`, `a/b`) in canonical form without slashes
/// around it (`sim1`, `a/b`; empty for none); an invalid one is an error naming it.
pub fn ros_namespace(ns: &str) -> Result<String, ConfigError> {
    let t = ns.trim().trim_matches('/');
    for tok in t.split('/').filter(|_| !t.is_empty()) {
        if !ros_token(tok) {
            return Err(ConfigError::Namespace { given: ns.to_string() });
        }
    }
    Ok(t.to_string())
}

/// One token of a ROS name: `[A-Za-z_][A-Za-z0-9_]*`.
fn ros_token(tok: &str) -> bool {
    !tok.is_empty()
        && !tok.starts_with(|c: char| c.is_ascii_digit())
        && tok.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// A topic name for `remap`: relative (`uav1/cmd`) or absolute (`/fleet/uav1/cmd`), tokens of
/// letters, digits and `_` not starting with a digit, as rcl validates topic names; ROS's `~`
/// and `{}` substitutions are refused (the gateway's node name is no help in a topic name).
pub fn ros_topic_name(name: &str) -> Result<String, ConfigError> {
    let body = name.strip_prefix('/').unwrap_or(name);
    let why = if body.is_empty() {
        Some("it is empty")
    } else if name.contains('~') || name.contains('{') || name.contains('}') {
        Some("ROS substitutions (~, {}) are not supported")
    } else if body.ends_with('/') {
        Some("it ends with '/'")
    } else if body.contains("//") {
        Some("it contains '//'")
    } else if !body.split('/').all(ros_token) {
        Some("each part must be letters, digits and '_' and not start with a digit")
    } else {
        None
    };
    match why {
        None => Ok(name.to_string()),
        Some(why) => Err(ConfigError::TopicName { name: name.to_string(), why }),
    }
}

/// The ROS node namespace of a canonical ROS namespace (`/` for none).
pub fn node_namespace(ns: &str) -> String {
    format!("/{ns}")
}

/// The node's full name under a canonical ROS namespace: `/NS/NODE`, or `/NODE`.
pub fn node_full_name(ns: &str, node: &str) -> String {
    if ns.is_empty() {
        format!("/{node}")
    } else {
        format!("/{ns}/{node}")
    }
}

/// The ROS 2 name of `name` (relative) under the canonical namespace `ns`: `/NS/NAME`, or
/// `/NAME` without a namespace.
pub fn ros_name(ns: &str, name: &str) -> String {
    if ns.is_empty() {
        format!("/{name}")
    } else {
        format!("/{ns}/{name}")
    }
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
pub fn plan(opts: &GatewayOptions) -> Result<Vec<PlannedSet>, ConfigError> {
    Ok(resolve(opts)?.sets)
}

/// Every set of `opts.model`: bridged (as [`plan`] returns them) or left out by `allow` /
/// `deny`, with the reason. Refuses `topics` that name no set, QoS overrides the domain's
/// flags forbid, a rate limit on a synchronous set and two topics of one name.
pub fn resolve(opts: &GatewayOptions) -> Result<Plan, ConfigError> {
    let rules = &opts.rules;
    let at = |key: &str| in_source(&rules.source, key);
    let pkg = mapping::package_name(&opts.ddf_path);
    let hashes = tutti_ros2::idl::type_hashes(&opts.model, &pkg).unwrap_or_default();
    let ns = ros_namespace(&opts.ros_namespace)?;
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
        taken.insert(dds_topic(&ns, "clock"), "the gateway's /clock (see --clock)".into());
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
                    let topic = dds_topic(&ns, rel);
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
        let source = cfg.source.clone().unwrap_or_default();
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

// ---------------------------------------------------------------------------------------
// The config file.

/// The config file (`--config gateway.json5`): every key optional, keys = the CLI's long
/// flags with `_` for `-` (`interface` and `peer` are lists), plus `allow`, `deny` and
/// `topics`. Also what the CLI makes of its own flags, to lay over the file's.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    /// The file it was read from, for messages (None: the command line).
    #[serde(skip)]
    pub source: Option<String>,
    #[serde(default, deserialize_with = "de_domain_id")]
    pub ros_domain_id: Option<u16>,
    #[serde(default, deserialize_with = "de_types")]
    pub ros2_types: Option<TypeMode>,
    #[serde(default, deserialize_with = "de_profile")]
    pub qos_profile: Option<Profile>,
    pub strength: Option<i32>,
    pub mirror: Option<bool>,
    pub node_name: Option<String>,
    pub interface: Option<Vec<IpAddr>>,
    /// The engine (`--engine`; `dds`, the key's old name, is taken too).
    #[serde(default, alias = "dds", deserialize_with = "de_engine")]
    pub engine: Option<EngineKind>,
    /// Checked where each stands ([`parse_peer`]).
    #[serde(default, deserialize_with = "de_peers")]
    pub peer: Option<Vec<String>>,
    /// A domain, or `none`.
    pub clock: Option<String>,
    #[serde(default, deserialize_with = "de_rate")]
    pub clock_rate: Option<f64>,
    #[serde(default, deserialize_with = "de_period")]
    pub timeout: Option<Duration>,
    #[serde(default, deserialize_with = "de_wait")]
    pub wait: Option<WaitMode>,
    #[serde(default, deserialize_with = "de_span")]
    pub poll: Option<Duration>,
    #[serde(default, deserialize_with = "de_period")]
    pub status_every: Option<Duration>,
    #[serde(default, deserialize_with = "de_span")]
    pub duration: Option<Duration>,
    pub quiet: Option<bool>,
    /// Canonical (`a/b`).
    #[serde(default, deserialize_with = "de_namespace")]
    pub ros_namespace: Option<String>,
    /// Bridge a domain only while a framework hosts it (default true; `--all-domains` is false).
    pub hosted_only: Option<bool>,
    #[serde(default, deserialize_with = "de_period")]
    pub lease: Option<Duration>,
    /// DDS readers of synchronous PUBLISH sets get every step (`--every-step`).
    pub every_step: Option<bool>,
    /// Offer no `simulation_interfaces` services (`--passive`).
    pub passive: Option<bool>,
    pub http: Option<SocketAddr>,
    /// The Foxglove WebSocket server's address (`--foxglove`).
    pub foxglove: Option<SocketAddr>,
    /// Regexes over set keys (`DOMAIN/publish`), checked when read.
    #[serde(default, deserialize_with = "de_patterns")]
    pub allow: Option<Vec<String>>,
    #[serde(default, deserialize_with = "de_patterns")]
    pub deny: Option<Vec<String>>,
    /// Per set key (`DOMAIN/publish`, `DOMAIN/subscribe`).
    pub topics: Option<BTreeMap<String, TopicEntry>>,
}

/// One entry of `topics`.
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

/// What a gateway config file is, for the reader's messages.
const GATEWAY_CONFIG: tutti_config::Kind = tutti_config::Kind { name: "gateway config", levels: 4 };

/// Reads a config file; errors name the file, and the line, column and key where they can.
pub fn load(path: &Path) -> Result<ConfigFile, ConfigError> {
    let mut c: ConfigFile = tutti_config::load(path, GATEWAY_CONFIG)?;
    c.source = Some(path.display().to_string());
    Ok(c)
}

/// A config file's text, read from `source` (named in errors).
pub fn parse(text: &str, source: &str) -> Result<ConfigFile, ConfigError> {
    let mut c: ConfigFile = tutti_config::from_str(text, source, GATEWAY_CONFIG)?;
    c.source = Some(source.to_string());
    Ok(c)
}

/// The deepest nesting of objects and arrays a config file may have (the parser recurses
/// once per level, so a deeper file is refused before it is parsed).
pub use tutti_config::MAX_NESTING;

impl ConfigFile {
    /// `self` (the flags) laid over the keys of the config file `config`, if there is one.
    pub fn layered(self, config: Option<&Path>) -> Result<ConfigFile, ConfigError> {
        match config {
            None => Ok(self),
            Some(path) => Ok(self.over(load(path)?)),
        }
    }

    /// `self`'s keys, and `lower`'s where `self` has none (flags over the file).
    pub fn over(self, lower: ConfigFile) -> ConfigFile {
        ConfigFile {
            source: self.source.or(lower.source),
            ros_domain_id: self.ros_domain_id.or(lower.ros_domain_id),
            ros2_types: self.ros2_types.or(lower.ros2_types),
            qos_profile: self.qos_profile.or(lower.qos_profile),
            strength: self.strength.or(lower.strength),
            mirror: self.mirror.or(lower.mirror),
            node_name: self.node_name.or(lower.node_name),
            interface: self.interface.or(lower.interface),
            engine: self.engine.or(lower.engine),
            peer: self.peer.or(lower.peer),
            clock: self.clock.or(lower.clock),
            clock_rate: self.clock_rate.or(lower.clock_rate),
            timeout: self.timeout.or(lower.timeout),
            wait: self.wait.or(lower.wait),
            poll: self.poll.or(lower.poll),
            status_every: self.status_every.or(lower.status_every),
            duration: self.duration.or(lower.duration),
            quiet: self.quiet.or(lower.quiet),
            ros_namespace: self.ros_namespace.or(lower.ros_namespace),
            hosted_only: self.hosted_only.or(lower.hosted_only),
            lease: self.lease.or(lower.lease),
            every_step: self.every_step.or(lower.every_step),
            passive: self.passive.or(lower.passive),
            http: self.http.or(lower.http),
            foxglove: self.foxglove.or(lower.foxglove),
            allow: self.allow.or(lower.allow),
            deny: self.deny.or(lower.deny),
            topics: self.topics.or(lower.topics),
        }
    }

    /// Sets the options these keys give; the others keep their value (a default, or what
    /// the environment said). `status_every`, `duration` and `quiet` are the CLI's.
    pub fn apply(&self, opts: &mut GatewayOptions) -> Result<(), ConfigError> {
        fn set<T: Clone>(dst: &mut T, v: &Option<T>) {
            if let Some(v) = v {
                *dst = v.clone();
            }
        }
        set(&mut opts.ros_domain_id, &self.ros_domain_id);
        set(&mut opts.types, &self.ros2_types);
        set(&mut opts.profile, &self.qos_profile);
        set(&mut opts.strength, &self.strength);
        set(&mut opts.mirror, &self.mirror);
        set(&mut opts.node_name, &self.node_name);
        set(&mut opts.interfaces, &self.interface);
        set(&mut opts.engine, &self.engine);
        set(&mut opts.peers, &self.peer);
        if let Some(c) = &self.clock {
            opts.clock = match c.as_str() {
                "none" => ClockSource::Off,
                d => ClockSource::Domain(d.to_string()),
            };
        }
        if self.clock_rate.is_some() {
            opts.clock_rate = self.clock_rate;
        }
        set(&mut opts.timeout, &self.timeout);
        set(&mut opts.wait, &self.wait);
        set(&mut opts.poll, &self.poll);
        set(&mut opts.ros_namespace, &self.ros_namespace);
        set(&mut opts.hosted_only, &self.hosted_only);
        set(&mut opts.lease, &self.lease);
        set(&mut opts.every_step, &self.every_step);
        set(&mut opts.passive, &self.passive);
        if self.http.is_some() {
            opts.http = self.http;
        }
        if self.foxglove.is_some() {
            opts.foxglove = self.foxglove;
        }
        opts.rules = TopicRules::from_config(self)?;
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------
// Environment: the one reader of each of the gateway's variables.

/// What ROS 2's discovery variables ask for (`ROS_LOCALHOST_ONLY`,
/// `ROS_AUTOMATIC_DISCOVERY_RANGE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DiscoveryRange {
    /// `SUBNET`, `SYSTEM_DEFAULT` or unset: as configured.
    #[default]
    Default,
    /// This machine only: the gateway uses the loopback interface.
    Localhost,
    /// No automatic discovery: only the peers given.
    Off,
}

/// The discovery range of ROS 2's variables, given their values. `ROS_LOCALHOST_ONLY=1`
/// wins, as in ROS 2 Jazzy (which still honours it, deprecated); an unknown range is an
/// error naming the variable.
pub fn discovery_range(localhost_only: Option<&str>, range: Option<&str>) -> Result<DiscoveryRange, ConfigError> {
    if localhost_only.is_some_and(|v| v.trim() == "1") {
        return Ok(DiscoveryRange::Localhost);
    }
    match range.map(|r| r.trim().to_ascii_uppercase()).as_deref() {
        None | Some("" | "SUBNET" | "SYSTEM_DEFAULT") => Ok(DiscoveryRange::Default),
        Some("LOCALHOST") => Ok(DiscoveryRange::Localhost),
        Some("OFF") => Ok(DiscoveryRange::Off),
        Some(_) => Err(ConfigError::DiscoveryRange { value: range.unwrap_or_default().to_string() }),
    }
}

/// The gateway's environment variables, each read here and nowhere else (the CLI and the
/// library alike): the DDS domain, ROS 2's discovery range, the engine and the interfaces.
/// A variable set to nothing counts as unset; a bad value is an error naming the variable.
pub mod env {
    use std::net::IpAddr;

    use super::{discovery_range, ConfigError, DiscoveryRange};
    use crate::engine::EngineKind;

    /// The value of `name`, None when unset or blank.
    fn var(name: &str) -> Option<String> {
        std::env::var(name).ok().filter(|v| !v.trim().is_empty())
    }

    /// `ROS_DOMAIN_ID`, if set.
    pub fn domain_id() -> Result<Option<u16>, ConfigError> {
        let Some(s) = var("ROS_DOMAIN_ID") else { return Ok(None) };
        match s.trim().parse::<u16>().ok().filter(|&d| d <= 232) {
            Some(d) => Ok(Some(d)),
            None => Err(ConfigError::DomainIdVar { value: s }),
        }
    }

    /// `TUTTI_DDS`, else the default engine (cyclone).
    pub fn engine() -> Result<EngineKind, ConfigError> {
        match var("TUTTI_DDS") {
            Some(s) => s.parse().map_err(|error| ConfigError::EngineVar { value: s, error }),
            None => Ok(EngineKind::default()),
        }
    }

    /// `ROS_LOCALHOST_ONLY` and `ROS_AUTOMATIC_DISCOVERY_RANGE`.
    pub fn discovery() -> Result<DiscoveryRange, ConfigError> {
        discovery_range(
            std::env::var("ROS_LOCALHOST_ONLY").ok().as_deref(),
            std::env::var("ROS_AUTOMATIC_DISCOVERY_RANGE").ok().as_deref(),
        )
    }

    /// `TUTTI_GATEWAY_INTERFACE` (comma-separated addresses), if set.
    pub fn interfaces() -> Result<Option<Vec<IpAddr>>, ConfigError> {
        let Some(s) = var("TUTTI_GATEWAY_INTERFACE") else { return Ok(None) };
        s.split(',')
            .map(|a| {
                a.trim().parse::<IpAddr>().map_err(|error| ConfigError::InterfaceVar { value: a.to_string(), error })
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }
}

impl GatewayOptions {
    /// The options of the gateway for `model` read from `ddf`: the defaults, then the
    /// environment where `keys` (flags laid over the config file) say nothing, then `keys`.
    /// With ROS 2's discovery range OFF, peers must be given.
    pub fn configured(ddf: &Path, model: Model, keys: &ConfigFile) -> Result<GatewayOptions, ConfigError> {
        let mut opts = GatewayOptions::new(ddf, model);
        if keys.ros_domain_id.is_none() {
            opts.ros_domain_id = env::domain_id()?.unwrap_or(0);
        }
        if keys.engine.is_none() {
            opts.engine = env::engine()?;
        }
        let range = env::discovery()?;
        if keys.interface.is_none() {
            opts.interfaces = match env::interfaces()? {
                Some(i) => i,
                // This machine only: loopback.
                None if range == DiscoveryRange::Localhost => vec![IpAddr::from([127, 0, 0, 1])],
                None => Vec::new(),
            };
        }
        keys.apply(&mut opts)?;
        if range == DiscoveryRange::Off {
            // Cyclone has no switch for "peers only" that we could set without overriding
            // CYCLONEDDS_URI; with peers given, they are used beside what Cyclone is configured for.
            if opts.peers.is_empty() {
                return Err(ConfigError::DiscoveryOff);
            }
            tracing::warn!(
                "ROS_AUTOMATIC_DISCOVERY_RANGE=OFF: discovering the peers {:?}; multicast discovery stays as \
                 CYCLONEDDS_URI configures it",
                opts.peers
            );
        }
        Ok(opts)
    }
}

// ---------------------------------------------------------------------------------------
// Value parsers, shared by the CLI's flags and the file's keys.

/// The longest duration a key or flag takes: 365 days. Longer ones are refused, since a
/// deadline is the time now plus the duration, and that sum overflows the clock for
/// durations of some hundred billion years (a panic, not an error).
pub const MAX_DURATION: Duration = Duration::from_secs(365 * 24 * 3600);

/// The lowest rate a key or flag takes: one sample in [`MAX_DURATION`] (the interval between
/// samples is 1 / rate, which must be a duration).
pub const MIN_RATE: f64 = 1.0 / (365.0 * 24.0 * 3600.0);

/// A rate in Hz (`100`, `100Hz`), at least [`MIN_RATE`].
pub fn parse_rate(s: &str) -> Result<f64, ConfigError> {
    match s.trim().trim_end_matches("Hz").trim_end_matches("hz").parse::<f64>() {
        Ok(r) if r.is_finite() && r >= MIN_RATE => Ok(r),
        _ => Err(ConfigError::Rate { value: s.to_string() }),
    }
}

/// A duration from zero to [`MAX_DURATION`] (`poll`, where 0 means keep polling;
/// `duration`).
pub fn parse_span(s: &str) -> Result<Duration, ConfigError> {
    let d = parse_duration(s)?;
    if d > MAX_DURATION {
        return Err(ConfigError::Duration { value: s.to_string(), why: "longer than 365 days" });
    }
    Ok(d)
}

/// A period above zero, at most [`MAX_DURATION`]: `timeout`, `status_every`, `lease` (a
/// period of zero would time out every wait, or tick without end).
pub fn parse_period(s: &str) -> Result<Duration, ConfigError> {
    let d = parse_span(s)?;
    if d.is_zero() {
        return Err(ConfigError::Duration { value: s.to_string(), why: "it must be longer than zero" });
    }
    Ok(d)
}

/// A wait mode (`block`, `spin`, `poll:DURATION`) whose poll interval is at most
/// [`MAX_DURATION`].
pub fn parse_wait_mode(s: &str) -> Result<WaitMode, ConfigError> {
    match parse_wait(s)? {
        WaitMode::Poll(d) if d > MAX_DURATION => {
            Err(ConfigError::Duration { value: s.to_string(), why: "longer than 365 days" })
        }
        w => Ok(w),
    }
}

/// The port Cyclone assumes for a peer given without one does not matter here: host names
/// are resolved only to check that they resolve.
const ANY_PORT: u16 = 7400;

/// A unicast discovery peer as Cyclone DDS takes it in `<Peer address="...">` on its default
/// UDP/IPv4 transport: an IPv4 address or a host name, with an optional `:PORT` (1-65535).
/// A host name must resolve to an IPv4 address now: Cyclone aborts the process on a peer it
/// cannot resolve, and on an IPv6 one. The value comes back as given (trimmed).
pub fn parse_peer(s: &str) -> Result<String, ConfigError> {
    let t = s.trim();
    // Shown escaped: the value may hold control characters.
    let bad = |why: String| ConfigError::Peer { value: s.escape_debug().to_string(), why };
    let (host, port) = match t.rsplit_once(':') {
        Some((h, p)) if !h.contains(':') => {
            let port = p.parse::<u16>().ok().filter(|&p| p > 0);
            (h, Some(port.ok_or_else(|| bad(format!("'{p}' is not a port (1-65535)")))?))
        }
        _ => (t, None),
    };
    if host.parse::<std::net::Ipv4Addr>().is_ok() {
        return Ok(t.to_string());
    }
    if t.trim_start_matches('[').split(']').next().is_some_and(|h| h.parse::<std::net::Ipv6Addr>().is_ok()) {
        return Err(bad("IPv6 peers are not supported: the gateway's Cyclone DDS talks UDP over IPv4".into()));
    }
    if !host_name(host) {
        return Err(bad("not an IPv4 address or a host name (letters, digits, '-' and '.', like 192.0.2.1, \
             site-b.example or site-b:7410)"
            .into()));
    }
    use std::net::ToSocketAddrs;
    match (host, port.unwrap_or(ANY_PORT)).to_socket_addrs() {
        Ok(mut addrs) => match addrs.any(|a| a.is_ipv4()) {
            true => Ok(t.to_string()),
            false => Err(bad(format!("host name '{host}' has no IPv4 address"))),
        },
        Err(e) => Err(bad(format!("host name '{host}' does not resolve: {e}"))),
    }
}

/// A host name as RFC 1123 has it: dot-separated labels of 1-63 letters, digits and `-`, not
/// starting or ending with `-`; 253 characters at most (a final `.` allowed).
fn host_name(h: &str) -> bool {
    let h = h.strip_suffix('.').unwrap_or(h);
    !h.is_empty()
        && h.len() <= 253
        && h.split('.').all(|l| {
            (1..=63).contains(&l.len())
                && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
                && !l.starts_with('-')
                && !l.ends_with('-')
        })
}

fn parse_types(s: &str) -> Result<TypeMode, ConfigError> {
    match s {
        "typed" => Ok(TypeMode::Typed),
        "per-item" | "per_item" => Ok(TypeMode::PerItem),
        _ => Err(ConfigError::Types { value: s.to_string() }),
    }
}

/// A QoS profile: `ros2` or `dds`.
pub fn parse_profile(s: &str) -> Result<Profile, ConfigError> {
    match s {
        "ros2" => Ok(Profile::Ros2),
        "dds" => Ok(Profile::Dds),
        _ => Err(ConfigError::Profile { value: s.to_string() }),
    }
}

/// A ROS namespace in canonical form (see [`ros_namespace`]).
pub fn parse_namespace(s: &str) -> Result<String, ConfigError> {
    ros_namespace(s)
}

fn parse_pattern(s: &str) -> Result<String, ConfigError> {
    anchored(s).map(|_| s.to_string())
}

macro_rules! parsed {
    ($($name:ident -> $ty:ty = $parse:path, $what:literal;)*) => {$(
        fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<Option<$ty>, D::Error> {
            d.deserialize_any(Parsed { expecting: $what, parse: $parse }).map(Some)
        }
    )*};
}

parsed! {
    de_period -> Duration = parse_period, "a duration above zero like \"10ms\", \"2s\" or \"1min\"";
    de_span -> Duration = parse_span, "a duration like \"10ms\", \"2s\" or \"1min\"";
    de_wait -> WaitMode = parse_wait_mode, "\"block\", \"spin\" or \"poll:DURATION\"";
    de_types -> TypeMode = parse_types, "\"typed\" or \"per-item\"";
    de_profile -> Profile = parse_profile, "\"ros2\" or \"dds\"";
    de_engine -> EngineKind = std::str::FromStr::from_str, "\"cyclone\" or \"rustdds\"";
    de_namespace -> String = parse_namespace, "a ROS namespace like \"sim1\"";
    de_remap -> String = ros_topic_name, "a ROS topic name like \"uav1/cmd\" or \"/fleet/uav1/cmd\"";
}

fn de_rate<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    let expecting = "a rate in Hz above 0 (at least one sample in 365 days)";
    d.deserialize_any(Number { expecting, ok: |v| v >= MIN_RATE }).map(Some)
}

fn de_peers<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<String>>, D::Error> {
    struct Peers;
    impl<'de> Visitor<'de> for Peers {
        type Value = Vec<String>;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a list of peers, like [\"192.0.2.1\", \"site-b:7410\"]")
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<String>, A::Error> {
            let mut out = Vec::new();
            while let Some(p) =
                seq.next_element_seed(Parsed { expecting: "an IPv4 address or host name", parse: parse_peer })?
            {
                out.push(p);
            }
            Ok(out)
        }
    }
    d.deserialize_any(Peers).map(Some)
}

fn de_depth<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    let ok = |v: f64| v.fract() == 0.0 && (1.0..=f64::from(u32::MAX)).contains(&v);
    d.deserialize_any(Number { expecting: "a depth of 1 or more", ok }).map(|v| Some(v as u32))
}

fn de_domain_id<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u16>, D::Error> {
    let ok = |v: f64| v.fract() == 0.0 && (0.0..=232.0).contains(&v);
    d.deserialize_any(Number { expecting: "a DDS domain id (0-232)", ok }).map(|v| Some(v as u16))
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

/// The keys of the config file, for the docs' test that each is documented.
pub const KEYS: &[&str] = &[
    "ros_domain_id",
    "ros2_types",
    "qos_profile",
    "strength",
    "mirror",
    "node_name",
    "interface",
    "engine",
    "dds",
    "peer",
    "clock",
    "clock_rate",
    "timeout",
    "wait",
    "poll",
    "status_every",
    "duration",
    "quiet",
    "ros_namespace",
    "hosted_only",
    "lease",
    "every_step",
    "passive",
    "http",
    "foxglove",
    "allow",
    "deny",
    "topics",
];

#[cfg(test)]
mod tests {
    use super::*;

    fn repo(path: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(path)
    }

    /// Options for `ddf` (in the repo's `ddf/`) with the config text `cfg` applied.
    fn opts(ddf: &str, cfg: &str) -> Result<GatewayOptions, ConfigError> {
        let path = repo(&format!("ddf/{ddf}"));
        let model = tutti_core::ddf::load(&path).unwrap();
        let mut o = GatewayOptions::new(&path, model);
        parse(cfg, "gw.json5")?.apply(&mut o)?;
        Ok(o)
    }

    fn err(r: Result<impl fmt::Debug, ConfigError>) -> String {
        r.expect_err("refused").to_string()
    }

    fn resolved(ddf: &str, cfg: &str) -> Result<Plan, ConfigError> {
        resolve(&opts(ddf, cfg)?)
    }

    #[test]
    fn every_key_is_read() {
        let c = parse(
            r#"{ ros_domain_id: 7, ros2_types: "per-item", qos_profile: "dds", strength: 3, mirror: true,
                 node_name: "gw", interface: ["127.0.0.1"], dds: "rustdds", peer: ["localhost"], clock: "none",
                 clock_rate: 50, timeout: "2s", wait: "poll:50us", poll: "1ms", status_every: "10s",
                 duration: "1min", quiet: true, ros_namespace: "/sim1/", hosted_only: false, lease: "3s",
                 http: "127.0.0.1:9100", foxglove: "127.0.0.1:8765", allow: ["a/.*"], deny: ["b"], topics: {} }"#,
            "f",
        )
        .unwrap();
        assert_eq!(c.ros_domain_id, Some(7));
        assert_eq!(c.ros2_types, Some(TypeMode::PerItem));
        assert_eq!(c.engine, Some(EngineKind::Rustdds));
        assert_eq!(c.wait, Some(WaitMode::Poll(Duration::from_micros(50))));
        assert_eq!(c.ros_namespace.as_deref(), Some("sim1"));
        assert_eq!(c.lease, Some(Duration::from_secs(3)));
        assert_eq!(c.http, Some("127.0.0.1:9100".parse().unwrap()));
        let mut o = opts("product-sample.ddf", "{}").unwrap();
        c.apply(&mut o).unwrap();
        assert_eq!(o.foxglove, Some("127.0.0.1:8765".parse().unwrap()));
        assert_eq!((o.ros_domain_id, o.strength, o.mirror, o.hosted_only), (7, 3, true, false));
        assert_eq!((o.profile, o.engine, o.clock.clone()), (Profile::Dds, EngineKind::Rustdds, ClockSource::Off));
        assert_eq!((o.timeout, o.clock_rate, o.ros_namespace.as_str()), (Duration::from_secs(2), Some(50.0), "sim1"));
        assert_eq!(o.rules.allow.len() + o.rules.deny.len(), 2);
        assert_eq!(o.rules.source, "f");
    }

    #[test]
    fn unknown_keys_are_refused_with_the_key_its_place_and_the_accepted_keys() {
        let e = err(parse("{\n  timeout: \"1s\",\n  tiemout: \"2s\" }", "gw.json5"));
        assert!(e.starts_with("gw.json5:3:3: unknown field `tiemout`"), "{e}");
        assert!(e.contains("`timeout`") && e.contains("`ros_namespace`") && e.contains("`topics`"), "{e}");
        let e = err(parse(r#"{ topics: { "a/publish": { qos: { reliablity: "reliable" } } } }"#, "gw.json5"));
        assert!(e.contains("unknown field `reliablity`") && e.contains("`durability`"), "{e}");
        let e = err(parse(r#"{ topics: { "a/publish": { rate: 5 } } }"#, "gw.json5"));
        assert!(e.contains("unknown field `rate`") && e.contains("`max_rate`"), "{e}");
    }

    #[test]
    fn bad_values_and_syntax_are_refused_where_they_stand() {
        let e = err(parse("{\n  timeout: \"soon\" }", "gw.json5"));
        assert!(e.starts_with("gw.json5:2:12:") && e.contains("'soon' is not a duration"), "{e}");
        let e = err(parse("{ timeout: \"1s\" ", "gw.json5"));
        assert!(e.starts_with("gw.json5:1:") && e.contains("syntax error"), "{e}");
        let e = err(parse("{ allow: [\"ok\", \"uav(\"] }", "gw.json5"));
        assert!(e.starts_with("gw.json5:1:17:") && e.contains("bad pattern 'uav('"), "{e}");
        let e = err(parse("{ ros_domain_id: 300 }", "gw.json5"));
        assert!(e.contains("300 is not a DDS domain id (0-232)"), "{e}");
        let e = err(parse("{ topics: { \"a/publish\": { max_rate: 0 } } }", "gw.json5"));
        assert!(e.contains("0 is not a rate in Hz above 0"), "{e}");
        let e = err(parse("{ topics: { \"a/publish\": { qos: { reliability: \"sometimes\" } } } }", "gw.json5"));
        assert!(e.contains("unknown variant `sometimes`") && e.contains("`best_effort`"), "{e}");
        let e = err(parse("{ topics: { \"a/publish\": { remap: \"2fast\" } } }", "gw.json5"));
        assert!(e.contains("'2fast' is not a ROS topic name"), "{e}");
        let e = err(parse("{ ros_namespace: \"a b\" }", "gw.json5"));
        assert!(e.contains("ROS namespace 'a b'"), "{e}");
        assert!(err(load(Path::new("/nonexistent/gw.json5"))).starts_with("/nonexistent/gw.json5: cannot read"));
    }

    #[test]
    fn a_file_nested_too_deep_is_refused_where_it_goes_too_deep_before_it_is_parsed() {
        for (open, close) in [("[", "]"), ("{a:", "}")] {
            let text = format!("{{ topics: {}{} }}", open.repeat(100_000), close.repeat(100_000));
            let e = err(parse(&text, "deep.json5"));
            let col = 11 + (MAX_NESTING - 1) * open.len();
            assert!(e.starts_with(&format!("deep.json5:1:{col}: nested more than {MAX_NESTING} deep")), "{e}");
        }
        // Brackets in strings and comments do not count; the limit itself is parsed.
        let quoted =
            format!("{{ node_name: \"{}\", // {}\n /* {} */ }}", "[".repeat(99), "{".repeat(99), "[".repeat(99));
        assert_eq!(parse(&quoted, "q.json5").unwrap().node_name.as_deref(), Some("[".repeat(99).as_str()));
        let at_limit = format!("{}{}", "[".repeat(MAX_NESTING), "]".repeat(MAX_NESTING));
        assert!(!err(parse(&at_limit, "l.json5")).contains("nested more than"));
    }

    #[test]
    fn durations_and_rates_that_would_panic_are_refused_naming_the_key() {
        for key in ["timeout", "status_every", "lease"] {
            let e = err(parse(&format!("{{\n {key}: \"0s\" }}"), "gw.json5"));
            assert!(e.starts_with("gw.json5:2:") && e.contains("'0s': it must be longer than zero"), "{key}: {e}");
        }
        for key in ["timeout", "status_every", "lease", "poll", "duration"] {
            let e = err(parse(&format!("{{ {key}: \"400days\" }}"), "gw.json5"));
            assert!(e.contains("'400days': longer than 365 days"), "{key}: {e}");
            let e = err(parse(&format!("{{ {key}: \"18446744073709551615s\" }}"), "gw.json5"));
            assert!(e.starts_with("gw.json5:1:"), "{key}: {e}");
        }
        assert_eq!(parse("{ poll: \"0s\" }", "f").unwrap().poll, Some(Duration::ZERO));
        assert_eq!(parse("{ duration: \"0s\" }", "f").unwrap().duration, Some(Duration::ZERO));
        assert!(err(parse("{ wait: \"poll:400days\" }", "f")).contains("longer than 365 days"));
        for rate in ["1e-300", "-1", "0"] {
            let e = err(parse(&format!("{{ clock_rate: {rate} }}"), "f"));
            assert!(e.contains("is not a rate in Hz above 0"), "{rate}: {e}");
            let e = err(parse(&format!("{{ topics: {{ \"a/publish\": {{ max_rate: {rate} }} }} }}"), "f"));
            assert!(e.contains("is not a rate in Hz above 0"), "{rate}: {e}");
        }
        assert!(parse_rate("1e-300").is_err() && parse_rate("100Hz").is_ok());
        assert!(parse_period("0ms").is_err() && parse_span("0ms").is_ok());
    }

    #[test]
    fn peers_are_ipv4_addresses_or_host_names_that_resolve() {
        for ok in ["192.0.2.1", "127.0.0.1:7410", "localhost", "localhost:7412", " 10.0.0.2 "] {
            assert_eq!(parse_peer(ok).ok().as_deref(), Some(ok.trim()), "{ok}");
        }
        let refused = [
            ("\u{1}\u{ff}%%garbage", "not an IPv4 address or a host name"),
            ("", "not an IPv4 address or a host name"),
            ("a\"/><Peer address=\"x", "not an IPv4 address or a host name"),
            ("h<x>&", "not an IPv4 address or a host name"),
            ("-a.example", "not an IPv4 address or a host name"),
            ("::1", "IPv6 peers are not supported"),
            ("[::1]:7400", "IPv6 peers are not supported"),
            ("127.0.0.1:0", "is not a port"),
            ("127.0.0.1:99999", "is not a port"),
            ("nosuchhost.invalid", "does not resolve"),
        ];
        for (bad, why) in refused {
            let e = err(parse_peer(bad));
            assert!(e.contains(why), "{bad:?}: {e}");
        }
        // In the file: at the element, naming the file.
        let e = err(parse("{ peer: [\"127.0.0.1\",\n \"\\u0001garbage\"] }", "gw.json5"));
        assert!(e.starts_with("gw.json5:2:2: peer '\\u{1}garbage': not an IPv4 address"), "{e}");
    }

    #[test]
    fn ros_topic_names_are_checked() {
        for ok in ["a", "a/b", "/a/b_2", "_x/y"] {
            assert_eq!(ros_topic_name(ok).ok().as_deref(), Some(ok));
        }
        for bad in ["", "/", "a/", "a//b", "a/2b", "~/a", "{node}/a", "a-b", "a b"] {
            assert!(ros_topic_name(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn without_rules_every_set_is_bridged_as_the_table_says() {
        let p = resolved("product-sample.ddf", "{}").unwrap();
        assert!(p.left_out.is_empty());
        let keys: Vec<&str> = p.sets.iter().map(|s| s.key.as_str()).collect();
        assert_eq!(
            keys,
            ["grid_feeder/publish", "grid_feeder/subscribe", "grid_clock/publish", "grid_clock/subscribe"]
        );
        let s = &p.sets[0];
        assert_eq!((s.topic.as_str(), s.ros2_topic.as_str()), ("rt/grid_feeder/publish", "/grid_feeder/publish"));
        let o = opts("product-sample.ddf", "{}").unwrap();
        let d = &o.model.domains[0];
        assert_eq!(s.writer_qos, mapping::qos(d.flags, Profile::Ros2, Endpoint::Writer, 0));
        assert_eq!(s.reader_qos, mapping::qos(d.flags, Profile::Ros2, Endpoint::Reader, 0));
    }

    #[test]
    fn allow_and_deny_select_sets_and_say_why_one_is_left_out() {
        let p = resolved(
            "product-sample.ddf",
            r#"{ allow: ["grid_feeder/.*", "grid_clock/publish"], deny: [".*/subscribe"] }"#,
        )
        .unwrap();
        let keys: Vec<&str> = p.sets.iter().map(|s| s.key.as_str()).collect();
        assert_eq!(keys, ["grid_feeder/publish", "grid_clock/publish"]);
        let out: Vec<(&str, &str)> = p.left_out.iter().map(|l| (l.key.as_str(), l.reason.as_str())).collect();
        assert_eq!(
            out,
            [
                ("grid_feeder/subscribe", "matches deny pattern '.*/subscribe'"),
                ("grid_clock/subscribe", "matches deny pattern '.*/subscribe'"),
            ]
        );
        // Patterns match the whole key: `grid` alone matches nothing.
        let p = resolved("product-sample.ddf", r#"{ allow: ["grid"] }"#).unwrap();
        assert!(p.sets.is_empty());
        assert_eq!(p.left_out[0].reason, "matches no allow pattern ('grid')");
    }

    #[test]
    fn namespace_and_remapping_name_the_topics() {
        let cfg = r#"{ ros_namespace: "sim1", topics: {
            "grid_feeder/publish": { remap: "feeder/cmd" },
            "grid_clock/publish": { remap: "/plant/clock_out" } } }"#;
        let p = resolved("product-sample.ddf", cfg).unwrap();
        let names: Vec<(&str, &str)> = p.sets.iter().map(|s| (s.topic.as_str(), s.ros2_topic.as_str())).collect();
        assert_eq!(
            names,
            [
                ("rt/sim1/feeder/cmd", "/sim1/feeder/cmd"),
                ("rt/sim1/grid_feeder/subscribe", "/sim1/grid_feeder/subscribe"),
                ("rt/plant/clock_out", "/plant/clock_out"),
                ("rt/sim1/grid_clock/subscribe", "/sim1/grid_clock/subscribe"),
            ]
        );
        let o = opts("product-sample.ddf", cfg).unwrap();
        assert_eq!(o.engine_config().node_namespace, "/sim1");
        let items = item_topics(&o, &p.sets[0]);
        assert!(items.iter().all(|t| t.topic.starts_with("rt/sim1/feeder/cmd/")), "{items:?}");
    }

    #[test]
    fn overrides_apply_to_writer_and_reader_and_rates_are_copied() {
        let cfg = r#"{ topics: { "grid_feeder/subscribe": {
            qos: { reliability: "reliable", history: "keep_last", depth: 5 }, max_rate: 20 },
            "grid_clock/publish": { qos: { durability: "transient_local", history: "keep_all" } } } }"#;
        let p = resolved("product-sample.ddf", cfg).unwrap();
        let s = &p.sets[1];
        assert_eq!(s.max_rate, Some(20.0));
        for q in [s.writer_qos, s.reader_qos] {
            assert_eq!((q.reliability, q.history), (Reliability::Reliable, History::KeepLast(5)));
        }
        // states=yes: the writer's transient-local depth follows the overridden history.
        assert_eq!(s.writer_qos.durability, Durability::TransientLocal { depth: 5 });
        assert_eq!(s.reader_qos.durability, Durability::Volatile);
        let c = &p.sets[2];
        for q in [c.writer_qos, c.reader_qos] {
            assert_eq!((q.history, q.durability), (History::KeepAll, Durability::TransientLocal { depth: 1 }));
        }
        assert_eq!(p.sets[0].max_rate, None);
    }

    #[test]
    fn what_the_flags_forbid_is_refused_naming_the_key_and_the_flag() {
        let t = |key: &str, entry: &str| format!(r#"{{ topics: {{ "{key}": {entry} }} }}"#);
        let cases = [
            (t("grid_clock/publish", r#"{ qos: { reliability: "best_effort" } }"#), "topics.\"grid_clock/publish\".qos.reliability: best_effort is refused: domain 'grid_clock' has synchronous=yes"),
            (t("grid_clock/subscribe", r#"{ qos: { history: "keep_last" } }"#), "topics.\"grid_clock/subscribe\".qos.history: keep_last is refused: domain 'grid_clock' has synchronous=yes"),
            (t("grid_clock/publish", r#"{ max_rate: 10 }"#), "topics.\"grid_clock/publish\".max_rate: a rate limit is refused: domain 'grid_clock' has synchronous=yes"),
            (t("grid_feeder/publish", r#"{ qos: { durability: "volatile" } }"#), "topics.\"grid_feeder/publish\".qos.durability: volatile is refused: domain 'grid_feeder' has states=yes"),
            (t("grid_feeder/publish", r#"{ qos: { depth: 3 } }"#), "topics.\"grid_feeder/publish\".qos.depth: depth needs history \"keep_last\""),
            (t("grid_feeder/publish", r#"{ qos: { history: "keep_all", depth: 3 } }"#), "topics.\"grid_feeder/publish\".qos.depth: depth needs history \"keep_last\""),
            (t("grid_feeder/publish", r#"{ qos: { history: "keep_last", depth: 0 } }"#), "0 is not a depth of 1 or more"),
            (t("grid_feeder/publsh", "{}"), "topics.\"grid_feeder/publsh\": the DDF has no set 'grid_feeder/publsh' (sets: grid_feeder/publish, grid_feeder/subscribe, grid_clock/publish, grid_clock/subscribe)"),
        ];
        for (cfg, want) in cases {
            let e = err(resolved("product-sample.ddf", &cfg));
            assert!(e.starts_with("gw.json5") && e.contains(want), "{cfg}\n{e}");
        }
        // Lock-step's own terms, and best-effort or keep-last on an asynchronous set, are fine.
        let fine = t("grid_clock/publish", r#"{ qos: { reliability: "reliable", history: "keep_all" } }"#);
        resolved("product-sample.ddf", &fine).unwrap();
        resolved("product-sample.ddf", &t("grid_feeder/publish", r#"{ qos: { reliability: "best_effort" } }"#))
            .unwrap();
    }

    #[test]
    fn two_sets_on_one_topic_are_refused_naming_the_remap() {
        let both = r#"{ topics: { "grid_clock/publish": { remap: "/x" }, "grid_feeder/publish": { remap: "/x" } } }"#;
        let e = err(resolved("product-sample.ddf", both));
        assert!(
            e.contains("topics.\"grid_clock/publish\".remap: '/x' is also the topic of set 'grid_feeder/publish'"),
            "{e}"
        );
        // A remap onto another set's own name blames the remap, whichever comes first.
        let onto = r#"{ topics: { "grid_feeder/publish": { remap: "grid_clock/publish" } } }"#;
        let e = err(resolved("product-sample.ddf", onto));
        assert!(e.contains("topics.\"grid_feeder/publish\".remap: '/grid_clock/publish' is also the topic of set 'grid_clock/publish'"), "{e}");
        let clock = r#"{ topics: { "grid_feeder/publish": { remap: "/clock" } } }"#;
        assert!(err(resolved("product-sample.ddf", clock)).contains("the gateway's /clock"));
        resolved("product-sample.ddf", &clock.replace("{ topics", "{ clock: \"none\", topics")).unwrap();
    }

    #[test]
    fn flags_win_over_the_file_and_the_file_over_defaults() {
        let file = parse(r#"{ ros_domain_id: 7, strength: 3, timeout: "2s", allow: ["x"] }"#, "gw.json5").unwrap();
        let flags = ConfigFile { ros_domain_id: Some(9), poll: Some(Duration::from_millis(1)), ..Default::default() };
        let m = flags.over(file);
        assert_eq!((m.ros_domain_id, m.strength, m.timeout), (Some(9), Some(3), Some(Duration::from_secs(2))));
        assert_eq!(
            (m.poll, m.allow.as_deref(), m.source.as_deref()),
            (Some(Duration::from_millis(1)), Some(&["x".to_string()][..]), Some("gw.json5"))
        );
        let mut o = opts("product-sample.ddf", "{}").unwrap();
        let before = o.wait;
        m.apply(&mut o).unwrap();
        assert_eq!((o.ros_domain_id, o.wait), (9, before), "a key nobody gave keeps its default");
    }

    #[test]
    fn the_participant_announces_the_lease_but_never_less_than_the_floor() {
        let lease = |cfg: &str| opts("product-sample.ddf", cfg).unwrap().engine_config().participant_lease;
        assert_eq!(lease("{}"), Some(MIN_PARTICIPANT_LEASE), "the default lease (1 s) is below the floor");
        assert_eq!(lease(r#"{ lease: "5s" }"#), Some(Duration::from_secs(5)));
        assert_eq!(lease(r#"{ lease: "10ms" }"#), Some(MIN_PARTICIPANT_LEASE));
    }

    #[test]
    fn ros_discovery_variables() {
        use DiscoveryRange::*;
        assert_eq!(discovery_range(None, None).unwrap(), Default);
        assert_eq!(discovery_range(Some("1"), Some("SUBNET")).unwrap(), Localhost);
        assert_eq!(discovery_range(Some("0"), Some("LOCALHOST")).unwrap(), Localhost);
        assert_eq!(discovery_range(None, Some("OFF")).unwrap(), Off);
        assert_eq!(discovery_range(None, Some("SYSTEM_DEFAULT")).unwrap(), Default);
        assert!(err(discovery_range(None, Some("LAN"))).contains("ROS_AUTOMATIC_DISCOVERY_RANGE='LAN'"));
    }

    /// `examples/gateway.json5` stays valid for the DDF it is written for.
    #[test]
    fn the_example_config_loads_and_resolves() {
        let path = repo("ddf/multiuav.ddf");
        let mut o = GatewayOptions::new(&path, tutti_core::ddf::load(&path).unwrap());
        let cfg = load(&repo("examples/gateway.json5")).unwrap();
        cfg.apply(&mut o).unwrap();
        let p = resolve(&o).unwrap();
        assert!(
            !p.sets.is_empty()
                && !p.left_out.is_empty()
                && p.sets.iter().any(|s| s.ros2_topic != format!("/{}", s.key))
        );
    }

    /// Every key is documented in docs/gateway.md.
    #[test]
    fn every_key_is_documented() {
        let doc = std::fs::read_to_string(repo("docs/gateway.md")).unwrap();
        for k in KEYS {
            assert!(doc.contains(&format!("`{k}`")), "docs/gateway.md does not mention `{k}`");
        }
        for k in KEYS {
            let e = err(parse("{ nope: 1 }", "f"));
            assert!(e.contains(&format!("`{k}`")), "KEYS lists `{k}`, the parser does not: {e}");
        }
    }
}
