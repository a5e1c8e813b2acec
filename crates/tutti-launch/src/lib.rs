//! Launch files: one JSON5 file describes a whole co-simulation (`tutti run FILE`): the DDF,
//! how its framework steps, the components that join its domains, and the gateway.
//!
//! * [`file`](mod@file): the launch file, read and checked before anything starts ([`load`]): every
//!   mistake is refused with `FILE:LINE:COLUMN`.
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
pub mod session;
pub mod supervisor;

pub use error::{LaunchError, RunError, SupervisorError};
pub use file::{load, parse, Component, Framework, Launch, Program, Restart};
pub use session::{run, Outcome, RunOptions};
pub use supervisor::{ComponentState, ComponentStatus, End, Event, Supervisor, SupervisorOptions};
