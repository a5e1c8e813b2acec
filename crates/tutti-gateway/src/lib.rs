//! tutti's DDS / ROS 2 gateway (`docs/gateway.md`): every set of every domain is a DDS topic
//! bridged both ways, with the QoS the DDF's flags call for, and the gateway is one ROS 2
//! node. With `mirror`, the gateway is the framework of local segments fed from DDS, so that
//! a co-simulation spans machines.
//!
//! Shape, bottom up: [`cdr`] encodes and decodes the types (and holds [`cdr::Payload`],
//! what a sample carries into shared memory); [`engine`] is all the gateway needs from DDS,
//! with two implementations (Cyclone DDS through `cyclors`, the default and always built,
//! and rustdds behind the cargo feature `rustdds`, on by default), and imports nothing
//! above it; [`config`] holds the options, the environment and the config file's plan;
//! [`routes`] has one module per route kind, written once above the engines, each with
//! its constructor; [`manager`] builds the routes as domains come to be bridged and runs
//! one `select!` loop that compares discovery with the routes' connections and prints
//! status, while samples go straight from each engine's receive path to shared memory or
//! to a mirror's thread (no waiting call runs on the async runtime). [`in_process`] runs
//! the same gateway inside the framework's process, where the framework's own PUBLISH sets
//! go to DDS from its step (a `tutti_host::StepSink`). [`foxglove`] serves the same sets
//! over the Foxglove WebSocket protocol; [`services`] offers ROS 2's `simulation_interfaces`
//! services over the run's control plane. `qos` turns the QoS table into rustdds QoS.

#![deny(unsafe_op_in_unsafe_fn)]

pub mod cdr;
pub mod config;
pub mod engine;
mod error;
pub mod foxglove;
pub mod http;
pub mod in_process;
pub mod manager;
#[cfg(feature = "rustdds")]
pub mod qos;
pub mod routes;
pub mod services;
pub mod stats;

pub use config::{ClockSource, GatewayOptions, TypeMode};
pub use engine::EngineKind;
pub use error::GatewayError;
pub use manager::run;
pub use stats::Stats;
