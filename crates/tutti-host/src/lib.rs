//! tutti's runner as a library: the framework of every domain of a DDF, stepped at a fixed
//! period against absolute deadlines ([`Ticker`]), with what `tutti host` adds around the core's
//! [`Framework`](tutti_core::shm::Framework): `--set` values, holding participants until the
//! writers are there ([`wait_for_writers`]), seeds, real-time scheduling ([`enter_realtime`]),
//! per-step sinks (recordings) and reports of lateness, overruns and step timeouts.
//!
//! A run is a value ([`Host`]) that other code drives in-process: `tutti host`, the studio's
//! run control, replay, the UAV demo and the benchmarks. Nothing here prints: progress comes back as
//! [`Report`]s (whose `Display` is the line a user reads) and the end as a [`Summary`].
//!
//! # Layering
//!
//! The crate stands on `tutti-core` alone. Recordings plug in through [`StepSink`] instead of
//! this crate depending on `tutti-record`, so that `tutti-record` can stand on this one: its
//! replay drives a [`Host`] whose steps it paces itself ([`Host::step_domains`]), and its
//! recorders are sinks of a [`Host`]. The order is core → host → record → the binaries, with no cycle.
//!
//! Beside the runner sit two small process helpers that the binaries share: a child process
//! stopped when dropped ([`ChildProcess`]), and a stop flag raised by Ctrl-C
//! ([`stop_on_ctrl_c`]).

pub mod checkpoint;
mod child;
pub mod connect;
pub mod control;
mod error;
mod host;
mod realtime;
mod steps;
mod ticker;

pub use child::{ChildProcess, SpawnError, SIGINT, SIGTERM};
pub use error::HostError;
pub use host::{DomainStep, Host, HostOptions, Periodic, Progress, Published, Report, StepDone, StepSink, Summary};
pub use realtime::{enter_realtime, RealtimeOutcome, RealtimeRequest};
pub use steps::{complete_all, parse_wait_for, publish_all, step_all, wait_for_writers, WaitForError, WriterWait};
pub use ticker::{Tick, Ticker};

/// A flag raised by Ctrl-C (SIGINT) or SIGTERM, for a binary's main loop. Installs the
/// process's one signal handler: call it once per process.
pub fn stop_on_ctrl_c() -> Result<std::sync::Arc<std::sync::atomic::AtomicBool>, ctrlc::Error> {
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, std::sync::atomic::Ordering::SeqCst))?;
    Ok(stop)
}
