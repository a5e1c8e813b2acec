//! The synchronous step handshake, as small functions over atomics so that loom can check
//! exactly this code (`tests/loom.rs`).
//!
//! The framework publishes step `k` (the PUBLISH bucket, then `pub_step = k`). A connection
//! that reads synchronously acknowledges `k` after its copy (`last_read = k`); one that
//! writes commits its SUBSCRIBE data for `k` (`last_commit = k`). The framework starts step
//! `k + 1` only when no connection that takes part in step `k` still owes it a read or a
//! commit, or when the timeout expires. Since the framework never publishes twice while a
//! reader owes a read, a reader's copy is never lapped and no step is read twice or skipped.

use crate::sync::{AtomicU32, AtomicU64, Ordering};

/// Connection flag: the connection writes the SUBSCRIBE set.
pub const CONN_WRITER: u32 = 1;
/// Connection flag: the connection reads the PUBLISH set in lock-step.
pub const CONN_SYNC_READER: u32 = 2;
/// Connection flag: the connection stands for a DDS-side participant (via the gateway).
pub const CONN_REMOTE: u32 = 4;
/// Connection flag: a passive observer (never waited for, not a participant).
pub const CONN_OBSERVER: u32 = 8;

/// The step counters of one domain.
#[derive(Debug, Clone, Copy)]
pub struct StepCtl<'a> {
    /// Last step the framework published (0: none yet).
    pub pub_step: &'a AtomicU64,
    /// Bumped on every publish and state change; sync readers wait on it.
    pub step_seq: &'a AtomicU32,
    /// Bumped on every acknowledgement or commit; the framework waits on it.
    pub ack_seq: &'a AtomicU32,
}

/// The handshake fields of one connection slot.
#[derive(Debug, Clone, Copy)]
pub struct ConnCtl<'a> {
    /// Non-zero while the slot is in use (holds the owner's pid).
    pub active: &'a AtomicU32,
    pub flags: &'a AtomicU32,
    /// First step this connection takes part in.
    pub first_step: &'a AtomicU64,
    pub last_read: &'a AtomicU64,
    pub last_commit: &'a AtomicU64,
}

impl StepCtl<'_> {
    /// Framework: announce step `k` (its PUBLISH data is already in the bucket).
    pub fn publish(&self, k: u64) {
        self.pub_step.store(k, Ordering::Release);
        self.step_seq.fetch_add(1, Ordering::Release);
    }

    /// Participant: the step to read next, if the framework has published past `last_read`.
    pub fn next_step(&self, last_read: u64) -> Option<u64> {
        let k = self.pub_step.load(Ordering::Acquire);
        (k > last_read).then_some(k)
    }

    /// Participant: acknowledge having read step `k`.
    pub fn ack_read(&self, conn: &ConnCtl<'_>, k: u64) {
        conn.last_read.store(k, Ordering::Release);
        self.ack_seq.fetch_add(1, Ordering::Release);
    }

    /// Participant: record the commit (already in the SUBSCRIBE bucket) for step `k`.
    pub fn ack_commit(&self, conn: &ConnCtl<'_>, k: u64) {
        conn.last_commit.store(k, Ordering::Release);
        self.ack_seq.fetch_add(1, Ordering::Release);
    }
}

impl ConnCtl<'_> {
    /// Whether this connection still owes the framework something for step `k`.
    pub fn owes(&self, k: u64) -> bool {
        if self.active.load(Ordering::Acquire) == 0 {
            return false;
        }
        if self.first_step.load(Ordering::Acquire) > k {
            return false;
        }
        let flags = self.flags.load(Ordering::Acquire);
        (flags & CONN_SYNC_READER != 0 && self.last_read.load(Ordering::Acquire) < k)
            || (flags & CONN_WRITER != 0 && self.last_commit.load(Ordering::Acquire) < k)
    }
}
