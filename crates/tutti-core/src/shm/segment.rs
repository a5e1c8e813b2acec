//! One domain's shared-memory segment: a self-describing header (magic, version, layout
//! hash, item directory), the connection table, and the two buckets.
//!
//! ```text
//! 0        Header (HEADER_BYTES)
//! conn_off ConnSlot × conn_capacity (128 bytes each)
//! dir_off  directory: one 16-byte entry per leaf (PUBLISH leaves first)
//! str_off  string table: domain name, then item paths (UTF-8)
//! sets[r].slots_off  SLOTS slots of sets[r].words × 8 bytes, for each role r
//! ```
//!
//! The header's fields are grouped by who writes them, each group on cache lines of its own
//! (the framework's per-step words, the participants' per-commit words, each set's seqlock),
//! so that one side's writes do not steal lines the other side is polling.
//!
//! Everything in the segment except set bytes is read and written through atomics. Every offset and length
//! read from a segment is checked before use, and the directory is re-hashed and compared
//! with the header's layout hash, so a corrupted or hostile segment gives [`ShmError`], never
//! undefined behaviour.

use std::fs::File;
use std::io;
use std::mem::size_of;
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;

use super::bucket::{load_bytes, Bucket, SlotWords, Stamp, SLOTS};
use super::handshake::{ConnCtl, StepCtl, CONN_OBSERVER, CONN_REMOTE, CONN_SYNC_READER, CONN_WRITER, MASK_WORDS};
use super::os::{self, ProcessId};
use super::ShmError;
use crate::ddf::layout::{layout_hash, MAX_SET_BYTES};
use crate::ddf::{Domain, Flags, Leaf, Role, ScalarType, SetLayout};
use crate::sync::{AtomicU32, AtomicU64, Ordering};

/// `TUTTISHM`, little-endian.
pub(crate) const MAGIC: u64 = u64::from_le_bytes(*b"TUTTISHM");
/// Segment format version (2: header fields grouped by writer on separate cache lines; 3:
/// DDS writers and observers counted apart from participants, 192-byte connection slots).
pub const VERSION: u32 = 6;
/// Bytes reserved for the header.
pub(crate) const HEADER_BYTES: usize = 1024;
/// Connection slots per domain.
pub const DEFAULT_CONNECTIONS: u32 = 64;
/// Attempts of a seqlock read before a set is declared corrupt (only a writer committing
/// faster than one copy, without pause, or a damaged segment, exhausts them).
pub(crate) const MAX_READ_TRIES: u32 = 1 << 20;
const MAX_CONNECTIONS: u32 = 4096;
const CONN_BYTES: usize = 256;
const DIR_ENTRY_BYTES: usize = 16;
const ALIGN: usize = 64;

/// `ConnSlot::active` while a slot is being released (no process has this pid).
pub(crate) const RELEASING: u32 = u32::MAX;

/// Framework state values (0 while the framework initialises the segment).
pub(crate) const STATE_RUNNING: u32 = 1;
pub(crate) const STATE_STOPPED: u32 = 2;
/// The `paused` word of a paused framework: a pattern, not a flag, so that a header written
/// over is not read as a pause (which would hold participants' timeouts back).
pub(crate) const PAUSED: u32 = u32::from_le_bytes(*b"PAUS");

/// The namespace from `TUTTI_NAMESPACE` (default `tutti`).
pub fn namespace_from_env() -> String {
    std::env::var("TUTTI_NAMESPACE").ok().filter(|s| !s.is_empty()).unwrap_or_else(|| "tutti".to_string())
}

/// Checks a namespace: 1–64 characters of `[A-Za-z0-9_.-]`.
pub fn check_namespace(ns: &str) -> Result<(), ShmError> {
    let ok = !ns.is_empty()
        && ns.len() <= 64
        && ns.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '-'));
    if ok {
        Ok(())
    } else {
        Err(ShmError::InvalidNamespace { namespace: ns.to_string() })
    }
}

/// The shared-memory object name of a domain: `tutti.NAMESPACE.DOMAIN`.
pub fn segment_name(ns: &str, domain: &str) -> String {
    format!("tutti.{ns}.{domain}")
}

/// Where the segment of `domain` in namespace `ns` lives.
pub fn segment_path(ns: &str, domain: &str) -> std::path::PathBuf {
    std::path::Path::new(os::SHM_DIR).join(segment_name(ns, domain))
}

/// How a connection or the framework waits for the other side.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum WaitMode {
    /// Busy-wait: lowest latency, one core at 100 %.
    Spin,
    /// Check every given interval (the product's "flag delay").
    Poll(Duration),
    /// Sleep in the kernel (futex) until woken: no CPU use, a wake-up costs tens of µs.
    Block,
}

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
    /// Each slot's sequence number, generation and [`Stamp`](super::bucket::Stamp), on the
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
    /// Observer connections (see [`ConnKind::Observer`]).
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
    pub _reserved: [AtomicU64; 7],
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

fn flags_bits(f: Flags) -> u32 {
    u32::from(f.synchronous)
        | u32::from(f.multiple_publish_allowed) << 1
        | u32::from(f.states) << 2
        | u32::from(f.event) << 3
}

fn flags_from_bits(b: u32) -> Flags {
    Flags { synchronous: b & 1 != 0, event: b & 8 != 0, multiple_publish_allowed: b & 2 != 0, states: b & 4 != 0 }
}

