//! Plain CDR of the topics' types: the typed struct of a set ([`SetCodec`], in the core,
//! shared with the recordings), its serde forms for the rustdds engine ([`PreEncoded`] writes
//! an encoded body verbatim, [`SetSeed`] reads one through rustdds' CDR deserializer, either
//! byte order), the stock `std_msgs` messages of per-item mode ([`stock`], by their interface
//! files' codec, and the bytes of an item's leaf made from them), and [`Payload`], what a
//! sample carries into shared memory once decoded.
//!
//! This is the bottom of the gateway, with the engines: it imports nothing of the routes.

use std::fmt;
use std::sync::Arc;

use serde::de::{DeserializeSeed, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Serialize};
pub use tutti_core::cdr::{split_header, CdrError, Payload, SetCodec, TypedSample, HEADER_LE};
use tutti_core::ddf::ScalarType;

/// The stock messages of per-item mode (`std_msgs/msg/Float64`, `Bool`, `Float64MultiArray`),
/// read and written by their interfaces' codec (`tutti_ros2`), and the bytes of an item's leaf
/// made from them.
pub mod stock {
    use tutti_core::ddf::{Leaf, ScalarType, Value};
    use tutti_core::mapping;
    use tutti_ros2::{registry, Message, Struct, Value as Field};

    use super::{split_header, CdrError};

    /// The stock type of a leaf.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Stock {
        Float64,
        Bool,
        Array,
    }

    impl Stock {
        pub fn of(leaf: &Leaf) -> Stock {
            match mapping::per_item_type(leaf.ty, leaf.length) {
                "std_msgs::msg::dds_::Bool_" => Stock::Bool,
                "std_msgs::msg::dds_::Float64_" => Stock::Float64,
                _ => Stock::Array,
            }
        }

        /// Its message, from the registry.
        pub fn message(self) -> Message<'static> {
            let name = match self {
                Stock::Float64 => "std_msgs/msg/Float64",
                Stock::Bool => "std_msgs/msg/Bool",
                Stock::Array => "std_msgs/msg/Float64MultiArray",
            };
            match registry().message(name) {
                Some(m) => m,
                None => unreachable!("{name} is an embedded interface"),
            }
        }
    }

    /// A codec error as the gateway's.
    fn cdr(e: tutti_ros2::CdrError) -> CdrError {
        CdrError::Engine(e.to_string())
    }

    /// A serialized stock sample as its message's value.
    fn value(stock: Stock, raw: &[u8]) -> Result<Field, CdrError> {
        let (le, body) = split_header(raw)?;
        stock.message().decode(body, le).map_err(cdr)
    }

    /// The `data` of a stock message's value.
    fn data(v: &Field) -> Result<&Field, CdrError> {
        v.get("data").ok_or(CdrError::Unexpected("a stock message without its data"))
    }

    fn as_f64(v: &Field) -> Result<f64, CdrError> {
        v.as_f64().ok_or(CdrError::Unexpected("a double that is no number"))
    }

    /// The data of a `std_msgs/msg/Float64MultiArray` value (its layout is read past, not used).
    fn doubles(v: &Field) -> Result<Vec<f64>, CdrError> {
        let elements = data(v)?.as_array().ok_or(CdrError::Unexpected("a Float64MultiArray without data"))?;
        elements.iter().map(as_f64).collect()
    }

    /// `std_msgs/msg/Float64` from a serialized sample.
    pub fn float64(raw: &[u8]) -> Result<f64, CdrError> {
        as_f64(data(&value(Stock::Float64, raw)?)?)
    }

    /// `std_msgs/msg/Bool` from a serialized sample.
    pub fn boolean(raw: &[u8]) -> Result<bool, CdrError> {
        data(&value(Stock::Bool, raw)?)?.as_bool().ok_or(CdrError::Unexpected("a Bool that is no boolean"))
    }

    /// The data of a `std_msgs/msg/Float64MultiArray` from a serialized sample.
    pub fn float64_array(raw: &[u8]) -> Result<Vec<f64>, CdrError> {
        doubles(&value(Stock::Array, raw)?)
    }

    /// The bytes of `leaf` from its stock message's value (as an engine that decodes as it
    /// reads hands it over).
    pub fn leaf_of(leaf: &Leaf, v: &Field) -> Result<Vec<u8>, CdrError> {
        match Stock::of(leaf) {
            Stock::Float64 => Ok(leaf_bytes(leaf.ty, std::iter::once(Value::Float(as_f64(data(v)?)?)), 1)),
            Stock::Bool => {
                let b = data(v)?.as_bool().ok_or(CdrError::Unexpected("a Bool that is no boolean"))?;
                Ok(leaf_bytes(leaf.ty, std::iter::once(Value::Bool(b)), 1))
            }
            Stock::Array => array_leaf(leaf, doubles(v)?),
        }
    }

    /// Writes the little-endian CDR body of `stock` with `data` into `out` (cleared first).
    fn encode(stock: Stock, data: Field, out: &mut Vec<u8>) {
        out.clear();
        // `data` has the field's type: nothing in it can fail to encode.
        let _ = stock.message().encode_into(&Struct::new().with("data", data).into(), out);
    }

    /// The little-endian CDR body of a `Float64`.
    pub fn encode_float64(v: f64, out: &mut Vec<u8>) {
        encode(Stock::Float64, Field::Float(v), out);
    }

    /// The body of a `Bool`.
    pub fn encode_bool(v: bool, out: &mut Vec<u8>) {
        encode(Stock::Bool, Field::Bool(v), out);
    }

    /// The body of a `Float64MultiArray` with an empty layout.
    pub fn encode_float64_array(v: impl ExactSizeIterator<Item = f64>, out: &mut Vec<u8>) {
        encode(Stock::Array, Field::Array(v.map(Field::Float).collect()), out);
    }

    /// `n` values of type `ty`, in shared-memory layout.
    pub fn leaf_bytes(ty: ScalarType, values: impl Iterator<Item = Value>, n: usize) -> Vec<u8> {
        let size = ty.size() as usize;
        let mut out = vec![0u8; size * n];
        for (chunk, v) in out.chunks_exact_mut(size).zip(values) {
            ty.encode(v, chunk);
        }
        out
    }

    /// The bytes of array `leaf` from the data of a `Float64MultiArray`.
    pub fn array_leaf(leaf: &Leaf, data: Vec<f64>) -> Result<Vec<u8>, CdrError> {
        let n = usize::from(leaf.length);
        if data.len() != n {
            return Err(CdrError::ArrayLength { path: leaf.path.clone(), expected: n, got: data.len() });
        }
        Ok(leaf_bytes(leaf.ty, data.into_iter().map(Value::Float), n))
    }

    /// The bytes of `leaf` from a serialized stock sample.
    pub fn decode(leaf: &Leaf, raw: &[u8]) -> Result<Vec<u8>, CdrError> {
        leaf_of(leaf, &value(Stock::of(leaf), raw)?)
    }
}

