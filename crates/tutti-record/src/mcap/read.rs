//! Reading an MCAP file that may be damaged or hostile: every length read from the file is
//! checked against the bytes that follow it before anything is sliced or allocated, a chunk
//! may hold at most [`CHUNK_LIMIT`] bytes uncompressed, and every failure is a [`ReadError`]
//! with the byte offset where it stands. Nothing here panics or aborts on any input
//! (`tests/mcap_fuzz.rs` mutates recordings to check it).
//!
//! The records are framed and parsed here, and a zstd chunk is decompressed with the `zstd`
//! crate's one-shot call, bounded by the size the chunk states; the `mcap` crate only writes
//! (see [`super::McapRecorder`]). Its readers are not used on files we did not write, because
//! in version 0.26 they trust the lengths in the file (see `docs/recording.md`, "Reading a
//! damaged file"):
//!
//! * `mcap::MessageStream` (through `ChunkFlattener`) sets no record length limit, so a
//!   record length of `0xffff_ffff_ffff_ffff` overflows `OPCODE_LEN_SIZE + len` in
//!   `sans_io/linear_reader.rs:543` (a panic in a debug build; in a release build the sum
//!   wraps to 8 and the slice `[9..]` of those 8 bytes panics);
//! * the length of a record inside a zstd chunk goes, with no limit, to
//!   `decompress!(OPCODE_LEN_SIZE + len)` (`linear_reader.rs:779`), whose
//!   `RwBuf::reserve_exact` zero-fills that many bytes (`Vec::resize`, `linear_reader.rs:121`,
//!   from `decompress_inner`, `linear_reader.rs:922`): one flipped byte asks for exabytes and
//!   the process aborts ("memory allocation of … bytes failed", SIGABRT); with chunk CRCs
//!   prevalidated, a chunk's `uncompressed_size` takes the same path (`linear_reader.rs:720`);
//! * in an uncompressed chunk, a record longer than the chunk's remaining data underflows
//!   `compressed_remaining -= OPCODE_LEN_SIZE + len` (`linear_reader.rs:745`) when bytes of the
//!   file follow the chunk;
//! * `parse_record` slices an attachment's body as `[header_len..body.len() - 4]`
//!   (`read.rs:176`), which panics when the body ends less than 4 bytes after the data length.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::sync::Arc;

use ::mcap::records::op;
use ::mcap::MAGIC;

/// The most bytes a chunk may hold uncompressed. Writers make chunks of about 1 MiB
/// (`mcap`'s and `ros2 bag`'s default is 768 KiB); a chunk that states more than this is
/// refused before anything is allocated for it.
pub const CHUNK_LIMIT: u64 = 256 << 20;

/// Opcode and length of a record, before its body.
const RECORD_HEADER: usize = 1 + 8;

/// Where in the file something is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Position {
    /// A byte offset in the file.
    File(u64),
    /// A byte offset in the (uncompressed) records of the chunk at byte `chunk` of the file.
    Chunk { chunk: u64, offset: u64 },
}

impl fmt::Display for Position {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Position::File(at) => write!(f, "at byte {at}"),
            Position::Chunk { chunk, offset } => {
                write!(f, "at byte {offset} of the records of the chunk at byte {chunk}")
            }
        }
    }
}

/// Why an MCAP file cannot be read, and where.
#[derive(Debug, thiserror::Error)]
#[error("{at}: {kind}")]
pub struct ReadError {
    pub at: Position,
    pub kind: ReadErrorKind,
}

