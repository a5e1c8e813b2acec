//! The connection table: a slot per connection, claimed, identified, described and
//! released here, and what a slot stands for.

use super::format::{ConnSlot, Header, CONN_BYTES, HEADER_BYTES, RELEASING};
use super::status::LinkInfo;
use super::wait::wake;
use super::Segment;
use crate::ddf::Role;
use crate::shm::bucket::{load_bytes, store_bytes};
use crate::shm::handshake::{ConnCtl, CONN_OBSERVER, CONN_REMOTE, CONN_SYNC_READER};
use crate::shm::os::{self, ProcessId};
use crate::shm::ShmError;
use crate::sync::{AtomicU32, Ordering};

impl Segment {
    /// Connection slot `i` (`i < conn_capacity`, checked).
    pub(crate) fn conn(&self, i: usize) -> Option<&ConnSlot> {
        let cap = self.capacity();
        if i >= cap {
            return None;
        }
        // SAFETY: the table [HEADER_BYTES, HEADER_BYTES + cap·128) was bounds-checked on
        // create/open (cap is re-clamped by `capacity`), slots are 128-byte aligned and made of
        // atomics only.
        Some(unsafe { &*self.map.as_mut_ptr().add(HEADER_BYTES + i * CONN_BYTES).cast::<ConnSlot>() })
    }

    /// Connection capacity, as validated on open.
    pub(crate) fn capacity(&self) -> usize {
        let cap = self.header().conn_capacity.load(Ordering::Relaxed) as usize;
        cap.min((self.len.saturating_sub(HEADER_BYTES)) / CONN_BYTES)
    }

    /// Slots to scan: up to the high-water mark.
    pub(crate) fn scan_len(&self) -> usize {
        (self.header().conn_hwm.load(Ordering::Acquire) as usize).min(self.capacity())
    }

