//! What can go wrong in a run.

use tutti_core::shm::ShmError;

/// A run that cannot start or cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum HostError {
    /// The step period is zero.
    #[error("--step must be longer than 0")]
    ZeroStep,
    /// The speed is not a positive number (or makes the period zero).
    #[error("speed {0}: must be a positive number of simulated seconds per wall-clock second")]
    Speed(f64),
    /// A `DOMAIN/ITEM=VALUE` that does not apply to the model.
    #[error("--set '{set}': {reason}")]
    Set { set: String, reason: String },
    /// `--wait-for` names a domain the run does not have.
    #[error("--wait-for {domain}={writers}: no domain '{domain}' in {ddf}")]
    WaitForDomain { domain: String, writers: usize, ddf: String },
    /// The domains could not be created.
    #[error("hosting {ddf}: {source}")]
    Create {
        ddf: String,
        #[source]
        source: ShmError,
    },
    /// A domain failed during a step or a wait.
    #[error("domain '{domain}': {source}")]
    Domain {
        domain: String,
        #[source]
        source: ShmError,
    },
    /// A step names a domain index the run does not have.
    #[error("no domain {index} in the run")]
    NoDomain { index: usize },
    /// A connection that cannot be made.
    #[error(transparent)]
    Connect(#[from] crate::connect::ConnectError),
    /// The control plane could not be served.
    #[error(transparent)]
    Control(#[from] crate::control::ControlError),
    /// A checkpoint could not be put back at the start (`tutti run --restore`).
    #[error("restoring the checkpoint: {0}")]
    Checkpoint(#[source] crate::checkpoint::CheckpointError),
    /// A step sink (a recording) failed.
    #[error("{what}: {source}")]
    Sink {
        what: &'static str,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

impl HostError {
    /// Whether the options asked for something impossible (the CLI's exit status 2), rather
    /// than the run failing.
    pub fn is_invalid(&self) -> bool {
        matches!(
            self,
            HostError::ZeroStep
                | HostError::Speed(_)
                | HostError::Set { .. }
                | HostError::WaitForDomain { .. }
                | HostError::Connect(_)
        ) || matches!(self, HostError::Checkpoint(e) if e.is_invalid())
    }
}
