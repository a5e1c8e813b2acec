//! SSP import: a system of FMUs described by an SSP archive (System Structure and Parameterization)
//! becomes a DDF with a domain per component and one launch file (`tutti run`).
//!
//! * [`archive`]: the `.ssp` zip: its SSD, its SSV files, extraction (paths kept inside);
//! * [`xml`]: the SSD and SSV read into a tree with positions (the core's positioned reader)
//!   and their namespaces resolved;
//! * [`model`]: the validated system: components, connectors, connections, units,
//!   parameter values, each with its `FILE:LINE:COL`; what is not supported is refused where
//!   it stands;
//! * [`plan`]: the system against its FMUs: the DDF (`tutti_fmu::ddf`), the framework
//!   connections (`tutti_host::connect`, units included) and the launch file
//!   (`tutti_launch`'s keys).
//!
//! See docs/ssp.md.

pub mod archive;
mod error;
pub mod model;
pub mod plan;
pub mod xml;

pub use archive::Archive;
pub use error::SspError;
pub use model::{Causality, Component, Connection, Connector, ParamValue, SspVersion, System, Type};
pub use plan::{prepare, Plan, PlanOptions, Prepared};