    pub(crate) fn conn_ctl(&self, i: usize) -> Option<ConnCtl<'_>> {
        self.conn(i).map(|c| ConnCtl {
            active: &c.active,
            flags: &c.flags,
            first_step: &c.first_step,
            last_read: &c.last_read,
            last_commit: &c.last_commit,
            due_index: &c.due_index,
            answered: &c.answered,
            read_items: &c.read_items,
            due_at: &c.due_at,
            due_seq: &c.due_seq,
        })
    }

    /// Participants now in the domain: the connections of components, not those standing
    /// for DDS writers ([`dds_writer_count`](Self::dds_writer_count)) nor observers.
    pub fn connection_count(&self) -> u32 {
        self.header().conn_count.load(Ordering::Acquire)
    }

    /// Connections standing for DDS writers, through the gateway.
    pub fn dds_writer_count(&self) -> u32 {
        self.header().remote_count.load(Ordering::Acquire)
    }

    /// Sets the DDS reader count an observer's slot `i` shows.
    pub(crate) fn set_link(&self, i: usize, link: &LinkInfo) {
        if let Some(c) = self.conn(i) {
            for (slot, v) in c.link.iter().zip([link.lookahead, link.ahead, link.rtt_us, link.link_waits]) {
                slot.store(v, Ordering::Relaxed);
            }
        }
    }

    pub(crate) fn set_peers(&self, i: usize, n: u64) {
        if let Some(c) = self.conn(i) {
            c.peers.store(n, Ordering::Relaxed);
        }
    }

    /// The process holding the SUBSCRIBE set exclusively (a domain without
    /// `multiple_publish_allowed`), if one does now.
    pub fn exclusive_owner_pid(&self) -> Option<u32> {
        let owner = self.header().owner_conn.load(Ordering::Acquire);
        (owner != 0).then(|| self.conn(Self::slot_of(owner)).map(|c| c.active.load(Ordering::Relaxed))).flatten()
    }

    /// The slot of connection id `id` (see [`conn_id`](Self::conn_id)).
    pub(crate) fn slot_of(id: u64) -> usize {
        ((id & 0xffff_ffff) as usize).wrapping_sub(1)
    }

    /// Releases the connection in slot `i` if its process (`pid`) is dead; returns whether
    /// this call released it.
    pub(crate) fn release_if_dead(&self, i: usize, pid: u32) -> bool {
        let start_time = self.conn(i).map_or(0, |c| c.start_time.load(Ordering::Acquire));
        pid != 0 && pid != RELEASING && !os::is_alive(ProcessId { pid, start_time }) && self.release_slot(i, pid)
    }

    /// The id of connection slot `i` in its current generation (never 0).
    pub(crate) fn conn_id(&self, i: usize) -> u64 {
        let generation = self.conn(i).map_or(0, |c| c.generation.load(Ordering::Acquire));
        u64::from(generation) << 32 | (i as u64 + 1)
    }

    /// Claims a free connection slot for this process; returns its index. Only
    /// [`ConnKind::Participant`] slots count in [`connection_count`](Self::connection_count).
    /// `keeps_state` is set before the slot is ready, so that a checkpoint never sees the
    /// connection without it.
    pub(crate) fn claim_slot(
        &self,
        me: ProcessId,
        name: &str,
        kind: ConnKind,
        keeps_state: bool,
    ) -> Result<usize, ShmError> {
        let h = self.header();
        for i in 0..self.capacity() {
            let Some(c) = self.conn(i) else { break };
            if c.active.compare_exchange(0, me.pid, Ordering::AcqRel, Ordering::Relaxed).is_err() {
                continue;
            }
            c.start_time.store(me.start_time, Ordering::Relaxed);
            c.since_ns.store(os::now_ns(), Ordering::Relaxed);
            // In a synchronous domain a connection takes part in lock-step from the start.
            let flags = match kind {
                ConnKind::Remote => CONN_REMOTE,
                ConnKind::Observer => CONN_OBSERVER,
                ConnKind::Participant if self.info.flags.synchronous => CONN_SYNC_READER,
                ConnKind::Participant => 0,
            };
            c.flags.store(flags, Ordering::Relaxed);
            let step = h.pub_step.load(Ordering::Acquire);
            // A participant that connects while the framework holds wait-to-go takes part in
            // lock-step only once released ([`Participant::connect`] sets its first step
            // then): the framework must not wait for a connection it is holding itself.
            let held = kind == ConnKind::Participant && h.hold.load(Ordering::Acquire) != 0;
            c.first_step.store(if held { u64::MAX } else { step + 1 }, Ordering::Relaxed);
            c.last_read.store(step, Ordering::Relaxed);
            c.last_commit.store(step, Ordering::Relaxed);
            c.due_index.store(0, Ordering::Relaxed);
            c.due_at.store(0, Ordering::Relaxed);
            c.answered.store(step, Ordering::Relaxed);
            c.read_items.iter().for_each(|w| w.store(0, Ordering::Relaxed));
            c.reads.store(0, Ordering::Relaxed);
            c.commits.store(0, Ordering::Relaxed);
            c.missed.store(0, Ordering::Relaxed);
            c.peers.store(0, Ordering::Relaxed);
            c.keeps_state.store(u64::from(keeps_state), Ordering::Relaxed);
            // Requests made before the connection came are not its to answer.
            c.state_done.store(h.state_seq.load(Ordering::Acquire), Ordering::Relaxed);
            let mut bytes = [0u8; 48];
            let n = name.len().min(47);
            // Cut at a character boundary.
            let n = (0..=n).rev().find(|&k| name.is_char_boundary(k)).unwrap_or(0);
            bytes[..n].copy_from_slice(&name.as_bytes()[..n]);
            store_bytes(&c.name, &bytes);
            h.conn_hwm.fetch_max(i as u32 + 1, Ordering::AcqRel);
            c.ready.store(1, Ordering::Release);
            kind.counter(h).fetch_add(1, Ordering::AcqRel);
            h.ack_seq.fetch_add(1, Ordering::Release);
            return Ok(i);
        }
        Err(ShmError::TooManyConnections { domain: self.info.name.clone(), capacity: self.capacity() })
    }

    /// Releases slot `i` held by `pid`: its ownership, its writer lock (repairing a commit
    /// it abandoned half-way) and its pending handshakes. Returns false if someone else
    /// released it first. Exclusive: the caller that swaps `pid` for [`RELEASING`] does the
    /// whole release, so two releasers (the framework's sweep and a writer freeing a dead
    /// owner) can never both touch a slot that a new connection has meanwhile claimed.
    pub(crate) fn release_slot(&self, i: usize, pid: u32) -> bool {
        let h = self.header();
        let Some(c) = self.conn(i) else { return false };
        if pid == 0 || pid == RELEASING {
            return false;
        }
        if c.active.compare_exchange(pid, RELEASING, Ordering::AcqRel, Ordering::Relaxed).is_err() {
            return false;
        }
        let was_ready = c.ready.swap(0, Ordering::AcqRel);
        if was_ready == 0 && pid != os::current_process().pid && os::is_alive(ProcessId { pid, start_time: 0 }) {
            // A live process still claiming the slot: not ours to release.
            c.active.store(pid, Ordering::Release);
            return false;
        }
        let id = self.conn_id(i);
        let _ = h.owner_conn.compare_exchange(id, 0, Ordering::AcqRel, Ordering::Relaxed);
        if h.writer_lock.load(Ordering::Acquire) == id {
            self.bucket(Role::Subscribe).recover();
            let _ = h.writer_lock.compare_exchange(id, 0, Ordering::AcqRel, Ordering::Relaxed);
        }
        let kind = ConnKind::of_flags(c.flags.swap(0, Ordering::AcqRel));
        c.generation.fetch_add(1, Ordering::AcqRel);
        c.active.store(0, Ordering::Release);
        if was_ready != 0 {
            kind.counter(h).fetch_sub(1, Ordering::AcqRel);
        }
        h.ack_seq.fetch_add(1, Ordering::Release);
        wake(&h.ack_seq, &h.ack_waiters);
        // An event-driven connection waiting for its due step hears of its removal at once.
        c.due_seq.fetch_add(1, Ordering::Release);
        wake(&c.due_seq, &c.due_waiters);
        true
    }

    /// Connection slot `i` as a person reads it: `'NAME' (pid N)`, with `, a DDS writer`
    /// for one standing for DDS.
    pub(crate) fn describe_conn(&self, i: usize) -> String {
        let Some(c) = self.conn(i) else { return format!("slot {i}") };
        let remote = c.flags.load(Ordering::Relaxed) & CONN_REMOTE != 0;
        format!(
            "'{}' (pid {}{})",
            conn_name(c),
            c.active.load(Ordering::Relaxed),
            if remote { ", a DDS writer through the gateway" } else { "" }
        )
    }
}

