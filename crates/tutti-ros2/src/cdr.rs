//! Plain CDR (XCDR1, as ROS 2 sends it) of any message of a registry, driven by its parsed
//! spec: a [`Value`] encoded into a body and a body decoded into a [`Value`]
//! (`registry::Message::encode`, `decode`).
//!
//! The body is the sample without its 4-byte encapsulation header. Each primitive is aligned
//! to its size (at most 8), counted from the start of the body; a string is its length with
//! its NUL as a `u32`, its bytes and the NUL; a sequence its count as a `u32`, then its
//! elements; a fixed-size array its elements; a nested message its fields in order. Encoding
//! writes little-endian; decoding reads either byte order.
//!
//! Encoding takes a message as a [`Value::Struct`]: a field it leaves out takes its `.msg`
//! default, else zero, empty or its nested message's defaults; a field the message does not
//! have, or a value of the wrong kind or out of its type's range, is an error. Decoding trusts
//! nothing: every count is checked against the bytes left before anything is allocated for
//! it, and every bound against its spec. `wstring` has no codec (ROS 2's wide strings differ
//! between DDS implementations): [`CdrError::Unsupported`].

use crate::registry::{Entry, Message, Registry};
use crate::spec::{BaseType, FieldType, Primitive, Shape, TypeName};
use crate::value::{Struct, Value};

/// Why a value cannot be encoded, or a body decoded. `path` is where: the type, then the
/// fields and indices down to the value (`geometry_msgs/msg/Polygon.points[2].x`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CdrError {
    #[error("{path}: the message has no field {field}")]
    UnknownField { path: String, field: String },
    #[error("{path}: expected {expected}, found a {found}")]
    WrongType { path: String, expected: String, found: &'static str },
    #[error("{path}: {value} is out of the range of {ty}")]
    OutOfRange { path: String, value: String, ty: &'static str },
    #[error("{path}: an array of {expected} elements, not {found}")]
    ArrayLength { path: String, expected: u64, found: usize },
    #[error("{path}: {len} elements or bytes, above the bound {bound}")]
    Bound { path: String, len: u64, bound: u64 },
    #[error("{path}: the body ends at byte {len}, before the {need} byte(s) at {at}")]
    Truncated { path: String, at: usize, need: usize, len: usize },
    #[error("{path}: a count of {count}, with only {left} byte(s) left")]
    Count { path: String, count: u64, left: usize },
    #[error("{path}: the string is not UTF-8")]
    Utf8 { path: String },
    #[error("{path}: {what} has no CDR codec")]
    Unsupported { path: String, what: &'static str },
    #[error("{path}: {len} elements or bytes do not fit a CDR length")]
    TooLong { path: String, len: usize },
}

/// One step of the path to a value.
#[derive(Debug, Clone, Copy)]
enum Seg<'a> {
    Field(&'a str),
    Index(u64),
}

/// Where the codec is in a message, for errors.
#[derive(Debug)]
struct Path<'r> {
    top: &'r TypeName,
    segs: Vec<Seg<'r>>,
}

impl Path<'_> {
    fn text(&self) -> String {
        let mut s = self.top.to_string();
        for seg in &self.segs {
            match seg {
                Seg::Field(f) => {
                    s.push('.');
                    s.push_str(f);
                }
                Seg::Index(i) => s.push_str(&format!("[{i}]")),
            }
        }
        s
    }
}

fn base_text(base: &BaseType) -> String {
    match base {
        BaseType::Primitive(p) => p.msg_name().to_string(),
        BaseType::String { .. } => "string".into(),
        BaseType::WString { .. } => "wstring".into(),
        BaseType::Nested(n) => format!("a {n}"),
    }
}

/// `value` of message `msg`, appended to `out` (aligned from `out`'s start).
pub(crate) fn encode(msg: Message<'_>, value: &Value, out: &mut Vec<u8>) -> Result<(), CdrError> {
    let mut e = Encoder { registry: msg.registry(), path: Path { top: msg.name(), segs: Vec::new() }, out };
    e.message(msg.entry(), Some(value))
}

struct Encoder<'r, 'o> {
    registry: &'r Registry,
    path: Path<'r>,
    out: &'o mut Vec<u8>,
}

