//! Errors of the gateway, each with the domain or topic involved.

use tutti_core::shm::ShmError;

#[derive(Debug, thiserror::Error)]
pub enum GatewayError {
    /// The options or the DDF cannot be served (exit status 2).
    #[error("{0}")]
    Invalid(String),
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
        matches!(self, GatewayError::Invalid(_))
    }
}
