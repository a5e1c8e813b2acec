//! What can go wrong: a launch file that is refused ([`LaunchError`]), and a run that fails
//! ([`RunError`]).

use std::path::PathBuf;

/// A launch file that cannot be used; nothing has been started.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// The file cannot be read.
    #[error("reading {file}: {source}")]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    /// A mistake at a place of the file: `FILE:LINE:COLUMN: message`.
    #[error("{file}:{line}:{column}: {message}")]
    At { file: String, line: usize, column: usize, message: String },
    /// A mistake json5 could not place.
    #[error("{file}: {message}")]
    File { file: String, message: String },
}

/// A run that could not start or did not end well.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The framework could not be created (its options do not apply: invalid input).
    #[error(transparent)]
    Host(#[from] tutti_host::HostError),
    /// A recording could not be started.
    #[error("starting the recording {path}: {source}")]
    Record {
        path: PathBuf,
        #[source]
        source: Box<tutti_record::RecordError>,
    },
    /// The log directory cannot be made.
    #[error("creating the log directory {dir}: {source}")]
    LogDir {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The supervisor failed.
    #[error(transparent)]
    Supervisor(#[from] SupervisorError),
    /// The gateway could not be started.
    #[error("starting the gateway: {0}")]
    Gateway(#[source] tutti_gateway::GatewayError),
}

impl RunError {
    /// Whether the launch asked for something impossible (exit status 2) rather than the
    /// run failing.
    pub fn is_invalid(&self) -> bool {
        match self {
            RunError::Host(e) => e.is_invalid(),
            RunError::Gateway(e) => e.is_invalid(),
            _ => false,
        }
    }
}

/// What the supervisor reports as failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SupervisorError {
    /// No component of that name.
    #[error("no component '{name}' (components: {known})")]
    NoComponent { name: String, known: String },
    /// `start` of a component that runs.
    #[error("component '{name}' is already running (pid {pid})")]
    AlreadyRunning { name: String, pid: u32 },
    /// Its process could not be started.
    #[error("component '{name}': cannot start {program}: {reason}")]
    Spawn { name: String, program: String, reason: String },
    /// It did not connect to its domain in time.
    #[error(
        "component '{name}' did not connect to domain '{domain}' within {timeout:?}; its output is in {}",
        log.display()
    )]
    ConnectTimeout { name: String, domain: String, timeout: std::time::Duration, log: PathBuf },
    /// It ended before it had connected.
    #[error("component '{name}' ended ({end}) before it connected; its output is in {}", log.display())]
    EndedBeforeConnecting { name: String, end: String, log: PathBuf },
    /// A signal for a component that has no process.
    #[error("component '{name}' is not running ({state}): there is no process to signal")]
    NotRunning { name: String, state: String },
    /// The signal could not be sent.
    #[error("component '{name}': sending signal {signal} to pid {pid}: {reason}")]
    Signal { name: String, pid: u32, signal: i32, reason: String },
    /// The run is being torn down (Ctrl-C, a stop), or is over.
    #[error("the run is stopping")]
    Stopping,
}