impl<'r> Encoder<'r, '_> {
    fn wrong(&self, expected: String, found: &Value) -> CdrError {
        CdrError::WrongType { path: self.path.text(), expected, found: found.kind() }
    }

    fn align(&mut self, n: usize) {
        let len = self.out.len().next_multiple_of(n);
        self.out.resize(len, 0);
    }

    fn u32(&mut self, n: usize) -> Result<(), CdrError> {
        let n = u32::try_from(n).map_err(|_| CdrError::TooLong { path: self.path.text(), len: n })?;
        self.align(4);
        self.out.extend_from_slice(&n.to_le_bytes());
        Ok(())
    }

    fn message(&mut self, entry: &'r Entry, value: Option<&Value>) -> Result<(), CdrError> {
        let given: Option<&Struct> = match value {
            None => None,
            Some(Value::Struct(s)) => Some(s),
            Some(v) => return Err(self.wrong(format!("a {}", entry.spec.name), v)),
        };
        if let Some((field, _)) = given.and_then(|s| s.iter().find(|(n, _)| entry.spec.field(n).is_none())) {
            return Err(CdrError::UnknownField { path: self.path.text(), field: field.to_string() });
        }
        for (f, nested) in entry.spec.fields.iter().zip(&entry.nested) {
            self.path.segs.push(Seg::Field(&f.name));
            let v = given.and_then(|s| s.get(&f.name)).or(f.default.as_ref());
            self.field(&f.ty, *nested, v)?;
            self.path.segs.pop();
        }
        Ok(())
    }

    fn field(&mut self, ty: &'r FieldType, nested: Option<usize>, v: Option<&Value>) -> Result<(), CdrError> {
        let elements: &[Value] = match (ty.shape, v) {
            (Shape::Single, v) => return self.one(&ty.base, nested, v),
            (_, None) => &[][..],
            (_, Some(Value::Array(a))) => a.as_slice(),
            (_, Some(v)) => return Err(self.wrong(format!("an array of {}", base_text(&ty.base)), v)),
        };
        match ty.shape {
            Shape::Array(n) => {
                if v.is_some() && elements.len() as u64 != n {
                    return Err(CdrError::ArrayLength { path: self.path.text(), expected: n, found: elements.len() });
                }
                for i in 0..n {
                    self.path.segs.push(Seg::Index(i));
                    self.one(&ty.base, nested, usize::try_from(i).ok().and_then(|i| elements.get(i)))?;
                    self.path.segs.pop();
                }
                return Ok(());
            }
            Shape::Bounded(bound) if elements.len() as u64 > bound => {
                return Err(CdrError::Bound { path: self.path.text(), len: elements.len() as u64, bound });
            }
            _ => {}
        }
        self.u32(elements.len())?;
        for (i, e) in elements.iter().enumerate() {
            self.path.segs.push(Seg::Index(i as u64));
            self.one(&ty.base, nested, Some(e))?;
            self.path.segs.pop();
        }
        Ok(())
    }

    fn one(&mut self, base: &'r BaseType, nested: Option<usize>, v: Option<&Value>) -> Result<(), CdrError> {
        match base {
            BaseType::Primitive(p) => self.primitive(*p, v),
            BaseType::String { bound } => {
                let s = match v {
                    None => "",
                    Some(Value::String(s)) => s,
                    Some(v) => return Err(self.wrong("a string".into(), v)),
                };
                if let Some(bound) = bound.filter(|b| s.len() as u64 > *b) {
                    return Err(CdrError::Bound { path: self.path.text(), len: s.len() as u64, bound });
                }
                self.u32(s.len() + 1)?;
                self.out.extend_from_slice(s.as_bytes());
                self.out.push(0);
                Ok(())
            }
            BaseType::WString { .. } => Err(CdrError::Unsupported { path: self.path.text(), what: "wstring" }),
            BaseType::Nested(_) => match nested {
                Some(i) => self.message(&self.registry.entries[i], v),
                None => Err(CdrError::Unsupported { path: self.path.text(), what: "an unresolved nested type" }),
            },
        }
    }

    /// The 8 little-endian bytes of integer `n`, when it is in `range` of type `p`.
    fn integer(&self, p: Primitive, n: i128, (lo, hi): (i128, i128)) -> Result<[u8; 8], CdrError> {
        if !(lo..=hi).contains(&n) {
            return Err(CdrError::OutOfRange { path: self.path.text(), value: n.to_string(), ty: p.msg_name() });
        }
        Ok(widen(&n.to_le_bytes()[..8]))
    }

    fn primitive(&mut self, p: Primitive, v: Option<&Value>) -> Result<(), CdrError> {
        let bytes: [u8; 8] = match (p, v, p.int_range()) {
            (_, None, _) => [0; 8],
            (Primitive::Bool, Some(Value::Bool(b)), _) => [u8::from(*b), 0, 0, 0, 0, 0, 0, 0],
            (Primitive::Float32, Some(Value::Float(f)), _) => widen(&(*f as f32).to_le_bytes()),
            (Primitive::Float64, Some(Value::Float(f)), _) => f.to_le_bytes(),
            (p, Some(Value::Int(i)), Some(range)) => self.integer(p, i128::from(*i), range)?,
            (p, Some(Value::UInt(u)), Some(range)) => self.integer(p, i128::from(*u), range)?,
            (p, Some(v), _) => return Err(self.wrong(format!("a {}", p.msg_name()), v)),
        };
        self.align(p.size());
        self.out.extend_from_slice(&bytes[..p.size()]);
        Ok(())
    }
}

