//! The segment format: where things lie in a domain's shared memory, the header and the
//! connection slot laid over it (atomics only, the header's fields grouped by writer on
//! cache lines of their own), and the description of the domain that the directory holds.

use std::mem::size_of;

use crate::ddf::{Domain, Flags, Leaf, Role, SetLayout};
use crate::shm::bucket::{SlotWords, SLOTS};
use crate::shm::handshake::MASK_WORDS;
use crate::sync::{AtomicU32, AtomicU64};

/// `TUTTISHM`, little-endian.
pub(crate) const MAGIC: u64 = u64::from_le_bytes(*b"TUTTISHM");
/// Segment format version (2: header fields grouped by writer on separate cache lines; 3:
/// DDS writers and observers counted apart from participants, 192-byte connection slots; 7:
/// a component's state saved and restored through the segment, `docs/run.md` "Checkpoints").
pub const VERSION: u32 = 7;
/// Bytes reserved for the header.
pub(crate) const HEADER_BYTES: usize = 1024;
/// Connection slots per domain.
pub const DEFAULT_CONNECTIONS: u32 = 64;
/// Attempts of a seqlock read before a set is declared corrupt (only a writer committing
/// faster than one copy, without pause, or a damaged segment, exhausts them).
pub(crate) const MAX_READ_TRIES: u32 = 1 << 20;
pub(super) const MAX_CONNECTIONS: u32 = 4096;
pub(super) const CONN_BYTES: usize = 256;
pub(super) const DIR_ENTRY_BYTES: usize = 16;
pub(super) const ALIGN: usize = 64;

/// `ConnSlot::active` while a slot is being released (no process has this pid).
pub(crate) const RELEASING: u32 = u32::MAX;

/// Framework state values (0 while the framework initialises the segment).
pub(crate) const STATE_RUNNING: u32 = 1;
pub(crate) const STATE_STOPPED: u32 = 2;
/// The `paused` word of a paused framework: a pattern, not a flag, so that a header written
/// over is not read as a pause (which would hold participants' timeouts back).
pub(crate) const PAUSED: u32 = u32::from_le_bytes(*b"PAUS");

/// Zero bytes that start a new cache line: the header field after it is 64-byte aligned.
#[repr(C, align(64))]
#[derive(Debug)]
pub(crate) struct LineBreak;

#[repr(C)]
#[derive(Debug)]
pub(crate) struct SetHeader {
    /// Each set's seqlock words on lines of their own: one writer, polled by the other side.
    pub _line: LineBreak,
    pub size: AtomicU32,
    pub align: AtomicU32,
    /// Words (8 bytes) per slot.
    pub words: AtomicU32,
    pub _pad: AtomicU32,
    pub slots_off: AtomicU64,
    pub current: AtomicU64,
    pub commits: AtomicU64,
    /// Each slot's sequence number, generation and [`Stamp`](crate::shm::bucket::Stamp), on the
    /// next lines (two slots a line).
    pub meta: [SlotWords; SLOTS],
}

#[repr(C)]
#[derive(Debug)]
pub(crate) struct Header {
    pub magic: AtomicU64,
    pub version: AtomicU32,
    pub header_bytes: AtomicU32,
    pub total_size: AtomicU64,
    pub layout_hash: AtomicU64,
    pub flags: AtomicU32,
    pub conn_capacity: AtomicU32,
    pub owner_pid: AtomicU32,
    pub state: AtomicU32,
    pub owner_start: AtomicU64,
    pub created_ns: AtomicU64,
    pub name_off: AtomicU32,
    pub name_len: AtomicU32,
    pub dir_off: AtomicU32,
    pub dir_count: AtomicU32,
    pub str_off: AtomicU32,
    pub str_len: AtomicU32,
    pub conn_off: AtomicU32,
    /// One past the highest connection slot ever used (bounds the scans).
    pub conn_hwm: AtomicU32,
    /// Wait-to-go: 1 while the framework holds participants.
    pub hold: AtomicU32,
    pub conn_count: AtomicU32,
    pub go_waiters: AtomicU32,
    /// Observer connections (see [`ConnKind::Observer`](super::ConnKind::Observer)).
    pub observer_count: AtomicU32,
    /// [`PAUSED`] while the framework is paused: participants waiting for a step do not time
    /// out.
    pub paused: AtomicU32,
    /// When the framework last resumed (ns since the epoch): a wait that began during the
    /// pause gets a whole timeout from then.
    pub resumed_ns: AtomicU64,
    pub sets: [SetHeader; 2],
    /// Written by the framework on every step.
    pub _framework: LineBreak,
    pub pub_step: AtomicU64,
    pub step_seq: AtomicU32,
    pub ack_waiters: AtomicU32,
    pub sim_time_bits: AtomicU64,
    pub heartbeat_ns: AtomicU64,
    pub steps: AtomicU64,
    pub period_ns: AtomicU64,
    pub overruns: AtomicU64,
    pub timeouts: AtomicU64,
    pub max_late_ns: AtomicU64,
    pub last_late_ns: AtomicU64,
    /// The last step whose PUBLISH set differs from the step before (event-driven domains).
    pub changed_step: AtomicU64,
    /// The index of the published step: its simulated time over the step, which a framework
    /// not paced by the wall clock advances by more than one where nobody is due (written
    /// before `pub_step`).
    pub pub_index: AtomicU64,
    /// Every event-driven connection is due at this step (the first after a reset).
    pub all_due_step: AtomicU64,
    /// The simulated time of a step, seconds (f64 bits; 0: not said).
    pub sim_step_bits: AtomicU64,
    /// The PUBLISH items that changed at `changed_step`, a bit per item (by its index in the
    /// set; the last bit stands for every item from it on).
    pub changed_items: [AtomicU64; MASK_WORDS],
    /// A request to the connections that keep a state ([`crate::shm::state`]): its number
    /// (bumped once the request's files are in place) and what it asks.
    pub state_seq: AtomicU64,
    pub state_kind: AtomicU32,
    /// Bumped each time the framework sets its simulated time back (a reset, a restore),
    /// after `sim_time_bits` holds the new time: a clock that follows the domain says the new
    /// time at once, without waiting for the next step.
    pub time_resets: AtomicU32,
    /// Written by participants on their reads and commits.
    pub _participants: LineBreak,
    pub ack_seq: AtomicU32,
    pub step_waiters: AtomicU32,
    pub seeded: AtomicU32,
    /// Connections standing for DDS writers (through the gateway); not in `conn_count`.
    pub remote_count: AtomicU32,
    /// Exclusive SUBSCRIBE owner (connection id), 0 when none.
    pub owner_conn: AtomicU64,
    /// Connection id committing to SUBSCRIBE right now, 0 when none.
    pub writer_lock: AtomicU64,
    pub rejected: AtomicU64,
}