/// What is wrong (see [`ReadError`] for where).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReadErrorKind {
    #[error("not an MCAP file (it does not start with the MCAP magic bytes)")]
    NoMagic,
    #[error("the file ends inside a record's opcode and length (was the recording finished?)")]
    Truncated,
    #[error("a {name} record (opcode {opcode:#04x}) says it is {len} bytes long, but {left} bytes follow")]
    TooLong { opcode: u8, name: &'static str, len: u64, left: u64 },
    #[error("the file ends without a footer (was the recording finished?)")]
    NoFooter,
    #[error("the footer is not followed by the MCAP magic bytes")]
    NoEndMagic,
    #[error("a {record} record ends inside its {field}")]
    Short { record: &'static str, field: &'static str },
    #[error("a {record} record's {field} is not UTF-8")]
    NotUtf8 { record: &'static str, field: &'static str },
    #[error("a chunk says it holds {size} bytes uncompressed; a chunk may hold at most {CHUNK_LIMIT}")]
    ChunkTooLarge { size: u64 },
    #[error("a chunk compressed with '{0}', which this reader does not decompress (zstd, or none)")]
    Compression(String),
    #[error("a chunk does not decompress to the {size} bytes it says it holds: {detail}")]
    Decompress { size: u64, detail: String },
    #[error("a chunk's records have the CRC {calculated:#010x}, not the {saved:#010x} it states")]
    ChunkCrc { saved: u32, calculated: u32 },
    #[error("an attachment's bytes have the CRC {calculated:#010x}, not the {saved:#010x} it states")]
    AttachmentCrc { saved: u32, calculated: u32 },
    #[error("a message on channel {0}, which no channel record before it defines")]
    UnknownChannel(u16),
}

/// An attachment (its data borrowed from the file).
#[derive(Debug, Clone)]
pub struct Attachment<'a> {
    /// The offset of its record.
    pub at: Position,
    pub name: String,
    pub media_type: String,
    pub data: &'a [u8],
}

/// A metadata record.
#[derive(Debug, Clone)]
pub struct Metadata {
    pub name: String,
    pub entries: BTreeMap<String, String>,
}

/// A channel record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Channel {
    pub id: u16,
    pub topic: String,
    pub message_encoding: String,
}

/// A message, with its channel.
#[derive(Debug, Clone)]
pub struct Message {
    /// The offset of its record.
    pub at: Position,
    pub channel: Arc<Channel>,
    pub sequence: u32,
    pub log_time: u64,
    pub publish_time: u64,
    pub data: Vec<u8>,
}

/// A record of the data section: its opcode, offset and body.
#[derive(Debug, Clone, Copy)]
struct Span<'a> {
    opcode: u8,
    at: u64,
    body: &'a [u8],
}

/// An MCAP file whose framing is checked: it starts and ends with the magic bytes, every
/// record's length fits in the file, and it has a footer.
#[derive(Debug)]
pub struct McapFile<'a> {
    /// The records of the data section (up to the data end record, or the footer).
    data: Vec<Span<'a>>,
}

impl<'a> McapFile<'a> {
    /// Checks the framing of `bytes` (an MCAP file read into memory).
    pub fn parse(bytes: &'a [u8]) -> Result<McapFile<'a>, ReadError> {
        if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != *MAGIC {
            return Err(ReadError { at: Position::File(0), kind: ReadErrorKind::NoMagic });
        }
        let mut data = Vec::new();
        let mut in_data = true;
        let mut at = MAGIC.len();
        loop {
            let err = |kind| ReadError { at: Position::File(at as u64), kind };
            if at == bytes.len() {
                return Err(err(ReadErrorKind::NoFooter));
            }
            let (opcode, body) = frame(&bytes[at..]).map_err(err)?;
            let span = Span { opcode, at: at as u64, body };
            at += RECORD_HEADER + body.len();
            match opcode {
                op::FOOTER => {
                    if bytes[at..] != *MAGIC {
                        return Err(ReadError { at: Position::File(at as u64), kind: ReadErrorKind::NoEndMagic });
                    }
                    return Ok(McapFile { data });
                }
                op::DATA_END => in_data = false,
                _ if in_data => data.push(span),
                _ => {}
            }
        }
    }

    /// The attachments of the data section, in file order.
    pub fn attachments(&self) -> Result<Vec<Attachment<'a>>, ReadError> {
        self.data.iter().filter(|s| s.opcode == op::ATTACHMENT).map(|s| attachment(s)).collect()
    }