/// Up to 8 little-endian bytes, zero-padded.
fn widen(b: &[u8]) -> [u8; 8] {
    let mut out = [0u8; 8];
    out[..b.len()].copy_from_slice(b);
    out
}

/// The message `msg` at `start` of `body`, and the offset after it.
pub(crate) fn decode(msg: Message<'_>, body: &[u8], start: usize, le: bool) -> Result<(Value, usize), CdrError> {
    let mut d =
        Decoder { registry: msg.registry(), path: Path { top: msg.name(), segs: Vec::new() }, b: body, pos: start, le };
    let v = d.message(msg.entry())?;
    Ok((v, d.pos))
}

struct Decoder<'r, 'b> {
    registry: &'r Registry,
    path: Path<'r>,
    b: &'b [u8],
    pos: usize,
    le: bool,
}

impl<'r, 'b> Decoder<'r, 'b> {
    fn left(&self) -> usize {
        self.b.len().saturating_sub(self.pos)
    }

    fn truncated(&self, at: usize, need: usize) -> CdrError {
        CdrError::Truncated { path: self.path.text(), at, need, len: self.b.len() }
    }

    /// `n` bytes at the next multiple of `align`.
    fn take(&mut self, n: usize, align: usize) -> Result<&'b [u8], CdrError> {
        let at = self.pos.next_multiple_of(align);
        let s = at.checked_add(n).and_then(|end| self.b.get(at..end)).ok_or_else(|| self.truncated(at, n))?;
        self.pos = at + n;
        Ok(s)
    }

    /// `n` bytes as a little-endian u64 (sign-extended when `signed`).
    fn number(&mut self, n: usize, signed: bool) -> Result<u64, CdrError> {
        let s = self.take(n, n)?;
        let mut le = [0u8; 8];
        le[..n].copy_from_slice(s);
        if !self.le {
            le[..n].reverse();
        }
        if signed && le[n - 1] & 0x80 != 0 {
            le[n..].fill(0xff);
        }
        Ok(u64::from_le_bytes(le))
    }

    /// A count (`u32`), which cannot exceed the bytes left (every element takes one at least).
    fn count(&mut self) -> Result<usize, CdrError> {
        let n = self.number(4, false)?;
        match usize::try_from(n) {
            Ok(n) if n <= self.left() => Ok(n),
            _ => Err(CdrError::Count { path: self.path.text(), count: n, left: self.left() }),
        }
    }

    fn message(&mut self, entry: &'r Entry) -> Result<Value, CdrError> {
        let mut s = Struct::new();
        for (f, nested) in entry.spec.fields.iter().zip(&entry.nested) {
            self.path.segs.push(Seg::Field(&f.name));
            let v = self.field(&f.ty, *nested)?;
            self.path.segs.pop();
            s.set(&f.name, v);
        }
        Ok(Value::Struct(s))
    }

    fn field(&mut self, ty: &'r FieldType, nested: Option<usize>) -> Result<Value, CdrError> {
        let n = match ty.shape {
            Shape::Single => return self.one(&ty.base, nested),
            Shape::Array(n) => match usize::try_from(n) {
                Ok(n) if n <= self.left() => n,
                _ => return Err(CdrError::Count { path: self.path.text(), count: n, left: self.left() }),
            },
            Shape::Bounded(bound) => {
                let n = self.count()?;
                if n as u64 > bound {
                    return Err(CdrError::Bound { path: self.path.text(), len: n as u64, bound });
                }
                n
            }
            Shape::Unbounded => self.count()?,
        };
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            self.path.segs.push(Seg::Index(i as u64));
            out.push(self.one(&ty.base, nested)?);
            self.path.segs.pop();
        }
        Ok(Value::Array(out))
    }

    fn one(&mut self, base: &'r BaseType, nested: Option<usize>) -> Result<Value, CdrError> {
        match base {
            BaseType::Primitive(p) => self.primitive(*p),
            BaseType::String { bound } => {
                let n = self.count()?;
                let bytes = self.take(n, 1)?;
                let bytes = bytes.strip_suffix(&[0]).unwrap_or(bytes);
                if let Some(bound) = bound.filter(|b| bytes.len() as u64 > *b) {
                    return Err(CdrError::Bound { path: self.path.text(), len: bytes.len() as u64, bound });
                }
                let s = std::str::from_utf8(bytes).map_err(|_| CdrError::Utf8 { path: self.path.text() })?;
                Ok(Value::String(s.to_string()))
            }
            BaseType::WString { .. } => Err(CdrError::Unsupported { path: self.path.text(), what: "wstring" }),
            BaseType::Nested(_) => match nested {
                Some(i) => self.message(&self.registry.entries[i]),
                None => Err(CdrError::Unsupported { path: self.path.text(), what: "an unresolved nested type" }),
            },
        }
    }

    fn primitive(&mut self, p: Primitive) -> Result<Value, CdrError> {
        let bits = self.number(p.size(), p.is_signed())?;
        Ok(match p {
            Primitive::Bool => Value::Bool(bits != 0),
            Primitive::Float32 => Value::Float(f64::from(f32::from_bits(bits as u32))),
            Primitive::Float64 => Value::Float(f64::from_bits(bits)),
            p if p.is_signed() => Value::Int(bits as i64),
            _ => Value::UInt(bits),
        })
    }
}

