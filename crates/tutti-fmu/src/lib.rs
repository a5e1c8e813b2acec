//! FMI components for tutti: any FMI 2.0 or 3.0 co-simulation FMU (Linux x86_64 binary)
//! joins a domain as an external participant, with no code written.
//!
//! * [`model`]: what `modelDescription.xml` says (variables, capabilities, experiment);
//! * [`fmu`]: opening an archive and instantiating it (the `fmi` crate unpacks it and binds
//!   its functions; [`fmi2`] and [`fmi3`] call them);
//! * [`ddf`]: a DDF with one domain for an FMU, and the name mapping between both;
//! * [`mapping`]: FMU variables paired with domain items, checked before the first step;
//! * [`participant`]: the FMU as a participant, stepping with a synchronous framework or on
//!   its own clock, and keeping its state for the framework's checkpoints when it can
//!   ([`Instance::save_state`], [`Instance::restore_state`]).
//!
//! See docs/fmu.md.

mod call;
pub mod ddf;
pub mod fmi2;
pub mod fmi3;
pub mod fmu;
pub mod log_capture;
pub mod mapping;
pub mod model;
pub mod pack;
pub mod participant;

pub use fmu::{CallError, CallStatus, Fmu, Instance, LoadError};
pub use mapping::{Mapping, MappingError, Pair};
pub use model::{Causality, FmiVersion, ModelDescription, VarType, Variable};
pub use participant::{FmuParticipant, RunError, RunOptions, StepMode};
