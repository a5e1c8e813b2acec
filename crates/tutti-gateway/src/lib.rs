//! tutti's DDS / ROS 2 gateway (`docs/gateway.md`): every set of every domain is a DDS topic
//! bridged both ways, with the QoS the DDF's flags call for, and the gateway is one ROS 2
//! node. With `mirror`, the gateway is the framework of local segments fed from DDS, so that
//! a co-simulation spans machines.
//!
//! Shape, bottom up: the engine layer (`tutti_engine`: all the gateway needs from a
//! middleware, Cyclone DDS always and rustdds behind the cargo feature `rustdds`, on by
//! default; its codec holds what a sample carries into shared memory) is a crate of its own
//! below this one; [`config`] holds the options, the environment and the config file's plan;
//! [`routes`] has one module per route kind, written once above the engines, each with
//! its constructor; [`manager`] builds the routes as domains come to be bridged and runs
//! one `select!` loop that compares discovery with the routes' connections and prints
//! status, while samples go straight from each engine's receive path to shared memory or
//! to a mirror's thread (no waiting call runs on the async runtime). [`in_process`] runs
//! the same gateway inside the framework's process, where the framework's own PUBLISH sets
//! go to DDS from its step (a `tutti_host::StepSink`). [`foxglove`] serves the same sets
//! over the Foxglove WebSocket protocol; [`services`] offers ROS 2's `simulation_interfaces`
//! services over the run's control plane, and [`entities`] the run's bodies for the entity
//! services.

#![deny(unsafe_op_in_unsafe_fn)]

pub mod config;
pub mod entities;
mod error;
pub mod foxglove;
pub mod http;
pub mod in_process;
pub mod manager;
pub mod routes;
pub mod services;
pub mod stats;

pub use config::{ClockSource, GatewayOptions, TypeMode};
pub use error::GatewayError;
pub use manager::run;
pub use stats::Stats;
pub use tutti_engine::{self as engine, cdr, EngineKind};
