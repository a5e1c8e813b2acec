//! Return codes: stable numbers, never reused, each with a static text.
//!
//! `RTAPIReturn_t` is a C `int` (not a C enum) so that a value the library does not know,
//! passed back to [`message`], is still a valid value on both sides of the boundary.

use std::ffi::{c_int, CStr};

use tutti_core::shm::ShmError;

/// The return type of every RTAPI call: 0 is success, anything else one of the `RTAPI_*`
/// codes below.
#[allow(non_camel_case_types)]
pub type RTAPIReturn_t = c_int;

/// The call succeeded.
pub const RTAPI_SUCCESS: RTAPIReturn_t = 0;
/// Subscribing failed because the framework has stopped (its domain is gone); the
/// connection has been closed.
pub const RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED: RTAPIReturn_t = 1;
/// Publishing failed because the framework has stopped (its domain is gone); the
/// connection has been closed.
pub const RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED: RTAPIReturn_t = 2;
/// A pointer argument was NULL.
pub const RTAPI_ERROR_NULL_POINTER: RTAPIReturn_t = 3;
/// The current connection (or the given one) is not connected to a domain.
pub const RTAPI_ERROR_NOT_CONNECTED: RTAPIReturn_t = 4;
/// No connection has this key (see RTNewConnectionKey).
pub const RTAPI_ERROR_UNKNOWN_CONNECTION_KEY: RTAPIReturn_t = 5;
/// The domain has no item with this path or key in the set the call works on.
pub const RTAPI_ERROR_UNKNOWN_ITEM: RTAPIReturn_t = 6;
/// The size given differs from the item's size (element size times length).
pub const RTAPI_ERROR_WRONG_SIZE: RTAPIReturn_t = 7;
/// Timed out waiting for the framework (its domain, its next step, wait-to-go or another
/// writer).
pub const RTAPI_ERROR_TIMEOUT: RTAPIReturn_t = 8;
/// No running framework hosts this domain (in this TUTTI_NAMESPACE).
pub const RTAPI_ERROR_DOMAIN_NOT_FOUND: RTAPIReturn_t = 9;
/// The DDF describes the domain with another layout or other flags than the running domain.
pub const RTAPI_ERROR_LAYOUT_MISMATCH: RTAPIReturn_t = 10;
/// The DDF cannot be read, is invalid, or does not describe the domain.
pub const RTAPI_ERROR_DDF_INVALID: RTAPIReturn_t = 11;
/// The domain admits one writer at a time (multiplePublishAllowed=no) and another
/// connection owns its SUBSCRIBE set.
pub const RTAPI_ERROR_NOT_OWNER: RTAPIReturn_t = 12;
/// Every connection slot of the domain is in use.
pub const RTAPI_ERROR_TOO_MANY_CONNECTIONS: RTAPIReturn_t = 13;
/// The call is out of order: an unlock without its lock, a lock taken twice, or RTPublish /
/// RTSubscribe outside a lock pair in a synchronous domain.
pub const RTAPI_ERROR_OUT_OF_ORDER: RTAPIReturn_t = 14;
/// The domain's shared-memory segment is corrupted or is not a tutti segment.
pub const RTAPI_ERROR_CORRUPT_SEGMENT: RTAPIReturn_t = 15;
/// Internal error: the library caught a bug (a panic) and returned instead of crashing.
pub const RTAPI_ERROR_INTERNAL: RTAPIReturn_t = 16;
/// The current connection is already connected: disconnect it first, or use another key.
pub const RTAPI_ERROR_ALREADY_CONNECTED: RTAPIReturn_t = 17;
/// An argument is out of range or not valid text (UTF-8), or TUTTI_NAMESPACE is invalid.
pub const RTAPI_ERROR_INVALID_ARGUMENT: RTAPIReturn_t = 18;
/// The framework removed this connection (it judged it dead); the connection has been closed.
pub const RTAPI_ERROR_CONNECTION_LOST: RTAPIReturn_t = 19;
/// A system call failed (opening or mapping the shared-memory segment).
pub const RTAPI_ERROR_SYSTEM: RTAPIReturn_t = 20;
/// The segment was written by an incompatible version of the library.
pub const RTAPI_ERROR_VERSION_MISMATCH: RTAPIReturn_t = 21;
/// A remote connection (`RTSetupRefMemRemoteConnection`) to a domain that no framework or
/// mirror gateway serves on this machine: start `tutti gateway --mirror DDF` here.
pub const RTAPI_ERROR_REMOTE_NOT_SERVED: RTAPIReturn_t = 22;

/// The domain's segment is not trusted: it is a symbolic link, or another user owns it and
/// `TUTTI_TRUST_UIDS` does not name that user.
pub const RTAPI_ERROR_NOT_TRUSTED: RTAPIReturn_t = 23;