fn round_up(n: usize, a: usize) -> usize {
    n.div_ceil(a) * a
}

/// A mapped segment.
#[derive(Debug)]
pub struct Segment {
    map: os::SharedMap,
    /// The segment's file, kept to look at its size when something reads wrong.
    file: File,
    len: usize,
    /// Each set's slots: (byte offset, words per slot), checked against the mapping when the
    /// segment is created or opened and never read from shared memory again.
    slots: [(usize, usize); 2],
    /// The shared-memory object name.
    pub shm_name: String,
    pub info: Arc<DomainInfo>,
}

// SAFETY: the mapping is only accessed through atomics (Header, ConnSlot, slot words), which
// are Sync; the raw pointer is never used for plain reads or writes.
unsafe impl Send for Segment {}
// SAFETY: as above.
unsafe impl Sync for Segment {}

impl Segment {
    /// Creates the segment of `domain` in namespace `ns`, reclaiming a stale one left by a
    /// dead framework; a live one is refused with its owner's pid.
    /// With `hold`, the segment is published already holding wait-to-go, so that no
    /// participant can slip past a hold its framework is about to set.
    pub(crate) fn create(
        ns: &str,
        domain: &Domain,
        conn_capacity: u32,
        mode: u32,
        hold: bool,
    ) -> Result<Segment, ShmError> {
        check_namespace(ns)?;
        let shm_name = segment_name(ns, &domain.name);
        let info = DomainInfo::from_domain(domain);
        let file = match os::shm_open(&shm_name, true, mode) {
            Ok(f) => f,
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {
                reclaim_stale(&shm_name, &domain.name)?;
                os::shm_open(&shm_name, true, mode)
                    .map_err(|e| ShmError::io(format!("creating {}/{shm_name}", os::SHM_DIR), e))?
            }
            Err(e) => return Err(ShmError::io(format!("creating {}/{shm_name}", os::SHM_DIR), e)),
        };
        match Self::init(file, &shm_name, info, conn_capacity.clamp(1, MAX_CONNECTIONS), hold) {
            Ok(seg) => Ok(seg),
            Err(e) => {
                let _ = os::shm_unlink(&shm_name);
                Err(e)
            }
        }
    }

    fn init(file: File, shm_name: &str, info: DomainInfo, cap: u32, hold: bool) -> Result<Segment, ShmError> {
        let leaves: Vec<(Role, &Leaf)> = info.leaves().collect();
        let mut strings = Vec::new();
        strings.extend_from_slice(info.name.as_bytes());
        let mut entries = Vec::with_capacity(leaves.len());
        for (role, leaf) in &leaves {
            let off = strings.len() as u64;
            strings.extend_from_slice(leaf.path.as_bytes());
            let ty = ScalarType::ALL.iter().position(|t| *t == leaf.ty).unwrap_or(0) as u64;
            let w0 = off | (leaf.path.len() as u64) << 32 | (*role as u64) << 48 | ty << 56;
            let w1 = u64::from(leaf.length) | u64::from(leaf.offset) << 16;
            entries.push((w0, w1));
        }
        let conn_off = HEADER_BYTES;
        let dir_off = conn_off + cap as usize * CONN_BYTES;
        let str_off = dir_off + entries.len() * DIR_ENTRY_BYTES;
        let mut end = round_up(str_off + strings.len(), ALIGN);
        let mut set_geom = [(0usize, 0usize); 2];
        for role in Role::ALL {
            let words = round_up(info.set(role).size as usize, ALIGN) / 8;
            set_geom[role as usize] = (end, words);
            end += SLOTS * words * 8;
        }
        let total = end;
        file.set_len(total as u64).map_err(|e| ShmError::io(format!("sizing {}/{shm_name}", os::SHM_DIR), e))?;
        let map = os::map(&file).map_err(|e| ShmError::io(format!("mapping {}/{shm_name}", os::SHM_DIR), e))?;
        let seg =
            Segment { map, file, len: total, slots: set_geom, shm_name: shm_name.to_string(), info: Arc::new(info) };
        let h = seg.header();
        let me = os::current_process();
        h.owner_pid.store(me.pid, Ordering::Relaxed);
        h.owner_start.store(me.start_time, Ordering::Relaxed);
        h.version.store(VERSION, Ordering::Relaxed);
        h.header_bytes.store(HEADER_BYTES as u32, Ordering::Relaxed);
        h.total_size.store(total as u64, Ordering::Relaxed);
        h.layout_hash.store(seg.info.layout_hash, Ordering::Relaxed);
        h.flags.store(flags_bits(seg.info.flags), Ordering::Relaxed);
        h.conn_capacity.store(cap, Ordering::Relaxed);
        h.created_ns.store(os::now_ns(), Ordering::Relaxed);
        h.name_off.store(0, Ordering::Relaxed);
        h.name_len.store(seg.info.name.len() as u32, Ordering::Relaxed);
        h.conn_off.store(conn_off as u32, Ordering::Relaxed);
        h.dir_off.store(dir_off as u32, Ordering::Relaxed);
        h.dir_count.store(entries.len() as u32, Ordering::Relaxed);
        h.str_off.store(str_off as u32, Ordering::Relaxed);
        h.str_len.store(strings.len() as u32, Ordering::Relaxed);
        let dir = seg.words_at(dir_off, entries.len() * 2)?;
        for (i, (w0, w1)) in entries.iter().enumerate() {
            dir[2 * i].store(*w0, Ordering::Relaxed);
            dir[2 * i + 1].store(*w1, Ordering::Relaxed);
        }
        let str_words = seg.words_at(str_off - str_off % 8, (str_off % 8 + strings.len()).div_ceil(8))?;
        let mut padded = vec![0u8; str_off % 8];
        padded.extend_from_slice(&strings);
        super::bucket::store_bytes(str_words, &padded);
        for role in Role::ALL {
            let (off, words) = set_geom[role as usize];
            let sh = &h.sets[role as usize];
            let layout = seg.info.set(role);
            sh.size.store(layout.size, Ordering::Relaxed);
            sh.align.store(layout.align, Ordering::Relaxed);
            sh.words.store(words as u32, Ordering::Relaxed);
            sh.slots_off.store(off as u64, Ordering::Relaxed);
            let defaults = layout.default_bytes();
            for slot in seg.bucket(role).slots {
                super::bucket::store_bytes(slot, &defaults);
            }
        }
        h.hold.store(u32::from(hold), Ordering::Relaxed);
        h.state.store(STATE_RUNNING, Ordering::Relaxed);
        // Publish the header last: a participant trusts nothing before it sees the magic.
        h.magic.store(MAGIC, Ordering::Release);
        Ok(seg)
    }

