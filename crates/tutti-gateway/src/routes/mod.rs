//! Routes: one module per kind.
//!
//! * [`to_dds`]: a set in shared memory -> its DDS writer (typed), polled when asynchronous,
//!   in lock-step through a remote connection when synchronous;
//! * [`from_dds`]: a DDS reader -> shared memory, through one remote connection per
//!   matched DDS writer (so role rules, exclusivity and seeding are the core's); with a
//!   lookahead, a synchronous writer's thread is `lookahead`'s (its answers K steps on);
//! * [`per_item`]: the same two directions with one stock-typed topic per item;
//! * [`mirror`]: local segments whose framework is fed from DDS (`--mirror`), each sample
//!   handed by the reader's sink straight to the mirror's thread;
//! * [`clock`]: one domain's simulated time on `/clock`;
//! * [`from_step`]: the framework's own PUBLISH set written to DDS from its step, when the
//!   gateway runs in the framework's process ([`crate::in_process`]).
//!
//! Each kind has its constructor here ([`to_dds::typed`], [`to_dds::items`],
//! [`from_step::typed`], [`from_step::items`],
//! [`from_dds::reader`], [`mirror::spawn`], [`clock::route`]); the manager calls them as
//! domains come to be bridged and keeps what they return for discovery. This module only
//! holds what they share; it imports none of them.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use tutti_core::shm::{ConnKind, ConnectOptions, WaitMode};

use crate::cdr::{CdrError, Payload};
use crate::engine::EndpointId;
use crate::stats::{SetStats, Stats};

pub mod clock;
pub mod from_dds;
pub mod from_step;
mod lookahead;
pub mod mirror;
pub mod per_item;
pub mod poses;
pub mod to_dds;

/// A DDS sample from a remote writer, for route `route`.
#[derive(Debug)]
pub struct Inbound {
    pub route: usize,
    pub writer: EndpointId,
    pub payload: Payload,
}

/// What readers' sinks tell the manager.
#[derive(Debug)]
pub enum Event {
    /// A sample of a writer that has no connection yet.
    Sample(Inbound),
    /// A sample that could not be decoded.
    Bad { route: usize, error: CdrError },
}

/// How routes connect to shared memory.
#[derive(Debug, Clone)]
pub struct ShmConfig {
    pub namespace: String,
    pub timeout: Duration,
    pub wait: WaitMode,
    pub poll: Duration,
    /// How long a synchronous DDS writer may owe the step's answer, silent, before its
    /// lock-step share is released.
    pub lease: Duration,
    pub stop: Arc<AtomicBool>,
}

impl ShmConfig {
    /// How long a synchronous step's write waits for a DDS writer that refuses it.
    pub fn patience(&self) -> Patience {
        Patience { timeout: self.timeout, stop: self.stop.clone() }
    }

    /// Options of a connection standing for a DDS-side participant.
    pub fn connect_options(&self, name: String, connect_timeout: Duration) -> ConnectOptions {
        ConnectOptions {
            namespace: self.namespace.clone(),
            name,
            connect_timeout,
            timeout: self.timeout,
            wait: self.wait,
            skip_wait_to_go: true,
            kind: ConnKind::Remote,
            state: None,
        }
    }
}

/// How a step of a synchronous set is written to DDS: a write the DDS writer refuses (its
/// reliable, keep-all history is full until its readers acknowledge) is retried until it is
/// taken, for at most `timeout` (the domain's step timeout) or until the gateway stops; the
/// writing thread waits meanwhile, which is the back-pressure that paces the framework
/// (docs/gateway.md, "Nothing lost on a synchronous set").
#[derive(Debug, Clone)]
pub struct Patience {
    pub timeout: Duration,
    pub stop: Arc<AtomicBool>,
}

/// Where a route counts what it moves: the gateway's totals and its set's own counters.
#[derive(Debug, Clone)]
pub struct Counters {
    pub total: Arc<Stats>,
    pub set: Arc<SetStats>,
}
