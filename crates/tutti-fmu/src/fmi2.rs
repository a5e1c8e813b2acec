//! An FMI 2.0 co-simulation instance over the `fmi` crate's binding (`fmi-sys`), with tutti's
//! own callbacks: the crate's instance type logs through a callback that dereferences the
//! message category without a NULL check, and PythonFMU passes NULL when the Python model
//! raises, which crashed the process instead of reporting the FMU's failure. The logger here
//! is a C shim (src/fmi2_logger.c, for the printf-style arguments) calling
//! [`tutti_fmu_fmi2_log`], which takes NULLs.

use std::ffi::{c_char, c_uint, c_void, CString};

use fmi::fmi2::binding::{self, Fmi2Binding};

use crate::call::{text, CallStatus, FmuState, StateFunctions};
use crate::log_capture;

extern "C" {
    /// The C shim (src/fmi2_logger.c): formats and calls [`tutti_fmu_fmi2_log`].
    fn tutti_fmu_fmi2_logger(
        env: binding::fmi2ComponentEnvironment,
        instance: binding::fmi2String,
        status: binding::fmi2Status,
        category: binding::fmi2String,
        message: binding::fmi2String,
        ...
    );
}

/// Receives every message an FMI 2.0 FMU logs (through the C shim).
///
/// # Safety
/// Called by the shim with strings that are NULL or NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn tutti_fmu_fmi2_log(
    _env: *mut c_void,
    instance: *const c_char,
    status: c_uint,
    category: *const c_char,
    message: *const c_char,
) {
    let level = match status {
        0 => "INFO",
        1 => "WARN",
        2 => "DISCARD",
        3 => "ERROR",
        4 => "FATAL",
        _ => "PENDING",
    };
    // SAFETY: the shim passes the FMU's strings (NULL or NUL-terminated) and its own buffer.
    let (instance, category, message) = unsafe { (text(instance), text(category), text(message)) };
    let category = if category.is_empty() { String::new() } else { format!(" ({category})") };
    log_capture::record(format!("[{level}] {instance}{category}: {message}"));
}

fn check(status: binding::fmi2Status) -> Result<(), CallStatus> {
    CallStatus::check(status, true)
}

/// One FMI 2.0 co-simulation instance. Freed on drop.
pub struct Fmi2Cs {
    /// Dropped with the instance, unless the FMU reported Fatal (see `Drop`).
    binding: std::mem::ManuallyDrop<Fmi2Binding>,
    /// The FMU reported Fatal: no further call is allowed, not even freeing the instance.
    fatal: bool,
    component: binding::fmi2Component,
    /// The FMU may keep a pointer to these for the life of the instance.
    _callbacks: Box<binding::fmi2CallbackFunctions>,
}

impl std::fmt::Debug for Fmi2Cs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fmi2Cs").field("component", &self.component).finish()
    }
}

impl Fmi2Cs {
    /// The result of a call, remembering a Fatal status.
    fn note(&mut self, status: binding::fmi2Status) -> Result<(), CallStatus> {
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

    /// `fmi2Instantiate` for co-simulation; `None` when the FMU refuses (see the log).
    pub fn instantiate(binding: Fmi2Binding, instance_name: &str, guid: &str, resource_url: &str) -> Option<Fmi2Cs> {
        let callbacks = Box::new(binding::fmi2CallbackFunctions {
            logger: Some(tutti_fmu_fmi2_logger),
            allocateMemory: Some(calloc),
            freeMemory: Some(free),
            stepFinished: None,
            componentEnvironment: std::ptr::null_mut(),
        });
        // Interior NULs cannot come from XML attributes; refuse rather than truncate.
        let (name, guid, url) =
            (CString::new(instance_name).ok()?, CString::new(guid).ok()?, CString::new(resource_url).ok()?);
        // SAFETY: every pointer is valid for the call; the callbacks outlive the instance (they
        // are kept in it and the instance is freed before them, in `drop`).
        let component = unsafe {
            binding.fmi2Instantiate(
                name.as_ptr(),
                binding::fmi2Type_fmi2CoSimulation,
                guid.as_ptr(),
                url.as_ptr(),
                &*callbacks,
                0,
                1,
            )
        };
        (!component.is_null()).then(|| Fmi2Cs {
            binding: std::mem::ManuallyDrop::new(binding),
            fatal: false,
            component,
            _callbacks: callbacks,
        })
    }

    pub fn setup_experiment(&mut self, start: f64) -> Result<(), CallStatus> {
        // SAFETY: a live component of this binding.
        self.note(unsafe { self.binding.fmi2SetupExperiment(self.component, 0, 0.0, start, 0, 0.0) })
    }

    pub fn enter_initialization_mode(&mut self) -> Result<(), CallStatus> {
        // SAFETY: a live component of this binding.
        self.note(unsafe { self.binding.fmi2EnterInitializationMode(self.component) })
    }

    pub fn exit_initialization_mode(&mut self) -> Result<(), CallStatus> {
        // SAFETY: a live component of this binding.
        self.note(unsafe { self.binding.fmi2ExitInitializationMode(self.component) })
    }

    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), CallStatus> {
        // SAFETY: a live component of this binding.
        self.note(unsafe { self.binding.fmi2DoStep(self.component, t, h, 1) })
    }

    pub fn terminate(&mut self) -> Result<(), CallStatus> {
        self.live()?;
        // SAFETY: a live component of this binding.
        self.note(unsafe { self.binding.fmi2Terminate(self.component) })
    }

