//! The config file (`tutti gateway --config gateway.json5`): its keys lie flat, as the CLI's
//! long flags do, but each belongs to the part of the gateway that uses it, which parses it
//! in a section of its own: the engine's ([`EngineKeys`], in `tutti-engine`), the plan's
//! ([`PlanKeys`]), the Foxglove server's ([`FoxgloveKeys`]), the HTTP server's
//! ([`HttpKeys`]) and the gateway's own ([`GatewayKeys`]). One reader
//! (`tutti_config`) reads the file, with positions; [`ConfigFile`]'s deserializer hands each
//! key to its section, on the same reader, so every error still names the file, the line,
//! the column and the key.

use std::fmt;
use std::path::Path;
use std::time::Duration;

use serde::de::{MapAccess, Visitor};
use serde::{Deserialize, Deserializer};
use tutti_config::sections::{take_into, unowned, KeySeed, Section};
use tutti_core::mapping::Profile;
use tutti_core::shm::WaitMode;
use tutti_engine::keys::EngineKeys;

use super::entities::EntityKeys;
use super::plan::{PlanKeys, TopicRules};
use super::values::{de_lookahead, de_namespace, de_period, de_profile, de_rate, de_span, de_types, de_wait};
use super::{ClockSource, ConfigError, GatewayOptions, TypeMode};
use crate::foxglove::FoxgloveKeys;
use crate::http::HttpKeys;

/// The config file: every key optional, keys = the CLI's long flags with `_` for `-`
/// (`interface` and `peer` are lists), plus `allow`, `deny` and `topics`, each in its
/// owner's section. Also what the CLI makes of its own flags, to lay over the file's.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConfigFile {
    /// The file it was read from, for messages (None: the command line).
    pub source: Option<String>,
    /// `ros_domain_id`, `engine` (`dds`), `interface`, `peer`.
    pub engine: EngineKeys,
    /// `allow`, `deny`, `topics`.
    pub plan: PlanKeys,
    /// `foxglove`.
    pub foxglove: FoxgloveKeys,
    /// `http`.
    pub http: HttpKeys,
    /// Every other key: how the gateway bridges and runs.
    pub gateway: GatewayKeys,
    /// `entities`, `pose_rate`.
    pub entities: EntityKeys,
}

/// The gateway's own keys: how it maps, steps and names.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GatewayKeys {
    #[serde(default, deserialize_with = "de_types")]
    pub ros2_types: Option<TypeMode>,
    #[serde(default, deserialize_with = "de_profile")]
    pub qos_profile: Option<Profile>,
    pub strength: Option<i32>,
    pub mirror: Option<bool>,
    pub node_name: Option<String>,
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
    /// Steps of lookahead of synchronous domains (`--lookahead`).
    #[serde(default, deserialize_with = "de_lookahead")]
    pub lookahead: Option<super::Lookahead>,
}

impl Section for GatewayKeys {
    const KEYS: &'static [&'static str] = &[
        "ros2_types",
        "qos_profile",
        "strength",
        "mirror",
        "node_name",
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
        "lookahead",
    ];

    fn over(self, lower: Self) -> Self {
        GatewayKeys {
            ros2_types: self.ros2_types.or(lower.ros2_types),
            qos_profile: self.qos_profile.or(lower.qos_profile),
            strength: self.strength.or(lower.strength),
            mirror: self.mirror.or(lower.mirror),
            node_name: self.node_name.or(lower.node_name),
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
            lookahead: match (self.lookahead, lower.lookahead) {
                (Some(a), Some(b)) => Some(a.over(b)),
                (a, b) => a.or(b),
            },
        }
    }
}

/// The keys of the config file, every section's, in the order the docs list them (for the
/// message that refuses an unknown key, and the docs' test that each is documented).
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
    "zenoh_connect",
    "zenoh_listen",
    "security_enable",
    "security_keystore",
    "enclave",
    "security_strategy",
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
    "lookahead",
    "http",
    "foxglove",
    "allow",
    "deny",
    "topics",
    "entities",
    "pose_rate",
];

impl<'de> Deserialize<'de> for ConfigFile {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(FileVisitor)
    }
}

struct FileVisitor;

impl<'de> Visitor<'de> for FileVisitor {
    type Value = ConfigFile;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("the gateway config file's keys")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<ConfigFile, A::Error> {
        let mut c = ConfigFile::default();
        let mut seen = Vec::new();
        while let Some(key) =
            map.next_key_seed(KeySeed { keys: KEYS, aliases: &[("dds", "engine")], seen: &mut seen })?
        {
            let taken = take_into(&mut c.engine, key, &mut map)?
                || take_into(&mut c.gateway, key, &mut map)?
                || take_into(&mut c.plan, key, &mut map)?
                || take_into(&mut c.foxglove, key, &mut map)?
                || take_into(&mut c.http, key, &mut map)?
                || take_into(&mut c.entities, key, &mut map)?;
            if !taken {
                return Err(unowned(key));
            }
        }
        Ok(c)
    }
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
            engine: self.engine.over(lower.engine),
            plan: self.plan.over(lower.plan),
            foxglove: self.foxglove.over(lower.foxglove),
            http: self.http.over(lower.http),
            gateway: self.gateway.over(lower.gateway),
            entities: self.entities.over(lower.entities),
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
        let (e, g) = (&self.engine, &self.gateway);
        set(&mut opts.ros_domain_id, &e.ros_domain_id);
        set(&mut opts.interfaces, &e.interface);
        set(&mut opts.engine, &e.engine);
        set(&mut opts.peers, &e.peer);
        set(&mut opts.zenoh_connect, &e.zenoh_connect);
        set(&mut opts.zenoh_listen, &e.zenoh_listen);
        set(&mut opts.types, &g.ros2_types);
        set(&mut opts.profile, &g.qos_profile);
        set(&mut opts.strength, &g.strength);
        set(&mut opts.mirror, &g.mirror);
        set(&mut opts.node_name, &g.node_name);
        if let Some(c) = &g.clock {
            opts.clock = match c.as_str() {
                "none" => ClockSource::Off,
                d => ClockSource::Domain(d.to_string()),
            };
        }
        if g.clock_rate.is_some() {
            opts.clock_rate = g.clock_rate;
        }
        set(&mut opts.timeout, &g.timeout);
        set(&mut opts.wait, &g.wait);
        set(&mut opts.poll, &g.poll);
        set(&mut opts.ros_namespace, &g.ros_namespace);
        set(&mut opts.hosted_only, &g.hosted_only);
        set(&mut opts.lease, &g.lease);
        set(&mut opts.every_step, &g.every_step);
        set(&mut opts.passive, &g.passive);
        set(&mut opts.lookahead, &g.lookahead);
        if self.http.http.is_some() {
            opts.http = self.http.http;
        }
        if self.foxglove.foxglove.is_some() {
            opts.foxglove = self.foxglove.foxglove;
        }
        set(&mut opts.entities, &self.entities.entities);
        if self.entities.pose_rate.is_some() {
            opts.pose_rate = self.entities.pose_rate;
        }
        opts.rules = TopicRules::from_config(self)?;
        Ok(())
    }
}
