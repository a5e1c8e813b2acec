//! What the tests of the workspace share, in one place.
//!
//! * [`Proc`]: a child process with a watchdog, its output collected line by line, stopped
//!   (SIGINT, then SIGKILL) when dropped, so a failing test leaves nothing running.
//! * [`run_with_timeout`]: a command run to its end under a watchdog.
//! * [`tutti`], [`tutti_command`], [`tutti_exe`]: how a test runs the `tutti` binary.
//! * [`namespace`], [`dds_domain_in`]: a shared-memory namespace and a DDS domain of a test's
//!   own, so that tests run in parallel.
//! * [`python`]: the repository's `.venv` Python with the modules a test needs.
//! * [`require`], [`require_tool`]: the one policy for what a test needs from the machine:
//!   when it is missing the test is skipped with a message, and under `CI=true` it fails.
//! * [`Worker`]: a thread that loops until it is dropped (an in-process framework);
//!   [`within`]: a call on a thread of its own, failing the test if it hangs or panics.
//! * [`wait_until`], [`wait_for`], [`poll_for`]: a wait for something to happen, polled, under
//!   a deadline that fails the test naming what never happened ([`lazy`]: a message built
//!   only then).
//! * [`RemoveSegments`], [`segments_of`], [`shrink_segment`]: the shared-memory segments of a
//!   namespace; [`ShmFile`]: one crafted by hand.
//! * [`ddf::one_domain`]: a small DDF of one domain.
//! * [`mutate`]: the byte mutator of the fuzz tests.
//! * `ZenohRouter` (feature `zenoh`): a Zenoh router of the test's own on loopback.
//! * `Wire` (feature `wire`): two network namespaces joined by a link with a delay, losses,
//!   reordering and cuts, made in userspace (TAP devices); [`run_tool`]: a set-up command.
//! * [`compile_c`], [`rtapi_lib_dir`]: C programs built against this build's librtapi.
//! * `fmu` (feature `fmu`): FMUs built for the FMU tests.
//!
//! Nothing here asserts a duration: every limit is a watchdog that fails a test which hangs.

mod c;
pub mod ddf;
#[cfg(feature = "fmu")]
pub mod fmu;
mod hex;
pub mod mutate;
mod names;
mod policy;
mod proc;
mod run;
mod segments;
mod wait;
#[cfg(feature = "wire")]
mod wire;
mod worker;
#[cfg(feature = "zenoh")]
mod zenoh_router;

pub use c::{compile_c, rtapi_lib_dir};
pub use hex::{hex, unhex};
pub use names::{dds_domain_in, namespace};
pub use policy::{ci, python, require, require_tool, which};
pub use proc::{Output, Proc, Spawn};
pub use run::{
    run_output, run_tool, run_with_timeout, tutti, tutti_command, tutti_exe, workspace_bin, SetupError, TIMEOUT,
};
pub use segments::{segments_of, shrink_segment, RemoveSegments, ShmFile};
pub use wait::{lazy, poll_for, wait_for, wait_until, Lazy, POLL};
#[cfg(feature = "wire")]
pub use wire::{Faults, Wire};
pub use worker::{within, Worker};
#[cfg(feature = "zenoh")]
pub use zenoh_router::ZenohRouter;

use std::path::{Path, PathBuf};

/// The workspace root (where `ddf/`, `tests/` and `.venv` are).
pub fn repo_root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// The cargo that runs the tests (`CARGO`), else the one that built them, else `cargo`.
pub fn cargo() -> std::ffi::OsString {
    std::env::var_os("CARGO").or_else(|| option_env!("CARGO").map(Into::into)).unwrap_or_else(|| "cargo".into())
}

/// `target/<profile>` of the running test: the folder of the binaries this build made.
pub fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test's executable");
    // target/<profile>/deps/<test>-<hash>
    exe.parent().and_then(Path::parent).expect("`target/<profile>`").to_path_buf()
}
