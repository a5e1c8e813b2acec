//! What the FMI 2.0 and 3.0 callers share: the status of a call that did not succeed, and
//! the C strings an FMU hands over.

use std::ffi::{c_char, CStr};

/// What an FMI call returned when it is neither OK nor Warning, or why it was not made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CallStatus {
    #[error("Discard")]
    Discard,
    #[error("Error")]
    Error,
    /// After Fatal the FMU allows no further call.
    #[error("Fatal")]
    Fatal,
    #[error("Pending")]
    Pending,
    /// A status number the standard does not define.
    #[error("unknown")]
    Unknown,
    /// A variable of a type tutti does not exchange with this FMI version.
    #[error("not exchanged")]
    NotExchanged,
}

/// A C string that may be NULL or not UTF-8.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string valid for this call.
pub(crate) unsafe fn text(p: *const c_char) -> String {
    if p.is_null() {
        return String::new();
    }
    // SAFETY: not NULL, and NUL-terminated by the caller's contract.
    unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
}
