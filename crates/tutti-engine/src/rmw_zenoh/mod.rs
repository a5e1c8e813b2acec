//! rmw_zenoh's wire format (rmw_zenoh_cpp 0.2.10, ROS 2 Jazzy), in pure Rust and without Zenoh
//! itself: what a Zenoh engine must write and read so that rmw_zenoh nodes and tutti see each
//! other as ROS 2 entities.
//!
//! Every rule cites its source as `rmw_zenoh_cpp/src/detail/FILE.cpp:LINE` of that release (and
//! zenoh-c / zenoh-ext / zenoh-cpp where rmw_zenoh hands the bytes to them).
//!
//! * [`keyexpr`]: the key expressions data travels on, one per topic and one per service
//!   (`<domain>/<name>/<type>/<type hash>`);
//! * [`liveliness`]: the liveliness tokens (`@ros2_lv/…`) that make the ROS 2 graph: an
//!   [`Entity`] (node, publisher, subscription, service, client) to its key and back;
//! * [`qos`]: the QoS string inside a token ([`QosProfile`]) and rmw_zenoh's defaults;
//! * [`zenoh_options`]: how rmw_zenoh maps a ROS 2 QoS onto Zenoh publishers, subscribers,
//!   queriers and queryables, as plain data;
//! * [`attachment`]: the 33 bytes on every sample, query and reply (sequence number, source
//!   timestamp, GID);
//! * [`gid`]: an entity's 16-byte GID, the XXH3-128 of its token key;
//! * [`type_names`]: `pkg/msg/Type` to `pkg::msg::dds_::Type_` and back, and service types;
//! * [`zid`]: the Zenoh session id as it is written in tokens.
//!
//! # Stricter than rmw_zenoh
//!
//! The parsers accept every key and attachment rmw_zenoh 0.2.10 writes, and reject with a typed
//! error what rmw_zenoh itself rejects. Where rmw_zenoh's C++ is looser than any writer of the
//! format (numbers read with `strtoull`/`std::stoul`, which skip leading blanks, take a `+` and,
//! for `stoul`, ignore trailing junk; node and entity ids kept as any non-empty string; session
//! ids kept as any string), these parsers take plain decimal digits and zenoh's own session-id
//! form only. Numbers may still have leading zeros, as `strtoull` allows. Extra trailing fields
//! of a token or a QoS string are ignored, as rmw_zenoh does.
//!
//! rmw_zenoh never parses a data key (it only declares and matches them): [`DataKey::parse`] is
//! tutti's own reading of what rmw_zenoh writes. [`Attachment::decode`] refuses bytes after the
//! GID, which rmw_zenoh ignores; [`Attachment::decode_prefix`] reads as rmw_zenoh does.
//!
//! The encoders refuse (rather than write) what would give a key rmw_zenoh cannot read back or
//! Zenoh refuses: an empty field (rmw_zenoh's builder ends the key at the first empty field,
//! `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:471-484`), a `%` in a mangled field (it would
//! come back as `/`), one of Zenoh's reserved `*`, `$`, `?`, `#`, or a data key's name that is
//! not a fully qualified ROS 2 name.

pub mod attachment;
pub mod gid;
pub mod keyexpr;
pub mod liveliness;
pub mod qos;
pub mod type_names;
pub mod zenoh_options;
pub mod zid;

#[cfg(test)]
mod tests_golden;
#[cfg(test)]
mod tests_prop;

pub use attachment::{Attachment, AttachmentError};
pub use gid::{gid_of_key, xxh3_128, Gid};
pub use keyexpr::{DataKey, DataKeyError};
pub use liveliness::{Entity, EntityKind, NodeInfo, TokenError, TopicInfo};
pub use qos::{QosError, QosProfile};
pub use zid::{ZenohId, ZidError};

/// A non-negative decimal number as rmw_zenoh writes them (`std::to_string` of an unsigned):
/// ASCII digits only, at least one, fitting in 64 bits. Leading zeros are taken, as `strtoull`
/// takes them (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:252-286`).
pub(crate) fn parse_decimal(s: &str) -> Option<u64> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::parse_decimal;

    #[test]
    fn decimal_numbers_are_digits_only() {
        assert_eq!(parse_decimal("0"), Some(0));
        assert_eq!(parse_decimal("007"), Some(7));
        assert_eq!(parse_decimal("18446744073709551615"), Some(u64::MAX));
        for bad in ["", "+1", "-1", " 1", "1 ", "1a", "18446744073709551616", "0x10"] {
            assert_eq!(parse_decimal(bad), None, "{bad:?}");
        }
    }
}
