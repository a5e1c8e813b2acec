//! An FMI 3.0 co-simulation instance over the `fmi` crate's binding (`fmi-sys`), with tutti's
//! own logger callback, which accepts NULL strings, as for FMI 2.0 (src/fmi2.rs). Event mode,
//! early return and intermediate updates are not used.

use std::ffi::{c_char, c_uint, c_void, CString};

use fmi::fmi3::binding::{self, Fmi3Binding};

use crate::call::{CallStatus, FmuState, StateFunctions};
use crate::log_capture;

/// Receives every message an FMI 3.0 FMU logs; the environment is the instance's name.
///
/// # Safety
/// `env` is the `CString` an [`Fmi3Cs`] passed at instantiation (alive as long as it);
/// `category` and `message` are NULL or NUL-terminated.
unsafe extern "C" fn log_message(env: *mut c_void, status: c_uint, category: *const c_char, message: *const c_char) {
    let level = match status {
        0 => "INFO",
        1 => "WARN",
        2 => "DISCARD",
        3 => "ERROR",
        _ => "FATAL",
    };
    // SAFETY: per this function's contract.
    let (name, category, message) =
        unsafe { (crate::call::text(env as *const c_char), crate::call::text(category), crate::call::text(message)) };
    let category = if category.is_empty() { String::new() } else { format!(" ({category})") };
    log_capture::record(format!("[{level}] {name}{category}: {message}"));
}

fn check(status: binding::fmi3Status) -> Result<(), CallStatus> {
    CallStatus::check(status, false)
}

/// One FMI 3.0 co-simulation instance. Freed on drop.
pub struct Fmi3Cs {
    /// Dropped with the instance, unless the FMU reported Fatal (see `Drop`).
    binding: std::mem::ManuallyDrop<Fmi3Binding>,
    /// The FMU reported Fatal: no further call is allowed, not even freeing the instance.
    fatal: bool,
    instance: binding::fmi3Instance,
    /// The logger's environment: must outlive the instance.
    _name: Box<CString>,
}

impl std::fmt::Debug for Fmi3Cs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fmi3Cs").field("instance", &self.instance).field("name", &self._name).finish()
    }
}

macro_rules! get_set {
    ($get:ident, $set:ident, $fget:ident, $fset:ident, $t:ty, $zero:expr) => {
        pub fn $get(&mut self, vr: u32) -> Result<$t, CallStatus> {
            let mut v: $t = $zero;
            // SAFETY: one value reference and one value, both valid for the call.
            self.note(unsafe { self.binding.$fget(self.instance, &vr, 1, &mut v, 1) }).map(|()| v)
        }

        pub fn $set(&mut self, vr: u32, v: $t) -> Result<(), CallStatus> {
            // SAFETY: one value reference and one value, both valid for the call.
            self.note(unsafe { self.binding.$fset(self.instance, &vr, 1, &v, 1) })
        }
    };
}

impl Fmi3Cs {
    /// The result of a call, remembering a Fatal status.
    fn note(&mut self, status: binding::fmi3Status) -> Result<(), CallStatus> {
        let r = check(status);
        if r == Err(CallStatus::Fatal) {
            self.fatal = true;
        }
        r
    }

    /// No call after Fatal (the standard allows none).
    fn live(&self) -> Result<(), CallStatus> {
        if self.fatal {
            Err(CallStatus::Fatal)
        } else {
            Ok(())
        }
    }

    /// `fmi3InstantiateCoSimulation`; `None` when the FMU refuses (see the log).
    pub fn instantiate(binding: Fmi3Binding, instance_name: &str, token: &str, resources: &str) -> Option<Fmi3Cs> {
        let name = Box::new(CString::new(instance_name).ok()?);
        let (token, resources) = (CString::new(token).ok()?, CString::new(resources).ok()?);
        // SAFETY: every pointer is valid for the call; the logger's environment (`name`) is
        // kept in the instance, which is freed (in `drop`) before it.
        let instance = unsafe {
            binding.fmi3InstantiateCoSimulation(
                name.as_ptr(),
                token.as_ptr(),
                resources.as_ptr(),
                false,
                true,
                false,
                false,
                std::ptr::null(),
                0,
                name.as_ptr() as *mut c_void,
                Some(log_message),
                None,
            )
        };
        (!instance.is_null()).then(|| Fmi3Cs {
            binding: std::mem::ManuallyDrop::new(binding),
            fatal: false,
            instance,
            _name: name,
        })
    }

    pub fn enter_initialization_mode(&mut self, start: f64) -> Result<(), CallStatus> {
        // SAFETY: a live instance of this binding.
        self.note(unsafe { self.binding.fmi3EnterInitializationMode(self.instance, false, 0.0, start, false, 0.0) })
    }

