//! Errors of the gateway, each with the domain, topic, address or setting involved: the
//! gateway's own ([`GatewayError`]), its configuration's ([`ConfigError`]) and an unknown
//! engine name ([`UnknownEngine`]). This module imports nothing of the gateway.

use std::net::SocketAddr;

use tutti_core::shm::ShmError;

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GatewayError {
    /// The flags, the config file or the environment cannot be served (exit status 2).
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// `--mirror` with per-item types (exit status 2).
    #[error("--mirror needs --ros2-types typed: per-item samples carry no step")]
    MirrorNeedsTyped,
    /// `--mirror` for a gateway in the framework's process, which is itself the framework
    /// (exit status 2).
    #[error("a gateway in the framework's process cannot be a mirror: the mirror is the framework of its domains")]
    InProcessMirror,
    /// The rustdds engine was given unicast peers (exit status 2).
    #[error("the rustdds engine cannot be given unicast peers (--peer); use --dds cyclone")]
    PeersUnsupported,
    /// An engine this build does not contain (exit status 2).
    #[error("the {engine} engine is not in this build of the gateway (built without its cargo feature)")]
    EngineNotBuilt { engine: &'static str },
    /// A node name ROS 2 refuses (exit status 2).
    #[error("invalid ROS 2 node name '{name}': {detail}")]
    NodeName { name: String, detail: String },
    /// A name handed to DDS with a NUL byte in it (exit status 2).
    #[error("{what} '{value}' contains a NUL byte")]
    NulByte { what: &'static str, value: String },
    /// `--http` cannot listen on its address (exit status 2).
    #[error("--http {addr}: cannot listen there: {error}")]
    Listen { addr: SocketAddr, error: std::io::Error },
    /// `--foxglove` cannot listen on its address (exit status 2).
    #[error("--foxglove {addr}: cannot listen there: {error}")]
    FoxgloveListen { addr: SocketAddr, error: std::io::Error },
    /// A set's `ros2msg` schema cannot be written (for the Foxglove server's channels).
    #[error("the Foxglove server's schemas: {0}")]
    Schema(#[from] tutti_core::idl::ros2msg::SchemaError),
    /// A mirrored domain whose local framework is missing.
    #[error("domain '{domain}' was not created")]
    NotCreated { domain: String },
    /// DDS refused to create an entity.
    #[error("DDS: cannot create {what}: {detail}")]
    Dds { what: String, detail: String },
    /// The shared-memory layer failed (mirror: creating the local domains).
    #[error(transparent)]
    Shm(#[from] ShmError),
    #[error("cannot start the gateway's runtime: {0}")]
    Runtime(#[source] std::io::Error),
}

impl GatewayError {
    pub(crate) fn dds(what: impl Into<String>, detail: impl std::fmt::Display) -> Self {
        GatewayError::Dds { what: what.into(), detail: detail.to_string() }
    }

    /// Whether the error is bad input (exit status 2) rather than a runtime failure.
    pub fn is_invalid(&self) -> bool {
        use GatewayError::*;
        matches!(
            self,
            Config(_)
                | MirrorNeedsTyped
                | InProcessMirror
                | PeersUnsupported
                | EngineNotBuilt { .. }
                | NodeName { .. }
                | NulByte { .. }
                | Listen { .. }
                | FoxgloveListen { .. }
                | NotCreated { .. }
        )
    }
}

/// Why the gateway's configuration (its flags, config file or environment) cannot be
/// served. Each names where the value came from: the file with its line and column or key,
/// the flag, or the variable.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The config file cannot be read.
    #[error("{file}: cannot read the gateway config: {error}")]
    Read { file: String, error: std::io::Error },
    /// JSON5 syntax, an unknown key or a bad value, where it stands in the file.
    #[error("{file}{}: {message}", position.map(|(l, c)| format!(":{l}:{c}")).unwrap_or_default())]
    File { file: String, position: Option<(usize, usize)>, message: String },
    /// A `topics` key that names no set of the DDF.
    #[error("{at}: the DDF has no set '{set}' (sets: {sets})")]
    NoSuchSet { at: String, set: String, sets: String },
    /// Two sets (or a set and `/clock`) on one topic.
    #[error("{at}: '{topic}' is also the topic of {other}; two sets cannot share a topic")]
    TopicTaken { at: String, topic: String, other: String },
    /// A QoS or rate the domain's flags forbid.
    #[error("{at}: {term} is refused: domain '{domain}' has {flag} ({why})")]
    Refused { at: String, term: &'static str, domain: String, flag: &'static str, why: &'static str },
    /// `depth` without `history: "keep_last"`.
    #[error("{at}: depth needs history \"keep_last\" (it is how many samples KEEP_LAST keeps)")]
    DepthWithoutKeepLast { at: String },
    /// A bad `allow` / `deny` pattern, at its key.
    #[error("{at}: {error}")]
    PatternAt { at: String, error: Box<ConfigError> },
    /// A regular expression that does not compile.
    #[error("bad pattern '{pattern}': {error}")]
    Pattern { pattern: String, error: regex::Error },
    /// An invalid ROS namespace.
    #[error("ROS namespace '{given}': each part must be letters, digits and '_' and not start with a digit (e.g. sim1 or site_a/sim1)")]
    Namespace { given: String },
    /// An invalid ROS topic name (`remap`).
    #[error("'{name}' is not a ROS topic name: {why} (e.g. uav1/cmd, or /fleet/uav1/cmd)")]
    TopicName { name: String, why: &'static str },
    /// Not a rate of at least one sample in 365 days.
    #[error("'{value}' is not a rate in Hz above 0 (e.g. 100; at least one sample in 365 days)")]
    Rate { value: String },
    /// Not a duration.
    #[error(transparent)]
    Parse(#[from] tutti_core::parse::ParseError),
    /// A duration out of its key's range.
    #[error("'{value}': {why}")]
    Duration { value: String, why: &'static str },
    /// A discovery peer Cyclone DDS would not take.
    #[error("peer '{value}': {why}")]
    Peer { value: String, why: String },
    /// Not a type mapping.
    #[error("'{value}': use typed or per-item")]
    Types { value: String },
    /// Not a QoS profile.
    #[error("'{value}': use ros2 or dds")]
    Profile { value: String },
    /// `--clock` names no domain of the DDF.
    #[error("--clock {name}: the DDF has no domain '{name}' (domains: {domains})")]
    NoSuchClockDomain { name: String, domains: String },
    /// An unknown `ROS_AUTOMATIC_DISCOVERY_RANGE`.
    #[error("ROS_AUTOMATIC_DISCOVERY_RANGE='{value}': expected SUBNET, LOCALHOST, OFF or SYSTEM_DEFAULT")]
    DiscoveryRange { value: String },
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE=OFF` and no peers.
    #[error("ROS_AUTOMATIC_DISCOVERY_RANGE=OFF: no automatic discovery, so the gateway would find nobody; give the peers with --peer ADDR (or the config file's `peer`), or unset the variable")]
    DiscoveryOff,
    /// A bad `ROS_DOMAIN_ID`.
    #[error("ROS_DOMAIN_ID='{value}' is not a DDS domain id (0-232)")]
    DomainIdVar { value: String },
    /// A bad `TUTTI_DDS`.
    #[error("TUTTI_DDS='{value}': {error}")]
    EngineVar { value: String, error: UnknownEngine },
    /// A bad address in `TUTTI_GATEWAY_INTERFACE`.
    #[error("TUTTI_GATEWAY_INTERFACE: '{value}': {error}")]
    InterfaceVar { value: String, error: std::net::AddrParseError },
}

/// A name that is not one of the engines.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown DDS engine '{name}' (expected cyclone or rustdds)")]
pub struct UnknownEngine {
    pub name: String,
}
