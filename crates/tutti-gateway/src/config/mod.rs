//! What the gateway serves and how ([`GatewayOptions`]): the defaults, then the environment,
//! then the config file's keys with the CLI's flags laid over them.
//!
//! The config file (`tutti gateway --config gateway.json5`) is parsed, then validated, in two
//! steps: [`load`] reads it into a [`ConfigFile`] (JSON5, unknown keys refused, every value
//! checked where it stands, so errors carry the file, line and column; each key parsed by the
//! section of the part that uses it, see [`mod@file`]), [`ConfigFile::apply`] puts it into
//! [`GatewayOptions`], and [`resolve`] checks the `topics` against the DDF's flags (a QoS that
//! would break lock-step or the seed of late joiners is refused, naming the key and the
//! flag). Its keys are the CLI's long flags with `_` for `-`; the CLI builds a [`ConfigFile`]
//! from the flags it was given and lays it [`over`](ConfigFile::over) the file's, so flags
//! win over the file and the file over the defaults.

use std::net::{IpAddr, SocketAddr};
use std::path::{Path, PathBuf};
use std::time::Duration;

use tutti_core::ddf::Model;
use tutti_core::mapping::Profile;
use tutti_core::shm::WaitMode;
use tutti_ros2::env::DiscoveryRange;
use tutti_ros2::names;

use crate::engine::{EngineConfig, EngineKind};

pub mod entities;
pub mod file;
pub mod plan;
pub mod values;

pub use crate::error::ConfigError;
pub use entities::{with_model, Attitude, Entity, EntityError, Form};
pub use file::{load, parse, ConfigFile, GatewayKeys, KEYS};
pub use plan::{
    anchored, item_ros2_topics, item_topics, plan, resolve, set_key, LeftOut, Plan, PlanKeys, PlannedSet, QosOverride,
    TopicEntry, TopicRules, TopicSettings,
};
pub use tutti_config::MAX_NESTING;
pub use tutti_engine::keys::{parse_peer, EngineKeys};
pub use tutti_engine::security::Strategy;
pub use values::{
    parse_lookahead, parse_namespace, parse_period, parse_profile, parse_rate, parse_span, parse_topic_name,
    parse_wait_mode, MAX_DURATION, MAX_LOOKAHEAD, MIN_RATE,
};

/// The shortest lease the gateway's DDS participant announces, whatever `--lease` says: the
/// participant renews it every 4/5 of the lease, and a peer that misses a renewal on a
/// loaded machine would drop every route of a gateway that is still there.
pub const MIN_PARTICIPANT_LEASE: Duration = Duration::from_secs(2);

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
    /// Zenoh endpoints to connect to and to listen on (Zenoh engine; empty: its configuration's).
    pub zenoh_connect: Vec<String>,
    pub zenoh_listen: Vec<String>,
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
    /// The run's bodies as ROS 2 entities (docs/gateway.md, "Entities"), checked against the
    /// DDF by [`resolve`].
    pub entities: Vec<Entity>,
    /// At most this many poses a second on `/tf` and `<entity>/pose` (None: one per step).
    pub pose_rate: Option<f64>,
    /// Which sets are bridged, and per-topic QoS, rate and name (the config file's
    /// `allow`, `deny` and `topics`).
    pub rules: TopicRules,
    /// How many steps late the framework takes the answers of a synchronous domain's DDS
    /// writers (docs/run.md, "Sites and lookahead").
    pub lookahead: Lookahead,
    /// The DDS Security enclave the engine's participant runs in, its files checked (None:
    /// unsecured; docs/security.md, "What the network can do").
    pub security: Option<tutti_engine::security::Enclave>,
}

/// The steps of lookahead of each synchronous domain (`--lookahead`, `lookahead:`): the
/// answer a DDS writer (a mirror on another site) gives to step n is committed for step
/// n + K, so the framework runs up to K steps ahead of the link. 0: lock-step as ever.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Lookahead {
    /// Every synchronous domain's, unless named in `domains`.
    pub all: Option<u32>,
    /// Per domain, in the order given.
    pub domains: Vec<(String, u32)>,
}

impl Lookahead {
    /// The lookahead of domain `name`.
    pub fn of(&self, name: &str) -> u32 {
        self.domains.iter().rev().find(|(d, _)| d == name).map_or(self.all.unwrap_or(0), |(_, k)| *k)
    }

    /// `self`'s, and `lower`'s where `self` says nothing (flags over the file).
    pub fn over(mut self, lower: Lookahead) -> Lookahead {
        let mut domains = lower.domains;
        domains.append(&mut self.domains);
        Lookahead { all: self.all.or(lower.all), domains }
    }

    /// Whether any domain has one.
    pub fn any(&self) -> bool {
        self.all.is_some_and(|k| k > 0) || self.domains.iter().any(|(_, k)| *k > 0)
    }

