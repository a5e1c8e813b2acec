//! What tutti's binaries (`tutti`, `tutti-bench`, `tutti-demo`) share: the exit statuses of
//! `docs/cli.md` (0 success, 2 invalid input or usage, 1 a runtime failure), the failure that
//! carries one, the `--realtime` options, and where the benchmarks and the demo find the
//! `tutti` executable. It is for
//! binaries only, so its errors are `anyhow`'s, printed as one chain ([`said_once`]).

use std::path::{Path, PathBuf};

use anyhow::Context;
use std::process::ExitCode;

/// Exit status for invalid input or usage.
pub const EXIT_INVALID: u8 = 2;
/// Exit status for a runtime failure.
pub const EXIT_FAILURE: u8 = 1;

/// A failure with the exit status it maps to.
#[derive(Debug)]
pub struct Failure {
    pub code: u8,
    pub error: anyhow::Error,
}

impl Failure {
    /// Invalid input or usage (exit status 2).
    pub fn invalid(error: impl Into<anyhow::Error>) -> Self {
        Failure { code: EXIT_INVALID, error: error.into() }
    }

    /// `error`, invalid input (status 2) when `invalid`, else a runtime failure (status 1):
    /// for library errors that know which they are (`e.is_invalid()`).
    pub fn classed(invalid: bool, error: impl Into<anyhow::Error>) -> Self {
        Failure { code: if invalid { EXIT_INVALID } else { EXIT_FAILURE }, error: error.into() }
    }
}

impl From<anyhow::Error> for Failure {
    fn from(error: anyhow::Error) -> Self {
        Failure { code: EXIT_FAILURE, error }
    }
}

/// What a subcommand returns.
pub type CliResult = Result<(), Failure>;

/// Loads a DDF, mapping its diagnostics to exit status 2.
pub fn load_ddf(path: &Path) -> Result<tutti_core::ddf::Model, Failure> {
    tutti_core::ddf::load(path).map_err(Failure::invalid)
}

/// The process's exit: success, or the failure's chain on stderr and its status.
pub fn exit(result: CliResult) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("{}", said_once(&f.error));
            ExitCode::from(f.code)
        }
    }
}

/// The error and its causes, as `{:#}` prints them (`outer: cause: cause`), except that a
/// cause whose text the message already holds is not said again: many errors put their
/// source in their own text (`"{path}: {source}"`) and mark it as the source too.
pub fn said_once(error: &anyhow::Error) -> String {
    let mut out = error.to_string();
    for cause in error.chain().skip(1) {
        let text = cause.to_string();
        if !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
    }
    out
}

/// The `tutti` executable for `tutti-bench` and `tutti-demo`: `TUTTI_EXE`, else the one next
/// to the running executable.
pub fn tutti_exe() -> anyhow::Result<PathBuf> {
    if let Some(p) = std::env::var_os("TUTTI_EXE") {
        return Ok(PathBuf::from(p));
    }
    let exe = std::env::current_exe().context("locating this executable")?;
    let tutti = exe.with_file_name("tutti");
    anyhow::ensure!(
        tutti.is_file(),
        "no tutti executable next to {}: build it with `cargo build --release -p tutti` (or set TUTTI_EXE)",
        exe.display()
    );
    Ok(tutti)
}

/// `--realtime [--cpu N] [--priority P]`, shared by the commands that step domains
/// (`tutti host`, `tutti-demo uav`).
#[derive(Debug, Clone, clap::Args)]
pub struct RealtimeArgs {
    /// Step under SCHED_FIFO with locked memory (mlockall), as far as the machine allows;
    /// what it refuses is a warning, not an error.
    #[arg(long)]
    pub realtime: bool,
    /// With --realtime: pin the stepping thread to this CPU.
    #[arg(long, value_name = "N", requires = "realtime")]
    pub cpu: Option<usize>,
    /// With --realtime: the SCHED_FIFO priority (1..99, default 50).
    #[arg(long, value_name = "P", requires = "realtime")]
    pub priority: Option<i32>,
}

impl RealtimeArgs {
    /// What to apply, when `--realtime` was given.
    pub fn request(&self) -> Option<tutti_host::RealtimeRequest> {
        self.realtime.then_some(tutti_host::RealtimeRequest { cpu: self.cpu, priority: self.priority })
    }
}

/// Applies `--realtime` to the calling thread when it was given, and prints (unless `quiet`)
/// what was applied and what was not, prefixed by `who`.
pub fn enter_realtime(args: &RealtimeArgs, who: &str, quiet: bool) {
    let Some(req) = args.request() else { return };
    let out = tutti_host::enter_realtime(&req);
    if quiet {
        return;
    }
    if !out.applied.is_empty() {
        eprintln!("{who}: real-time: {}", out.applied.join(", "));
    }
    for w in &out.warnings {
        eprintln!("{who}: warning: {w}");
    }
}

/// The flag Ctrl-C (or SIGTERM) raises: a command's loop stops when it is set. Installs the
/// process's one signal handler: call it once per process.
pub fn stop_flag() -> anyhow::Result<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    tutti_host::stop_on_ctrl_c().context("installing the signal handler")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("reading {path}: {source}")]
    struct Reading {
        path: String,
        #[source]
        source: std::io::Error,
    }

    #[test]
    fn a_cause_already_in_the_message_is_said_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory");
        let e = anyhow::Error::new(Reading { path: "a.ddf".into(), source: io }).context("hosting");
        assert_eq!(said_once(&e), "hosting: reading a.ddf: No such file or directory");
        let plain = anyhow::anyhow!("inner").context("outer");
        assert_eq!(said_once(&plain), "outer: inner");
    }
}
