//! Synchronisation shim: std atomics normally, loom's under `--cfg tutti_loom`, so that the
//! seqlock and the step handshake are model-checked with the very code that runs.

#[cfg(not(tutti_loom))]
pub use std::sync::atomic::{fence, AtomicU32, AtomicU64, Ordering};

#[cfg(tutti_loom)]
pub use loom::sync::atomic::{fence, AtomicU32, AtomicU64, Ordering};

/// One turn of a busy wait.
#[inline]
pub fn spin_hint() {
    #[cfg(not(tutti_loom))]
    std::hint::spin_loop();
    #[cfg(tutti_loom)]
    loom::thread::yield_now();
}
