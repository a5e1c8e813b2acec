//! Which segments this process trusts: its own user's, or those of the users
//! `TUTTI_TRUST_UIDS` names, and never a link; and a segment left by a dead framework,
//! reclaimed.

use std::fs::File;
use std::io;

use super::format::{Header, HEADER_BYTES, MAGIC, STATE_STOPPED};
use crate::shm::os::{self, ProcessId};
use crate::shm::ShmError;
use crate::sync::Ordering;

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
pub(super) fn open_trusted(shm_name: &str, domain: &str) -> Result<File, ShmError> {
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
pub(super) fn reclaim_stale(shm_name: &str, domain: &str) -> Result<(), ShmError> {
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
