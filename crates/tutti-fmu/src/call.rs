//! What the FMI 2.0 and 3.0 callers share: the status of a call that did not succeed, the
//! C strings an FMU hands over, and saving and restoring an FMU's state (the same six
//! functions in both standards).

use std::ffi::{c_char, c_void, CStr};

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
    /// The FMU does not declare the capability the call needs (in its modelDescription.xml),
    /// so it was not made.
    #[error("not supported")]
    Unsupported,
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

/// An FMU state (FMI 2.0 `fmi2FMUstate`, FMI 3.0 `fmi3FMUState`): the FMU's own copy of its
/// state, opaque to the importer.
pub(crate) type FmuState = *mut c_void;

/// One of the FMU-state functions, in the order of [`FMI2_STATE_FUNCTIONS`] and
/// [`FMI3_STATE_FUNCTIONS`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum StateCall {
    Get,
    Set,
    Free,
    Size,
    Serialize,
    Deserialize,
}

/// FMI 2.0's FMU-state functions: the first three need `canGetAndSetFMUstate`, the last three
/// `canSerializeFMUstate`.
pub(crate) const FMI2_STATE_FUNCTIONS: [&str; 6] = [
    "fmi2GetFMUstate",
    "fmi2SetFMUstate",
    "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize",
    "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate",
];

/// FMI 3.0's FMU-state functions: the first three need `canGetAndSetFMUState`, the last three
/// `canSerializeFMUState`.
pub(crate) const FMI3_STATE_FUNCTIONS: [&str; 6] = [
    "fmi3GetFMUState",
    "fmi3SetFMUState",
    "fmi3FreeFMUState",
    "fmi3SerializedFMUStateSize",
    "fmi3SerializeFMUState",
    "fmi3DeserializeFMUState",
];

/// The FMU-state functions of one instance, which FMI 2.0 and 3.0 define alike. Each is made
/// only when the FMU declares the capability (the library was checked to export it then),
/// and none after the FMU reported Fatal.
pub(crate) trait StateFunctions {
    /// A new copy of the FMU's state (`getFMUState` with a NULL state: the FMU allocates).
    fn get_state(&mut self) -> Result<FmuState, CallStatus>;

    /// A new FMU state made from `bytes` (`deserializeFMUState`; the FMU allocates).
    fn deserialize_state(&mut self, bytes: &[u8]) -> Result<FmuState, CallStatus>;

    /// Makes `state` the FMU's state (`setFMUState`).
    ///
    /// # Safety
    /// `state` was given by this instance ([`get_state`](Self::get_state) or
    /// [`deserialize_state`](Self::deserialize_state)) and not freed.
    unsafe fn set_state(&mut self, state: FmuState) -> Result<(), CallStatus>;

    /// Frees `state` (`freeFMUState`).
    ///
    /// # Safety
    /// As for [`set_state`](Self::set_state); `state` is not used after.
    unsafe fn free_state(&mut self, state: FmuState) -> Result<(), CallStatus>;

    /// The size of `state` serialized (`serializedFMUStateSize`).
    ///
    /// # Safety
    /// As for [`set_state`](Self::set_state).
    unsafe fn serialized_size(&mut self, state: FmuState) -> Result<usize, CallStatus>;

    /// Serializes `state` into `out`, of the size [`serialized_size`](Self::serialized_size)
    /// said (`serializeFMUState`).
    ///
    /// # Safety
    /// As for [`set_state`](Self::set_state).
    unsafe fn serialize_state(&mut self, state: FmuState, out: &mut [u8]) -> Result<(), CallStatus>;
}

/// The FMU-state call that failed, and how.
pub(crate) type StateFailure = (StateCall, CallStatus);

/// The FMU's state as bytes: get a copy, serialize it, free it (also when serializing fails).
pub(crate) fn save_state(f: &mut impl StateFunctions) -> Result<Vec<u8>, StateFailure> {
    let state = f.get_state().map_err(|e| (StateCall::Get, e))?;
    // SAFETY: `state` was just given by this instance and is freed only below.
    let bytes = unsafe { serialize(f, state) };
    // SAFETY: the same state, freed once, here, and not used after.
    let freed = unsafe { f.free_state(state) }.map_err(|e| (StateCall::Free, e));
    let bytes = bytes?;
    freed.map(|()| bytes)
}

/// # Safety
/// `state` was given by this instance and not freed.
unsafe fn serialize(f: &mut impl StateFunctions, state: FmuState) -> Result<Vec<u8>, StateFailure> {
    // SAFETY: per this function's contract.
    let size = unsafe { f.serialized_size(state) }.map_err(|e| (StateCall::Size, e))?;
    let mut bytes = vec![0u8; size];
    // SAFETY: per this function's contract; `bytes` has the size the FMU asked for.
    unsafe { f.serialize_state(state, &mut bytes) }.map_err(|e| (StateCall::Serialize, e))?;
    Ok(bytes)
}