    /// Opens the segment of `domain` in `ns` and checks everything in it.
    pub fn open(ns: &str, domain: &str) -> Result<Segment, ShmError> {
        check_namespace(ns)?;
        let shm_name = segment_name(ns, domain);
        let file = open_trusted(&shm_name, domain).map_err(|e| match e {
            ShmError::Io { source, .. } if source.kind() == io::ErrorKind::NotFound => {
                ShmError::NoSuchDomain { domain: domain.to_string(), namespace: ns.to_string() }
            }
            e => e,
        })?;
        Self::open_file(file, &shm_name, domain)
    }

    /// Fails once another process has shrunk the segment's file under this mapping (see
    /// [`os::SharedMap`]): what was read since may be zeros, not the domain's data.
    pub fn intact(&self) -> Result<(), ShmError> {
        self.intact_if(self.map.truncated())
    }

    /// [`intact`](Self::intact), and also fails when the file is now shorter than the
    /// mapping though no cut page was touched yet (the tail of the last page reads as zeros
    /// without a fault). A system call: for error paths, where zeros were read.
    pub fn intact_checked(&self) -> Result<(), ShmError> {
        let shorter = self.file.metadata().is_ok_and(|m| (m.len() as usize) < self.len);
        self.intact_if(self.map.truncated() || shorter)
    }

    fn intact_if(&self, truncated: bool) -> Result<(), ShmError> {
        if truncated {
            return Err(ShmError::Truncated {
                domain: self.info.name.clone(),
                path: format!("{}/{}", os::SHM_DIR, self.shm_name),
                size: self.len,
            });
        }
        Ok(())
    }

    fn open_file(file: File, shm_name: &str, domain: &str) -> Result<Segment, ShmError> {
        let corrupt = |detail: String| ShmError::Corrupt { domain: domain.to_string(), detail };
        let meta = file.metadata().map_err(|e| ShmError::io(format!("inspecting {shm_name}"), e))?;
        let len = meta.len() as usize;
        // Created but not sized yet: its framework is between `shm_open` and `ftruncate`,
        // which follow each other at once. Empty for longer, something else emptied it.
        if len == 0 {
            let age = meta.modified().ok().and_then(|t| t.elapsed().ok()).unwrap_or_default();
            if age < Duration::from_secs(1) {
                return Err(ShmError::NotReady { domain: domain.to_string() });
            }
            return Err(corrupt("the segment is 0 bytes: another process has truncated it".into()));
        }
        if len < HEADER_BYTES {
            return Err(corrupt(format!(
                "the segment is {len} bytes, smaller than a header: another process has truncated it"
            )));
        }
        let map = os::map(&file).map_err(|e| ShmError::io(format!("mapping {}/{shm_name}", os::SHM_DIR), e))?;
        let placeholder = Arc::new(DomainInfo {
            name: domain.to_string(),
            flags: flags_from_bits(0),
            layout_hash: 0,
            publish: SetLayout::default(),
            subscribe: SetLayout::default(),
        });
        let mut seg = Segment { map, file, len, slots: [(0, 0); 2], shm_name: shm_name.to_string(), info: placeholder };
        let h = seg.header();
        let magic = h.magic.load(Ordering::Acquire);
        if magic == 0 {
            return Err(ShmError::NotReady { domain: domain.to_string() });
        }
        if magic != MAGIC {
            return Err(ShmError::NotTuttiSegment {
                domain: domain.to_string(),
                path: format!("{}/{shm_name}", os::SHM_DIR),
            });
        }
        let version = h.version.load(Ordering::Relaxed);
        if version != VERSION {
            return Err(ShmError::VersionMismatch { domain: domain.to_string(), found: version, expected: VERSION });
        }
        if h.header_bytes.load(Ordering::Relaxed) as usize != HEADER_BYTES {
            return Err(corrupt("header size field is wrong".into()));
        }
        if h.total_size.load(Ordering::Relaxed) != len as u64 {
            return Err(corrupt(format!(
                "the segment is {len} bytes but its header says {}: another process has resized it",
                h.total_size.load(Ordering::Relaxed)
            )));
        }
        let (info, slots) = seg.decode_directory(domain)?;
        seg.info = Arc::new(info);
        seg.slots = slots;
        Ok(seg)
    }

