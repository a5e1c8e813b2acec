//! What can go wrong: a launch file that is refused ([`LaunchError`], a key's mistake
//! being a [`KeyError`]), and a run that fails ([`RunError`]).

use std::path::PathBuf;
use std::sync::Arc;

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
    /// A mistake at a place of the file, `FILE:LINE:COLUMN: message` (JSON5 syntax, nesting,
    /// an unknown key, a value of the wrong type, a [`KeyError`] where its key stands), or
    /// `FILE: message` where json5 cannot place it.
    #[error(transparent)]
    File(#[from] tutti_config::Error),
    /// A key's mistake found once the file was read, where it has no place: a program that
    /// was found while the file was checked and is gone now.
    #[error("{file}: {error}")]
    Unplaced { file: String, error: Box<KeyError> },
}

/// What a key of the launch file says that cannot be used. Its place in the file is added
/// by the reader ([`LaunchError::File`]); each names the key, and the component it belongs to.
#[derive(Debug, thiserror::Error)]
pub enum KeyError {
    /// The DDF cannot be loaded.
    #[error("ddf: {0}")]
    Ddf(Arc<tutti_core::ddf::DdfError>),
    /// Not a duration.
    #[error("{key}: {error}")]
    Duration { key: &'static str, error: tutti_core::parse::ParseError },
    #[error("step: must be longer than 0")]
    ZeroStep,
    #[error("speed: {0}: must be a positive number of simulated seconds per wall-clock second, or 0 for as fast as possible")]
    Speed(f64),
    #[error("wait: {0}")]
    Wait(tutti_core::parse::ParseError),
    #[error("ordering: {0}")]
    Ordering(tutti_host::connect::UnknownOrder),
    /// A `set` value that does not fit the DDF.
    #[error("set: {0}")]
    Set(Box<tutti_host::HostError>),
    #[error("framework: give `duration` or `steps`, not both")]
    DurationAndSteps,
    /// A connection that does not parse or does not fit the DDF.
    #[error("connections: {0}")]
    Connections(tutti_host::connect::ConnectError),
    #[error("name '{0}': use letters, digits, '_', '-' and '.' (not first): it names the component's log file")]
    Name(String),
    #[error("name '{0}' is given to two components: names must be unique")]
    NameTaken(String),
    #[error("{who}: run: give the program and its arguments, like [\"./controller\", \"--gain\", \"2\"]")]
    RunEmpty { who: String },
    #[error("{who}: run: '{program}' is not an executable file ({}; relative paths start at the launch file's directory)", path.display())]
    NotExecutable { who: String, program: String, path: PathBuf },
    #[error("{who}: run: command '{program}' not found on PATH")]
    NotOnPath { who: String, program: String },
    #[error("{who}: fmu: no file {}", path.display())]
    NoFmu { who: String, path: PathBuf },
    /// The FMU cannot be opened, or is no co-simulation FMU.
    #[error("{who}: fmu: {error}")]
    Fmu { who: String, error: Box<tutti_fmu::LoadError> },
    #[error("{who}: domain '{domain}' is not in {} (its domains: {domains})", ddf.display())]
    NoDomain { who: String, domain: String, ddf: PathBuf, domains: String },
    #[error("{who}: cwd: no directory {}", dir.display())]
    NoCwd { who: String, dir: PathBuf },
    #[error("{who}: an FMU component needs `domain`: the domain it joins")]
    FmuWithoutDomain { who: String },
    /// The FMU's variables do not fit its domain's items.
    #[error("{who}: {} does not fit domain '{domain}': {error}", fmu.display())]
    Misfit { who: String, fmu: PathBuf, domain: String, error: Box<tutti_fmu::MappingError> },
    #[error("{who}: params: '{param}' is not NAME=VALUE")]
    ParamForm { who: String, param: String },
    /// A `params` entry the FMU cannot take.
    #[error("{who}: params: '{param}': {why}")]
    Param { who: String, param: String, why: ParamError },
    #[error("checkpoint: every must be a number of steps above 0")]
    CheckpointEvery,
    #[error("{who}: give `run` or `fmu`, not both")]
    RunAndFmu { who: String },
    #[error("{who}: `params` are an FMU's: give them with `fmu`")]
    ParamsWithoutFmu { who: String },
    #[error("{who}: give `run: [PROGRAM, ARGS…]` or `fmu: FILE`")]
    NoProgram { who: String },
    #[error("gateway: give `config: FILE` or the config file's keys, not both")]
    GatewayConfigAndKeys,
    /// The gateway's keys, or its config file, refused (by the gateway's own checks).
    #[error("gateway: {0}")]
    Gateway(Box<tutti_gateway::config::ConfigError>),
}

/// Why an FMU component's `params` entry names no variable that `--param` can set.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParamError {
    #[error("model '{model}' has no variable '{name}'")]
    NoVariable { model: String, name: String },
    #[error("'{name}' is {variability} {causality}, not a parameter or an input")]
    NotSettable { name: String, variability: String, causality: &'static str },
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
