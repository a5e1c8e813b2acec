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
//!
//! The format itself is in `format`; `create` writes a new segment and `open` checks an
//! existing one (`trust` says whose segments are opened at all, `names` where they live);
//! `conns` keeps the connection table, `reads` holds the typed reads other crates use,
//! `status` what `tutti status` shows, and `wait` the one way of waiting for the other side.

use std::fs::File;
use std::sync::Arc;

use super::bucket::Bucket;
use super::handshake::StepCtl;
use super::os;
use super::ShmError;
use crate::ddf::Role;
use crate::sync::AtomicU64;

mod conns;
mod create;
mod format;
mod names;
mod open;
mod reads;
mod status;
mod trust;
mod wait;

pub(crate) use conns::conn_name;
pub use conns::ConnKind;
use format::Header;
pub use format::{DomainInfo, DEFAULT_CONNECTIONS, VERSION};
pub(crate) use format::{MAX_READ_TRIES, PAUSED, RELEASING, STATE_RUNNING, STATE_STOPPED};
pub use names::{check_namespace, namespace_from_env, segment_name, segment_path};
pub use status::{list_domains, ConnectionInfo, DomainStatus, LinkInfo};
pub use wait::WaitMode;
pub(crate) use wait::{wake, Waited, Waiter};

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
}
