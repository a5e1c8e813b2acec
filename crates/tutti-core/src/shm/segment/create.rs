//! Creating a domain's segment: sized for the domain's layout, its header, directory,
//! string table and default values written, and the magic published last.

use std::fs::File;
use std::io;
use std::sync::Arc;

use super::format::{
    flags_bits, round_up, DomainInfo, ALIGN, CONN_BYTES, DIR_ENTRY_BYTES, HEADER_BYTES, MAGIC, MAX_CONNECTIONS,
    STATE_RUNNING, VERSION,
};
use super::names::{check_namespace, segment_name};
use super::trust::reclaim_stale;
use super::Segment;
use crate::ddf::{Domain, Leaf, Role, ScalarType};
use crate::shm::bucket::{store_bytes, SLOTS};
use crate::shm::{os, ShmError};
use crate::sync::Ordering;

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
        store_bytes(str_words, &padded);
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
                store_bytes(slot, &defaults);
            }
        }
        h.hold.store(u32::from(hold), Ordering::Relaxed);
        h.state.store(STATE_RUNNING, Ordering::Relaxed);
        // Publish the header last: a participant trusts nothing before it sees the magic.
        h.magic.store(MAGIC, Ordering::Release);
        Ok(seg)
    }
}
