//! Launch files: one JSON5 file describes a whole co-simulation (`tutti run FILE`): the DDF,
//! how its framework steps, the components that join its domains, and the gateway.
//!
//! * [`file`](mod@file): the launch file, read and checked before anything starts ([`load`]): every
//!   mistake is refused with `FILE:LINE:COLUMN`.
//! * [`keys`]: the launch file's keys as written ([`LaunchKeys`]), read with their checks and
//!   written back (`tutti ssp ddf` writes its launch file with them).
//! * [`supervisor`]: the components as child processes: started in file order, each once
//!   the one before has connected, their output in log files and on the terminal, restarted
//!   by their policy, torn down in reverse order ([`Supervisor`]).
//! * [`session`]: a whole run: the framework (a `tutti-host` [`Host`](tutti_host::Host)),
//!   its recordings, the gateway, the supervisor, and the outcome ([`run`]).
//! * [`gateway`]: where the gateway of a launch file is started.
//!
//! See docs/run.md.

mod error;
pub mod file;
pub mod gateway;
pub mod keys;
pub mod session;
pub mod supervisor;

pub use error::{KeyError, LaunchError, ParamError, RunError, SupervisorError};
pub use file::{load, parse, Component, Framework, Launch, Program, Restart};
pub use keys::{ComponentKeys, FrameworkKeys, LaunchKeys};
pub use session::{run, Outcome, RunOptions};
pub use supervisor::{ComponentState, ComponentStatus, End, Event, Supervisor, SupervisorOptions};