    /// Reads the directory and string table, validating every offset, and re-derives the
    /// layout hash from them; also returns the sets' slot geometry, checked.
    fn decode_directory(&self, domain: &str) -> Result<(DomainInfo, [(usize, usize); 2]), ShmError> {
        let corrupt = |detail: String| ShmError::Corrupt { domain: domain.to_string(), detail };
        let h = self.header();
        let ld = |a: &AtomicU32| a.load(Ordering::Relaxed) as usize;
        let cap = h.conn_capacity.load(Ordering::Relaxed);
        if cap == 0 || cap > MAX_CONNECTIONS {
            return Err(corrupt(format!("connection capacity {cap} out of range")));
        }
        if ld(&h.conn_off) != HEADER_BYTES {
            return Err(corrupt("connection table offset is wrong".into()));
        }
        self.check_range(HEADER_BYTES, cap as usize * CONN_BYTES, "connection table")?;
        let (dir_off, dir_count) = (ld(&h.dir_off), ld(&h.dir_count));
        if dir_off % 8 != 0 || dir_count > 2 * 65536 {
            return Err(corrupt("directory position or size out of range".into()));
        }
        self.check_range(dir_off, dir_count * DIR_ENTRY_BYTES, "directory")?;
        let (str_off, str_len) = (ld(&h.str_off), ld(&h.str_len));
        self.check_range(str_off, str_len, "string table")?;
        let base = str_off - str_off % 8;
        let mut strings = vec![0u8; str_off % 8 + str_len];
        load_bytes(self.words_at(base, strings.len().div_ceil(8))?, &mut strings);
        let strings = &strings[str_off % 8..];
        let text = |off: usize, len: usize, what: &str| -> Result<String, ShmError> {
            let bytes = strings
                .get(off..off.saturating_add(len))
                .ok_or_else(|| corrupt(format!("{what} outside the string table")))?;
            String::from_utf8(bytes.to_vec()).map_err(|_| corrupt(format!("{what} is not UTF-8")))
        };
        let name = text(ld(&h.name_off), ld(&h.name_len), "domain name")?;
        if name != domain {
            return Err(corrupt(format!("segment names domain '{name}'")));
        }
        let flags = flags_from_bits(h.flags.load(Ordering::Relaxed));
        let mut sets = [SetLayout::default(), SetLayout::default()];
        let mut slots = [(0, 0); 2];
        for role in Role::ALL {
            let sh = &h.sets[role as usize];
            let size = sh.size.load(Ordering::Relaxed);
            let align = sh.align.load(Ordering::Relaxed);
            let words = sh.words.load(Ordering::Relaxed) as usize;
            let off = sh.slots_off.load(Ordering::Relaxed);
            if u64::from(size) > MAX_SET_BYTES || words * 8 < size as usize || !align.is_power_of_two() || align > 8 {
                return Err(corrupt(format!("{role} set size fields are inconsistent")));
            }
            let off = usize::try_from(off).map_err(|_| corrupt(format!("{role} slots offset out of range")))?;
            if off % ALIGN != 0 {
                return Err(corrupt(format!("{role} slots are misaligned")));
            }
            self.check_range(off, SLOTS * words * 8, "set slots")?;
            sets[role as usize] = SetLayout { size, align, leaves: Vec::new() };
            slots[role as usize] = (off, words);
        }
        let dir = self.words_at(dir_off, dir_count * 2)?;
        for i in 0..dir_count {
            let w0 = dir[2 * i].load(Ordering::Relaxed);
            let w1 = dir[2 * i + 1].load(Ordering::Relaxed);
            let path = text((w0 & 0xffff_ffff) as usize, ((w0 >> 32) & 0xffff) as usize, "item path")?;
            let role = match (w0 >> 48) & 0xff {
                0 => Role::Publish,
                1 => Role::Subscribe,
                r => return Err(corrupt(format!("item '{path}' has role {r}"))),
            };
            let ty = *ScalarType::ALL
                .get(((w0 >> 56) & 0xff) as usize)
                .ok_or_else(|| corrupt(format!("item '{path}' has an unknown type")))?;
            let length = (w1 & 0xffff) as u16;
            let offset = ((w1 >> 16) & 0xffff_ffff) as u32;
            let size = u32::from(length) * ty.size();
            let set = &mut sets[role as usize];
            if length == 0 || u64::from(offset) + u64::from(size) > u64::from(set.size) || offset % ty.size() != 0 {
                return Err(corrupt(format!("item '{path}' lies outside its set")));
            }
            set.leaves.push(Leaf { path, ty, length, offset, size, default: None });
        }
        let [publish, subscribe] = sets;
        let hash = layout_hash(&name, flags, &publish, &subscribe);
        let stored = h.layout_hash.load(Ordering::Relaxed);
        if hash != stored {
            return Err(corrupt(format!("layout hash {stored:016x} does not match the directory ({hash:016x})")));
        }
        Ok((DomainInfo { name, flags, layout_hash: hash, publish, subscribe }, slots))
    }

    fn check_range(&self, off: usize, len: usize, what: &str) -> Result<(), ShmError> {
        match off.checked_add(len) {
            Some(end) if end <= self.len => Ok(()),
            _ => Err(ShmError::Corrupt {
                domain: self.info.name.clone(),
                detail: format!("{what} lies outside the segment"),
            }),
        }
    }

