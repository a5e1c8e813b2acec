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

impl CallStatus {
    /// An FMI status number: OK (0) and Warning (1) are success; 2 Discard, 3 Error and 4
    /// Fatal mean the same in FMI 2.0 and 3.0; 5 Pending exists in FMI 2.0 only
    /// (`pending`), and is unknown from a 3.0 FMU.
    pub(crate) fn check(status: std::ffi::c_uint, pending: bool) -> Result<(), CallStatus> {
        match status {
            0 | 1 => Ok(()),
            2 => Err(CallStatus::Discard),
            3 => Err(CallStatus::Error),
            4 => Err(CallStatus::Fatal),
            5 if pending => Err(CallStatus::Pending),
            _ => Err(CallStatus::Unknown),
        }
    }
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

#[cfg(test)]
mod tests {
    use super::CallStatus;

    #[test]
    fn status_numbers_map_as_each_standard_defines_them() {
        assert_eq!(CallStatus::check(0, true), Ok(()));
        assert_eq!(CallStatus::check(1, false), Ok(()));
        assert_eq!(CallStatus::check(2, false), Err(CallStatus::Discard));
        assert_eq!(CallStatus::check(4, true), Err(CallStatus::Fatal));
        assert_eq!(CallStatus::check(5, true), Err(CallStatus::Pending), "FMI 2.0 has Pending");
        assert_eq!(CallStatus::check(5, false), Err(CallStatus::Unknown), "FMI 3.0 has none");
        assert_eq!(CallStatus::check(9, true), Err(CallStatus::Unknown));
    }
}
