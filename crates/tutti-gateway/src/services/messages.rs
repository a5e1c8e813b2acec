//! The `simulation_interfaces` 1.x types the gateway serves (docs/ros2.md), as plain CDR
//! bodies: their constants, the requests decoded and the responses encoded. In
//! rmw_cyclonedds's form a body starts with the 16-byte request header (`wire`), and alignment
//! is counted from the start of the body, header included; in Fast DDS's form there is no
//! header, and since 16 is a multiple of every alignment each field keeps its alignment.

use tutti_core::cdr::CdrError;

/// `simulation_interfaces/msg/Result` codes.
pub mod result {
    pub const FEATURE_UNSUPPORTED: u8 = 0;
    pub const OK: u8 = 1;
    pub const NOT_FOUND: u8 = 2;
    pub const INCORRECT_STATE: u8 = 3;
    pub const OPERATION_FAILED: u8 = 4;
    /// `SetSimulationState`'s own codes.
    pub const ALREADY_IN_TARGET_STATE: u8 = 101;
    pub const STATE_TRANSITION_ERROR: u8 = 102;
    pub const INCORRECT_TRANSITION: u8 = 103;
}

/// `simulation_interfaces/msg/SimulationState` values.
pub mod state {
    pub const STOPPED: u8 = 0;
    pub const PLAYING: u8 = 1;
    pub const PAUSED: u8 = 2;
    pub const QUITTING: u8 = 3;
    pub const NO_WORLD: u8 = 4;
    pub const LOADING_WORLD: u8 = 5;
}

/// `simulation_interfaces/msg/SimulatorFeatures` values (those tutti names).
pub mod feature {
    pub const SIMULATION_RESET: u16 = 20;
    pub const SIMULATION_RESET_TIME: u16 = 21;
    pub const SIMULATION_STATE_GETTING: u16 = 24;
    pub const SIMULATION_STATE_SETTING: u16 = 25;
    pub const SIMULATION_STATE_PAUSE: u16 = 26;
    pub const STEP_SIMULATION_SINGLE: u16 = 31;
    pub const STEP_SIMULATION_MULTIPLE: u16 = 32;
    pub const STEP_SIMULATION_ACTION: u16 = 33;
}

/// `simulation_interfaces/srv/ResetSimulation` scopes.
pub mod scope {
    pub const DEFAULT: u8 = 0;
    pub const TIME: u8 = 1;
    pub const STATE: u8 = 2;
    pub const SPAWNED: u8 = 4;
    pub const ALL: u8 = 255;
}

/// A `simulation_interfaces/msg/Result`: a code of [`result`] and a message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outcome {
    pub code: u8,
    pub message: String,
}

impl Outcome {
    pub fn ok() -> Outcome {
        Outcome { code: result::OK, message: String::new() }
    }

    pub fn new(code: u8, message: impl Into<String>) -> Outcome {
        Outcome { code, message: message.into() }
    }
}

/// Reads the fixed-size fields of a request body (header included, if any) in the sample's byte
/// order; every field the gateway reads lies at an offset aligned for its size.
#[derive(Debug, Clone, Copy)]
pub struct Body<'a> {
    pub le: bool,
    pub bytes: &'a [u8],
}

impl Body<'_> {
    fn take<const N: usize>(&self, at: usize) -> Result<[u8; N], CdrError> {
        let end = at.checked_add(N).ok_or(CdrError::Truncated { len: self.bytes.len() })?;
        let b = self.bytes.get(at..end).ok_or(CdrError::Truncated { len: self.bytes.len() })?;
        let mut out = [0u8; N];
        out.copy_from_slice(b);
        if !self.le {
            out.reverse();
        }
        Ok(out)
    }

    pub fn u8(&self, at: usize) -> Result<u8, CdrError> {
        Ok(self.take::<1>(at)?[0])
    }

    pub fn u64(&self, at: usize) -> Result<u64, CdrError> {
        Ok(u64::from_le_bytes(self.take::<8>(at)?))
    }

    pub fn i32(&self, at: usize) -> Result<i32, CdrError> {
        Ok(i32::from_le_bytes(self.take::<4>(at)?))
    }

    pub fn u32(&self, at: usize) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.take::<4>(at)?))
    }

    /// 16 bytes as they are (a UUID: octets, no byte order).
    pub fn octets16(&self, at: usize) -> Result<[u8; 16], CdrError> {
        let b = self.bytes.get(at..at + 16).ok_or(CdrError::Truncated { len: self.bytes.len() })?;
        let mut out = [0u8; 16];
        out.copy_from_slice(b);
        Ok(out)
    }
}

/// A little-endian CDR body being written; alignment counts from its start.
#[derive(Debug, Default)]
pub struct Out(pub Vec<u8>);

impl Out {
    fn align(&mut self, n: usize) {
        let len = self.0.len().next_multiple_of(n);
        self.0.resize(len, 0);
    }

    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.0.push(v);
        self
    }

    pub fn i8(&mut self, v: i8) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    pub fn bool(&mut self, v: bool) -> &mut Self {
        self.u8(u8::from(v))
    }

    pub fn u16(&mut self, v: u16) -> &mut Self {
        self.align(2);
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    pub fn i64(&mut self, v: i64) -> &mut Self {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    pub fn octets(&mut self, v: &[u8]) -> &mut Self {
        self.0.extend_from_slice(v);
        self
    }

    /// A CDR string: length with its NUL, the bytes, the NUL.
    pub fn string(&mut self, s: &str) -> &mut Self {
        self.u32(u32::try_from(s.len() + 1).unwrap_or(u32::MAX));
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
        self
    }

    /// A sequence's length.
    pub fn len(&mut self, n: usize) -> &mut Self {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX))
    }

    /// A `simulation_interfaces/msg/Result`.
    pub fn outcome(&mut self, o: &Outcome) -> &mut Self {
        self.u8(o.code).string(&o.message)
    }
}

/// `GetSimulatorFeatures_Response`'s `SimulatorFeatures` after the header in `out`.
pub fn features(out: &mut Out, features: &[u16], custom_info: &str) {
    out.len(features.len());
    for f in features {
        out.u16(*f);
    }
    out.len(0); // spawn_formats: tutti spawns nothing
    out.string(custom_info);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_result_after_the_header_is_its_code_then_an_aligned_string() {
        let mut out = Out(vec![7; 16]);
        out.outcome(&Outcome::new(result::INCORRECT_STATE, "ab"));
        let mut want = vec![7u8; 16];
        want.extend_from_slice(&[3, 0, 0, 0, 3, 0, 0, 0, b'a', b'b', 0]);
        assert_eq!(out.0, want);
    }

    #[test]
    fn features_are_aligned_u16_then_no_formats_then_the_info() {
        let mut out = Out(vec![0; 16]);
        features(&mut out, &[20, 21], "x");
        let mut want = vec![0u8; 16];
        want.extend_from_slice(&[2, 0, 0, 0, 20, 0, 21, 0, 0, 0, 0, 0, 2, 0, 0, 0, b'x', 0]);
        assert_eq!(out.0, want);
    }

    #[test]
    fn a_body_reads_either_byte_order_and_refuses_a_short_one() {
        let le = Body { le: true, bytes: &[1, 0, 0, 0, 0, 0, 0, 0, 9] };
        assert_eq!((le.u64(0).unwrap(), le.u8(8).unwrap()), (1, 9));
        let be = Body { le: false, bytes: &[0, 0, 0, 0, 0, 0, 0, 2] };
        assert_eq!(be.u64(0).unwrap(), 2);
        assert!(le.u64(4).is_err() && le.u8(9).is_err());
    }
}