/// A CDR body already encoded, passed through ros2-client's serde-only publisher: a tuple
/// of bytes is written verbatim (no length prefix, bytes need no alignment).
#[derive(Debug, Clone, Default)]
pub struct PreEncoded(pub Vec<u8>);

impl Serialize for PreEncoded {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(self.0.len())?;
        for b in &self.0 {
            t.serialize_element(b)?;
        }
        t.end()
    }
}

/// Reads a typed sample of one set through a serde CDR deserializer.
#[derive(Debug, Clone)]
pub struct SetSeed(pub Arc<SetCodec>);

impl<'de> DeserializeSeed<'de> for SetSeed {
    type Value = TypedSample;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<TypedSample, D::Error> {
        let elements = 2 + self.0.fields().iter().map(|f| f.count).sum::<usize>();
        d.deserialize_tuple(elements, self)
    }
}

impl<'de> Visitor<'de> for SetSeed {
    type Value = TypedSample;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a typed set sample of {} CDR bytes", self.0.cdr_size())
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<TypedSample, A::Error> {
        fn next<'de, T: Deserialize<'de>, A: SeqAccess<'de>>(seq: &mut A) -> Result<T, A::Error> {
            seq.next_element::<T>()?.ok_or_else(|| serde::de::Error::custom("truncated sample"))
        }
        let step: u64 = next(&mut seq)?;
        let sim_time: f64 = next(&mut seq)?;
        let mut data = vec![0u8; self.0.shm_size()];
        for f in self.0.fields() {
            let size = f.ty.size() as usize;
            for i in 0..f.count {
                let at = f.shm + i * size;
                let out = &mut data[at..at + size];
                use ScalarType::*;
                match f.ty {
                    Boolean => out[0] = u8::from(next::<bool, A>(&mut seq)?),
                    Int8 => out.copy_from_slice(&next::<i8, A>(&mut seq)?.to_ne_bytes()),
                    UInt8 => out.copy_from_slice(&next::<u8, A>(&mut seq)?.to_ne_bytes()),
                    Int16 => out.copy_from_slice(&next::<i16, A>(&mut seq)?.to_ne_bytes()),
                    UInt16 => out.copy_from_slice(&next::<u16, A>(&mut seq)?.to_ne_bytes()),
                    Int32 => out.copy_from_slice(&next::<i32, A>(&mut seq)?.to_ne_bytes()),
                    UInt32 => out.copy_from_slice(&next::<u32, A>(&mut seq)?.to_ne_bytes()),
                    Int64 => out.copy_from_slice(&next::<i64, A>(&mut seq)?.to_ne_bytes()),
                    UInt64 => out.copy_from_slice(&next::<u64, A>(&mut seq)?.to_ne_bytes()),
                    Float32 => out.copy_from_slice(&next::<f32, A>(&mut seq)?.to_ne_bytes()),
                    Float64 => out.copy_from_slice(&next::<f64, A>(&mut seq)?.to_ne_bytes()),
                }
            }
        }
        Ok(TypedSample { step, sim_time, data })
    }
}

