//! Errors of the shared-memory layer: one enum, each variant with the domain (and item)
//! involved, so a message alone tells the user what to fix.

use std::io;

use crate::ddf::Role;

#[derive(Debug, thiserror::Error)]
pub enum ShmError {
    #[error("{what}: {source}")]
    Io {
        what: String,
        #[source]
        source: io::Error,
    },
    #[error("invalid namespace '{namespace}': use 1 to 64 characters of A-Z a-z 0-9 _ . - (set by TUTTI_NAMESPACE)")]
    InvalidNamespace { namespace: String },
    #[error("domain '{domain}' is already hosted by a running framework (pid {pid}, segment {path})")]
    DomainBusy { domain: String, pid: u32, path: String },
    #[error("{path} exists but is not a tutti segment; remove it if nothing uses it (domain '{domain}')")]
    NotTuttiSegment { domain: String, path: String },
    #[error("domain '{domain}': the shared-memory segment is corrupted: {detail}")]
    Corrupt { domain: String, detail: String },
    #[error("domain '{domain}': segment format version {found}, this library speaks version {expected}")]
    VersionMismatch { domain: String, found: u32, expected: u32 },
    #[error("domain '{domain}' is being created: its framework has not finished initialising it")]
    NotReady { domain: String },
    #[error("no domain '{domain}' in namespace '{namespace}': is its framework (tutti host) running, with the same TUTTI_NAMESPACE?")]
    NoSuchDomain { domain: String, namespace: String },
    #[error("domain '{domain}': the DDF does not describe the running domain: {difference} (layout hash {expected:016x}, running {found:016x})")]
    LayoutMismatch { domain: String, expected: u64, found: u64, difference: String },
    #[error("domain '{domain}': the framework has stopped")]
    FrameworkStopped { domain: String },
    #[error("domain '{domain}': timed out after {ms} ms waiting for {what}")]
    Timeout { domain: String, what: &'static str, ms: u64 },
    #[error("domain '{domain}': all {capacity} connection slots are in use")]
    TooManyConnections { domain: String, capacity: usize },
    #[error("domain '{domain}' allows one writer at a time and the SUBSCRIBE set is owned by another connection (pid {owner_pid})")]
    NotOwner { domain: String, owner_pid: u32 },
    #[error("domain '{domain}': {role} set is {expected} bytes, got {got}")]
    SizeMismatch { domain: String, role: Role, expected: usize, got: usize },
    #[error("domain '{domain}': bytes {offset}..{end} lie outside the {role} set of {size} bytes")]
    OutOfRange { domain: String, role: Role, offset: usize, end: usize, size: usize },
    #[error("domain '{domain}': no item '{item}' in the {role} set")]
    UnknownItem { domain: String, role: Role, item: String },
    #[error("domain '{domain}': refusing {path}: {reason}")]
    Untrusted { domain: String, path: String, reason: String },
    #[error("domain '{domain}': another process shrank {path} under this process (it was {size} bytes); the domain's data can no longer be trusted")]
    Truncated { domain: String, path: String, size: usize },
    #[error("domain '{domain}': {what} {value} s: {reason}")]
    InvalidTiming { domain: String, what: &'static str, value: f64, reason: String },
    #[error("domain '{domain}': the connection was removed (the framework judged it dead or it disconnected)")]
    ConnectionLost { domain: String },
}

impl ShmError {
    pub(crate) fn io(what: impl Into<String>, source: io::Error) -> Self {
        ShmError::Io { what: what.into(), source }
    }
}