    /// The metadata records of the data section, in file order.
    pub fn metadata(&self) -> Result<Vec<Metadata>, ReadError> {
        self.data
            .iter()
            .filter(|s| s.opcode == op::METADATA)
            .map(|s| {
                let err = |kind| ReadError { at: Position::File(s.at), kind };
                let mut f = Fields::new(s.body, "metadata");
                let name = f.string("name").map_err(err)?;
                Ok(Metadata { name, entries: f.string_map("metadata").map_err(err)? })
            })
            .collect()
    }

    /// The messages of the data section, in file order, chunks decompressed one at a time.
    /// After an error the iterator ends.
    pub fn messages(&self) -> Messages<'a, '_> {
        Messages { data: &self.data, next: 0, chunk: None, channels: HashMap::new(), done: false }
    }
}

/// The records of a file or a chunk: the opcode and body of the record that `bytes` starts
/// with, its length checked against the bytes that follow.
fn frame(bytes: &[u8]) -> Result<(u8, &[u8]), ReadErrorKind> {
    let Some((&opcode, rest)) = bytes.split_first() else { return Err(ReadErrorKind::Truncated) };
    let Some((len, rest)) = rest.split_first_chunk::<8>() else { return Err(ReadErrorKind::Truncated) };
    let len = u64::from_le_bytes(*len);
    let left = rest.len() as u64;
    if len > left {
        return Err(ReadErrorKind::TooLong { opcode, name: record_name(opcode), len, left });
    }
    // `len <= rest.len()`, so it fits a usize.
    Ok((opcode, &rest[..len as usize]))
}

fn record_name(opcode: u8) -> &'static str {
    match opcode {
        op::HEADER => "header",
        op::FOOTER => "footer",
        op::SCHEMA => "schema",
        op::CHANNEL => "channel",
        op::MESSAGE => "message",
        op::CHUNK => "chunk",
        op::MESSAGE_INDEX => "message index",
        op::CHUNK_INDEX => "chunk index",
        op::ATTACHMENT => "attachment",
        op::ATTACHMENT_INDEX => "attachment index",
        op::STATISTICS => "statistics",
        op::METADATA => "metadata",
        op::METADATA_INDEX => "metadata index",
        op::SUMMARY_OFFSET => "summary offset",
        op::DATA_END => "data end",
        _ => "unknown",
    }
}

fn attachment<'a>(s: &Span<'a>) -> Result<Attachment<'a>, ReadError> {
    let at = Position::File(s.at);
    let err = |kind| ReadError { at, kind };
    let mut f = Fields::new(s.body, "attachment");
    f.u64("log time").map_err(err)?;
    f.u64("create time").map_err(err)?;
    let name = f.string("name").map_err(err)?;
    let media_type = f.string("media type").map_err(err)?;
    let data = f.bytes_u64("data").map_err(err)?;
    let covered = f.pos;
    let saved = f.u32("crc").map_err(err)?;
    if saved != 0 {
        let calculated = crc32fast::hash(&s.body[..covered]);
        if calculated != saved {
            return Err(err(ReadErrorKind::AttachmentCrc { saved, calculated }));
        }
    }
    Ok(Attachment { at, name, media_type, data })
}

/// Reads the fields of one record's body, never past its end.
struct Fields<'a> {
    body: &'a [u8],
    pos: usize,
    record: &'static str,
}

impl<'a> Fields<'a> {
    fn new(body: &'a [u8], record: &'static str) -> Self {
        Fields { body, pos: 0, record }
    }

