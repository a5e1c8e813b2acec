//! Child processes of the binaries (the demo's components, the benchmarks' peers, the
//! studio's gateway): started so that they die with their parent (the core's
//! [`os::die_with_parent_on_spawn`]), and stopped when their [`ChildProcess`] is dropped.

use std::process::{Child, Command, ExitStatus};
use std::time::{Duration, Instant};

use tutti_core::shm::os;

/// SIGINT, as a number for [`ChildProcess::stop`].
pub const SIGINT: i32 = 2;
/// SIGTERM, as a number for [`ChildProcess::stop`].
pub const SIGTERM: i32 = 15;

/// A child that could not be started.
#[derive(Debug, thiserror::Error)]
#[error("starting {name} ({program}): {source}")]
pub struct SpawnError {
    pub name: String,
    pub program: String,
    #[source]
    pub source: std::io::Error,
}

/// A child process; dropping it stops it as [`ChildProcess::stop_on_drop`] says (by default
/// SIGTERM, 1.5 s to exit, then SIGKILL).
#[derive(Debug)]
pub struct ChildProcess {
    /// What the child is, for messages.
    pub name: String,
    pub child: Child,
    done: Option<ExitStatus>,
    on_drop: (Option<i32>, Duration),
}

impl ChildProcess {
    /// Starts `cmd` as a child that dies with this process and runs under normal scheduling,
    /// pinned to `cpu` if given.
    pub fn spawn(name: &str, mut cmd: Command, cpu: Option<usize>) -> Result<ChildProcess, SpawnError> {
        os::die_with_parent_on_spawn(&mut cmd, cpu);
        let child = cmd.spawn().map_err(|source| SpawnError {
            name: name.to_string(),
            program: cmd.get_program().to_string_lossy().into_owned(),
            source,
        })?;
        Ok(ChildProcess {
            name: name.to_string(),
            child,
            done: None,
            on_drop: (Some(SIGTERM), Duration::from_millis(1500)),
        })
    }

    /// What dropping does: send `sig` (None: none) and wait up to `grace`, then SIGKILL.
    pub fn stop_on_drop(mut self, sig: Option<i32>, grace: Duration) -> ChildProcess {
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

impl Drop for ChildProcess {
    fn drop(&mut self) {
        let (sig, grace) = self.on_drop;
        self.stop(sig, grace);
    }
}