/// Every code, in order (code `i` is at index `i`).
pub const ALL: [RTAPIReturn_t; 24] = [
    RTAPI_SUCCESS,
    RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED,
    RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED,
    RTAPI_ERROR_NULL_POINTER,
    RTAPI_ERROR_NOT_CONNECTED,
    RTAPI_ERROR_UNKNOWN_CONNECTION_KEY,
    RTAPI_ERROR_UNKNOWN_ITEM,
    RTAPI_ERROR_WRONG_SIZE,
    RTAPI_ERROR_TIMEOUT,
    RTAPI_ERROR_DOMAIN_NOT_FOUND,
    RTAPI_ERROR_LAYOUT_MISMATCH,
    RTAPI_ERROR_DDF_INVALID,
    RTAPI_ERROR_NOT_OWNER,
    RTAPI_ERROR_TOO_MANY_CONNECTIONS,
    RTAPI_ERROR_OUT_OF_ORDER,
    RTAPI_ERROR_CORRUPT_SEGMENT,
    RTAPI_ERROR_INTERNAL,
    RTAPI_ERROR_ALREADY_CONNECTED,
    RTAPI_ERROR_INVALID_ARGUMENT,
    RTAPI_ERROR_CONNECTION_LOST,
    RTAPI_ERROR_SYSTEM,
    RTAPI_ERROR_VERSION_MISMATCH,
    RTAPI_ERROR_REMOTE_NOT_SERVED,
    RTAPI_ERROR_NOT_TRUSTED,
];

/// The C name of a code (`None` for an unknown code).
pub fn name(code: RTAPIReturn_t) -> Option<&'static str> {
    describe(code).map(|(n, _)| n)
}

/// The static text of a code; unknown codes get a text saying so.
pub fn message(code: RTAPIReturn_t) -> &'static CStr {
    describe(code).map_or(c"unknown RTAPI return code", |(_, m)| m)
}

fn describe(code: RTAPIReturn_t) -> Option<(&'static str, &'static CStr)> {
    Some(match code {
        RTAPI_SUCCESS => ("RTAPI_SUCCESS", c"success"),
        RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED => (
            "RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED",
            c"subscribe failed: the framework has stopped (call RTDisconnect)",
        ),
        RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED => (
            "RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED",
            c"publish failed: the framework has stopped (call RTDisconnect)",
        ),
        RTAPI_ERROR_NULL_POINTER => ("RTAPI_ERROR_NULL_POINTER", c"a pointer argument is NULL"),
        RTAPI_ERROR_NOT_CONNECTED => ("RTAPI_ERROR_NOT_CONNECTED", c"the connection is not connected to a domain"),
        RTAPI_ERROR_UNKNOWN_CONNECTION_KEY => {
            ("RTAPI_ERROR_UNKNOWN_CONNECTION_KEY", c"unknown connection key (get one with RTNewConnectionKey)")
        }
        RTAPI_ERROR_UNKNOWN_ITEM => ("RTAPI_ERROR_UNKNOWN_ITEM", c"the domain has no such item in the set this call works on"),
        RTAPI_ERROR_WRONG_SIZE => ("RTAPI_ERROR_WRONG_SIZE", c"the size given differs from the item's size"),
        RTAPI_ERROR_TIMEOUT => ("RTAPI_ERROR_TIMEOUT", c"timed out waiting for the framework"),
        RTAPI_ERROR_DOMAIN_NOT_FOUND => {
            ("RTAPI_ERROR_DOMAIN_NOT_FOUND", c"domain not found: no running framework hosts it in this TUTTI_NAMESPACE")
        }
        RTAPI_ERROR_LAYOUT_MISMATCH => {
            ("RTAPI_ERROR_LAYOUT_MISMATCH", c"the DDF does not match the running domain (items, types, sizes or flags differ)")
        }
        RTAPI_ERROR_DDF_INVALID => ("RTAPI_ERROR_DDF_INVALID", c"the DDF cannot be read, is invalid, or does not describe the domain"),
        RTAPI_ERROR_NOT_OWNER => {
            ("RTAPI_ERROR_NOT_OWNER", c"the domain allows one writer at a time and another connection owns it")
        }
        RTAPI_ERROR_TOO_MANY_CONNECTIONS => ("RTAPI_ERROR_TOO_MANY_CONNECTIONS", c"every connection slot of the domain is in use"),
        RTAPI_ERROR_OUT_OF_ORDER => (
            "RTAPI_ERROR_OUT_OF_ORDER",
            c"call out of order (unlock without lock, lock taken twice, or publish/subscribe outside a lock pair in a synchronous domain)",
        ),
        RTAPI_ERROR_CORRUPT_SEGMENT => ("RTAPI_ERROR_CORRUPT_SEGMENT", c"the domain's shared-memory segment is corrupted"),
        RTAPI_ERROR_INTERNAL => ("RTAPI_ERROR_INTERNAL", c"internal error in the RTAPI library (a bug: please report it)"),
        RTAPI_ERROR_ALREADY_CONNECTED => ("RTAPI_ERROR_ALREADY_CONNECTED", c"the connection is already connected"),
        RTAPI_ERROR_INVALID_ARGUMENT => ("RTAPI_ERROR_INVALID_ARGUMENT", c"invalid argument"),
        RTAPI_ERROR_CONNECTION_LOST => {
            ("RTAPI_ERROR_CONNECTION_LOST", c"the framework removed this connection (call RTDisconnect)")
        }
        RTAPI_ERROR_SYSTEM => ("RTAPI_ERROR_SYSTEM", c"a system call failed (shared-memory segment)"),
        RTAPI_ERROR_VERSION_MISMATCH => {
            ("RTAPI_ERROR_VERSION_MISMATCH", c"the domain's segment was written by an incompatible library version")
        }
        RTAPI_ERROR_REMOTE_NOT_SERVED => (
            "RTAPI_ERROR_REMOTE_NOT_SERVED",
            c"the remote domain is not served on this machine: start `tutti gateway --mirror DDF` here",
        ),
        RTAPI_ERROR_NOT_TRUSTED => (
            "RTAPI_ERROR_NOT_TRUSTED",
            c"the domain's segment is a symbolic link or belongs to another user (see TUTTI_TRUST_UIDS)",
        ),
        _ => return None,
    })
}

