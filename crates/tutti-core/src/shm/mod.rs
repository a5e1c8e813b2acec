//! Shared-memory domains: one segment per domain (`segment`), the bucket that holds each
//! set (`bucket`), the synchronous handshake (`handshake`), and the two roles on top: the
//! [`Framework`] that creates and steps domains and the [`Participant`] that connects to one.
//! All OS calls live in `os`.
//!
//! The segment format (its header words, the buckets, the connection table and the
//! handshake) is this module's alone: other crates see a domain through the roles and the
//! typed reads of [`Segment`] ([`Segment::step`], [`Segment::sim_time`],
//! [`Segment::period`], [`Segment::seeded`], [`Segment::read_set`], …), never its words.
//! The handshake is public only to the loom model check (`--cfg tutti_loom`); the bucket is
//! public as a seqlock over memory its caller provides (the loom check and the benchmarks'
//! copy floor use it), but only the core hands out a segment's buckets.

pub mod bucket;
#[cfg(not(tutti_loom))]
mod error;
#[cfg(not(tutti_loom))]
mod framework;
#[cfg(tutti_loom)]
pub mod handshake;
#[cfg(not(tutti_loom))]
pub(crate) mod handshake;
#[cfg(not(tutti_loom))]
pub mod observer;
#[cfg(not(tutti_loom))]
pub mod os;
#[cfg(not(tutti_loom))]
mod participant;
#[cfg(not(tutti_loom))]
pub mod segment;
#[cfg(not(tutti_loom))]
pub mod state;

pub use bucket::Stamp;
#[cfg(not(tutti_loom))]
pub use error::ShmError;
#[cfg(not(tutti_loom))]
pub use framework::{DomainHost, Framework, FrameworkOptions, StepReport};
#[cfg(not(tutti_loom))]
pub use observer::{Look, Observer};
#[cfg(not(tutti_loom))]
pub use participant::{ConnectOptions, Participant, StepGate, COMPONENT_ENV};
#[cfg(not(tutti_loom))]
pub use segment::{
    check_namespace, list_domains, namespace_from_env, segment_name, segment_path, ConnKind, ConnectionInfo,
    DomainInfo, DomainStatus, LinkInfo, Segment, WaitMode, DEFAULT_CONNECTIONS,
};
#[cfg(not(tutti_loom))]
pub use state::{SharedState, StateAnswer, StateConnection, StateError, StateHandler, StateRequest};
