//! The attachment rmw_zenoh puts on every sample, query and reply
//! (`rmw_zenoh_cpp/src/detail/attachment_helpers.cpp:67-82`): the sequence number, the source
//! timestamp and the GID, written one after the other by zenoh's ext serializer.
//!
//! The bytes (zenoh-cpp `zenoh/api/ext/serialization.hxx`, which calls zenoh-c
//! `src/serialization.rs`, which calls zenoh-ext `src/serialization.rs`):
//!
//! * bytes 0..8, the sequence number: `int64_t` through `ze_serializer_serialize_int64`,
//!   zenoh-ext's `impl_num!`: `i64::to_le_bytes`;
//! * bytes 8..16, the source timestamp: the same; nanoseconds since the Unix epoch
//!   (`rmw_zenoh_cpp/src/detail/zenoh_utils.cpp:68-72`);
//! * byte 16, the GID's length, 16 (`0x10`): a `std::array<uint8_t, 16>` is a sequence, its
//!   length through `ze_serializer_serialize_sequence_length`, zenoh-ext's `VarInt<usize>`:
//!   unsigned LEB128;
//! * bytes 17..33, the GID: each element through `ze_serializer_serialize_uint8`, one byte.
//!
//! What each field holds: on a publisher's sample, its next sequence number (from 1), the send
//! time and the publisher's GID (`rmw_zenoh_cpp/src/detail/rmw_publisher_data.cpp:309-312`); on a
//! client's query, the request's sequence number (from 1), the send time and the client's GID
//! (`rmw_zenoh_cpp/src/detail/rmw_client_data.cpp:381-387`); on a service's reply, the request's
//! sequence number and the *client's* GID taken from the request, with the reply's send time
//! (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:442-446`). A sample or query without an
//! attachment is dropped (`rmw_zenoh_cpp/src/detail/rmw_subscription_data.cpp:221-227`,
//! `rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:322-327`), and a server or client refuses a
//! negative sequence number or timestamp
//! (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:333-345`,
//! `rmw_zenoh_cpp/src/detail/rmw_client_data.cpp:315-323`).
//!
//! Reading (`rmw_zenoh_cpp/src/detail/attachment_helpers.cpp:76-82`) goes through the same
//! functions: the LEB128 reader is the `leb128` crate's (0.2) `read::unsigned`, which takes
//! over-long forms (`0x90 0x00` is 16) and refuses a number past 64 bits; a length other than 16
//! is refused (zenoh-cpp's `std::array` reader, "Incorrect sequence size"). rmw_zenoh does not
//! check that the bytes end there (it never calls `is_done`): [`Attachment::decode_prefix`] reads
//! as it does, [`Attachment::decode`] also refuses trailing bytes.

/// The three fields rmw_zenoh attaches (`rmw_zenoh_cpp/src/detail/attachment_helpers.hpp:28-49`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Attachment {
    pub sequence_number: i64,
    /// Nanoseconds since the Unix epoch, the sender's system clock.
    pub source_timestamp: i64,
    pub source_gid: [u8; 16],
}

/// Why bytes are not an attachment rmw_zenoh reads.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AttachmentError {
    #[error("the attachment ends inside its {field} ({len} bytes)")]
    Truncated { field: &'static str, len: usize },
    #[error("the attachment's GID length overflows 64 bits")]
    LengthOverflow,
    #[error("the attachment's GID has {0} bytes, not 16")]
    GidLength(u64),
    #[error("the attachment has {0} bytes after its GID")]
    TrailingBytes(usize),
}

/// The length of an attachment as rmw_zenoh writes it.
pub const ENCODED_LEN: usize = 33;

impl Attachment {
    /// The bytes rmw_zenoh writes (`AttachmentData::serialize_to_zbytes`).
    pub fn encode(&self) -> [u8; ENCODED_LEN] {
        let mut out = [0u8; ENCODED_LEN];
        out[..8].copy_from_slice(&self.sequence_number.to_le_bytes());
        out[8..16].copy_from_slice(&self.source_timestamp.to_le_bytes());
        // LEB128 of 16 is the one byte 0x10.
        out[16] = 16;
        out[17..].copy_from_slice(&self.source_gid);
        out
    }

