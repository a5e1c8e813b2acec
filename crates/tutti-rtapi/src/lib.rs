//! RTAPI: the C library `librtapi.so` / `librtapi.a`, source-compatible with the RTAPI of
//! RT-LAB Orchestra (same call names, same header name `RTAPI.h`), over the shared-memory
//! domains of `tutti-core`. See docs/rtapi.md for every call, the return codes and how to
//! move a product client over.
//!
//! Rust programs use [`tutti_core::shm::Participant`] directly (typed, errors as
//! [`tutti_core::shm::ShmError`]); this crate is the C layer on top of it: a process-wide
//! connection table with a current connection, per-connection buffers that C code reads
//! and writes through pointers, and stable return codes ([`codes`]).
#![allow(non_snake_case)]

pub mod api;
pub mod checkpoint;
pub mod codes;
mod ffi;
mod state;

pub use api::*;
pub use codes::*;