#[cfg(all(test, feature = "rustdds"))]
mod tests {
    use super::*;
    use ros2_client::dds::rustdds::cdr_encoding::to_vec;
    use ros2_client::dds::rustdds::{CdrDeserializer, RepresentationIdentifier};
    use tutti_core::ddf::{parse_str, SetLayout};

    type LE = ros2_client::dds::rustdds::bytes::Bytes;

    fn codec(items: &str) -> (SetCodec, SetLayout) {
        let ddf = format!(
            r#"<orchestra><domain name="d"><synchronous>no</synchronous><multiplePublishAllowed>no</multiplePublishAllowed>
               <states>no</states><block name="d/Publish">{items}</block></domain></orchestra>"#
        );
        let m = parse_str(&ddf, "t.ddf").unwrap();
        let l = m.domains[0].publish.layout.clone();
        (SetCodec::new(&l), l)
    }

    fn item(name: &str, ty: &str) -> String {
        format!("<item name=\"{name}\"><type>{ty}</type></item>")
    }

    #[test]
    fn alignment_is_relative_to_the_body_and_nested_structs_add_no_padding() {
        // C layout: a@0 (bool) v@8..32 (3 doubles); CDR: step 0, sim_time 8, a@16, v@24.
        let (c, _) = codec(
            &(item("a", "boolean")
                + "<item name=\"v\"><type>double</type><length>3</length></item>"
                + &item("t", "int8")),
        );
        assert_eq!(c.fields().iter().map(|f| f.cdr).collect::<Vec<_>>(), vec![16, 24, 48]);
        assert_eq!(c.cdr_size(), 49);
    }

    #[test]
    fn encoding_matches_the_cdr_engine_of_rustdds() {
        #[derive(Serialize)]
        struct Bus {
            p: f32,
            c: i8,
        }
        #[derive(Serialize)]
        struct Expected {
            step: u64,
            sim_time: f64,
            a: bool,
            b: Bus,
            s: u16,
            d: [f64; 2],
        }
        let items = item("a", "boolean")
            + "<item name=\"b\"><type>bus</type>"
            + &item("p", "float32")
            + &item("c", "int8")
            + "</item>"
            + &item("s", "uint16")
            + "<item name=\"d\"><type>double</type><length>2</length></item>";
        let (c, l) = codec(&items);
        let mut shm = vec![0u8; l.size as usize];
        let put = |shm: &mut Vec<u8>, path: &str, b: &[u8]| {
            let o = l.leaf(path).unwrap().offset as usize;
            shm[o..o + b.len()].copy_from_slice(b);
        };
        put(&mut shm, "a", &[1]);
        put(&mut shm, "b/p", &1.5f32.to_le_bytes());
        put(&mut shm, "b/c", &(-3i8).to_le_bytes());
        put(&mut shm, "s", &700u16.to_le_bytes());
        put(&mut shm, "d", &[2.5f64.to_le_bytes(), (-1.0f64).to_le_bytes()].concat());
        let mut body = Vec::new();
        c.encode(42, 0.125, &shm, &mut body);
        let want = Expected { step: 42, sim_time: 0.125, a: true, b: Bus { p: 1.5, c: -3 }, s: 700, d: [2.5, -1.0] };
        let want = to_vec::<_, byteorder::LittleEndian>(&want).unwrap();
        assert_eq!(&body[..], &want[..body.len()]);
        assert!(want[body.len()..].iter().all(|&b| b == 0), "only trailing padding may differ");

        // And back, in both byte orders.
        let seed = SetSeed(Arc::new(c.clone()));
        let got = seed.clone().deserialize(&mut CdrDeserializer::<byteorder::LittleEndian>::new(&body)).unwrap();
        assert_eq!(got, TypedSample { step: 42, sim_time: 0.125, data: shm.clone() });
        let be = to_vec::<_, byteorder::BigEndian>(&Expected {
            step: 42,
            sim_time: 0.125,
            a: true,
            b: Bus { p: 1.5, c: -3 },
            s: 700,
            d: [2.5, -1.0],
        })
        .unwrap();
        let got = seed.deserialize(&mut CdrDeserializer::<byteorder::BigEndian>::new(&be)).unwrap();
        assert_eq!(got.data, shm);
        let _ = (RepresentationIdentifier::CDR_LE, LE::new());
    }

