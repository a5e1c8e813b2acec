//! tutti's DDS / ROS 2 gateway (SPEC section 5): every set of every domain is a DDS topic
//! bridged both ways, with the QoS the DDF's flags call for, and the gateway is one ROS 2
//! node. With `mirror`, the gateway is the framework of local segments fed from DDS, so that
//! a co-simulation spans machines.
//!
//! Shape: [`engine`] is all the gateway needs from DDS, with two implementations (Cyclone
//! DDS through `cyclors`, the default, and rustdds); [`routes`] has one module per route
//! kind, written once above the engines; [`manager`] builds every route and runs one
//! `select!` loop that compares discovery with the routes' connections and prints status,
//! while samples go straight from each engine's receive path to shared memory (no waiting
//! call runs on the async runtime). [`cdr`] encodes and decodes the types, [`qos`] turns the
//! QoS table into rustdds QoS.

#![deny(unsafe_op_in_unsafe_fn)]

pub mod cdr;
pub mod config;
pub mod engine;
mod error;
pub mod http;
pub mod manager;
mod options;
pub mod qos;
pub mod routes;
pub mod stats;

pub use engine::EngineKind;
pub use error::GatewayError;
pub use manager::run;
pub use options::{ClockSource, GatewayOptions, TypeMode};
pub use stats::Stats;
