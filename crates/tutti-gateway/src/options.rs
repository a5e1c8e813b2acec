//! What the gateway serves and how.

use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::time::Duration;

use tutti_core::ddf::Model;
use tutti_core::mapping::Profile;
use tutti_core::shm::WaitMode;

use crate::config::TopicRules;
use crate::engine::{EngineConfig, EngineKind};

/// The two type mappings of SPEC section 5.
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
    /// next sample).
    pub lease: Duration,
    /// DDS readers of a synchronous PUBLISH set get every step: the gateway reads the set in
    /// lock-step through an observer connection that the framework waits for (a copy and a
    /// DDS write a step), instead of following it passively.
    pub every_step: bool,
    /// Serve the counters over HTTP (JSON at `/stats`, Prometheus text at `/metrics`).
    pub http: Option<SocketAddr>,
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
            engine: EngineKind::from_env().unwrap_or_default(),
            peers: Vec::new(),
            clock: ClockSource::default(),
            clock_rate: None,
            ros_namespace: String::new(),
            hosted_only: true,
            lease: Duration::from_secs(1),
            every_step: false,
            http: None,
            rules: TopicRules::default(),
        }
    }

    /// The index of the domain whose time goes out on `/clock`, if any; an unknown name is
    /// an error. A mirror publishes no clock (the home gateway does).
    pub fn clock_domain(&self) -> Result<Option<usize>, crate::GatewayError> {
        if self.mirror {
            return Ok(None);
        }
        match &self.clock {
            ClockSource::Off => Ok(None),
            ClockSource::FirstSynchronous => Ok(self.model.domains.iter().position(|d| d.flags.synchronous)),
            ClockSource::Domain(name) => match self.model.domains.iter().position(|d| &d.name == name) {
                Some(i) => Ok(Some(i)),
                None => Err(crate::GatewayError::Invalid(format!(
                    "--clock {name}: the DDF has no domain '{name}' (domains: {})",
                    self.model.domains.iter().map(|d| d.name.as_str()).collect::<Vec<_>>().join(", ")
                ))),
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
            node_namespace: crate::config::node_namespace(self.ros_namespace.trim().trim_matches('/')),
        }
    }
}