    fn take(&mut self, n: u64, field: &'static str) -> Result<&'a [u8], ReadErrorKind> {
        let left = &self.body[self.pos..];
        if n > left.len() as u64 {
            return Err(ReadErrorKind::Short { record: self.record, field });
        }
        // `n <= left.len()`, so it fits a usize.
        self.pos += n as usize;
        Ok(&left[..n as usize])
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], ReadErrorKind> {
        let b = self.take(N as u64, field)?;
        let mut a = [0; N];
        a.copy_from_slice(b);
        Ok(a)
    }

    fn u16(&mut self, field: &'static str) -> Result<u16, ReadErrorKind> {
        self.array(field).map(u16::from_le_bytes)
    }

    fn u32(&mut self, field: &'static str) -> Result<u32, ReadErrorKind> {
        self.array(field).map(u32::from_le_bytes)
    }

    fn u64(&mut self, field: &'static str) -> Result<u64, ReadErrorKind> {
        self.array(field).map(u64::from_le_bytes)
    }

    /// A u32 length, then that many bytes of UTF-8.
    fn string(&mut self, field: &'static str) -> Result<String, ReadErrorKind> {
        let len = self.u32(field)?;
        let bytes = self.take(u64::from(len), field)?;
        String::from_utf8(bytes.to_vec()).map_err(|_| ReadErrorKind::NotUtf8 { record: self.record, field })
    }

    /// A u64 length, then that many bytes.
    fn bytes_u64(&mut self, field: &'static str) -> Result<&'a [u8], ReadErrorKind> {
        let len = self.u64(field)?;
        self.take(len, field)
    }

    /// A u32 length in bytes, then key and value strings filling exactly that many bytes.
    fn string_map(&mut self, field: &'static str) -> Result<BTreeMap<String, String>, ReadErrorKind> {
        let len = self.u32(field)?;
        let mut inner = Fields::new(self.take(u64::from(len), field)?, self.record);
        let mut map = BTreeMap::new();
        while inner.pos < inner.body.len() {
            let k = inner.string(field)?;
            let v = inner.string(field)?;
            map.insert(k, v);
        }
        Ok(map)
    }

    /// What is left of the body.
    fn rest(&mut self) -> &'a [u8] {
        let r = &self.body[self.pos..];
        self.pos = self.body.len();
        r
    }
}

/// The chunk being read: its records (uncompressed) and how far.
#[derive(Debug)]
struct OpenChunk<'a> {
    at: u64,
    records: Cow<'a, [u8]>,
    pos: usize,
}

/// The messages of an [`McapFile`] (see [`McapFile::messages`]).
#[derive(Debug)]
pub struct Messages<'a, 'f> {
    data: &'f [Span<'a>],
    next: usize,
    chunk: Option<OpenChunk<'a>>,
    channels: HashMap<u16, Arc<Channel>>,
    done: bool,
}

impl Messages<'_, '_> {
    /// The message in a channel or message record, or None for another record (a channel is
    /// kept).
    fn record(&mut self, opcode: u8, body: &[u8], at: Position) -> Result<Option<Message>, ReadError> {
        let err = |kind| ReadError { at, kind };
        match opcode {
            op::CHANNEL => {
                let mut f = Fields::new(body, "channel");
                let id = f.u16("id").map_err(err)?;
                f.u16("schema id").map_err(err)?;
                let topic = f.string("topic").map_err(err)?;
                let message_encoding = f.string("message encoding").map_err(err)?;
                f.string_map("metadata").map_err(err)?;
                self.channels.insert(id, Arc::new(Channel { id, topic, message_encoding }));
                Ok(None)
            }
            op::MESSAGE => {
                let mut f = Fields::new(body, "message");
                let id = f.u16("channel id").map_err(err)?;
                let sequence = f.u32("sequence").map_err(err)?;
                let log_time = f.u64("log time").map_err(err)?;
                let publish_time = f.u64("publish time").map_err(err)?;
                let channel = self.channels.get(&id).cloned().ok_or(err(ReadErrorKind::UnknownChannel(id)))?;
                Ok(Some(Message { at, channel, sequence, log_time, publish_time, data: f.rest().to_vec() }))
            }
            _ => Ok(None),
        }
    }

