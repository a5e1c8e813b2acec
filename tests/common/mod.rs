//! Support for the CLI tests: run the `tutti` binary with a watchdog.
#![allow(dead_code)]

use std::ffi::OsStr;
use std::io::Read;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// Longest a single `tutti` command may take in a test.
pub const TIMEOUT: Duration = Duration::from_secs(60);

/// Runs `tutti ARGS` in the repository root with a watchdog; returns (exit code, stdout,
/// stderr). A command that outlives [`TIMEOUT`] is killed and fails the test.
pub fn tutti<I, S>(args: I) -> (i32, String, String)
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_tutti"));
    cmd.args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    let (status, out, err) = run_with_timeout(cmd, TIMEOUT);
    (status.code().unwrap_or(-1), out, err)
}

/// Runs `cmd` (no stdin) and collects its stdout and stderr; a command that outlives
/// `limit` is killed and fails the test.
pub fn run_with_timeout(mut cmd: Command, limit: Duration) -> (ExitStatus, String, String) {
    let shown = format!("{cmd:?}");
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start {shown}: {e}"));
    let read_all = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            let _ = r.read_to_string(&mut s);
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
            let tail = |s: String| {
                s.lines().rev().take(20).collect::<Vec<_>>().into_iter().rev().collect::<Vec<_>>().join("\n")
            };
            let (out, err) = (tail(out.join().unwrap_or_default()), tail(err.join().unwrap_or_default()));
            panic!("{shown} did not finish within {limit:?}; killed\n--- stdout (end) ---\n{out}\n--- stderr (end) ---\n{err}");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    (status, out.join().expect("stdout reader"), err.join().expect("stderr reader"))
}

/// The folder of librtapi.so next to the tutti executable (the demo looks there); built
/// when missing.
pub fn ensure_rtapi() -> std::path::PathBuf {
    let exe = std::path::PathBuf::from(env!("CARGO_BIN_EXE_tutti"));
    let dir = exe.parent().expect("the executable's folder");
    if let Some(d) = [dir.to_path_buf(), dir.join("deps")].into_iter().find(|d| d.join("librtapi.so").is_file()) {
        return d;
    }
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.args(["build", "-q", "-p", "tutti-rtapi"]).current_dir(env!("CARGO_MANIFEST_DIR"));
    if dir.file_name().is_some_and(|n| n == "release") {
        cmd.arg("--release");
    }
    assert!(cmd.status().expect("running cargo").success(), "building librtapi");
    dir.to_path_buf()
}

/// The executable `bin` of the workspace member `package` (the benchmarks' `tutti-bench`,
/// the demo's `tutti-demo`), next to the tutti executable: built when missing, as that one was
/// (debug or release).
pub fn ensure_bin(package: &str, bin: &str) -> std::path::PathBuf {
    let exe = std::path::PathBuf::from(env!("CARGO_BIN_EXE_tutti"));
    let path = exe.with_file_name(bin);
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.args(["build", "-q", "-p", package]).current_dir(env!("CARGO_MANIFEST_DIR"));
    if exe.parent().and_then(|d| d.file_name()).is_some_and(|n| n == "release") {
        cmd.arg("--release");
    }
    assert!(cmd.status().expect("running cargo").success(), "building {bin}");
    assert!(path.is_file(), "{} not built", path.display());
    path
}

/// Compiles the C program `source` against include/RTAPI.h and this build's librtapi (run
/// path set, so it runs from there) into `out`, with the compiler flags `flags`; fails the
/// test with the compiler's output when it does not compile.
pub fn compile_c(source: &std::path::Path, out: &std::path::Path, flags: &[&str]) -> std::path::PathBuf {
    let lib = ensure_rtapi();
    let include = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("include");
    let mut cc = Command::new("gcc");
    cc.args(flags)
        .arg(format!("-I{}", include.display()))
        .arg(source)
        .arg("-o")
        .arg(out)
        .arg(format!("-L{}", lib.display()))
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .arg("-lrtapi");
    let (status, _, err) = run_with_timeout(cc, Duration::from_secs(120));
    assert!(status.success(), "compiling {}: {err}", source.display());
    out.to_path_buf()
}

/// The shared-memory segments of namespace `ns` now in /dev/shm (their file names).
pub fn segments_of(ns: &str) -> Vec<String> {
    let prefix = format!("tutti.{ns}.");
    std::fs::read_dir("/dev/shm")
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&prefix))
        .collect()
}

/// Removes the segments of namespace `.0` when dropped: a test's cleanup, which runs even
/// when the test fails or a framework it started was killed.
pub struct RemoveSegments(pub String);

impl Drop for RemoveSegments {
    fn drop(&mut self) {
        for name in segments_of(&self.0) {
            let _ = std::fs::remove_file(format!("/dev/shm/{name}"));
        }
    }
}
