//! tutti's DDS / ROS 2 gateway (SPEC section 5): every set of every domain is a DDS topic
//! bridged both ways, with the QoS the DDF's flags call for, and the gateway is one ROS 2
//! node. With `mirror`, the gateway is the framework of local segments fed from DDS, so that
//! a co-simulation spans machines.
//!
//! Shape: [`node`] builds the DDS participant, the ROS 2 node and every endpoint; [`routes`]
//! has one module per route kind; [`manager`] runs the one `select!` loop that takes DDS
//! samples and matching changes ([`discovery`]) and hands shared-memory work that waits to
//! dedicated threads (no waiting call runs on the async runtime; the reader tasks of
//! asynchronous domains commit themselves, since such a commit never waits). [`cdr`] encodes
//! and decodes the types, [`qos`] turns the QoS table into rustdds QoS.

#![deny(unsafe_op_in_unsafe_fn)]

pub mod cdr;
pub mod echo;
pub mod engine;
mod error;
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