    /// The next message, or None at the end of the data section.
    fn advance(&mut self) -> Result<Option<Message>, ReadError> {
        loop {
            if let Some(c) = self.chunk.take() {
                if c.pos < c.records.len() {
                    let at = Position::Chunk { chunk: c.at, offset: c.pos as u64 };
                    let (opcode, body) = frame(&c.records[c.pos..]).map_err(|kind| ReadError { at, kind })?;
                    let next = c.pos + RECORD_HEADER + body.len();
                    let found = self.record(opcode, body, at)?;
                    self.chunk = Some(OpenChunk { pos: next, ..c });
                    if found.is_some() {
                        return Ok(found);
                    }
                }
                continue;
            }
            let Some(&span) = self.data.get(self.next) else { return Ok(None) };
            self.next += 1;
            let at = Position::File(span.at);
            if span.opcode == op::CHUNK {
                let records = chunk_records(span.body).map_err(|kind| ReadError { at, kind })?;
                self.chunk = Some(OpenChunk { at: span.at, records, pos: 0 });
            } else if let Some(m) = self.record(span.opcode, span.body, at)? {
                return Ok(Some(m));
            }
        }
    }
}

impl Iterator for Messages<'_, '_> {
    type Item = Result<Message, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let r = self.advance().transpose();
        self.done = !matches!(r, Some(Ok(_)));
        r
    }
}

