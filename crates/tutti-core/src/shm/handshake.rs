//! The synchronous step handshake, as small functions over atomics so that loom can check
//! exactly this code (`tests/loom.rs`).
//!
//! The framework publishes step `k` (the PUBLISH bucket, then `pub_step = k`). A connection
//! that reads synchronously acknowledges `k` after its copy (`last_read = k`); one that
//! writes commits its SUBSCRIBE data for `k` (`last_commit = k`). The framework starts step
//! `k + 1` only when no connection that takes part in step `k` still owes it a read or a
//! commit, or when the timeout expires. Since the framework never publishes twice while a
//! reader owes a read, a reader's copy is never lapped and no step is read twice or skipped.
//!
//! In an event-driven domain (`docs/timing.md`) a connection that has said when it is next
//! due ([`CONN_EVENT`]) takes part only in the steps it is due at: from the step whose index
//! (simulated time over the step, `pub_index`) reaches its `due_index` on, at a step where an
//! item it reads changed if it wakes on change ([`CONN_WAKE`]), and at the step after a reset
//! (`all_due_step`). Indexes, not step numbers, so that a framework may leave out steps (or
//! fall behind the wall clock) without shifting anyone's due times. It answers its due step
//! `k` by asking for the next ([`StepCtl::answer`]: `due_index` first, then `answered = k`),
//! so the framework, which does not start `k + 1` before that answer, always knows the next
//! due step in time, and a participant never misses a step it is due at.

use crate::sync::{AtomicU32, AtomicU64, Ordering};

/// Connection flag: the connection writes the SUBSCRIBE set.
pub const CONN_WRITER: u32 = 1;
/// Connection flag: the connection reads the PUBLISH set in lock-step.
pub const CONN_SYNC_READER: u32 = 2;
/// Connection flag: the connection stands for a DDS-side participant (via the gateway).
pub const CONN_REMOTE: u32 = 4;
/// Connection flag: a passive observer (never waited for, not a participant).
pub const CONN_OBSERVER: u32 = 8;
/// Connection flag: an event-driven connection, due only at some steps (`due_index`, …).
pub const CONN_EVENT: u32 = 16;
/// Connection flag: an event-driven connection also due at any step whose PUBLISH set
/// differs from the step before.
pub const CONN_WAKE: u32 = 32;

/// The step counters of one domain.
#[derive(Debug, Clone, Copy)]
pub struct StepCtl<'a> {
    /// Last step the framework published (0: none yet).
    pub pub_step: &'a AtomicU64,
    /// Bumped on every publish and state change; sync readers wait on it.
    pub step_seq: &'a AtomicU32,
    /// Bumped on every acknowledgement or commit; the framework waits on it.
    pub ack_seq: &'a AtomicU32,
    /// The last step whose PUBLISH set differs from the step before (written before
    /// `pub_step`).
    pub changed_step: &'a AtomicU64,
    /// The index of the published step (written before `pub_step`).
    pub pub_index: &'a AtomicU64,
    /// Every event-driven connection is due at this step (the first after a reset).
    pub all_due_step: &'a AtomicU64,
    /// The PUBLISH items that changed at `changed_step` ([`item_bit`]).
    pub changed_items: &'a [AtomicU64; MASK_WORDS],
}

/// Words of an item mask.
pub const MASK_WORDS: usize = 4;

/// The word and bit of PUBLISH item `index` in an item mask: the last bit stands for every
/// item from it on.
pub fn item_bit(index: usize) -> (usize, u64) {
    let i = index.min(MASK_WORDS * 64 - 1);
    (i / 64, 1 << (i % 64))
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
    /// Event-driven: the step index from which the connection is next due.
    pub due_index: &'a AtomicU64,
    /// Event-driven: the last step the connection answered.
    pub answered: &'a AtomicU64,
    /// Event-driven, waking on change: the items it reads ([`item_bit`]; none: all).
    pub read_items: &'a [AtomicU64; MASK_WORDS],
    /// Event-driven: the last step the framework found it due at.
    pub due_at: &'a AtomicU64,
    /// Event-driven: bumped when the framework tells it (its own wait word).
    pub due_seq: &'a AtomicU32,
}

