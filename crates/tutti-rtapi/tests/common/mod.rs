//! Test support: a framework stepping in a thread, child processes with a watchdog, C
//! compilation against the built library, and cleanup that runs even when a test fails.
#![allow(dead_code)]

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tutti_core::ddf::{self, Model, Role, ScalarType};
use tutti_core::shm::{Framework, FrameworkOptions};

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").canonicalize().expect("workspace root")
}

/// target/<profile> of this build.
pub fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test exe");
    exe.parent().and_then(Path::parent).expect("target/<profile>").to_path_buf()
}

/// The directory holding librtapi.so / librtapi.a of this build: `deps/`, where `cargo test`
/// builds them (it copies them up to target/<profile> only on `cargo build`), else
/// target/<profile>.
pub fn lib_dir() -> PathBuf {
    let profile = profile_dir();
    let dir = [profile.join("deps"), profile.clone()].into_iter().find(|d| d.join("librtapi.so").exists());
    dir.unwrap_or_else(|| panic!("librtapi.so missing under {}: run `cargo build -p tutti-rtapi`", profile.display()))
}

/// A namespace unique to this process and test.
pub fn namespace(test: &str) -> String {
    format!("rt{}-{test}", std::process::id())
}

pub fn load(path: &str) -> Model {
    ddf::load(root().join(path)).expect("DDF")
}

/// One step's view of a domain: the step number and the SUBSCRIBE set read after it.
#[derive(Debug, Clone)]
pub struct Seen {
    pub domain: String,
    pub step: u64,
    pub subscribe: Vec<u8>,
}

/// A framework for every domain of a model, stepped in a thread: every float64 PUBLISH
/// element of step k holds k. Stops (and removes its segments) when dropped.
pub struct Host {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    pub seen: Arc<Mutex<Vec<Seen>>>,
}

impl Host {
    pub fn start(model: &Model, opts: FrameworkOptions, period: Duration) -> Host {
        let mut fw = Framework::create(model, &opts).expect("creating the framework");
        let stop = Arc::new(AtomicBool::new(false));
        let seen = Arc::new(Mutex::new(Vec::new()));
        let (stop2, seen2) = (stop.clone(), seen.clone());
        let thread = std::thread::spawn(move || {
            let mut k = 0u64;
            while !stop2.load(Ordering::Acquire) {
                k += 1;
                for host in &mut fw.domains {
                    let info = host.info().clone();
                    let mut buf = vec![0u8; info.publish.size as usize];
                    for leaf in info.set(Role::Publish).leaves.iter().filter(|l| l.ty == ScalarType::Float64) {
                        for e in 0..leaf.length as usize {
                            let off = leaf.offset as usize + 8 * e;
                            buf[off..off + 8].copy_from_slice(&(k as f64).to_ne_bytes());
                        }
                    }
                    if host.step(&buf, k as f64 * period.as_secs_f64()).is_err() {
                        return;
                    }
                    let entry = Seen {
                        domain: info.name.clone(),
                        step: host.current_step(),
                        subscribe: host.subscribe().to_vec(),
                    };
                    seen2.lock().unwrap_or_else(|e| e.into_inner()).push(entry);
                }
                std::thread::sleep(period);
            }
        });
        Host { stop, thread: Some(thread), seen }
    }

    pub fn seen(&self) -> Vec<Seen> {
        self.seen.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// What the framework saw, once it has finished each (domain, step) of `until` (or after
    /// `timeout`): a client that exits right after its last commit can be faster than the
    /// framework completing the step that commit answers, above all on a loaded machine.
    pub fn seen_through(&self, until: &[(&str, u64)], timeout: Duration) -> Vec<Seen> {
        let end = std::time::Instant::now() + timeout;
        loop {
            let seen = self.seen();
            let done = |&(d, k): &(&str, u64)| seen.iter().any(|s| s.domain == d && s.step >= k);
            if until.iter().all(done) || std::time::Instant::now() > end {
                return seen;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

impl Drop for Host {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A child process stopped when dropped, so a failing test leaves nothing running. It gets
/// SIGINT first, so a `tutti host` removes its segments, and then SIGKILL if it is still
/// there after 3 s.
pub struct ChildGuard(pub Option<Child>);

impl ChildGuard {
    /// Waits for the child at most `limit`; kills it and fails the test on a timeout.
    pub fn wait_output(mut self, limit: Duration) -> Output {
        let mut child = self.0.take().expect("child");
        let deadline = Instant::now() + limit;
        loop {
            match child.try_wait().expect("waiting for the child") {
                Some(status) => {
                    let mut stdout = Vec::new();
                    let mut stderr = Vec::new();
                    if let Some(mut s) = child.stdout.take() {
                        let _ = s.read_to_end(&mut stdout);
                    }
                    if let Some(mut s) = child.stderr.take() {
                        let _ = s.read_to_end(&mut stderr);
                    }
                    return Output { status, stdout, stderr };
                }
                None if Instant::now() >= deadline => {
                    let _ = child.kill();
                    let _ = child.wait();
                    panic!("child process did not finish within {limit:?}: killed");
                }
                None => std::thread::sleep(Duration::from_millis(10)),
            }
        }
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            if let Ok(None) = c.try_wait() {
                let _ = Command::new("kill").args(["-INT", &c.id().to_string()]).status();
                let end = Instant::now() + Duration::from_secs(3);
                while Instant::now() < end && matches!(c.try_wait(), Ok(None)) {
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Spawns `cmd` with piped output. The pipes are drained only at the end, so children must
/// print little (a pipe holds 64 KiB).
pub fn spawn(cmd: &mut Command) -> ChildGuard {
    ChildGuard(Some(cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("spawning a child")))
}

/// Runs `cmd` to completion under a watchdog.
pub fn run(cmd: &mut Command, limit: Duration) -> Output {
    spawn(cmd).wait_output(limit)
}

/// Compiles `source` (C, or C++ if it ends in .cpp) against include/RTAPI.h and librtapi.so
/// into `out_dir`; returns the program's path.
pub fn compile(source: &Path, out_dir: &Path) -> PathBuf {
    compile_with(source, out_dir, &[])
}

/// [`compile`] with extra compiler flags (e.g. `-Wconversion`).
pub fn compile_with(source: &Path, out_dir: &Path, extra: &[&str]) -> PathBuf {
    let lib = lib_dir();
    let cpp = source.extension().is_some_and(|e| e == "cpp");
    let out = out_dir.join(source.file_stem().expect("file name"));
    let mut cmd = Command::new(if cpp { "g++" } else { "gcc" });
    if cpp {
        cmd.args(["-std=c++11", "-Wall", "-Wextra", "-Werror"]);
    } else {
        cmd.args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]);
    }
    cmd.args(extra);
    cmd.arg("-g").arg(format!("-I{}", root().join("include").display())).arg(source).arg("-o").arg(&out);
    cmd.arg(format!("-L{}", lib.display())).arg(format!("-Wl,-rpath,{}", lib.display())).arg("-lrtapi");
    let output = run(&mut cmd, Duration::from_secs(120));
    assert!(
        output.status.success(),
        "compiling {} failed:\n{}",
        source.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    out
}

/// A file in /dev/shm removed when dropped (crafted segments).
pub struct ShmFile(pub PathBuf);

impl Drop for ShmFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
        let _ = std::fs::remove_dir(&self.0);
    }
}

/// Path of the segment of `domain` in namespace `ns`.
pub fn shm_path(ns: &str, domain: &str) -> PathBuf {
    tutti_core::shm::segment::segment_path(ns, domain)
}
