//! Errors of the gateway, each with the domain, topic, address or setting involved: the
//! gateway's own ([`GatewayError`], its engine's included) and its configuration's
//! ([`ConfigError`]). This module imports nothing of the gateway.

use std::net::SocketAddr;

use tutti_core::shm::ShmError;
use tutti_engine::EngineError;

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
    /// The engine, or one of its entities, cannot be made (exit status 2 where the engine
    /// says the input was bad).
    #[error(transparent)]
    Engine(#[from] EngineError),
    /// `--http` cannot listen on its address (exit status 2).
    #[error("--http {addr}: cannot listen there: {error}")]
    Listen { addr: SocketAddr, error: std::io::Error },
    /// `--foxglove` cannot listen on its address (exit status 2).
    #[error("--foxglove {addr}: cannot listen there: {error}")]
    FoxgloveListen { addr: SocketAddr, error: std::io::Error },
    /// A set's `ros2msg` schema cannot be written (for the Foxglove server's channels).
    #[error("the Foxglove server's schemas: {0}")]
    Schema(#[from] tutti_ros2::idl::ros2msg::SchemaError),
    /// A mirrored domain whose local framework is missing.
    #[error("domain '{domain}' was not created")]
    NotCreated { domain: String },
    /// A thread of the gateway cannot be started.
    #[error("cannot start {0}: {1}")]
    Thread(&'static str, #[source] std::io::Error),
    /// The shared-memory layer failed (mirror: creating the local domains).
    #[error(transparent)]
    Shm(#[from] ShmError),
    #[error("cannot start the gateway's runtime: {0}")]
    Runtime(#[source] std::io::Error),
}

impl GatewayError {
    /// Whether the error is bad input (exit status 2) rather than a runtime failure.
    pub fn is_invalid(&self) -> bool {
        use GatewayError::*;
        if let Engine(e) = self {
            return e.is_invalid();
        }
        matches!(
            self,
            Config(_) | MirrorNeedsTyped | InProcessMirror | Listen { .. } | FoxgloveListen { .. } | NotCreated { .. }
        )
    }
}

/// Why the gateway's configuration (its flags, config file or environment) cannot be
/// served. Each names where the value came from: the file with its line and column or key,
/// the flag, or the variable.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The config file cannot be read, or has a mistake where it stands: JSON5 syntax,
    /// nesting too deep, an unknown key or a bad value.
    #[error(transparent)]
    File(#[from] tutti_config::Error),
    /// An entity whose domain or items the DDF does not have.
    #[error("{at}: {error}")]
    Entity { at: String, error: EntityError },
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
    /// An invalid ROS namespace or topic name (`remap`).
    #[error(transparent)]
    Name(#[from] tutti_ros2::names::NameError),
    /// Not a rate of at least one sample in 365 days.
    #[error("'{value}' is not a rate in Hz above 0 (e.g. 100; at least one sample in 365 days)")]
    Rate { value: String },
    /// Not a lookahead (`K` or `DOMAIN=K`).
    #[error("'{value}' is not a lookahead: give a number of steps from 0 to 100000 (every synchronous domain), or DOMAIN=STEPS")]
    Lookahead { value: String },
    /// A lookahead for a domain the DDF does not have, or cannot have one.
    #[error("lookahead for domain '{domain}': {why}")]
    LookaheadDomain { domain: String, why: String },
    /// Not a duration.
    #[error(transparent)]
    Parse(#[from] tutti_core::parse::ParseError),
    /// A duration out of its key's range.
    #[error("'{value}': {why}")]
    Duration { value: String, why: &'static str },
    /// A discovery peer the engine would not take, or a bad engine variable
    /// (`TUTTI_DDS`, `TUTTI_GATEWAY_INTERFACE`).
    #[error(transparent)]
    Engine(#[from] tutti_engine::keys::KeysError),
    /// A DDS Security enclave that cannot be used under `Enforce`, or a bad security
    /// setting: the message names the file or variable.
    #[error("DDS Security: {0}")]
    Security(#[from] tutti_engine::security::SecurityError),
    /// Not a type mapping.
    #[error("'{value}': use typed or per-item")]
    Types { value: String },
    /// Not a QoS profile.
    #[error("'{value}': use ros2 or dds")]
    Profile { value: String },
    /// `--clock` names no domain of the DDF.
    #[error("--clock {name}: the DDF has no domain '{name}' (domains: {domains})")]
    NoSuchClockDomain { name: String, domains: String },
    /// A bad ROS 2 variable (`ROS_DOMAIN_ID`, `ROS_AUTOMATIC_DISCOVERY_RANGE`).
    #[error(transparent)]
    Env(#[from] tutti_ros2::env::EnvError),
    /// `ROS_AUTOMATIC_DISCOVERY_RANGE=OFF` and no peers.
    #[error("ROS_AUTOMATIC_DISCOVERY_RANGE=OFF: no automatic discovery, so the gateway would find nobody; give the peers with --peer ADDR (or the config file's `peer`), or unset the variable")]
    DiscoveryOff,
}

/// Why an entity is refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EntityError {
    #[error("entity '{0}': {1}")]
    Shape(String, String),
    #[error("entity '{entity}': the DDF has no domain '{domain}' (domains: {domains})")]
    NoDomain { entity: String, domain: String, domains: String },
    /// An item its set does not have, or one that is not one number: what is wrong, in full.
    #[error("entity '{entity}': {why}")]
    Item { entity: String, why: String },
    #[error("entity '{0}' is declared twice")]
    Twice(String),
}
