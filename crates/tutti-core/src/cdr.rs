//! Plain CDR (XCDR1, final structs) of a set's typed struct, the one `tutti idl` writes:
//! `uint64 step; double sim_time;` then the items in DDF order, arrays fixed-size, buses
//! nested. Used by the gateway (DDS samples) and by the recordings (MCAP messages).
//!
//! The struct has only fixed-size members, so its body is a fixed plan: every element
//! aligned to its own size relative to the start of the body (right after the 4-byte
//! encapsulation header), nested structs adding no padding of their own. The plan maps each
//! leaf of the shared-memory layout ([`SetLayout`]) to its place in the body.
//! [`SetCodec::encode`] writes a little-endian body; [`SetCodec::decode`] reads either byte
//! order and refuses a short body or another representation.

use crate::ddf::{ScalarType, SetLayout};

/// Why a serialized sample cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum CdrError {
    /// Shorter than the 4-byte encapsulation header.
    #[error("a sample of {len} bytes has no encapsulation header")]
    NoHeader { len: usize },
    /// Not plain CDR (XCDR1).
    #[error("unsupported data representation {:02x}{:02x} (expected plain CDR)", .id[0], .id[1])]
    Representation { id: [u8; 2] },
    /// A typed body shorter than the set's struct.
    #[error("a typed sample of {got} bytes, expected {expected}")]
    ShortSample { got: usize, expected: usize },
    /// A destination shorter than the set in shared memory.
    #[error("a set of {got} bytes, expected {expected}")]
    ShortSet { got: usize, expected: usize },
    /// A body that ends before the element being read.
    #[error("truncated sample ({len} bytes)")]
    Truncated { len: usize },
    /// A sequence longer than the body could hold.
    #[error("a sequence of {count} doubles in {len} bytes")]
    Sequence { count: usize, len: usize },
    /// An array item whose sample has another number of elements.
    #[error("{path} has {expected} elements, the sample {got}")]
    ArrayLength { path: String, expected: usize, got: usize },
    /// A sample of another kind than the reader expects.
    #[error("{0}")]
    Unexpected(&'static str),
    /// The DDS implementation could not deserialize the sample (its own words).
    #[error("{0}")]
    Engine(String),
}

/// One leaf of a set in the CDR body.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub ty: ScalarType,
    /// Elements (1 for a scalar).
    pub count: usize,
    /// Offset in the shared-memory set.
    pub shm: usize,
    /// Offset in the CDR body.
    pub cdr: usize,
}

/// Bytes of the `step` and `sim_time` header fields.
const HEADER: usize = 16;

/// The CDR plan of one set's typed struct.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SetCodec {
    fields: Vec<Field>,
    shm_size: usize,
    cdr_size: usize,
}

/// What a sample from outside (DDS, a Foxglove client) carries into shared memory.
#[derive(Debug, Clone, PartialEq)]
pub enum Payload {
    /// A whole set (typed mode).
    Set(TypedSample),
    /// One item (per-item mode): its path and its bytes in shared-memory layout.
    Item { path: std::sync::Arc<str>, bytes: Vec<u8> },
}

/// A decoded typed sample: the header fields and the set in shared-memory layout.
#[derive(Debug, Clone, PartialEq)]
pub struct TypedSample {
    pub step: u64,
    pub sim_time: f64,
    pub data: Vec<u8>,
}

impl SetCodec {
    /// The plan for a set laid out as `layout` (its leaves are in DDF order, depth first,
    /// which is the member order of the struct and its nested bus structs).
    pub fn new(layout: &SetLayout) -> SetCodec {
        let mut pos = HEADER;
        let fields = layout
            .leaves
            .iter()
            .map(|leaf| {
                let size = leaf.ty.size() as usize;
                pos = pos.next_multiple_of(size);
                let f = Field { ty: leaf.ty, count: usize::from(leaf.length), shm: leaf.offset as usize, cdr: pos };
                pos += size * f.count;
                f
            })
            .collect();
        SetCodec { fields, shm_size: layout.size as usize, cdr_size: pos }
    }

    /// The leaves in body order.
    pub fn fields(&self) -> &[Field] {
        &self.fields
    }

    /// Bytes of the CDR body (without the encapsulation header).
    pub fn cdr_size(&self) -> usize {
        self.cdr_size
    }

    /// Bytes of the set in shared memory.
    pub fn shm_size(&self) -> usize {
        self.shm_size
    }

