//! Shared-memory domains: one segment per domain (`segment`), the bucket that holds each
//! set (`bucket`), the synchronous handshake (`handshake`), and the two roles on top: the
//! [`Framework`] that creates and steps domains and the [`Participant`] that connects to one.
//! All OS calls live in `os`.

pub mod bucket;
#[cfg(not(tutti_loom))]
mod error;
#[cfg(not(tutti_loom))]
mod framework;
pub mod handshake;
#[cfg(not(tutti_loom))]
pub mod observer;
#[cfg(not(tutti_loom))]
pub mod os;
#[cfg(not(tutti_loom))]
mod participant;
#[cfg(not(tutti_loom))]
pub mod segment;

#[cfg(not(tutti_loom))]
pub use error::ShmError;
#[cfg(not(tutti_loom))]
pub use framework::{DomainHost, Framework, FrameworkOptions, StepReport};
#[cfg(not(tutti_loom))]
pub use participant::{ConnectOptions, Participant};
#[cfg(not(tutti_loom))]
pub use segment::{list_domains, ConnKind, ConnectionInfo, DomainStatus, WaitMode};
