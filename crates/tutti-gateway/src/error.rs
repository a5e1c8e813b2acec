//! Errors of the gateway, each with the domain, topic, address or setting involved.

use std::net::SocketAddr;

use tutti_core::shm::ShmError;

use crate::config::ConfigError;

#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GatewayError {
    /// The flags, the config file or the environment cannot be served (exit status 2).
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// `--mirror` with per-item types (exit status 2).
    #[error("--mirror needs --ros2-types typed: per-item samples carry no step")]
    MirrorNeedsTyped,
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
    /// A benchmark peer's domain cannot be echoed (exit status 2).
    #[error("domain '{domain}': the echo needs equal PUBLISH and SUBSCRIBE layouts")]
    EchoLayouts { domain: String },
    /// A benchmark ping got no answer (exit status 2).
    #[error("no echo (is the loopback interface up?)")]
    NoEcho,
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
                | PeersUnsupported
                | EngineNotBuilt { .. }
                | NodeName { .. }
                | NulByte { .. }
                | Listen { .. }
                | EchoLayouts { .. }
                | NoEcho
                | NotCreated { .. }
        )
    }
}