#[repr(C)]
#[derive(Debug)]
pub(crate) struct ConnSlot {
    /// The owner's pid while in use, 0 when free.
    pub active: AtomicU32,
    pub generation: AtomicU32,
    pub flags: AtomicU32,
    pub ready: AtomicU32,
    pub start_time: AtomicU64,
    pub since_ns: AtomicU64,
    pub first_step: AtomicU64,
    pub last_read: AtomicU64,
    pub last_commit: AtomicU64,
    pub reads: AtomicU64,
    pub commits: AtomicU64,
    pub missed: AtomicU64,
    pub name: [AtomicU64; 6],
    /// An observer's DDS readers (the gateway's count of the readers of this domain's
    /// topics, every set's readers once).
    pub peers: AtomicU64,
    /// Event-driven: the index (simulated time over the step) from which the connection is
    /// next due.
    pub due_index: AtomicU64,
    /// Event-driven: the last step the connection answered.
    pub answered: AtomicU64,
    /// Event-driven, waking on change: the PUBLISH items the connection reads, a bit per
    /// item as in `Header::changed_items` (none: every item).
    pub read_items: [AtomicU64; MASK_WORDS],
    /// Event-driven: the last step the framework found the connection due at (it stays at
    /// that step until the connection answers it).
    pub due_at: AtomicU64,
    /// Event-driven: bumped when the framework tells the connection it is due (or stops, or
    /// removes it); the connection waits on it alone, so the steps it is not due at do not
    /// wake it.
    pub due_seq: AtomicU32,
    pub due_waiters: AtomicU32,
    /// A remote writer across a link with a lookahead (the gateway's): its steps of
    /// lookahead, how many steps the framework is ahead of its newest answer, the link's
    /// latest round trip (µs) and the steps that waited for the link; all 0 otherwise.
    pub link: [AtomicU64; 4],
    /// The connection keeps a state that it saves and restores on request
    /// ([`crate::shm::state`]): 1, else 0.
    pub keeps_state: AtomicU64,
    /// The last state request the connection answered, with
    /// [`STATE_FAILED`](crate::shm::state) set when it could not do it.
    pub state_done: AtomicU64,
    pub _reserved: [AtomicU64; 1],
}

const _: () = assert!(size_of::<Header>() <= HEADER_BYTES);
const _: () = assert!(size_of::<ConnSlot>() == CONN_BYTES);

/// What a segment says about its domain, decoded and checked.
#[derive(Debug, Clone, PartialEq)]
pub struct DomainInfo {
    pub name: String,
    pub flags: Flags,
    pub layout_hash: u64,
    pub publish: SetLayout,
    pub subscribe: SetLayout,
}

impl DomainInfo {
    pub fn from_domain(d: &Domain) -> Self {
        DomainInfo {
            name: d.name.clone(),
            flags: d.flags,
            layout_hash: d.layout_hash,
            publish: d.publish.layout.clone(),
            subscribe: d.subscribe.layout.clone(),
        }
    }

    pub fn set(&self, role: Role) -> &SetLayout {
        match role {
            Role::Publish => &self.publish,
            Role::Subscribe => &self.subscribe,
        }
    }

    /// All leaves, PUBLISH first: the index is the RTAPI item key.
    pub fn leaves(&self) -> impl Iterator<Item = (Role, &Leaf)> {
        self.publish
            .leaves
            .iter()
            .map(|l| (Role::Publish, l))
            .chain(self.subscribe.leaves.iter().map(|l| (Role::Subscribe, l)))
    }
}

pub(super) fn flags_bits(f: Flags) -> u32 {
    u32::from(f.synchronous)
        | u32::from(f.multiple_publish_allowed) << 1
        | u32::from(f.states) << 2
        | u32::from(f.event) << 3
}

pub(super) fn flags_from_bits(b: u32) -> Flags {
    Flags { synchronous: b & 1 != 0, event: b & 8 != 0, multiple_publish_allowed: b & 2 != 0, states: b & 4 != 0 }
}

pub(super) fn round_up(n: usize, a: usize) -> usize {
    n.div_ceil(a) * a
}