    /// `n` words at byte offset `off`, bounds- and alignment-checked.
    fn words_at(&self, off: usize, n: usize) -> Result<&[AtomicU64], ShmError> {
        self.check_range(off, n * 8, "data")?;
        if off % 8 != 0 {
            return Err(ShmError::Corrupt { domain: self.info.name.clone(), detail: "misaligned data".into() });
        }
        // SAFETY: the range [off, off + 8n) lies inside the mapping (checked above), which
        // lives as long as `self`; it is 8-aligned (mmap is page-aligned, `off` is a multiple
        // of 8); AtomicU64 has the size and alignment of u64 and any bit pattern is valid.
        Ok(unsafe { std::slice::from_raw_parts(self.map.as_mut_ptr().add(off).cast::<AtomicU64>(), n) })
    }

    pub(crate) fn header(&self) -> &Header {
        // SAFETY: every segment is at least HEADER_BYTES long (created so, checked on open),
        // the mapping is page-aligned, and Header consists of atomics only, valid for any
        // bit pattern and safe to share between processes.
        unsafe { &*self.map.as_mut_ptr().cast::<Header>() }
    }

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

    pub(crate) fn step_ctl(&self) -> StepCtl<'_> {
        let h = self.header();
        StepCtl {
            pub_step: &h.pub_step,
            step_seq: &h.step_seq,
            ack_seq: &h.ack_seq,
            changed_step: &h.changed_step,
            pub_index: &h.pub_index,
            all_due_step: &h.all_due_step,
            changed_items: &h.changed_items,
        }
    }

    /// The bucket of one set. Its geometry was checked when the segment was created or
    /// opened and is not read from shared memory again, so a process that rewrites the header
    /// afterwards cannot move the slots.
    pub(crate) fn bucket(&self, role: Role) -> Bucket<'_> {
        let sh = &self.header().sets[role as usize];
        let (off, words) = self.slots[role as usize];
        let slots = std::array::from_fn(|i| {
            // SAFETY: `off + SLOTS * words * 8 <= self.len` and `off % 64 == 0` were checked
            // (open) or constructed (create), and the mapping lives as long as `self`; see
            // `words_at` for the rest.
            unsafe {
                std::slice::from_raw_parts(self.map.as_mut_ptr().add(off + i * words * 8).cast::<AtomicU64>(), words)
            }
        });
        Bucket { meta: &sh.meta, current: &sh.current, slots }
    }

    /// A consistent copy of `out.len()` bytes of set `role` from byte `offset` (the caller
    /// keeps the range inside the set); returns the value's generation.
    /// A copy that met a shrunk segment is refused (see [`intact`](Self::intact)).
    pub fn read_set_at(&self, role: Role, offset: usize, out: &mut [u8]) -> Result<u64, ShmError> {
        let generation =
            self.bucket(role).read_at(offset, out, MAX_READ_TRIES).ok_or_else(|| self.never_settles(role))?;
        self.intact()?;
        Ok(generation)
    }

    /// A consistent copy of the whole set `role`; returns its generation.
    pub fn read_set(&self, role: Role, out: &mut [u8]) -> Result<u64, ShmError> {
        self.read_set_at(role, 0, out)
    }

    /// The error of a set that never holds still long enough to be read.
    pub(crate) fn never_settles(&self, role: Role) -> ShmError {
        ShmError::Corrupt { domain: self.info.name.clone(), detail: format!("{role} set never settles") }
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
    pub(crate) fn set_peers(&self, i: usize, n: u64) {
        if let Some(c) = self.conn(i) {
            c.peers.store(n, Ordering::Relaxed);
        }
    }

    /// Waits (blocking on the step word, at most `timeout`) until the framework has
    /// published past step `after` or stopped; returns the latest step. Needs no connection:
    /// an observer that follows every step this way is never waited for.
    pub fn wait_step_after(&self, after: u64, timeout: Duration) -> u64 {
        let h = self.header();
        let w = Waiter { mode: WaitMode::Block, futex: &h.step_seq, waiters: &h.step_waiters, check_every: timeout };
        let deadline = Instant::now() + timeout;
        let _ = w.wait::<()>(
            deadline,
            || Ok(h.pub_step.load(Ordering::Acquire) > after || h.state.load(Ordering::Acquire) != STATE_RUNNING),
            || Ok(()),
        );
        h.pub_step.load(Ordering::Acquire)
    }

    /// The process holding the SUBSCRIBE set exclusively (a domain without
    /// `multiple_publish_allowed`), if one does now.
    pub fn exclusive_owner_pid(&self) -> Option<u32> {
        let owner = self.header().owner_conn.load(Ordering::Acquire);
        (owner != 0).then(|| self.conn(Self::slot_of(owner)).map(|c| c.active.load(Ordering::Relaxed))).flatten()
    }

    /// How many times a set was written: a cheap test for new data before copying it.
    pub fn generation(&self, role: Role) -> u64 {
        self.header().sets[role as usize].current.load(Ordering::Acquire)
    }

    /// The step the framework published last (0 before its first).
    pub fn step(&self) -> u64 {
        self.header().pub_step.load(Ordering::Acquire)
    }

    /// The simulated time (seconds) of the step the framework published last.
    pub fn sim_time(&self) -> f64 {
        f64::from_bits(self.header().sim_time_bits.load(Ordering::Acquire))
    }

    /// The framework's step period, when it steps at a fixed rate (`None` when it has not
    /// said: it steps as fast as it can, or is driven from outside).
    pub fn period(&self) -> Option<Duration> {
        match self.header().period_ns.load(Ordering::Relaxed) {
            0 => None,
            ns => Some(Duration::from_nanos(ns)),
        }
    }

    /// The simulated time of one step, seconds, as the framework said it
    /// (`DomainHost::set_sim_step`); else the period, if the framework steps at a fixed rate.
    pub fn sim_step(&self) -> Option<f64> {
        match f64::from_bits(self.header().sim_step_bits.load(Ordering::Acquire)) {
            s if s > 0.0 && s.is_finite() => Some(s),
            _ => self.period().map(|p| p.as_secs_f64()),
        }
    }

    /// Whether the SUBSCRIBE set has been committed at least once (its values are no longer
    /// only the DDF's defaults).
    pub fn seeded(&self) -> bool {
        self.header().seeded.load(Ordering::Acquire) != 0
    }

    /// A consistent copy of the whole set `role` if one is had within `tries` attempts (a
    /// writer committing without pause can exhaust them); returns its generation. For a
    /// poller that would rather look again later than wait for a busy set to settle.
    pub fn try_read_set(&self, role: Role, out: &mut [u8], tries: u32) -> Option<u64> {
        self.try_read_set_stamped(role, out, tries).map(|(generation, _)| generation)
    }

    /// [`try_read_set`](Self::try_read_set), with the step the copy belongs to and that step's
    /// simulated time, read with it as one ([`Stamp`]): what a reader that labels values with
    /// their step uses, rather than the framework's latest step, which may have moved on.
    pub fn try_read_set_stamped(&self, role: Role, out: &mut [u8], tries: u32) -> Option<(u64, Stamp)> {
        self.bucket(role).read_stamped_at(0, out, tries).filter(|_| !self.map.truncated())
    }

    /// The stamp of set `role`'s latest value (without copying it), or `None` if it never
    /// holds still for `tries` attempts.
    pub fn stamp(&self, role: Role, tries: u32) -> Option<Stamp> {
        self.bucket(role).read_stamped_at(0, &mut [], tries).map(|(_, stamp)| stamp)
    }

    pub(crate) fn framework_id(&self) -> ProcessId {
        let h = self.header();
        ProcessId { pid: h.owner_pid.load(Ordering::Relaxed), start_time: h.owner_start.load(Ordering::Relaxed) }
    }

    /// Whether the framework is paused (its run holds every domain at a step boundary).
    pub fn paused(&self) -> bool {
        self.header().paused.load(Ordering::Acquire) == PAUSED
    }

    /// Whether a wait of at most `timeout` for the framework's next step may time out now:
    /// not while the framework is paused, nor within `timeout` after it resumed.
    pub(crate) fn step_wait_may_time_out(&self, timeout: Duration) -> bool {
        // Only the framework's own words count: the PAUSED pattern, and a resume that is
        // not in the future. Anything else (a segment written over) leaves the timeout as it
        // is, so that no wait can last for ever on a corrupted word.
        let h = self.header();
        if h.paused.load(Ordering::Acquire) == PAUSED {
            return false;
        }
        let (now, resumed) = (os::now_ns(), h.resumed_ns.load(Ordering::Acquire));
        let timeout = timeout.as_nanos().min(u128::from(u64::MAX)) as u64;
        resumed > now || now - resumed >= timeout
    }

    /// Whether the framework is running (state and process both alive).
    pub fn framework_alive(&self) -> bool {
        self.header().state.load(Ordering::Acquire) == STATE_RUNNING && os::is_alive(self.framework_id())
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
    pub(crate) fn claim_slot(&self, me: ProcessId, name: &str, kind: ConnKind) -> Result<usize, ShmError> {
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
            let mut bytes = [0u8; 48];
            let n = name.len().min(47);
            // Cut at a character boundary.
            let n = (0..=n).rev().find(|&k| name.is_char_boundary(k)).unwrap_or(0);
            bytes[..n].copy_from_slice(&name.as_bytes()[..n]);
            super::bucket::store_bytes(&c.name, &bytes);
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

    /// Status of the domain and its connections, for `tutti status`.
    pub fn status(&self) -> DomainStatus {
        let h = self.header();
        let mut connections = Vec::new();
        for i in 0..self.scan_len() {
            let Some(c) = self.conn(i) else { break };
            let pid = c.active.load(Ordering::Acquire);
            if pid == 0 || c.ready.load(Ordering::Acquire) == 0 {
                continue;
            }
            let flags = c.flags.load(Ordering::Relaxed);
            connections.push(ConnectionInfo {
                slot: i as u32,
                pid,
                name: conn_name(c),
                writer: flags & CONN_WRITER != 0,
                sync_reader: flags & CONN_SYNC_READER != 0,
                remote: flags & CONN_REMOTE != 0,
                observer: flags & CONN_OBSERVER != 0,
                dds_readers: c.peers.load(Ordering::Relaxed),
                since_ns: c.since_ns.load(Ordering::Relaxed),
                reads: c.reads.load(Ordering::Relaxed),
                commits: c.commits.load(Ordering::Relaxed),
                missed_steps: c.missed.load(Ordering::Relaxed),
                alive: os::is_alive(ProcessId { pid, start_time: c.start_time.load(Ordering::Relaxed) }),
            });
        }
        let owner_pid = self.exclusive_owner_pid();
        DomainStatus {
            domain: self.info.name.clone(),
            segment: format!("{}/{}", os::SHM_DIR, self.shm_name),
            flags: self.info.flags,
            framework_pid: h.owner_pid.load(Ordering::Relaxed),
            framework_alive: self.framework_alive(),
            step: h.pub_step.load(Ordering::Acquire),
            sim_time: f64::from_bits(h.sim_time_bits.load(Ordering::Relaxed)),
            period_ns: h.period_ns.load(Ordering::Relaxed),
            steps: h.steps.load(Ordering::Relaxed),
            overruns: h.overruns.load(Ordering::Relaxed),
            step_timeouts: h.timeouts.load(Ordering::Relaxed),
            max_late_ns: h.max_late_ns.load(Ordering::Relaxed),
            last_late_ns: h.last_late_ns.load(Ordering::Relaxed),
            publish_commits: self.generation(Role::Publish),
            subscribe_commits: self.generation(Role::Subscribe),
            rejected: h.rejected.load(Ordering::Relaxed),
            seeded: h.seeded.load(Ordering::Relaxed) != 0,
            waiting_to_go: h.hold.load(Ordering::Relaxed) != 0,
            paused: h.paused.load(Ordering::Relaxed) == PAUSED,
            connection_count: h.conn_count.load(Ordering::Relaxed),
            dds_writers: h.remote_count.load(Ordering::Relaxed),
            // DDS readers of the domain's topics, as the live gateways attached to it count them.
            dds_readers: connections.iter().filter(|c| c.observer).map(|c| c.dds_readers).sum(),
            owner_pid,
            connections,
        }
    }
}

/// The name a connection slot holds (written by `claim_slot`, NUL-padded).
fn conn_name(c: &ConnSlot) -> String {
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

/// One connection, as `tutti status` shows it.
#[derive(Debug, Clone, Serialize)]
pub struct ConnectionInfo {
    pub slot: u32,
    pub pid: u32,
    pub name: String,
    pub writer: bool,
    pub sync_reader: bool,
    /// Stands for a DDS-side writer bridged by the gateway.
    pub remote: bool,
    /// A passive observer (a gateway bridging the domain): never waited for, not a
    /// participant.
    pub observer: bool,
    /// An observer's count of the DDS readers of the domain's topics.
    pub dds_readers: u64,
    pub since_ns: u64,
    pub reads: u64,
    pub commits: u64,
    pub missed_steps: u64,
    pub alive: bool,
}

/// A live domain, as `tutti status` shows it.
#[derive(Debug, Clone, Serialize)]
pub struct DomainStatus {
    pub domain: String,
    pub segment: String,
    pub flags: Flags,
    pub framework_pid: u32,
    pub framework_alive: bool,
    pub step: u64,
    pub sim_time: f64,
    pub period_ns: u64,
    pub steps: u64,
    pub overruns: u64,
    pub step_timeouts: u64,
    pub max_late_ns: u64,
    pub last_late_ns: u64,
    pub publish_commits: u64,
    pub subscribe_commits: u64,
    pub rejected: u64,
    pub seeded: bool,
    pub waiting_to_go: bool,
    /// The framework's run is paused (`tutti ctl pause`).
    pub paused: bool,
    /// Participants (components), not counting DDS writers or observers.
    pub connection_count: u32,
    /// Connections standing for DDS writers, through the gateway.
    pub dds_writers: u32,
    /// DDS readers of the domain's topics, as the gateways bridging it count them.
    pub dds_readers: u64,
    pub owner_pid: Option<u32>,
    pub connections: Vec<ConnectionInfo>,
}

/// Every domain segment of namespace `ns`, opened and checked (a segment that fails its
/// checks is reported as an error, not skipped).
pub fn list_domains(ns: &str) -> Result<Vec<Result<DomainStatus, ShmError>>, ShmError> {
    check_namespace(ns)?;
    let prefix = format!("tutti.{ns}.");
    let names = os::list_shm(&prefix).map_err(|e| ShmError::io(format!("listing {}", os::SHM_DIR), e))?;
    Ok(names.iter().map(|n| Segment::open(ns, &n[prefix.len()..]).map(|s| s.status())).collect())
}

/// The user ids whose segments this process trusts besides its own: `TUTTI_TRUST_UIDS`, a
/// comma-separated list of numbers (docs/security.md).
fn trusted_uids() -> Vec<u32> {
    std::env::var("TUTTI_TRUST_UIDS")
        .map(|v| v.split(',').filter_map(|u| u.trim().parse().ok()).collect())
        .unwrap_or_default()
}

/// Opens an existing segment without following a symbolic link, and refuses one that is not
/// a regular file or is owned by another user that `TUTTI_TRUST_UIDS` does not name: a
/// segment in a namespace others can write to could be theirs, planted with the expected
/// name.
fn open_trusted(shm_name: &str, domain: &str) -> Result<File, ShmError> {
    let path = format!("{}/{shm_name}", os::SHM_DIR);
    let untrusted = |reason: String| ShmError::Untrusted { domain: domain.to_string(), path: path.clone(), reason };
    let file = os::shm_open(shm_name, false, 0).map_err(|e| {
        if e.raw_os_error() == Some(rustix::io::Errno::LOOP.raw_os_error()) {
            untrusted("it is a symbolic link".into())
        } else {
            ShmError::io(format!("opening {path}"), e)
        }
    })?;
    let (uid, regular) = os::owner_of(&file).map_err(|e| ShmError::io(format!("inspecting {path}"), e))?;
    if !regular {
        return Err(untrusted("it is not a regular file".into()));
    }
    let me = os::euid();
    if uid != me && !trusted_uids().contains(&uid) {
        return Err(untrusted(format!(
            "it belongs to uid {uid}, not to this user (uid {me}); set TUTTI_TRUST_UIDS={uid} to trust it"
        )));
    }
    Ok(file)
}

/// An existing segment with our name: reclaim it if its framework is dead, else refuse.
/// Another user's segment (or a link) is refused, never reclaimed.
fn reclaim_stale(shm_name: &str, domain: &str) -> Result<(), ShmError> {
    let path = format!("{}/{shm_name}", os::SHM_DIR);
    let opened = match open_trusted(shm_name, domain) {
        Ok(file) => Some(file),
        Err(e @ ShmError::Untrusted { .. }) => return Err(e),
        Err(_) => None,
    };
    if let Some(file) = opened {
        let len = file.metadata().map(|m| m.len()).unwrap_or(0) as usize;
        if len >= HEADER_BYTES {
            if let Ok(map) = os::map(&file) {
                // SAFETY: the mapping is at least HEADER_BYTES long and page-aligned; Header is
                // atomics only.
                let h = unsafe { &*map.as_mut_ptr().cast::<Header>() };
                let magic = h.magic.load(Ordering::Acquire);
                let owner = ProcessId {
                    pid: h.owner_pid.load(Ordering::Relaxed),
                    start_time: h.owner_start.load(Ordering::Relaxed),
                };
                if magic != MAGIC && magic != 0 {
                    return Err(ShmError::NotTuttiSegment { domain: domain.to_string(), path });
                }
                if h.state.load(Ordering::Acquire) != STATE_STOPPED && os::is_alive(owner) {
                    return Err(ShmError::DomainBusy { domain: domain.to_string(), pid: owner.pid, path });
                }
            }
        }
    }
    match os::shm_unlink(shm_name) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(ShmError::io(format!("removing stale {path}"), e)),
    }
}

/// Waits for a condition, spinning, polling or blocking on a futex word, with a deadline
/// and a periodic liveness check. One mechanism serves every wait of the crate.
///
/// `ready` is tested first and after every wake-up; `futex`/`waiters` are the word the other
/// side bumps and the count of sleepers it checks before waking; `check` runs about every
/// `check_every` and may abort the wait.
pub(crate) struct Waiter<'a> {
    pub mode: WaitMode,
    pub futex: &'a AtomicU32,
    pub waiters: &'a AtomicU32,
    pub check_every: Duration,
}

/// Outcome of a wait.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Waited {
    Ready,
    TimedOut,
}