/// Which side of the exchange a call is on: decides the code for "framework stopped".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Connect,
    Subscribe,
    Publish,
}

/// The code for a core error.
pub fn for_error(e: &ShmError, side: Side) -> RTAPIReturn_t {
    match e {
        ShmError::Io { .. } | ShmError::DomainBusy { .. } => RTAPI_ERROR_SYSTEM,
        ShmError::InvalidNamespace { .. } | ShmError::InvalidTiming { .. } => RTAPI_ERROR_INVALID_ARGUMENT,
        ShmError::NotTuttiSegment { .. } | ShmError::Corrupt { .. } | ShmError::Truncated { .. } => {
            RTAPI_ERROR_CORRUPT_SEGMENT
        }
        ShmError::Untrusted { .. } => RTAPI_ERROR_NOT_TRUSTED,
        ShmError::VersionMismatch { .. } => RTAPI_ERROR_VERSION_MISMATCH,
        ShmError::NotReady { .. } | ShmError::NoSuchDomain { .. } => RTAPI_ERROR_DOMAIN_NOT_FOUND,
        ShmError::LayoutMismatch { .. } => RTAPI_ERROR_LAYOUT_MISMATCH,
        ShmError::FrameworkStopped { .. } => match side {
            Side::Connect => RTAPI_ERROR_DOMAIN_NOT_FOUND,
            Side::Subscribe => RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED,
            Side::Publish => RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED,
        },
        ShmError::Timeout { .. } => RTAPI_ERROR_TIMEOUT,
        ShmError::TooManyConnections { .. } => RTAPI_ERROR_TOO_MANY_CONNECTIONS,
        ShmError::NotOwner { .. } => RTAPI_ERROR_NOT_OWNER,
        ShmError::SizeMismatch { .. } | ShmError::OutOfRange { .. } => RTAPI_ERROR_WRONG_SIZE,
        ShmError::UnknownItem { .. } => RTAPI_ERROR_UNKNOWN_ITEM,
        ShmError::ConnectionLost { .. } => RTAPI_ERROR_CONNECTION_LOST,
    }
}

/// Whether an error ends the connection (the vendor: "an error in publishing or subscribing
/// disconnects the client"): only when the other side is gone. Argument errors, timeouts and
/// ownership refusals leave the connection as it was.
pub fn disconnects(e: &ShmError) -> bool {
    matches!(e, ShmError::FrameworkStopped { .. } | ShmError::ConnectionLost { .. })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_dense_named_and_distinct() {
        for (i, &c) in ALL.iter().enumerate() {
            assert_eq!(c as usize, i);
            assert!(name(c).is_some_and(|n| n.starts_with("RTAPI_")));
            assert!(!message(c).to_bytes().is_empty());
        }
        let mut texts: Vec<_> = ALL.iter().map(|&c| message(c)).collect();
        texts.sort();
        texts.dedup();
        assert_eq!(texts.len(), ALL.len());
        assert_eq!(message(9999), c"unknown RTAPI return code");
        assert_eq!(message(-1), c"unknown RTAPI return code");
    }
}