/// Message `msg` with every field at its default: its `.msg` default, else zero or empty.
pub(crate) fn default_value(msg: Message<'_>) -> Value {
    let entry = msg.entry();
    let s = entry
        .spec
        .fields
        .iter()
        .zip(&entry.nested)
        .map(|(f, nested)| {
            let v = f.default.clone().unwrap_or_else(|| {
                let one = || zero(msg.registry(), &f.ty.base, *nested);
                match f.ty.shape {
                    Shape::Single => one(),
                    Shape::Array(n) => Value::Array((0..n).map(|_| one()).collect()),
                    Shape::Bounded(_) | Shape::Unbounded => Value::Array(Vec::new()),
                }
            });
            (f.name.clone(), v)
        })
        .collect();
    Value::Struct(s)
}

fn zero(registry: &Registry, base: &BaseType, nested: Option<usize>) -> Value {
    match base {
        BaseType::Primitive(Primitive::Bool) => Value::Bool(false),
        BaseType::Primitive(p) if p.is_float() => Value::Float(0.0),
        BaseType::Primitive(p) if p.is_signed() => Value::Int(0),
        BaseType::Primitive(_) => Value::UInt(0),
        BaseType::String { .. } | BaseType::WString { .. } => Value::String(String::new()),
        BaseType::Nested(_) => nested.map_or(Value::Struct(Struct::new()), |i| default_value(registry.at(i))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registry::Registry;
    use crate::spec::Kind;

    fn registry(files: &[(&str, &str)]) -> Registry {
        let mut b = Registry::builder();
        for (name, text) in files {
            b.file("p", Kind::Msg, name, text).unwrap();
        }
        b.build().unwrap()
    }

    #[test]
    fn alignment_counts_from_the_body_and_strings_carry_their_nul() {
        let r = registry(&[("A", "uint8 a\nfloat64 b\nstring s\nint16[] v\nB inner\n"), ("B", "bool x\nuint32 y 7\n")]);
        let m = r.message("p/msg/A").unwrap();
        let v = Struct::new().with("a", 1u8).with("b", -2.0f64).with("s", "hi").with("v", vec![-1i16, 2]).into();
        let body = m.encode(&v).unwrap();
        let mut want = vec![1, 0, 0, 0, 0, 0, 0, 0];
        want.extend_from_slice(&(-2.0f64).to_le_bytes());
        want.extend_from_slice(&[3, 0, 0, 0, b'h', b'i', 0, 0]);
        want.extend_from_slice(&[2, 0, 0, 0, 0xff, 0xff, 2, 0]);
        want.extend_from_slice(&[0, 0, 0, 0, 7, 0, 0, 0]);
        assert_eq!(body, want);
        let back = m.decode(&body, true).unwrap();
        assert_eq!(back.get("inner").and_then(|i| i.get("y")), Some(&Value::UInt(7)));
        assert_eq!(back.get("v"), Some(&Value::Array(vec![Value::Int(-1), Value::Int(2)])));
        assert_eq!(back.get("s").and_then(Value::as_str), Some("hi"));
        // After a 16-byte request header, alignment still counts from the body's start.
        let mut out = vec![9; 3];
        r.message("p/msg/B").unwrap().encode_into(&Struct::new().into(), &mut out).unwrap();
        assert_eq!(out, [9, 9, 9, 0, 7, 0, 0, 0]);
    }

    #[test]
    fn big_endian_bodies_decode_too() {
        let r = registry(&[("A", "int16 a\nfloat32 b\nuint64[] c\n")]);
        let m = r.message("p/msg/A").unwrap();
        let mut be = vec![0xff, 0xfe, 0, 0];
        be.extend_from_slice(&1.5f32.to_be_bytes());
        be.extend_from_slice(&[0, 0, 0, 1, 0, 0, 0, 0]);
        be.extend_from_slice(&u64::MAX.to_be_bytes());
        let v = m.decode(&be, false).unwrap();
        assert_eq!(v.get("a"), Some(&Value::Int(-2)));
        assert_eq!(v.get("b"), Some(&Value::Float(1.5)));
        assert_eq!(v.get("c"), Some(&Value::Array(vec![Value::UInt(u64::MAX)])));
    }

    #[test]
    fn wrong_values_are_errors_that_say_where() {
        let r = registry(&[("A", "uint8 a\nint8[2] b\nstring<=2 s\nB[<=1] bs\n"), ("B", "float64 x\n")]);
        let m = r.message("p/msg/A").unwrap();
        let err = |v: Struct| m.encode(&v.into()).unwrap_err();
        assert_eq!(
            err(Struct::new().with("a", 256u32)),
            CdrError::OutOfRange { path: "p/msg/A.a".into(), value: "256".into(), ty: "uint8" }
        );
        assert_eq!(err(Struct::new().with("a", -1i8)).to_string(), "p/msg/A.a: -1 is out of the range of uint8");
        assert!(matches!(err(Struct::new().with("zz", 1u8)), CdrError::UnknownField { field, .. } if field == "zz"));
        assert!(matches!(err(Struct::new().with("a", 1.0f64)), CdrError::WrongType { .. }));
        assert!(matches!(err(Struct::new().with("b", vec![1i8])), CdrError::ArrayLength { expected: 2, found: 1, .. }));
        assert!(matches!(err(Struct::new().with("s", "abc")), CdrError::Bound { len: 3, bound: 2, .. }));
        let two = vec![Struct::new(), Struct::new()];
        assert!(matches!(err(Struct::new().with("bs", two)), CdrError::Bound { len: 2, bound: 1, .. }));
        let e = err(Struct::new().with("bs", vec![Struct::new().with("x", true)]));
        assert_eq!(e.to_string(), "p/msg/A.bs[0].x: expected a float64, found a bool");
    }

    #[test]
    fn hostile_bodies_are_errors() {
        let r = registry(&[("A", "string s\nuint8[] v\n"), ("B", "string<=1 s\n")]);
        let m = r.message("p/msg/A").unwrap();
        let e = m.decode(&[0xff, 0xff, 0xff, 0xff], true).unwrap_err();
        assert!(matches!(e, CdrError::Count { count: 0xffff_ffff, left: 0, .. }), "{e}");
        assert!(matches!(m.decode(&[2, 0, 0, 0, 0xc3, 0], true), Err(CdrError::Utf8 { .. })));
        assert!(matches!(m.decode(&[1, 0, 0], true), Err(CdrError::Truncated { .. })));
        assert!(matches!(m.decode(&[1, 0, 0, 0, 0, 0, 0, 0, 9, 0, 0, 0], true), Err(CdrError::Count { count: 9, .. })));
        let b = r.message("p/msg/B").unwrap();
        assert!(matches!(b.decode(&[3, 0, 0, 0, b'a', b'b', 0], true), Err(CdrError::Bound { len: 2, .. })));
    }

    #[test]
    fn defaults_fill_what_a_value_leaves_out() {
        let r =
            registry(&[("A", "uint8 a 3\nB b\nfloat32[2] f [0.5, 1]\nstring[] s\n"), ("B", "bool x true\nint8 y\n")]);
        let m = r.message("p/msg/A").unwrap();
        let d = m.default_value();
        assert_eq!(d.path("b.x"), Some(&Value::Bool(true)));
        assert_eq!(d.get("f"), Some(&Value::Array(vec![Value::Float(0.5), Value::Float(1.0)])));
        assert_eq!(m.encode(&Struct::new().into()).unwrap(), m.encode(&d).unwrap());
        assert_eq!(m.decode(&m.encode(&Struct::new().into()).unwrap(), true).unwrap(), d);
    }
}