    #[test]
    fn the_raw_decoder_reads_what_the_serde_decoder_reads_in_both_byte_orders() {
        let items = item("a", "boolean")
            + &item("s", "int16")
            + "<item name=\"d\"><type>double</type><length>2</length></item>"
            + &item("f", "float32");
        let (c, l) = codec(&items);
        let mut shm = vec![0u8; l.size as usize];
        for (i, b) in shm.iter_mut().enumerate() {
            *b = (i * 7 + 3) as u8;
        }
        shm[l.leaf("a").unwrap().offset as usize] = 1;
        // Only the leaves travel: compare with what the serde path rebuilds.
        let mut body = Vec::new();
        c.encode(9, 1.5, &shm, &mut body);
        let seed = SetSeed(Arc::new(c.clone()));
        let want = seed.deserialize(&mut CdrDeserializer::<byteorder::LittleEndian>::new(&body)).unwrap();
        let raw = [&HEADER_LE[..], &body].concat();
        assert_eq!(c.decode(&raw).unwrap(), want);
        // The same sample big-endian: every element reversed in place.
        let mut be = body.clone();
        be[0..8].reverse();
        be[8..16].reverse();
        for f in c.fields() {
            let size = f.ty.size() as usize;
            be[f.cdr..f.cdr + size * f.count].chunks_exact_mut(size).for_each(<[u8]>::reverse);
        }
        assert_eq!(c.decode(&[&[0u8, 0, 0, 0][..], &be].concat()).unwrap(), want);
        // Short bodies, no header, another representation.
        for n in [0, 3, 4, 20, raw.len() - 1] {
            assert!(c.decode(&raw[..n]).is_err(), "{n} bytes accepted");
        }
        let err = c.decode(&[&[0u8, 7, 0, 0][..], &body].concat()).unwrap_err().to_string();
        assert!(err.contains("0007"), "{err}");
    }

    #[test]
    fn stock_messages_round_trip_through_their_interfaces_codec() {
        let mut b = Vec::new();
        stock::encode_float64_array([1.0, -2.5].into_iter(), &mut b);
        // dim length 0, data_offset 0, data length 2, pad, two doubles.
        let mut want = vec![0, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0];
        want.extend_from_slice(&1.0f64.to_le_bytes());
        want.extend_from_slice(&(-2.5f64).to_le_bytes());
        assert_eq!(b, want);
        assert_eq!(stock::float64_array(&[&HEADER_LE[..], &b].concat()).unwrap(), vec![1.0, -2.5]);
        // A layout with a labelled dimension is read past, big-endian too.
        let mut labelled = vec![0, 0, 0, 1, 0, 0, 0, 4, b'x', b'y', b'z', 0, 0, 0, 0, 3, 0, 0, 0, 3];
        labelled.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 3, 0, 0, 0, 0]);
        for v in [4.0f64, 5.0, 6.0] {
            labelled.extend_from_slice(&v.to_be_bytes());
        }
        assert_eq!(stock::float64_array(&[&[0u8, 0, 0, 0][..], &labelled].concat()).unwrap(), vec![4.0, 5.0, 6.0]);
        assert!(stock::float64_array(&[&HEADER_LE[..], &b[..b.len() - 1]].concat()).is_err());
        stock::encode_float64(0.25, &mut b);
        assert_eq!(b, 0.25f64.to_le_bytes());
        assert_eq!(stock::float64(&[&HEADER_LE[..], &b].concat()).unwrap(), 0.25);
        stock::encode_bool(true, &mut b);
        assert_eq!(b, [1]);
        assert!(stock::boolean(&[&HEADER_LE[..], &b].concat()).unwrap());
        assert!(stock::boolean(&HEADER_LE).is_err());
    }

    #[test]
    fn truncated_bodies_are_refused() {
        let (c, _) = codec(&(item("x", "double") + &item("y", "double")));
        let mut body = Vec::new();
        c.encode(1, 0.0, &[0u8; 16], &mut body);
        let seed = SetSeed(Arc::new(c));
        for n in [0, 7, 16, 24, 31] {
            let r = seed.clone().deserialize(&mut CdrDeserializer::<byteorder::LittleEndian>::new(&body[..n]));
            assert!(r.is_err(), "{n} bytes accepted");
        }
    }
}
