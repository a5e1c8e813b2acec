//! Any ROS 2 message read through rustdds' serde CDR deserializer into a [`Value`], driven by
//! its interface's spec (`tutti_ros2`): ros2-client's typed subscriptions decode as they read,
//! and this seed makes them read a message no Rust type was written for (the per-item stock
//! messages), with the interface file the only definition of its layout.

use std::fmt;

use serde::de::{DeserializeSeed, Error as _, SeqAccess, Visitor};
use serde::Deserializer;
use tutti_ros2::{BaseType, FieldType, Message, Primitive, Shape, Struct, Value};

/// Reads one message of `message`'s type.
#[derive(Clone, Copy)]
pub(crate) struct ValueSeed<'r>(pub Message<'r>);

impl<'de> DeserializeSeed<'de> for ValueSeed<'_> {
    type Value = Value;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Value, D::Error> {
        d.deserialize_tuple(self.0.spec().fields.len(), self)
    }
}

impl<'de> Visitor<'de> for ValueSeed<'_> {
    type Value = Value;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a {}", self.0.name())
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut s = Struct::new();
        for field in &self.0.spec().fields {
            let seed = FieldSeed { message: self.0, ty: &field.ty };
            let v = seq.next_element_seed(seed)?.ok_or_else(|| A::Error::custom("truncated sample"))?;
            s.set(&field.name, v);
        }
        Ok(Value::Struct(s))
    }
}

/// One field: its values as its shape says.
#[derive(Clone, Copy)]
struct FieldSeed<'a, 'r> {
    message: Message<'r>,
    ty: &'a FieldType,
}

impl<'de> DeserializeSeed<'de> for FieldSeed<'_, '_> {
    type Value = Value;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Value, D::Error> {
        let base = BaseSeed { message: self.message, base: &self.ty.base };
        match self.ty.shape {
            Shape::Single => base.deserialize(d),
            Shape::Array(n) => {
                let n = usize::try_from(n).map_err(D::Error::custom)?;
                d.deserialize_tuple(n, Elements { base, fixed: Some(n) })
            }
            Shape::Bounded(_) | Shape::Unbounded => d.deserialize_seq(Elements { base, fixed: None }),
        }
    }
}

/// The elements of an array or a sequence.
struct Elements<'a, 'r> {
    base: BaseSeed<'a, 'r>,
    fixed: Option<usize>,
}

impl<'de> Visitor<'de> for Elements<'_, '_> {
    type Value = Value;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an array or a sequence")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut out = Vec::new();
        loop {
            if self.fixed.is_some_and(|n| out.len() == n) {
                break;
            }
            match seq.next_element_seed(self.base)? {
                Some(v) => out.push(v),
                None if self.fixed.is_none() => break,
                None => return Err(A::Error::custom("truncated array")),
            }
        }
        Ok(Value::Array(out))
    }
}

/// One value of a base type.
#[derive(Clone, Copy)]
struct BaseSeed<'a, 'r> {
    message: Message<'r>,
    base: &'a BaseType,
}

impl<'de> DeserializeSeed<'de> for BaseSeed<'_, '_> {
    type Value = Value;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Value, D::Error> {
        use Primitive::*;
        match self.base {
            BaseType::Primitive(p) => match p {
                Bool => d.deserialize_bool(Scalar),
                Byte | Char | UInt8 => d.deserialize_u8(Scalar),
                Int8 => d.deserialize_i8(Scalar),
                Int16 => d.deserialize_i16(Scalar),
                UInt16 => d.deserialize_u16(Scalar),
                Int32 => d.deserialize_i32(Scalar),
                UInt32 => d.deserialize_u32(Scalar),
                Int64 => d.deserialize_i64(Scalar),
                UInt64 => d.deserialize_u64(Scalar),
                Float32 => d.deserialize_f32(Scalar),
                Float64 => d.deserialize_f64(Scalar),
            },
            BaseType::String { .. } => d.deserialize_string(Scalar),
            BaseType::WString { .. } => Err(D::Error::custom("wstring has no codec")),
            BaseType::Nested(name) => match self.message.registry().message(&name.to_string()) {
                Some(m) => ValueSeed(m).deserialize(d),
                None => Err(D::Error::custom(format!("{name} is not described"))),
            },
        }
    }
}

/// A primitive or a string, as the deserializer hands it.
struct Scalar;

impl Visitor<'_> for Scalar {
    type Value = Value;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a primitive value or a string")
    }

    fn visit_bool<E>(self, v: bool) -> Result<Value, E> {
        Ok(Value::Bool(v))
    }

    fn visit_i64<E>(self, v: i64) -> Result<Value, E> {
        Ok(Value::Int(v))
    }

    fn visit_u64<E>(self, v: u64) -> Result<Value, E> {
        Ok(Value::UInt(v))
    }

    fn visit_f64<E>(self, v: f64) -> Result<Value, E> {
        Ok(Value::Float(v))
    }

    fn visit_str<E>(self, v: &str) -> Result<Value, E> {
        Ok(Value::String(v.to_string()))
    }

    fn visit_string<E>(self, v: String) -> Result<Value, E> {
        Ok(Value::String(v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ros2_client::dds::rustdds::CdrDeserializer;

    /// What the interface's own codec writes, rustdds' deserializer reads back through the
    /// seed, in either byte order: nested messages, sequences, strings and fixed arrays.
    #[test]
    fn the_seed_reads_what_the_codec_writes() {
        let r = tutti_ros2::registry();
        let m = r.message("std_msgs/msg/Float64MultiArray").unwrap();
        let dim = Struct::new().with("label", "xyz").with("size", 3u32).with("stride", 3u32);
        let layout = Struct::new().with("dim", vec![Value::from(dim)]).with("data_offset", 0u32);
        let v: Value = Struct::new()
            .with("layout", layout)
            .with("data", vec![Value::Float(4.0), Value::Float(-5.5), Value::Float(6.0)])
            .into();
        let body = m.encode(&v).unwrap();
        let back = ValueSeed(m).deserialize(&mut CdrDeserializer::<byteorder::LittleEndian>::new(&body)).unwrap();
        assert_eq!(m.encode(&back).unwrap(), body);
        assert_eq!(
            back.path("layout.dim").and_then(|d| d.at(0)).and_then(|d| d.get("label")),
            Some(&Value::from("xyz"))
        );
        let gid = r.message("rmw_dds_common/msg/Gid").unwrap();
        let g: Value = Struct::new().with("data", (0u8..16).map(Value::from).collect::<Vec<_>>()).into();
        let body = gid.encode(&g).unwrap();
        let back = ValueSeed(gid).deserialize(&mut CdrDeserializer::<byteorder::BigEndian>::new(&body)).unwrap();
        assert_eq!(back, g, "bytes need no byte order");
        let f = r.message("std_msgs/msg/Float64").unwrap();
        let be = 2.5f64.to_be_bytes();
        let back = ValueSeed(f).deserialize(&mut CdrDeserializer::<byteorder::BigEndian>::new(&be)).unwrap();
        assert_eq!(back.get("data"), Some(&Value::Float(2.5)));
        assert!(ValueSeed(f).deserialize(&mut CdrDeserializer::<byteorder::LittleEndian>::new(&be[..4])).is_err());
    }
}
