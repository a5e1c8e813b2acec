//! `RTSetStateCallbacks`: a C component's state, handed over and taken back as bytes at a
//! checkpoint (docs/rtapi.md, "Checkpoints").

use std::ffi::{c_int, c_uint, c_void};

use tutti_core::shm::{StateError, StateHandler};

/// Hands the component's state over: sets `*buffer` to bytes it owns (valid until the call
/// after this one into the component) and `*sizeBytes` to their length; returns 0, or
/// anything else when it cannot.
#[allow(non_camel_case_types)]
pub type RTSaveStateCallback_t =
    Option<unsafe extern "C" fn(context: *mut c_void, buffer: *mut *const c_void, sizeBytes: *mut c_uint) -> c_int>;

/// Takes back a state that the save callback handed over; returns 0, or anything else when
/// it cannot.
#[allow(non_camel_case_types)]
pub type RTRestoreStateCallback_t =
    Option<unsafe extern "C" fn(context: *mut c_void, buffer: *const c_void, sizeBytes: c_uint) -> c_int>;

/// A component's two callbacks and its context pointer.
#[derive(Debug, Clone, Copy)]
pub struct Callbacks {
    pub save: unsafe extern "C" fn(*mut c_void, *mut *const c_void, *mut c_uint) -> c_int,
    pub restore: unsafe extern "C" fn(*mut c_void, *const c_void, c_uint) -> c_int,
    pub context: *mut c_void,
}

// SAFETY: the context is the component's, handed back to its own callbacks only; the
// component promises (docs/rtapi.md) that they may be called from the thread that waits for
// the framework, which is what RTSetStateCallbacks asks of them.
unsafe impl Send for Callbacks {}

impl StateHandler for Callbacks {
    fn save(&mut self) -> Result<Vec<u8>, StateError> {
        let mut buffer: *const c_void = std::ptr::null();
        let mut size: c_uint = 0;
        // SAFETY: the component's own function, with its context and two out-pointers to
        // locals that live across the call.
        let rc = unsafe { (self.save)(self.context, &mut buffer, &mut size) };
        if rc != 0 {
            return Err(StateError::from(format!("its save callback returned {rc}")));
        }
        if size == 0 {
            return Ok(Vec::new());
        }
        if buffer.is_null() {
            return Err(StateError::from(format!("its save callback gave {size} bytes at NULL")));
        }
        // SAFETY: the callback promised `size` readable bytes at `buffer`, valid until the
        // next call into the component; they are copied now.
        Ok(unsafe { std::slice::from_raw_parts(buffer.cast::<u8>(), size as usize) }.to_vec())
    }

    fn restore(&mut self, state: &[u8]) -> Result<(), StateError> {
        let size = c_uint::try_from(state.len())
            .map_err(|_| StateError::from(format!("a state of {} bytes is too large", state.len())))?;
        // SAFETY: the component's own function, with its context and a buffer of `size`
        // bytes that outlives the call.
        let rc = unsafe { (self.restore)(self.context, state.as_ptr().cast(), size) };
        match rc {
            0 => Ok(()),
            rc => Err(StateError::from(format!("its restore callback returned {rc}"))),
        }
    }
}