    pub fn get_real(&mut self, vr: u32) -> Result<f64, CallStatus> {
        let mut v = 0.0;
        // SAFETY: one value reference, one value, both valid for the call.
        self.note(unsafe { self.binding.fmi2GetReal(self.component, &vr, 1, &mut v) }).map(|()| v)
    }

    pub fn get_integer(&mut self, vr: u32) -> Result<i32, CallStatus> {
        let mut v = 0;
        // SAFETY: one value reference, one value, both valid for the call.
        self.note(unsafe { self.binding.fmi2GetInteger(self.component, &vr, 1, &mut v) }).map(|()| v)
    }

    pub fn get_boolean(&mut self, vr: u32) -> Result<bool, CallStatus> {
        let mut v = 0;
        // SAFETY: one value reference, one value, both valid for the call.
        self.note(unsafe { self.binding.fmi2GetBoolean(self.component, &vr, 1, &mut v) }).map(|()| v != 0)
    }

    pub fn set_real(&mut self, vr: u32, v: f64) -> Result<(), CallStatus> {
        // SAFETY: one value reference, one value, both valid for the call.
        self.note(unsafe { self.binding.fmi2SetReal(self.component, &vr, 1, &v) })
    }

    pub fn set_integer(&mut self, vr: u32, v: i32) -> Result<(), CallStatus> {
        // SAFETY: one value reference, one value, both valid for the call.
        self.note(unsafe { self.binding.fmi2SetInteger(self.component, &vr, 1, &v) })
    }

    pub fn set_boolean(&mut self, vr: u32, v: bool) -> Result<(), CallStatus> {
        let v = i32::from(v);
        // SAFETY: one value reference, one value, both valid for the call.
        self.note(unsafe { self.binding.fmi2SetBoolean(self.component, &vr, 1, &v) })
    }
}

/// The FMU-state functions, made only when the FMU declares `canGetAndSetFMUstate` and
/// `canSerializeFMUstate`: `Fmu::instantiate` then checked that the library exports them, so
/// the binding has each (it panics on a function it did not find).
impl StateFunctions for Fmi2Cs {
    fn get_state(&mut self) -> Result<FmuState, CallStatus> {
        self.live()?;
        let mut state: FmuState = std::ptr::null_mut();
        // SAFETY: a live component; a NULL state asks the FMU for a new one.
        self.note(unsafe { self.binding.fmi2GetFMUstate(self.component, &mut state) }).map(|()| state)
    }

    fn deserialize_state(&mut self, bytes: &[u8]) -> Result<FmuState, CallStatus> {
        self.live()?;
        let mut state: FmuState = std::ptr::null_mut();
        // SAFETY: a live component; `bytes` is valid for its length; a NULL state asks the FMU
        // for a new one.
        let status = unsafe {
            self.binding.fmi2DeSerializeFMUstate(self.component, bytes.as_ptr().cast(), bytes.len(), &mut state)
        };
        self.note(status).map(|()| state)
    }

    unsafe fn set_state(&mut self, state: FmuState) -> Result<(), CallStatus> {
        self.live()?;
        // SAFETY: a live component and a state of it (the caller's contract).
        self.note(unsafe { self.binding.fmi2SetFMUstate(self.component, state) })
    }

    unsafe fn free_state(&mut self, mut state: FmuState) -> Result<(), CallStatus> {
        self.live()?;
        // SAFETY: a live component and a state of it, not used after (the caller's contract).
        self.note(unsafe { self.binding.fmi2FreeFMUstate(self.component, &mut state) })
    }

    unsafe fn serialized_size(&mut self, state: FmuState) -> Result<usize, CallStatus> {
        self.live()?;
        let mut size = 0;
        // SAFETY: a live component and a state of it (the caller's contract).
        self.note(unsafe { self.binding.fmi2SerializedFMUstateSize(self.component, state, &mut size) }).map(|()| size)
    }

    unsafe fn serialize_state(&mut self, state: FmuState, out: &mut [u8]) -> Result<(), CallStatus> {
        self.live()?;
        // SAFETY: a live component and a state of it (the caller's contract); `out` is valid
        // for its length.
        let status =
            unsafe { self.binding.fmi2SerializeFMUstate(self.component, state, out.as_mut_ptr().cast(), out.len()) };
        self.note(status)
    }
}

impl Drop for Fmi2Cs {
    fn drop(&mut self) {
        // After Fatal the FMU allows no call, and freeing (or unloading) a broken one can
        // crash the process (PythonFMU does): the instance and the library are leaked.
        if self.fatal {
            return;
        }
        // SAFETY: the component is live and freed exactly once, here.
        unsafe { self.binding.fmi2FreeInstance(self.component) };
        // SAFETY: dropped once, here, and not used after.
        unsafe { std::mem::ManuallyDrop::drop(&mut self.binding) };
    }
}

/// FMI 2.0's memory callbacks: the C allocator.
unsafe extern "C" fn calloc(n: usize, size: usize) -> *mut c_void {
    // SAFETY: the C allocator, called as the FMU asks.
    unsafe { libc_calloc(n, size) }
}

unsafe extern "C" fn free(p: *mut c_void) {
    // SAFETY: `p` was allocated by `calloc` above (the FMU's contract).
    unsafe { libc_free(p) }
}

extern "C" {
    #[link_name = "calloc"]
    fn libc_calloc(n: usize, size: usize) -> *mut c_void;
    #[link_name = "free"]
    fn libc_free(p: *mut c_void);
}
