//! Opening an existing segment: every offset and length read from it is checked, and its
//! directory is decoded and re-hashed against the header's layout hash before anything in
//! it is trusted.

use std::fs::File;
use std::io;
use std::sync::Arc;
use std::time::Duration;

use super::format::{
    flags_from_bits, DomainInfo, ALIGN, CONN_BYTES, DIR_ENTRY_BYTES, HEADER_BYTES, MAGIC, MAX_CONNECTIONS, VERSION,
};
use super::names::{check_namespace, segment_name};
use super::trust::open_trusted;
use super::Segment;
use crate::ddf::layout::{layout_hash, MAX_SET_BYTES};
use crate::ddf::{Leaf, Role, ScalarType, SetLayout};
use crate::shm::bucket::{load_bytes, SLOTS};
use crate::shm::{os, ShmError};
use crate::sync::{AtomicU32, Ordering};

impl Segment {
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

    fn open_file(file: File, shm_name: &str, domain: &str) -> Result<Segment, ShmError> {
        let meta = file.metadata().map_err(|e| ShmError::io(format!("inspecting {shm_name}"), e))?;
        let len = meta.len() as usize;
        // Created but not sized yet: its framework is between `shm_open` and `ftruncate`,
        // which follow each other at once. Empty for longer, something else emptied it.
        if len == 0 {
            let age = meta.modified().ok().and_then(|t| t.elapsed().ok()).unwrap_or_default();
            if age < Duration::from_secs(1) {
                return Err(ShmError::NotReady { domain: domain.to_string() });
            }
            return Err(corrupt(domain, "the segment is 0 bytes: another process has truncated it".into()));
        }
        if len < HEADER_BYTES {
            return Err(corrupt(
                domain,
                format!("the segment is {len} bytes, smaller than a header: another process has truncated it"),
            ));
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
            return Err(corrupt(domain, "header size field is wrong".into()));
        }
        if h.total_size.load(Ordering::Relaxed) != len as u64 {
            return Err(corrupt(
                domain,
                format!(
                    "the segment is {len} bytes but its header says {}: another process has resized it",
                    h.total_size.load(Ordering::Relaxed)
                ),
            ));
        }
        let (info, slots) = seg.decode_directory(domain)?;
        seg.info = Arc::new(info);
        seg.slots = slots;
        Ok(seg)
    }

    /// Reads the directory and string table, validating every offset, and re-derives the
    /// layout hash from them; also returns the sets' slot geometry, checked.
    fn decode_directory(&self, domain: &str) -> Result<(DomainInfo, SlotGeometry), ShmError> {
        let h = self.header();
        let (dir_off, dir_count) = self.check_tables(domain)?;
        let strings = self.string_table(domain)?;
        let name = strings.text(ld(&h.name_off), ld(&h.name_len), "domain name")?;
        if name != domain {
            return Err(corrupt(domain, format!("segment names domain '{name}'")));
        }
        let flags = flags_from_bits(h.flags.load(Ordering::Relaxed));
        let (mut sets, slots) = self.decode_sets(domain)?;
        self.decode_leaves(dir_off, dir_count, &strings, &mut sets)?;
        let [publish, subscribe] = sets;
        let hash = layout_hash(&name, flags, &publish, &subscribe);
        let stored = h.layout_hash.load(Ordering::Relaxed);
        if hash != stored {
            return Err(corrupt(
                domain,
                format!("layout hash {stored:016x} does not match the directory ({hash:016x})"),
            ));
        }
        Ok((DomainInfo { name, flags, layout_hash: hash, publish, subscribe }, slots))
    }

    /// Checks where the header puts the connection table and the directory; returns the
    /// directory's offset and entry count.
    fn check_tables(&self, domain: &str) -> Result<(usize, usize), ShmError> {
        let h = self.header();
        let cap = h.conn_capacity.load(Ordering::Relaxed);
        if cap == 0 || cap > MAX_CONNECTIONS {
            return Err(corrupt(domain, format!("connection capacity {cap} out of range")));
        }
        if ld(&h.conn_off) != HEADER_BYTES {
            return Err(corrupt(domain, "connection table offset is wrong".into()));
        }
        self.check_range(HEADER_BYTES, cap as usize * CONN_BYTES, "connection table")?;
        let (dir_off, dir_count) = (ld(&h.dir_off), ld(&h.dir_count));
        if dir_off % 8 != 0 || dir_count > 2 * 65536 {
            return Err(corrupt(domain, "directory position or size out of range".into()));
        }
        self.check_range(dir_off, dir_count * DIR_ENTRY_BYTES, "directory")?;
        Ok((dir_off, dir_count))
    }

