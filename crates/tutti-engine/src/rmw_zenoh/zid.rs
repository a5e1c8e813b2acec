//! The Zenoh session id (zid) as rmw_zenoh writes it in a liveliness token.
//!
//! rmw_zenoh writes `session->get_zid()` through `zenoh::Id::to_string`
//! (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:527`), which is zenoh-c's `z_id_to_string`:
//! the id's `Display` (zenoh-protocol `ZenohIdProto`), which is uhlc 0.8's `ID` display,
//! `format!("{:x}", u128::from_le_bytes(id))`: lowercase hexadecimal of the 16 id bytes read as a
//! little-endian integer, without leading zeros. A zid is never zero. Zenoh reads it back the
//! same way and refuses uppercase, leading zeros and the empty string (zenoh-protocol
//! `ZenohIdProto::from_str`, uhlc `ID::from_str`).

use std::fmt;
use std::num::NonZeroU128;
use std::str::FromStr;

/// A Zenoh session id.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ZenohId(NonZeroU128);

/// Why a string is not a session id as Zenoh writes it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ZidError {
    #[error("a session id is 1 to 32 lowercase hexadecimal digits without leading zero: {0:?}")]
    Malformed(String),
}

impl ZenohId {
    /// The id from its 16 bytes as Zenoh holds them (`z_id_t.id`); None for all zeros.
    pub fn from_le_bytes(bytes: [u8; 16]) -> Option<ZenohId> {
        NonZeroU128::new(u128::from_le_bytes(bytes)).map(ZenohId)
    }

    /// The id's 16 bytes, as Zenoh holds them (what tutti's `PeerId` carries).
    pub fn to_le_bytes(self) -> [u8; 16] {
        self.0.get().to_le_bytes()
    }
}

impl FromStr for ZenohId {
    type Err = ZidError;

    fn from_str(s: &str) -> Result<ZenohId, ZidError> {
        let malformed = || ZidError::Malformed(s.to_owned());
        let lower_hex = |b: u8| b.is_ascii_digit() || (b'a'..=b'f').contains(&b);
        if s.is_empty() || s.len() > 32 || s.starts_with('0') || !s.bytes().all(lower_hex) {
            return Err(malformed());
        }
        let n = u128::from_str_radix(s, 16).map_err(|_| malformed())?;
        NonZeroU128::new(n).map(ZenohId).ok_or_else(malformed)
    }
}

impl fmt::Display for ZenohId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:x}", self.0.get())
    }
}

impl fmt::Debug for ZenohId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_is_little_endian_hex_without_leading_zeros() {
        let mut bytes = [0u8; 16];
        bytes[0] = 0x1a;
        bytes[1] = 0x2b;
        let zid = ZenohId::from_le_bytes(bytes).expect("non-zero");
        assert_eq!(zid.to_string(), "2b1a");
        assert_eq!("2b1a".parse::<ZenohId>(), Ok(zid));
        assert_eq!(zid.to_le_bytes(), bytes);
    }

    #[test]
    fn malformed_ids_are_refused() {
        for bad in ["", "0", "01", "ABCD", "xyz", "123456789012345678901234567890123", " 1"] {
            assert!(bad.parse::<ZenohId>().is_err(), "{bad:?}");
        }
        assert_eq!(ZenohId::from_le_bytes([0; 16]), None);
    }
}