    pub fn exit_initialization_mode(&mut self) -> Result<(), CallStatus> {
        // SAFETY: a live instance of this binding.
        self.note(unsafe { self.binding.fmi3ExitInitializationMode(self.instance) })
    }

    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), CallStatus> {
        let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
        // SAFETY: a live instance; the out-parameters are valid for the call.
        self.note(unsafe {
            self.binding.fmi3DoStep(self.instance, t, h, true, &mut event, &mut terminate, &mut early, &mut last)
        })
    }

    pub fn terminate(&mut self) -> Result<(), CallStatus> {
        self.live()?;
        // SAFETY: a live instance of this binding.
        self.note(unsafe { self.binding.fmi3Terminate(self.instance) })
    }

    get_set!(get_float64, set_float64, fmi3GetFloat64, fmi3SetFloat64, f64, 0.0);
    get_set!(get_float32, set_float32, fmi3GetFloat32, fmi3SetFloat32, f32, 0.0);
    get_set!(get_int8, set_int8, fmi3GetInt8, fmi3SetInt8, i8, 0);
    get_set!(get_int16, set_int16, fmi3GetInt16, fmi3SetInt16, i16, 0);
    get_set!(get_int32, set_int32, fmi3GetInt32, fmi3SetInt32, i32, 0);
    get_set!(get_int64, set_int64, fmi3GetInt64, fmi3SetInt64, i64, 0);
    get_set!(get_uint8, set_uint8, fmi3GetUInt8, fmi3SetUInt8, u8, 0);
    get_set!(get_uint16, set_uint16, fmi3GetUInt16, fmi3SetUInt16, u16, 0);
    get_set!(get_uint32, set_uint32, fmi3GetUInt32, fmi3SetUInt32, u32, 0);
    get_set!(get_uint64, set_uint64, fmi3GetUInt64, fmi3SetUInt64, u64, 0);
    get_set!(get_boolean, set_boolean, fmi3GetBoolean, fmi3SetBoolean, bool, false);
}

/// The FMU-state functions, made only when the FMU declares `canGetAndSetFMUState` and
/// `canSerializeFMUState`: `Fmu::instantiate` then checked that the library exports them, so
/// the binding has each (it panics on a function it did not find).
impl StateFunctions for Fmi3Cs {
    fn get_state(&mut self) -> Result<FmuState, CallStatus> {
        self.live()?;
        let mut state: FmuState = std::ptr::null_mut();
        // SAFETY: a live instance; a NULL state asks the FMU for a new one.
        self.note(unsafe { self.binding.fmi3GetFMUState(self.instance, &mut state) }).map(|()| state)
    }

    fn deserialize_state(&mut self, bytes: &[u8]) -> Result<FmuState, CallStatus> {
        self.live()?;
        let mut state: FmuState = std::ptr::null_mut();
        // SAFETY: a live instance; `bytes` is valid for its length; a NULL state asks the FMU
        // for a new one.
        let status =
            unsafe { self.binding.fmi3DeserializeFMUState(self.instance, bytes.as_ptr(), bytes.len(), &mut state) };
        self.note(status).map(|()| state)
    }

    unsafe fn set_state(&mut self, state: FmuState) -> Result<(), CallStatus> {
        self.live()?;
        // SAFETY: a live instance and a state of it (the caller's contract).
        self.note(unsafe { self.binding.fmi3SetFMUState(self.instance, state) })
    }

    unsafe fn free_state(&mut self, mut state: FmuState) -> Result<(), CallStatus> {
        self.live()?;
        // SAFETY: a live instance and a state of it, not used after (the caller's contract).
        self.note(unsafe { self.binding.fmi3FreeFMUState(self.instance, &mut state) })
    }

    unsafe fn serialized_size(&mut self, state: FmuState) -> Result<usize, CallStatus> {
        self.live()?;
        let mut size = 0;
        // SAFETY: a live instance and a state of it (the caller's contract).
        self.note(unsafe { self.binding.fmi3SerializedFMUStateSize(self.instance, state, &mut size) }).map(|()| size)
    }

    unsafe fn serialize_state(&mut self, state: FmuState, out: &mut [u8]) -> Result<(), CallStatus> {
        self.live()?;
        // SAFETY: a live instance and a state of it (the caller's contract); `out` is valid
        // for its length.
        let status = unsafe { self.binding.fmi3SerializeFMUState(self.instance, state, out.as_mut_ptr(), out.len()) };
        self.note(status)
    }
}

impl Drop for Fmi3Cs {
    fn drop(&mut self) {
        // After Fatal the FMU allows no call, and freeing (or unloading) a broken one can
        // crash the process: the instance and the library are leaked.
        if self.fatal {
            return;
        }
        // SAFETY: the instance is live and freed exactly once, here.
        unsafe { self.binding.fmi3FreeInstance(self.instance) };
        // SAFETY: dropped once, here, and not used after.
        unsafe { std::mem::ManuallyDrop::drop(&mut self.binding) };
    }
}