    /// A copy of the string table, its range checked.
    fn string_table<'d>(&self, domain: &'d str) -> Result<StringTable<'d>, ShmError> {
        let h = self.header();
        let (str_off, str_len) = (ld(&h.str_off), ld(&h.str_len));
        self.check_range(str_off, str_len, "string table")?;
        let base = str_off - str_off % 8;
        let mut bytes = vec![0u8; str_off % 8 + str_len];
        load_bytes(self.words_at(base, bytes.len().div_ceil(8))?, &mut bytes);
        Ok(StringTable { bytes, start: str_off % 8, domain })
    }

    /// Each set's size and alignment (its leaves still empty) and its slots' geometry, checked
    /// against the mapping.
    fn decode_sets(&self, domain: &str) -> Result<([SetLayout; 2], SlotGeometry), ShmError> {
        let h = self.header();
        let mut sets = [SetLayout::default(), SetLayout::default()];
        let mut slots = [(0, 0); 2];
        for role in Role::ALL {
            let sh = &h.sets[role as usize];
            let size = sh.size.load(Ordering::Relaxed);
            let align = sh.align.load(Ordering::Relaxed);
            let words = sh.words.load(Ordering::Relaxed) as usize;
            let off = sh.slots_off.load(Ordering::Relaxed);
            if u64::from(size) > MAX_SET_BYTES || words * 8 < size as usize || !align.is_power_of_two() || align > 8 {
                return Err(corrupt(domain, format!("{role} set size fields are inconsistent")));
            }
            let off = usize::try_from(off).map_err(|_| corrupt(domain, format!("{role} slots offset out of range")))?;
            if off % ALIGN != 0 {
                return Err(corrupt(domain, format!("{role} slots are misaligned")));
            }
            self.check_range(off, SLOTS * words * 8, "set slots")?;
            sets[role as usize] = SetLayout { size, align, leaves: Vec::new() };
            slots[role as usize] = (off, words);
        }
        Ok((sets, slots))
    }

    /// The `dir_count` directory entries at `dir_off`, each a leaf of one of `sets`, checked
    /// to lie inside its set.
    fn decode_leaves(
        &self,
        dir_off: usize,
        dir_count: usize,
        strings: &StringTable<'_>,
        sets: &mut [SetLayout; 2],
    ) -> Result<(), ShmError> {
        let corrupt = |detail: String| corrupt(strings.domain, detail);
        let dir = self.words_at(dir_off, dir_count * 2)?;
        for i in 0..dir_count {
            let w0 = dir[2 * i].load(Ordering::Relaxed);
            let w1 = dir[2 * i + 1].load(Ordering::Relaxed);
            let path = strings.text((w0 & 0xffff_ffff) as usize, ((w0 >> 32) & 0xffff) as usize, "item path")?;
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
        Ok(())
    }
}

/// Each set's slots: (byte offset, words per slot), as [`Segment`] keeps them.
type SlotGeometry = [(usize, usize); 2];

/// A header word that holds an offset or a length.
fn ld(a: &AtomicU32) -> usize {
    a.load(Ordering::Relaxed) as usize
}

/// The error of a segment of `domain` that fails a check.
fn corrupt(domain: &str, detail: String) -> ShmError {
    ShmError::Corrupt { domain: domain.to_string(), detail }
}

/// The string table of a segment of `domain`, copied out of it: the domain name and the
/// item paths, each read by offset and length, checked.
struct StringTable<'d> {
    /// The table, after `start` bytes of the word it begins in.
    bytes: Vec<u8>,
    start: usize,
    domain: &'d str,
}

impl StringTable<'_> {
    /// The `len` bytes at `off` as text; `what` names them in the error.
    fn text(&self, off: usize, len: usize, what: &str) -> Result<String, ShmError> {
        let bytes = self.bytes[self.start..]
            .get(off..off.saturating_add(len))
            .ok_or_else(|| corrupt(self.domain, format!("{what} outside the string table")))?;
        String::from_utf8(bytes.to_vec()).map_err(|_| corrupt(self.domain, format!("{what} is not UTF-8")))
    }
}