    /// Writes the little-endian CDR body of (`step`, `sim_time`, `shm`) into `out`
    /// (cleared first). `shm` is the set in shared-memory layout, native (little-endian)
    /// byte order.
    pub fn encode(&self, step: u64, sim_time: f64, shm: &[u8], out: &mut Vec<u8>) {
        out.clear();
        out.resize(self.cdr_size, 0);
        out[0..8].copy_from_slice(&step.to_le_bytes());
        out[8..16].copy_from_slice(&sim_time.to_le_bytes());
        for f in &self.fields {
            let n = f.ty.size() as usize * f.count;
            if let Some(src) = shm.get(f.shm..f.shm + n) {
                out[f.cdr..f.cdr + n].copy_from_slice(src);
                if cfg!(target_endian = "big") {
                    for el in out[f.cdr..f.cdr + n].chunks_exact_mut(f.ty.size() as usize) {
                        el.reverse();
                    }
                }
            }
        }
    }
}

impl SetCodec {
    /// Reads a serialized sample (encapsulation header first) into a [`TypedSample`]:
    /// plain CDR (XCDR1) in either byte order; a short body or another representation is
    /// refused with a message.
    pub fn decode(&self, raw: &[u8]) -> Result<TypedSample, CdrError> {
        let (le, body) = self.check(raw)?;
        Ok(self.decode_body(le, body))
    }

    /// Checks a serialized sample: (little-endian?, CDR body) when it is plain CDR and long
    /// enough for this set.
    pub fn check<'a>(&self, raw: &'a [u8]) -> Result<(bool, &'a [u8]), CdrError> {
        let (le, body) = split_header(raw)?;
        if body.len() < self.cdr_size {
            return Err(CdrError::ShortSample { got: body.len(), expected: self.cdr_size });
        }
        Ok((le, body))
    }

    /// The step of a checked body.
    pub fn step(&self, le: bool, body: &[u8]) -> u64 {
        read_u64(body, 0, le)
    }

    /// Decodes a checked body ([`SetCodec::check`]).
    pub fn decode_body(&self, le: bool, body: &[u8]) -> TypedSample {
        let mut data = vec![0u8; self.shm_size];
        let _ = self.decode_into(le, body, &mut data);
        let step = read_u64(body, 0, le);
        let sim_time = f64::from_bits(read_u64(body, 8, le));
        TypedSample { step, sim_time, data }
    }

    /// Writes the items of CDR body `body` into `shm` (the set in shared-memory layout).
    pub fn decode_into(&self, le: bool, body: &[u8], shm: &mut [u8]) -> Result<(), CdrError> {
        if body.len() < self.cdr_size {
            return Err(CdrError::ShortSample { got: body.len(), expected: self.cdr_size });
        }
        if shm.len() < self.shm_size {
            return Err(CdrError::ShortSet { got: shm.len(), expected: self.shm_size });
        }
        for f in &self.fields {
            let size = f.ty.size() as usize;
            let n = size * f.count;
            let dst = &mut shm[f.shm..f.shm + n];
            dst.copy_from_slice(&body[f.cdr..f.cdr + n]);
            if le != cfg!(target_endian = "little") && size > 1 {
                dst.chunks_exact_mut(size).for_each(<[u8]>::reverse);
            }
        }
        Ok(())
    }
}

/// The representation identifiers of plain CDR (XCDR1), big- and little-endian.
const CDR_BE: [u8; 2] = [0, 0];
const CDR_LE: [u8; 2] = [0, 1];

/// The encapsulation header of little-endian plain CDR, as written by every engine.
pub const HEADER_LE: [u8; 4] = [0, 1, 0, 0];

/// Splits a serialized sample into (little-endian?, body).
pub fn split_header(raw: &[u8]) -> Result<(bool, &[u8]), CdrError> {
    let Some((id, body)) = raw.split_first_chunk::<4>() else {
        return Err(CdrError::NoHeader { len: raw.len() });
    };
    match [id[0], id[1]] {
        CDR_LE => Ok((true, body)),
        CDR_BE => Ok((false, body)),
        id => Err(CdrError::Representation { id }),
    }
}

fn read_u64(b: &[u8], at: usize, le: bool) -> u64 {
    let a: [u8; 8] = b[at..at + 8].try_into().unwrap_or_default();
    if le {
        u64::from_le_bytes(a)
    } else {
        u64::from_be_bytes(a)
    }
}
