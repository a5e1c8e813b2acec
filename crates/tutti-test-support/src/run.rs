//! Commands run to their end under a watchdog, and the `tutti` binary.

use std::borrow::BorrowMut;
use std::ffi::OsStr;
use std::io::Read;
use std::path::PathBuf;
use std::process::{Command, ExitStatus, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Longest a single `tutti` command of [`tutti`] may take.
pub const TIMEOUT: Duration = Duration::from_secs(60);

/// Runs `cmd` (no stdin) and collects its stdout and stderr; a command that outlives `limit`
/// is killed and fails the test, showing the end of what it printed.
pub fn run_with_timeout(cmd: impl BorrowMut<Command>, limit: Duration) -> (ExitStatus, String, String) {
    let out = run_output(cmd, limit);
    (out.status, String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// [`run_with_timeout`], with the output as bytes.
pub fn run_output(mut cmd: impl BorrowMut<Command>, limit: Duration) -> Output {
    let cmd = cmd.borrow_mut();
    let shown = format!("{cmd:?}");
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {shown}: {e}"));
    let read_all = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut s = Vec::new();
            let _ = r.read_to_end(&mut s);
            s
        })
    };
    let out = read_all(Box::new(child.stdout.take().expect("stdout")));
    let err = read_all(Box::new(child.stderr.take().expect("stderr")));
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap_or_else(|e| panic!("cannot wait for {shown}: {e}")) {
            break status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            // What it printed up to then says where it hung.
            let tail = |s: Vec<u8>| {
                let s = String::from_utf8_lossy(&s).into_owned();
                s.lines().rev().take(20).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>().join("\n")
            };
            let (out, err) = (tail(out.join().unwrap_or_default()), tail(err.join().unwrap_or_default()));
            panic!("{shown} did not finish within {limit:?}; killed\n--- stdout (end) ---\n{out}\n--- stderr (end) ---\n{err}");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Output { status, stdout: out.join().expect("stdout reader"), stderr: err.join().expect("stderr reader") }
}

/// The `tutti` binary of this build (`target/<profile>/tutti`). A test of the `tutti` package
/// always has it; a crate's test that needs it builds it when it is missing (`cargo build
/// --workspace` before the tests, as the test command does, keeps it current).
pub fn tutti_exe() -> PathBuf {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| workspace_bin("tutti", "tutti")).clone()
}

/// The executable `bin` of the workspace member `package` in this build's
/// `target/<profile>` (the benchmarks' `tutti-bench`, the demo's `tutti-demo`), built when it
/// is missing, as [`tutti_exe`] is.
pub fn workspace_bin(package: &str, bin: &str) -> PathBuf {
    let profile = crate::profile_dir();
    let exe = profile.join(bin);
    if !exe.is_file() {
        let mut cmd = Command::new(crate::cargo());
        cmd.args(["build", "-q", "-p", package, "--bin", bin]).current_dir(crate::repo_root());
        if profile.file_name().is_some_and(|n| n == "release") {
            cmd.arg("--release");
        }
        assert!(cmd.status().expect("running cargo").success(), "building {bin} of {package}");
        assert!(exe.is_file(), "{} missing after building it", exe.display());
    }
    exe
}

/// A `tutti` command, run in the repository root (so that `ddf/…` paths resolve).
pub fn tutti_command() -> Command {
    let mut cmd = Command::new(tutti_exe());
    cmd.current_dir(crate::repo_root());
    cmd
}

/// Runs `tutti ARGS` in the repository root with a watchdog of [`TIMEOUT`]; returns (exit
/// code, stdout, stderr). A command that outlives it is killed and fails the test.
pub fn tutti<I, S>(args: I) -> (i32, String, String)
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let mut cmd = tutti_command();
    cmd.args(args);
    let (status, out, err) = run_with_timeout(cmd, TIMEOUT);
    (status.code().unwrap_or(-1), out, err)
}

/// Why a test could not set the machine up for itself (network namespaces, devices, a tool).
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    /// `program` could not be started.
    #[error("{program}: {source}")]
    Spawn { program: String, source: std::io::Error },
    /// `command` ran and failed; what it printed on stderr.
    #[error("{command}: {stderr}")]
    Failed { command: String, stderr: String },
    /// A system call or file of the set-up failed.
    #[error("{what}: {source}")]
    Os { what: String, source: std::io::Error },
    /// A thread of the set-up panicked.
    #[error("{0} panicked")]
    Panicked(&'static str),
}

impl SetupError {
    /// [`SetupError::Os`] with the calling thread's last OS error.
    pub fn last_os(what: impl Into<String>) -> SetupError {
        SetupError::Os { what: what.into(), source: std::io::Error::last_os_error() }
    }

    /// A function that makes [`SetupError::Os`] of `what` from an I/O error (for `map_err`).
    pub fn os(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> SetupError {
        let what = what.into();
        move |source| SetupError::Os { what, source }
    }
}

/// Runs `program ARGS` to its end; Err with what it printed on failure (a test's set-up of
/// the machine: `ip`, `nft`).
pub fn run_tool(program: &str, args: &[&str]) -> Result<(), SetupError> {
    let out = Command::new(program)
        .args(args)
        .output()
        .map_err(|source| SetupError::Spawn { program: program.into(), source })?;
    if out.status.success() {
        Ok(())
    } else {
        Err(SetupError::Failed {
            command: format!("{program} {}", args.join(" ")),
            stderr: String::from_utf8_lossy(&out.stderr).trim().to_string(),
        })
    }
}