/// Takes back a state that [`save_state`] gave: deserialize it, set it, free it (also when
/// setting fails).
pub(crate) fn restore_state(f: &mut impl StateFunctions, bytes: &[u8]) -> Result<(), StateFailure> {
    let state = f.deserialize_state(bytes).map_err(|e| (StateCall::Deserialize, e))?;
    // SAFETY: `state` was just given by this instance and is freed only below.
    let set = unsafe { f.set_state(state) }.map_err(|e| (StateCall::Set, e));
    // SAFETY: the same state, freed once, here, and not used after.
    let freed = unsafe { f.free_state(state) }.map_err(|e| (StateCall::Free, e));
    set.and(freed)
}

#[cfg(test)]
mod tests {
    use super::{restore_state, save_state, CallStatus, FmuState, StateCall, StateFunctions};

    /// An instance whose state is a number behind a pointer, failing `fail` with `status`.
    struct Fake {
        value: u8,
        fail: Option<(StateCall, CallStatus)>,
        fatal: bool,
        live_states: i32,
    }

    impl Fake {
        fn call(&mut self, call: StateCall) -> Result<(), CallStatus> {
            if self.fatal {
                return Err(CallStatus::Fatal);
            }
            match self.fail {
                Some((c, status)) if c == call => {
                    self.fatal = status == CallStatus::Fatal;
                    Err(status)
                }
                _ => Ok(()),
            }
        }

        fn new_state(&mut self, value: u8) -> FmuState {
            self.live_states += 1;
            Box::into_raw(Box::new(value)).cast()
        }
    }

    impl StateFunctions for Fake {
        fn get_state(&mut self) -> Result<FmuState, CallStatus> {
            self.call(StateCall::Get)?;
            Ok(self.new_state(self.value))
        }

        fn deserialize_state(&mut self, bytes: &[u8]) -> Result<FmuState, CallStatus> {
            self.call(StateCall::Deserialize)?;
            Ok(self.new_state(bytes[0]))
        }

        unsafe fn set_state(&mut self, state: FmuState) -> Result<(), CallStatus> {
            self.call(StateCall::Set)?;
            // SAFETY: a state of `new_state`, live (the caller's contract).
            self.value = unsafe { *state.cast::<u8>() };
            Ok(())
        }

        unsafe fn free_state(&mut self, state: FmuState) -> Result<(), CallStatus> {
            self.call(StateCall::Free)?;
            self.live_states -= 1;
            // SAFETY: a state of `new_state`, freed once (the caller's contract).
            drop(unsafe { Box::from_raw(state.cast::<u8>()) });
            Ok(())
        }

        unsafe fn serialized_size(&mut self, _: FmuState) -> Result<usize, CallStatus> {
            self.call(StateCall::Size).map(|()| 1)
        }

        unsafe fn serialize_state(&mut self, state: FmuState, out: &mut [u8]) -> Result<(), CallStatus> {
            self.call(StateCall::Serialize)?;
            // SAFETY: a state of `new_state`, live (the caller's contract).
            out[0] = unsafe { *state.cast::<u8>() };
            Ok(())
        }
    }

    fn fake(value: u8, fail: Option<(StateCall, CallStatus)>) -> Fake {
        Fake { value, fail, fatal: false, live_states: 0 }
    }

    #[test]
    fn a_state_saves_restores_and_is_freed_whatever_fails() {
        let mut f = fake(42, None);
        let bytes = save_state(&mut f).unwrap();
        assert_eq!(bytes, [42]);
        f.value = 1;
        restore_state(&mut f, &bytes).unwrap();
        assert_eq!((f.value, f.live_states), (42, 0));
        // A failure after the state was made still frees it, and is the error reported.
        let mut f = fake(1, Some((StateCall::Serialize, CallStatus::Error)));
        assert_eq!(save_state(&mut f), Err((StateCall::Serialize, CallStatus::Error)));
        assert_eq!(f.live_states, 0);
        let mut f = fake(1, Some((StateCall::Set, CallStatus::Discard)));
        assert_eq!(restore_state(&mut f, &[2]), Err((StateCall::Set, CallStatus::Discard)));
        assert_eq!((f.value, f.live_states), (1, 0));
        let mut f = fake(1, Some((StateCall::Free, CallStatus::Error)));
        assert_eq!(save_state(&mut f), Err((StateCall::Free, CallStatus::Error)));
        // After Fatal no call is made, not even the free (the state is leaked).
        let mut f = fake(1, Some((StateCall::Size, CallStatus::Fatal)));
        assert_eq!(save_state(&mut f), Err((StateCall::Size, CallStatus::Fatal)));
        assert_eq!(f.live_states, 1);
        let mut f = fake(1, Some((StateCall::Get, CallStatus::Error)));
        assert_eq!(save_state(&mut f), Err((StateCall::Get, CallStatus::Error)));
        assert_eq!(f.live_states, 0);
    }

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