/// A chunk's records, uncompressed, checked against its stated size and CRC.
fn chunk_records(body: &[u8]) -> Result<Cow<'_, [u8]>, ReadErrorKind> {
    let mut f = Fields::new(body, "chunk");
    f.u64("message start time")?;
    f.u64("message end time")?;
    let size = f.u64("uncompressed size")?;
    let saved = f.u32("uncompressed crc")?;
    let compression = f.string("compression")?;
    let compressed = f.bytes_u64("records")?;
    if size > CHUNK_LIMIT {
        return Err(ReadErrorKind::ChunkTooLarge { size });
    }
    let records: Cow<'_, [u8]> = match compression.as_str() {
        "" if compressed.len() as u64 == size => Cow::Borrowed(compressed),
        "" => {
            let detail = format!("its records are {} bytes", compressed.len());
            return Err(ReadErrorKind::Decompress { size, detail });
        }
        // `size <= CHUNK_LIMIT`, so it fits a usize. The one-shot call reserves `size` bytes
        // (not written to) and fails if the data decompress to more.
        "zstd" => match zstd::bulk::decompress(compressed, size as usize) {
            Ok(r) if r.len() as u64 == size => Cow::Owned(r),
            Ok(r) => return Err(ReadErrorKind::Decompress { size, detail: format!("they are {} bytes", r.len()) }),
            Err(e) => return Err(ReadErrorKind::Decompress { size, detail: e.to_string() }),
        },
        other => return Err(ReadErrorKind::Compression(other.to_string())),
    };
    if saved != 0 {
        let calculated = crc32fast::hash(&records);
        if calculated != saved {
            return Err(ReadErrorKind::ChunkCrc { saved, calculated });
        }
    }
    Ok(records)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record: opcode, length, body.
    fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
        let mut r = vec![opcode];
        r.extend_from_slice(&(body.len() as u64).to_le_bytes());
        r.extend_from_slice(body);
        r
    }

    fn file(records: &[Vec<u8>]) -> Vec<u8> {
        let mut f = MAGIC.to_vec();
        for r in records {
            f.extend_from_slice(r);
        }
        f.extend(record(op::FOOTER, &[0; 20]));
        f.extend_from_slice(MAGIC);
        f
    }

    fn string(s: &str) -> Vec<u8> {
        let mut b = (s.len() as u32).to_le_bytes().to_vec();
        b.extend_from_slice(s.as_bytes());
        b
    }

    #[test]
    fn a_record_longer_than_the_file_is_refused_at_its_offset() {
        let mut bytes = file(&[record(op::HEADER, &[0; 8])]);
        bytes[9..17].copy_from_slice(&u64::MAX.to_le_bytes());
        let e = McapFile::parse(&bytes).unwrap_err();
        assert_eq!(e.at, Position::File(8));
        assert!(matches!(e.kind, ReadErrorKind::TooLong { opcode: op::HEADER, len: u64::MAX, .. }), "{e}");
        assert!(e.to_string().starts_with("at byte 8: a header record"), "{e}");
    }

    #[test]
    fn a_chunk_that_states_a_huge_size_is_refused_before_anything_is_allocated() {
        let mut chunk = Vec::new();
        chunk.extend_from_slice(&[0; 16]);
        chunk.extend_from_slice(&u64::MAX.to_le_bytes());
        chunk.extend_from_slice(&[0; 4]);
        chunk.extend(string("zstd"));
        chunk.extend_from_slice(&0u64.to_le_bytes());
        let bytes = file(&[record(op::HEADER, &[0; 8]), record(op::CHUNK, &chunk)]);
        let f = McapFile::parse(&bytes).unwrap();
        let e = f.messages().next().unwrap().unwrap_err();
        assert_eq!(e.at, Position::File(8 + 9 + 8));
        assert!(matches!(e.kind, ReadErrorKind::ChunkTooLarge { size: u64::MAX }), "{e}");
    }

    #[test]
    fn an_attachment_cut_before_its_crc_is_an_error_not_a_panic() {
        let mut a = vec![0; 16];
        a.extend(string("x.ddf"));
        a.extend(string("application/xml"));
        a.extend_from_slice(&0u64.to_le_bytes());
        a.extend_from_slice(&[0; 2]);
        let bytes = file(&[record(op::ATTACHMENT, &a)]);
        let e = McapFile::parse(&bytes).unwrap().attachments().unwrap_err();
        assert!(matches!(e.kind, ReadErrorKind::Short { record: "attachment", field: "crc" }), "{e}");
    }

    #[test]
    fn messages_of_plain_chunks_are_read_and_an_unknown_channel_is_an_error() {
        let mut channel = 7u16.to_le_bytes().to_vec();
        channel.extend_from_slice(&0u16.to_le_bytes());
        channel.extend(string("/t"));
        channel.extend(string("cdr"));
        channel.extend_from_slice(&0u32.to_le_bytes());
        let message = |id: u16| {
            let mut m = id.to_le_bytes().to_vec();
            m.extend_from_slice(&3u32.to_le_bytes());
            m.extend_from_slice(&[0; 16]);
            m.extend_from_slice(b"data");
            record(op::MESSAGE, &m)
        };
        let mut records = record(op::CHANNEL, &channel);
        records.extend(message(7));
        let mut chunk = vec![0; 16];
        chunk.extend_from_slice(&(records.len() as u64).to_le_bytes());
        chunk.extend_from_slice(&crc32fast::hash(&records).to_le_bytes());
        chunk.extend(string(""));
        chunk.extend_from_slice(&(records.len() as u64).to_le_bytes());
        chunk.extend_from_slice(&records);
        let bytes = file(&[record(op::CHUNK, &chunk), message(8)]);
        let f = McapFile::parse(&bytes).unwrap();
        let mut msgs = f.messages();
        let m = msgs.next().unwrap().unwrap();
        assert_eq!((m.channel.topic.as_str(), m.sequence, &m.data[..]), ("/t", 3, &b"data"[..]));
        assert_eq!(m.at, Position::Chunk { chunk: 8, offset: (RECORD_HEADER + channel.len()) as u64 });
        let e = msgs.next().unwrap().unwrap_err();
        assert!(matches!(e.kind, ReadErrorKind::UnknownChannel(8)), "{e}");
        assert!(msgs.next().is_none());
    }
}
