//! Test support: a framework stepping in a thread, C compilation against the built library,
//! and cleanup that runs even when a test fails; child processes with a watchdog are the
//! workspace's `tutti-test-support`.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tutti_core::ddf::{self, Model, Role, ScalarType};
use tutti_core::shm::{Framework, FrameworkOptions};
use tutti_test_support::{Proc, Worker};

/// The workspace root.
pub fn root() -> PathBuf {
    tutti_test_support::repo_root().canonicalize().expect("workspace root")
}

/// target/<profile> of this build.
pub fn profile_dir() -> PathBuf {
    tutti_test_support::profile_dir()
}

/// The directory holding librtapi.so / librtapi.a of this build.
pub fn lib_dir() -> PathBuf {
    tutti_test_support::rtapi_lib_dir()
}

/// A namespace unique to this process and test.
pub fn namespace(test: &str) -> String {
    tutti_test_support::namespace(&format!("rt-{test}-"))
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
    _stepping: Worker,
    pub seen: Arc<Mutex<Vec<Seen>>>,
}

impl Host {
    pub fn start(model: &Model, opts: FrameworkOptions, period: Duration) -> Host {
        let mut fw = Framework::create(model, &opts).expect("creating the framework");
        let seen = Arc::new(Mutex::new(Vec::new()));
        let seen2 = seen.clone();
        let stepping = Worker::spawn(move |stop2| {
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
        Host { _stepping: stepping, seen }
    }

    pub fn seen(&self) -> Vec<Seen> {
        self.seen.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// What the framework saw, once it has finished each (domain, step) of `until` (or after
    /// `timeout`): a client that exits right after its last commit can be faster than the
    /// framework completing the step that commit answers, above all on a loaded machine.
    pub fn seen_through(&self, until: &[(&str, u64)], timeout: Duration) -> Vec<Seen> {
        let through = || {
            let seen = self.seen();
            let done = |&(d, k): &(&str, u64)| seen.iter().any(|s| s.domain == d && s.step >= k);
            until.iter().all(done).then_some(seen)
        };
        // A test judges what was seen either way: a wait that runs out is no failure here.
        tutti_test_support::poll_for(timeout, through).unwrap_or_else(|| self.seen())
    }
}

/// Spawns `cmd` with its output collected and a watchdog; it is stopped when dropped
/// (SIGINT first, so a `tutti host` removes its segments, then SIGKILL after 3 s), so a
/// failing test leaves nothing running.
pub fn spawn(cmd: Command) -> Proc {
    Proc::spawn("child", cmd, Duration::from_secs(600))
}

/// Runs `cmd` to completion under a watchdog; a timeout kills it and fails the test.
pub fn run(cmd: &mut Command, limit: Duration) -> Output {
    tutti_test_support::run_output(cmd, limit)
}

/// The `tutti` binary of this build.
pub fn tutti() -> PathBuf {
    tutti_test_support::tutti_exe()
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

/// Path of the segment of `domain` in namespace `ns`.
pub fn shm_path(ns: &str, domain: &str) -> PathBuf {
    tutti_core::shm::segment::segment_path(ns, domain)
}
