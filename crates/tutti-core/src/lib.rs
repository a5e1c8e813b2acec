//! tutti core: the DDF model and its validation, the byte layout of sets, the shared-memory
//! domains and the Rust participant API.
//!
//! This crate depends on no async runtime and no DDS crate: the C library (`tutti-rtapi`)
//! links it alone. The gateway, the real-time host and the demo sit on top of it.
#![deny(unsafe_op_in_unsafe_fn)]

pub mod cdr;
pub mod ddf;
pub mod defaults;
pub mod mapping;
// The loom build models the bucket and the handshake only; the parsers name a segment's
// wait modes, which it leaves out.
#[cfg(not(tutti_loom))]
pub mod parse;
pub mod shm;
pub mod show;
pub mod sync;