    /// Each domain named must be one of `model`'s and synchronous, and per-item topics cannot
    /// have one (their samples carry no step). A mirror takes the home's K too: it steps the
    /// PUBLISH samples within K of the newest, in order, and skips older ones (steps the home
    /// made without it).
    pub fn check(&self, model: &Model, types: TypeMode) -> Result<(), ConfigError> {
        let refuse = |domain: &str, why: String| Err(ConfigError::LookaheadDomain { domain: domain.into(), why });
        if self.any() {
            let d = self.domains.iter().find(|(_, k)| *k > 0).map_or("*", |(d, _)| d.as_str());
            if types == TypeMode::PerItem {
                return refuse(d, "per-item topics carry no step to delay answers by: use --ros2-types typed".into());
            }
        }
        for (name, _) in &self.domains {
            match model.domains.iter().find(|d| &d.name == name) {
                None => {
                    let all: Vec<&str> = model.domains.iter().map(|d| d.name.as_str()).collect();
                    return refuse(name, format!("the DDF has no such domain (it has {})", all.join(", ")));
                }
                Some(d) if !d.flags.synchronous => {
                    return refuse(
                        name,
                        "the domain is asynchronous: a lookahead is counted in steps of lock-step".into(),
                    )
                }
                Some(_) => {}
            }
        }
        Ok(())
    }
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
            timeout: tutti_core::defaults::STEP_TIMEOUT,
            wait: WaitMode::adaptive(),
            poll: Duration::from_micros(500),
            discovery_every: Duration::from_millis(200),
            engine: EngineKind::default(),
            peers: Vec::new(),
            zenoh_connect: Vec::new(),
            zenoh_listen: Vec::new(),
            clock: ClockSource::default(),
            clock_rate: None,
            ros_namespace: String::new(),
            hosted_only: true,
            lease: Duration::from_secs(1),
            every_step: false,
            passive: false,
            entities: Vec::new(),
            pose_rate: None,
            http: None,
            foxglove: None,
            rules: TopicRules::default(),
            lookahead: Lookahead::default(),
            security: None,
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
            node_namespace: names::node_namespace(self.ros_namespace.trim().trim_matches('/')),
            participant_lease: Some(self.lease.max(MIN_PARTICIPANT_LEASE)),
            zenoh_connect: self.zenoh_connect.clone(),
            zenoh_listen: self.zenoh_listen.clone(),
            security: self.security.clone(),
        }
    }
}

impl GatewayOptions {
    /// The options of the gateway for `model` read from `ddf`: the defaults, then the
    /// environment where `keys` (flags laid over the config file) say nothing, then `keys`.
    /// With ROS 2's discovery range OFF, peers must be given.
    pub fn configured(ddf: &Path, model: Model, keys: &ConfigFile) -> Result<GatewayOptions, ConfigError> {
        let mut opts = GatewayOptions::new(ddf, model);
        if keys.engine.ros_domain_id.is_none() {
            opts.ros_domain_id = env::domain_id()?.unwrap_or(0);
        }
        if keys.engine.engine.is_none() {
            opts.engine = env::engine()?;
        }
        let range = env::discovery()?;
        if keys.engine.interface.is_none() {
            opts.interfaces = match env::interfaces()? {
                Some(i) => i,
                // This machine only: loopback.
                None if range == DiscoveryRange::Localhost => vec![IpAddr::from([127, 0, 0, 1])],
                None => Vec::new(),
            };
        }
        keys.apply(&mut opts)?;
        opts.lookahead.check(&opts.model, opts.types)?;
        opts.security = keys.engine.security()?.resolve(opts.engine)?;
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

/// The gateway's environment variables, each read once, by its owner: ROS 2's
/// (`ROS_DOMAIN_ID`, the discovery range) by `tutti_ros2::env`, the engine's (`TUTTI_DDS`,
/// `TUTTI_GATEWAY_INTERFACE`) by `tutti_engine::keys::env`. A variable set to nothing counts
/// as unset; a bad value is an error naming the variable.
pub mod env {
    use std::net::IpAddr;

    use super::ConfigError;
    use crate::engine::EngineKind;
    use tutti_ros2::env::DiscoveryRange;

    /// `ROS_DOMAIN_ID`, if set.
    pub fn domain_id() -> Result<Option<u16>, ConfigError> {
        Ok(tutti_ros2::env::domain_id()?)
    }

    /// `TUTTI_DDS`, else the default engine (cyclone).
    pub fn engine() -> Result<EngineKind, ConfigError> {
        Ok(tutti_engine::keys::env::engine()?)
    }

    /// `ROS_LOCALHOST_ONLY` and `ROS_AUTOMATIC_DISCOVERY_RANGE`.
    pub fn discovery() -> Result<DiscoveryRange, ConfigError> {
        Ok(tutti_ros2::env::discovery()?)
    }

    /// `TUTTI_GATEWAY_INTERFACE` (comma-separated addresses), if set.
    pub fn interfaces() -> Result<Option<Vec<IpAddr>>, ConfigError> {
        Ok(tutti_engine::keys::env::interfaces()?)
    }
}

#[cfg(test)]
mod tests;
