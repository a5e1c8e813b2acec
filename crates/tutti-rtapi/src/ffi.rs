//! The C boundary: every exported call runs its body through [`guard`], which catches
//! panics, and reads its pointer arguments through the helpers here, which check for NULL
//! before anything else.

use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use tutti_core::shm::ShmError;

use crate::codes::{
    self, RTAPIReturn_t, Side, RTAPI_ERROR_INTERNAL, RTAPI_ERROR_INVALID_ARGUMENT, RTAPI_ERROR_NULL_POINTER,
    RTAPI_SUCCESS,
};

/// Why a call failed: its code and a sentence with the details (domain, item, sizes).
#[derive(Debug)]
pub struct Failure {
    pub code: RTAPIReturn_t,
    pub detail: String,
}

impl Failure {
    pub fn new(code: RTAPIReturn_t, detail: impl Into<String>) -> Self {
        Failure { code, detail: detail.into() }
    }

    pub fn shm(e: &ShmError, side: Side) -> Self {
        Failure { code: codes::for_error(e, side), detail: e.to_string() }
    }
}

pub type CallResult<T = ()> = Result<T, Failure>;

thread_local! {
    /// The detail of this thread's last call if it failed, else empty (see
    /// `RTGetLastErrorDetail`): NUL-terminated bytes, emptied in place by a success so that
    /// a pointer handed out earlier stays valid and reads "".
    static LAST_DETAIL: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

/// Runs the body of an exported call: a panic becomes `RTAPI_ERROR_INTERNAL`, a failure its
/// code; the failure's detail is kept for `RTGetLastErrorDetail`.
pub fn guard(call: &str, body: impl FnOnce() -> CallResult) -> RTAPIReturn_t {
    let outcome = catch_unwind(AssertUnwindSafe(body)).unwrap_or_else(|panic| {
        let what = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        Err(Failure::new(RTAPI_ERROR_INTERNAL, format!("internal error: {what}")))
    });
    match outcome {
        Ok(()) => {
            clear_last_detail();
            RTAPI_SUCCESS
        }
        Err(f) => {
            set_last_detail(&format!("{call}: {}", f.detail));
            f.code
        }
    }
}

fn set_last_detail(text: &str) {
    let text = CString::new(text.replace('\0', " ")).unwrap_or_default().into_bytes_with_nul();
    // Ignore the error of a thread being torn down: the detail is only informative.
    let _ = LAST_DETAIL.try_with(|d| *d.borrow_mut() = text);
}

/// A successful call leaves no detail: the text becomes "" where it lies (no allocation).
fn clear_last_detail() {
    let _ = LAST_DETAIL.try_with(|d| {
        if let Some(first) = d.borrow_mut().first_mut() {
            *first = 0;
        }
    });
}

/// A pointer to this thread's last detail text ("" after a successful call), valid until
/// this thread's next failing call.
pub fn last_detail_ptr() -> *const c_char {
    LAST_DETAIL
        .try_with(|d| {
            let d = d.borrow();
            if d.is_empty() {
                c"".as_ptr()
            } else {
                d.as_ptr().cast()
            }
        })
        .unwrap_or(c"".as_ptr())
}

/// Fails with `RTAPI_ERROR_NULL_POINTER` if `p` is NULL; `what` names the argument.
pub fn non_null<T>(p: *const T, what: &str) -> CallResult<*const T> {
    if p.is_null() {
        Err(Failure::new(RTAPI_ERROR_NULL_POINTER, format!("argument '{what}' is NULL")))
    } else {
        Ok(p)
    }
}

/// Writes `value` to the out-parameter `p` after checking it.
///
/// # Safety
/// `p` must be NULL or valid for writing one `T` (it need not be aligned).
pub unsafe fn write_out<T>(p: *mut T, what: &str, value: T) -> CallResult {
    let p = non_null(p.cast_const(), what)?.cast_mut();
    // SAFETY: `p` is not NULL (checked) and the caller promises it is valid for writes of
    // one `T`; an unaligned write tolerates any alignment.
    unsafe { p.write_unaligned(value) };
    Ok(())
}

/// Reads a C string argument: NULL gives `RTAPI_ERROR_NULL_POINTER`, text that is not UTF-8
/// `RTAPI_ERROR_INVALID_ARGUMENT`.
///
/// # Safety
/// `p` must be NULL or point to a NUL-terminated string that stays unchanged during the call.
pub unsafe fn c_str<'a>(p: *const c_char, what: &str) -> CallResult<&'a str> {
    let p = non_null(p, what)?;
    // SAFETY: `p` is not NULL and, as the caller promises, NUL-terminated and unchanged for
    // the duration of the call (the returned borrow does not outlive the call).
    let s = unsafe { CStr::from_ptr(p) };
    s.to_str().map_err(|_| Failure::new(RTAPI_ERROR_INVALID_ARGUMENT, format!("argument '{what}' is not UTF-8 text")))
}

/// Reads `len` bytes at `p`.
///
/// # Safety
/// `p` must be NULL or valid for reading `len` bytes, unchanged during the call.
pub unsafe fn bytes_in<'a>(p: *const u8, len: usize, what: &str) -> CallResult<&'a [u8]> {
    let p = non_null(p, what)?;
    // SAFETY: `p` is not NULL and the caller promises `len` readable bytes; u8 needs no
    // alignment.
    Ok(unsafe { std::slice::from_raw_parts(p, len) })
}

/// The `len` bytes at `p`, for writing.
///
/// # Safety
/// `p` must be NULL or valid for writing `len` bytes, not aliased during the call.
pub unsafe fn bytes_out<'a>(p: *mut u8, len: usize, what: &str) -> CallResult<&'a mut [u8]> {
    let p = non_null(p.cast_const(), what)?.cast_mut();
    // SAFETY: `p` is not NULL and the caller promises `len` writable, unaliased bytes.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, len) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codes::RTAPI_ERROR_WRONG_SIZE;

    fn detail() -> String {
        // SAFETY: last_detail_ptr returns a valid NUL-terminated string.
        unsafe { CStr::from_ptr(last_detail_ptr()) }.to_string_lossy().into_owned()
    }

    #[test]
    fn a_panic_becomes_the_internal_error_code() {
        assert_eq!(guard("RTTest", || panic!("boom")), RTAPI_ERROR_INTERNAL);
        assert_eq!(detail(), "RTTest: internal error: boom");
        assert_eq!(guard("RTTest", || Err(Failure::new(RTAPI_ERROR_WRONG_SIZE, "sizes"))), RTAPI_ERROR_WRONG_SIZE);
        assert_eq!(detail(), "RTTest: sizes");
        assert_eq!(guard("RTTest", || Ok(())), RTAPI_SUCCESS);
    }

    #[test]
    fn null_pointers_are_refused_before_use() {
        // SAFETY: NULL is allowed by every helper's contract.
        unsafe {
            assert_eq!(write_out(std::ptr::null_mut::<u32>(), "p", 1).unwrap_err().code, RTAPI_ERROR_NULL_POINTER);
            assert_eq!(c_str(std::ptr::null(), "s").unwrap_err().code, RTAPI_ERROR_NULL_POINTER);
            assert_eq!(bytes_in(std::ptr::null(), 4, "b").unwrap_err().code, RTAPI_ERROR_NULL_POINTER);
            assert_eq!(bytes_out(std::ptr::null_mut(), 4, "b").unwrap_err().code, RTAPI_ERROR_NULL_POINTER);
        }
    }
}
