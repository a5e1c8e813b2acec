//! The engines' errors, each with the entity, name or setting involved.

/// Why an engine, or one of its entities, cannot be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EngineError {
    /// The rustdds engine was given unicast peers (exit status 2).
    #[error("the rustdds engine cannot be given unicast peers (--peer); use --engine cyclone (--dds cyclone)")]
    PeersUnsupported,
    /// An engine this build does not contain (exit status 2).
    #[error("the {engine} engine is not in this build of the gateway (built without its cargo feature)")]
    NotBuilt { engine: &'static str },
    /// A node name ROS 2 refuses (exit status 2).
    #[error("invalid ROS 2 node name '{name}': {detail}")]
    NodeName { name: String, detail: String },
    /// A name handed to the middleware with a NUL byte in it (exit status 2).
    #[error("{what} '{value}' contains a NUL byte")]
    NulByte { what: &'static str, value: String },
    /// The middleware refused to create an entity.
    #[error("DDS: cannot create {what}: {detail}")]
    Dds { what: String, detail: String },
    /// The Zenoh engine was given DDS discovery peers (exit status 2).
    #[error("the zenoh engine finds the others through a Zenoh router, not DDS peers (--peer): give its endpoint with --zenoh-connect tcp/HOST:7447")]
    ZenohPeers,
    /// A Zenoh configuration that Zenoh refuses: the file of `ZENOH_SESSION_CONFIG_URI`, an
    /// endpoint (exit status 2).
    #[error("Zenoh configuration: {detail}")]
    ZenohConfig { detail: String },
    /// Zenoh refused to open the session or to declare an entity.
    #[error("Zenoh: cannot create {what}: {detail}")]
    Zenoh { what: String, detail: String },
    /// The DDS Security enclave cannot be used (exit status 2): the error names the file.
    #[error("DDS Security: {0}")]
    Security(#[from] crate::security::SecurityError),
    /// DDS Security's access control refused an entity: the enclave's permissions do not
    /// allow the topic (for this direction, on this domain).
    #[error("DDS Security: the permissions do not allow {what}")]
    NotAllowed { what: String },
    /// The engine's own threads cannot be started.
    #[error("cannot start the engine's runtime: {0}")]
    Runtime(#[source] std::io::Error),
}

impl EngineError {
    pub(crate) fn dds(what: impl Into<String>, detail: impl std::fmt::Display) -> Self {
        EngineError::Dds { what: what.into(), detail: detail.to_string() }
    }

    /// Whether the error is bad input (exit status 2) rather than a runtime failure.
    pub fn is_invalid(&self) -> bool {
        matches!(
            self,
            EngineError::PeersUnsupported
                | EngineError::NotBuilt { .. }
                | EngineError::NodeName { .. }
                | EngineError::NulByte { .. }
                | EngineError::ZenohConfig { .. }
                | EngineError::ZenohPeers
                | EngineError::Security(_)
        )
    }
}

/// A name that is not one of the engines.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown engine '{name}' (expected cyclone, rustdds or zenoh)")]
pub struct UnknownEngine {
    pub name: String,
}
