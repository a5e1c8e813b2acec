//! Child processes of the CLI (the demo's components, the benchmarks' peers): started so
//! that they die with this process, and stopped when their [`Kid`] is dropped.

use std::os::unix::process::CommandExt;
use std::process::{Child, Command, ExitStatus};
use std::time::{Duration, Instant};

use anyhow::Context;
use tutti_core::shm::os;

pub const SIGINT: i32 = 2;
pub const SIGTERM: i32 = 15;

/// A child process; dropping it stops it as [`Kid::stop_on_drop`] says (by default SIGTERM,
/// 1.5 s to exit, then SIGKILL).
pub struct Kid {
    pub name: String,
    pub child: Child,
    done: Option<ExitStatus>,
    on_drop: (Option<i32>, Duration),
}

/// Starts `cmd` as a child that dies with this process and runs under normal scheduling,
/// pinned to `cpu` if given.
pub fn spawn(name: &str, mut cmd: Command, cpu: Option<usize>) -> anyhow::Result<Kid> {
    prepare(&mut cmd, cpu);
    let child = cmd.spawn().with_context(|| format!("starting {name} ({:?})", cmd.get_program()))?;
    Ok(Kid { name: name.to_string(), child, done: None, on_drop: (Some(SIGTERM), Duration::from_millis(1500)) })
}

/// Sets `cmd` up as [`spawn`] does (for a caller that runs it another way, e.g. `output`).
pub fn prepare(cmd: &mut Command, cpu: Option<usize>) {
    // SAFETY: the closure runs between fork and exec and only makes system calls (prctl,
    // sched_setscheduler, sched_setaffinity), which are async-signal-safe; it allocates
    // nothing (pin_to_cpu allocates only for a CPU number past the kernel's limit, and the
    // CPUs given here are small).
    unsafe {
        cmd.pre_exec(move || {
            let _ = os::set_normal_scheduling();
            if let Some(c) = cpu {
                os::pin_to_cpu(c)?;
            }
            os::die_with_parent()
        });
    }
}

impl Kid {
    /// What dropping does: send `sig` (None: none) and wait up to `grace`, then SIGKILL.
    pub fn stop_on_drop(mut self, sig: Option<i32>, grace: Duration) -> Kid {
        self.on_drop = (sig, grace);
        self
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The exit status, if it has exited.
    pub fn poll(&mut self) -> Option<ExitStatus> {
        if self.done.is_none() {
            self.done = self.child.try_wait().ok().flatten();
        }
        self.done
    }

    /// Sends `sig` and waits up to `grace` for the exit; then kills.
    pub fn stop(&mut self, sig: Option<i32>, grace: Duration) -> Option<ExitStatus> {
        if let (None, Some(sig)) = (self.poll(), sig) {
            let _ = os::send_signal(self.pid(), sig);
            self.wait(grace);
        }
        if self.poll().is_none() {
            let _ = self.child.kill();
            self.done = self.child.wait().ok();
        }
        self.done
    }

    /// Waits up to `limit` for the process to end by itself.
    pub fn wait(&mut self, limit: Duration) -> Option<ExitStatus> {
        let end = Instant::now() + limit;
        while self.poll().is_none() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(10));
        }
        self.done
    }
}

impl Drop for Kid {
    fn drop(&mut self) {
        let (sig, grace) = self.on_drop;
        self.stop(sig, grace);
    }
}