/// The name a connection slot holds (written by `claim_slot`, NUL-padded).
pub(crate) fn conn_name(c: &ConnSlot) -> String {
    let mut name = [0u8; 48];
    load_bytes(&c.name, &mut name);
    let end = name.iter().position(|&b| b == 0).unwrap_or(name.len());
    String::from_utf8_lossy(&name[..end]).into_owned()
}

/// What a connection slot stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConnKind {
    /// A component: counted as a participant.
    Participant,
    /// A DDS writer, through the gateway: takes part in lock-step once it writes, counted
    /// apart.
    Remote,
    /// A passive observer (the gateway's presence in a domain it bridges): never waited for,
    /// not a participant; carries its DDS reader count.
    Observer,
}

impl ConnKind {
    fn of_flags(flags: u32) -> ConnKind {
        if flags & CONN_OBSERVER != 0 {
            ConnKind::Observer
        } else if flags & CONN_REMOTE != 0 {
            ConnKind::Remote
        } else {
            ConnKind::Participant
        }
    }

    /// The header counter of this kind (observers: none, a counter of their own that
    /// nothing reads, so the arithmetic stays uniform).
    fn counter(self, h: &Header) -> &AtomicU32 {
        match self {
            ConnKind::Participant => &h.conn_count,
            ConnKind::Remote => &h.remote_count,
            ConnKind::Observer => &h.observer_count,
        }
    }
}