    /// The attachment in `bytes`, which must end with it.
    pub fn decode(bytes: &[u8]) -> Result<Attachment, AttachmentError> {
        let (attachment, used) = Attachment::decode_prefix(bytes)?;
        match bytes.len() - used {
            0 => Ok(attachment),
            extra => Err(AttachmentError::TrailingBytes(extra)),
        }
    }

    /// The attachment at the start of `bytes` and how many bytes it took, reading exactly as
    /// rmw_zenoh does (`AttachmentData(const zenoh::Bytes &)`), which ignores what follows.
    pub fn decode_prefix(bytes: &[u8]) -> Result<(Attachment, usize), AttachmentError> {
        let mut reader = Reader { bytes, at: 0 };
        let sequence_number = i64::from_le_bytes(reader.take("sequence number")?);
        let source_timestamp = i64::from_le_bytes(reader.take("source timestamp")?);
        let len = reader.leb128()?;
        if len != 16 {
            return Err(AttachmentError::GidLength(len));
        }
        let source_gid = reader.take("GID")?;
        Ok((Attachment { sequence_number, source_timestamp, source_gid }, reader.at))
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], AttachmentError> {
        let truncated = AttachmentError::Truncated { field, len: self.bytes.len() };
        let end = self.at.checked_add(N).ok_or(truncated.clone())?;
        let slice = self.bytes.get(self.at..end).ok_or(truncated.clone())?;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        self.at = end;
        Ok(out)
    }

    /// `leb128::read::unsigned` (leb128 0.2): seven bits a byte, least significant first; at the
    /// tenth byte (shift 63) only 0 or 1 may come, else the number overflows (the reader still
    /// skips to the byte that ends it).
    fn leb128(&mut self) -> Result<u64, AttachmentError> {
        let mut result = 0u64;
        let mut shift = 0u32;
        loop {
            let [byte] = self.take::<1>("GID length")?;
            if shift == 63 && byte != 0x00 && byte != 0x01 {
                let mut b = byte;
                while b & 0x80 != 0 {
                    [b] = self.take::<1>("GID length")?;
                }
                return Err(AttachmentError::LengthOverflow);
            }
            result |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(result);
            }
            shift += 7;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_length() {
        let a = Attachment { sequence_number: -5, source_timestamp: i64::MAX, source_gid: [0xab; 16] };
        let bytes = a.encode();
        assert_eq!(bytes.len(), ENCODED_LEN);
        assert_eq!(Attachment::decode(&bytes), Ok(a));
    }

    #[test]
    fn over_long_lengths_are_read_as_leb128_reads_them() {
        let a = Attachment { sequence_number: 1, source_timestamp: 2, source_gid: [7; 16] };
        let good = a.encode();
        let mut long = good[..16].to_vec();
        long.extend_from_slice(&[0x90, 0x80, 0x00]);
        long.extend_from_slice(&good[17..]);
        assert_eq!(Attachment::decode_prefix(&long), Ok((a, 35)));
    }

    #[test]
    fn malformed_attachments_are_refused() {
        let good = Attachment::default().encode();
        assert_eq!(Attachment::decode(&[]), Err(AttachmentError::Truncated { field: "sequence number", len: 0 }));
        assert!(matches!(
            Attachment::decode(&good[..12]),
            Err(AttachmentError::Truncated { field: "source timestamp", .. })
        ));
        assert!(matches!(Attachment::decode(&good[..16]), Err(AttachmentError::Truncated { field: "GID length", .. })));
        assert!(matches!(Attachment::decode(&good[..32]), Err(AttachmentError::Truncated { field: "GID", .. })));
        let mut wrong_len = good;
        wrong_len[16] = 15;
        assert_eq!(Attachment::decode(&wrong_len), Err(AttachmentError::GidLength(15)));
        let mut longer = good.to_vec();
        longer.push(0);
        assert_eq!(Attachment::decode(&longer), Err(AttachmentError::TrailingBytes(1)));
        assert_eq!(Attachment::decode_prefix(&longer), Ok((Attachment::default(), 33)));
        let mut overflow = good[..16].to_vec();
        overflow.extend_from_slice(&[0xff; 9]);
        overflow.push(0x02);
        assert_eq!(Attachment::decode(&overflow), Err(AttachmentError::LengthOverflow));
        overflow.truncate(25);
        overflow.push(0x82);
        assert!(matches!(Attachment::decode(&overflow), Err(AttachmentError::Truncated { .. })));
    }
}