impl Waiter<'_> {
    pub fn wait<E>(
        &self,
        deadline: Instant,
        mut ready: impl FnMut() -> Result<bool, E>,
        mut check: impl FnMut() -> Result<(), E>,
    ) -> Result<Waited, E> {
        let mut next_check = Instant::now() + self.check_every;
        let mut spins: u32 = 0;
        loop {
            let seen = self.futex.load(Ordering::Acquire);
            if ready()? {
                return Ok(Waited::Ready);
            }
            // Time is read once every 64 turns while spinning: Instant::now costs ~25 ns.
            spins = spins.wrapping_add(1);
            let now = if self.mode == WaitMode::Spin && spins % 64 != 0 { None } else { Some(Instant::now()) };
            if let Some(now) = now {
                if now >= deadline {
                    return Ok(Waited::TimedOut);
                }
                if now >= next_check {
                    check()?;
                    next_check = now + self.check_every;
                }
                match self.mode {
                    // Give the core away now and then: on an overloaded machine a pure spin
                    // can starve the very process it waits for.
                    WaitMode::Spin if spins % 4096 == 0 => std::thread::yield_now(),
                    WaitMode::Spin => std::hint::spin_loop(),
                    WaitMode::Poll(d) => std::thread::sleep(d.min(deadline - now)),
                    WaitMode::Block => {
                        self.waiters.fetch_add(1, Ordering::SeqCst);
                        // Re-test after announcing ourselves: the other side bumps the word
                        // and then checks the waiter count, so one of us sees the other.
                        if !ready()? {
                            let limit = (deadline - now)
                                .min(next_check.saturating_duration_since(now))
                                .max(Duration::from_micros(50));
                            os::futex_wait(self.futex, seen, limit);
                        }
                        self.waiters.fetch_sub(1, Ordering::SeqCst);
                    }
                }
            } else {
                std::hint::spin_loop();
            }
        }
    }
}

/// Wakes the sleepers of a futex word after bumping it (the bump is the caller's).
pub(crate) fn wake(futex: &AtomicU32, waiters: &AtomicU32) {
    crate::sync::fence(Ordering::SeqCst);
    if waiters.load(Ordering::SeqCst) > 0 {
        os::futex_wake_all(futex);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn namespaces_are_checked() {
        assert!(check_namespace("tutti").is_ok());
        assert!(check_namespace("t-1.x_y").is_ok());
        assert!(check_namespace("").is_err());
        assert!(check_namespace("a/b").is_err());
        assert!(check_namespace(&"x".repeat(65)).is_err());
    }
}