impl StepCtl<'_> {
    /// Framework: announce step `k`, of index `index` (its PUBLISH data is already in the
    /// bucket); `changed`: the items whose values differ from the step before's
    /// ([`item_bit`]; all zero: none).
    pub fn publish(&self, k: u64, index: u64, changed: &[u64; MASK_WORDS]) {
        self.pub_index.store(index, Ordering::Relaxed);
        if changed.iter().any(|&w| w != 0) {
            for (word, &bits) in self.changed_items.iter().zip(changed) {
                word.store(bits, Ordering::Relaxed);
            }
            self.changed_step.store(k, Ordering::Relaxed);
        }
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

    /// Framework: whether event-driven connection `conn` is due at step `k`, the step it
    /// published now (only the framework decides: it knows the step's index and changes).
    /// A reset makes everyone due at once, except a connection due only where its inputs
    /// change: it has no time to say anew, and answers changes only.
    pub fn due(&self, conn: &ConnCtl<'_>, k: u64) -> bool {
        let due_index = conn.due_index.load(Ordering::Acquire);
        self.pub_index.load(Ordering::Acquire) >= due_index
            || (self.all_due_step.load(Ordering::Acquire) == k && due_index != u64::MAX)
            || (conn.flags.load(Ordering::Acquire) & CONN_WAKE != 0
                && self.changed_step.load(Ordering::Acquire) == k
                && reads_changed(conn.read_items, self.changed_items))
    }

    /// Framework, at step `k`: tells connection `conn` that it is due at `k` if it owes `k`
    /// as an event-driven connection and has not been told; returns whether it told it now
    /// (the caller then wakes the connection, on `due_seq`).
    pub fn mark_due(&self, conn: &ConnCtl<'_>, k: u64) -> bool {
        if conn.flags.load(Ordering::Acquire) & CONN_EVENT == 0 || conn.due_at.load(Ordering::Acquire) >= k {
            return false;
        }
        if !conn.owes(self, k) {
            return false;
        }
        conn.due_at.store(k, Ordering::Release);
        conn.due_seq.fetch_add(1, Ordering::Release);
        true
    }

    /// Event-driven participant: the step the framework found it due at, if after
    /// `answered`. The framework stays at that step until it is answered, so waiting on this
    /// never misses one.
    pub fn next_due(&self, conn: &ConnCtl<'_>, answered: u64) -> Option<u64> {
        let k = conn.due_at.load(Ordering::Acquire);
        (k > answered).then_some(k)
    }

    /// Event-driven participant: answer step `k` (what it commits for `k` is in already) and
    /// be due next from the step of index `next_due` on, or where one of the items of `reads`
    /// changes if it wakes on change.
    pub fn answer(&self, conn: &ConnCtl<'_>, k: u64, next_due: u64, reads: &[u64; MASK_WORDS]) {
        for (word, &bits) in conn.read_items.iter().zip(reads) {
            word.store(bits, Ordering::Relaxed);
        }
        conn.due_index.store(next_due, Ordering::Release);
        conn.answered.store(k, Ordering::Release);
        self.ack_seq.fetch_add(1, Ordering::Release);
    }

    /// Participant: record the commit (already in the SUBSCRIBE bucket) for step `k`.
    pub fn ack_commit(&self, conn: &ConnCtl<'_>, k: u64) {
        conn.last_commit.store(k, Ordering::Release);
        self.ack_seq.fetch_add(1, Ordering::Release);
    }
}

/// Whether a connection reading the items of `reads` (none: all) reads one of `changed`.
fn reads_changed(reads: &[AtomicU64; MASK_WORDS], changed: &[AtomicU64; MASK_WORDS]) -> bool {
    reads_any(&load_mask(reads), &load_mask(changed))
}

/// An item mask as it stands.
pub fn load_mask(mask: &[AtomicU64; MASK_WORDS]) -> [u64; MASK_WORDS] {
    std::array::from_fn(|i| mask[i].load(Ordering::Acquire))
}

/// Whether a connection reading the items of `reads` (none: all) reads one of `changed`.
pub fn reads_any(reads: &[u64; MASK_WORDS], changed: &[u64; MASK_WORDS]) -> bool {
    let all = reads.iter().all(|&w| w == 0);
    reads.iter().zip(changed).any(|(&r, &c)| if all { c != 0 } else { r & c != 0 })
}

impl ConnCtl<'_> {
    /// Whether the connection is in use and takes part in step `k` (its first step is not
    /// after it).
    pub fn takes_part(&self, k: u64) -> bool {
        self.active.load(Ordering::Acquire) != 0 && self.first_step.load(Ordering::Acquire) <= k
    }

    /// Whether this connection still owes the framework something for step `k` (`step`: the
    /// domain's counters, for an event-driven connection's due steps).
    pub fn owes(&self, step: &StepCtl<'_>, k: u64) -> bool {
        if !self.takes_part(k) {
            return false;
        }
        let flags = self.flags.load(Ordering::Acquire);
        if flags & CONN_EVENT != 0 {
            // `answered` before `due_index`: an answer stores them the other way round.
            return self.answered.load(Ordering::Acquire) < k && step.due(self, k);
        }
        (flags & CONN_SYNC_READER != 0 && self.last_read.load(Ordering::Acquire) < k)
            || (flags & CONN_WRITER != 0 && self.last_commit.load(Ordering::Acquire) < k)
    }
}
