//! A message as a value: the tree the CDR codec (`cdr`) encodes and decodes, and what `.msg`
//! defaults and constants are.
//!
//! A message is a [`Struct`]: its fields by name, in the order of its spec once decoded.
//! Integers are [`Value::Int`] (signed types) or [`Value::UInt`] (unsigned, `byte` and `char`),
//! both `float32` and `float64` are [`Value::Float`], and arrays and sequences alike are
//! [`Value::Array`].

use std::fmt;

use serde::ser::{SerializeMap, SerializeSeq};
use serde::{Serialize, Serializer};

/// One value of a message.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Bool(bool),
    /// A signed integer.
    Int(i64),
    /// An unsigned integer (`byte` and `char` too).
    UInt(u64),
    /// `float32` or `float64`.
    Float(f64),
    /// `string` (`wstring` has no codec: `cdr::CdrError::Unsupported`).
    String(String),
    /// A fixed-size array or a sequence.
    Array(Vec<Value>),
    /// A nested message.
    Struct(Struct),
}

/// The fields of a message, by name, in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Struct {
    fields: Vec<(String, Value)>,
}

impl Struct {
    /// No fields: a message whose fields all take their defaults.
    pub fn new() -> Struct {
        Struct::default()
    }

    /// This struct with field `name` set to `value`.
    pub fn with(mut self, name: &str, value: impl Into<Value>) -> Struct {
        self.set(name, value);
        self
    }

    /// Sets field `name` (replacing it, in place, if it is there; else appending it).
    pub fn set(&mut self, name: &str, value: impl Into<Value>) {
        let value = value.into();
        match self.fields.iter_mut().find(|(n, _)| n == name) {
            Some((_, v)) => *v = value,
            None => self.fields.push((name.to_string(), value)),
        }
    }

    /// Field `name`.
    pub fn get(&self, name: &str) -> Option<&Value> {
        self.fields.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }

    /// Field `name`, to change it.
    pub fn get_mut(&mut self, name: &str) -> Option<&mut Value> {
        self.fields.iter_mut().find(|(n, _)| n == name).map(|(_, v)| v)
    }

    /// The fields in order.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &Value)> {
        self.fields.iter().map(|(n, v)| (n.as_str(), v))
    }

    /// How many fields it holds.
    pub fn len(&self) -> usize {
        self.fields.len()
    }

    /// Whether it holds no field.
    pub fn is_empty(&self) -> bool {
        self.fields.is_empty()
    }
}

impl<S: Into<String>, V: Into<Value>> FromIterator<(S, V)> for Struct {
    fn from_iter<I: IntoIterator<Item = (S, V)>>(iter: I) -> Struct {
        let mut s = Struct::new();
        for (n, v) in iter {
            let n: String = n.into();
            s.set(&n, v);
        }
        s
    }
}

impl Value {
    /// A message of these fields (`Value::structure([("sec", 1i32.into()), …])`).
    pub fn structure<S: Into<String>>(fields: impl IntoIterator<Item = (S, Value)>) -> Value {
        Value::Struct(fields.into_iter().collect())
    }

    /// Field `name` of a message.
    pub fn get(&self, name: &str) -> Option<&Value> {
        self.as_struct()?.get(name)
    }

    /// The value at a dotted path of fields (`"pose.position.x"`).
    pub fn path(&self, path: &str) -> Option<&Value> {
        path.split('.').try_fold(self, |v, name| v.get(name))
    }

    /// Element `i` of an array or a sequence.
    pub fn at(&self, i: usize) -> Option<&Value> {
        self.as_array()?.get(i)
    }

    pub fn as_bool(&self) -> Option<bool> {
        match self {
            Value::Bool(b) => Some(*b),
            _ => None,
        }
    }

    /// An integer that fits an `i64`.
    pub fn as_i64(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            Value::UInt(u) => i64::try_from(*u).ok(),
            _ => None,
        }
    }

    /// An integer that fits a `u64`.
    pub fn as_u64(&self) -> Option<u64> {
        match self {
            Value::UInt(u) => Some(*u),
            Value::Int(i) => u64::try_from(*i).ok(),
            _ => None,
        }
    }

    /// A number, as the nearest `f64`.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Value::Float(f) => Some(*f),
            Value::Int(i) => Some(*i as f64),
            Value::UInt(u) => Some(*u as f64),
            _ => None,
        }
    }

    pub fn as_str(&self) -> Option<&str> {
        match self {
            Value::String(s) => Some(s),
            _ => None,
        }
    }

    /// The elements of an array or a sequence.
    pub fn as_array(&self) -> Option<&[Value]> {
        match self {
            Value::Array(a) => Some(a),
            _ => None,
        }
    }

    pub fn as_struct(&self) -> Option<&Struct> {
        match self {
            Value::Struct(s) => Some(s),
            _ => None,
        }
    }

    pub fn as_struct_mut(&mut self) -> Option<&mut Struct> {
        match self {
            Value::Struct(s) => Some(s),
            _ => None,
        }
    }

    /// What kind of value it is, for messages: `bool`, `signed integer`, …
    pub fn kind(&self) -> &'static str {
        match self {
            Value::Bool(_) => "bool",
            Value::Int(_) => "signed integer",
            Value::UInt(_) => "unsigned integer",
            Value::Float(_) => "float",
            Value::String(_) => "string",
            Value::Array(_) => "array",
            Value::Struct(_) => "struct",
        }
    }
}

macro_rules! from_int {
    ($variant:ident, $wide:ty: $($t:ty),*) => {$(
        impl From<$t> for Value {
            fn from(v: $t) -> Value {
                Value::$variant(<$wide>::from(v))
            }
        }
    )*};
}
from_int!(Int, i64: i8, i16, i32, i64);
from_int!(UInt, u64: u8, u16, u32, u64);

impl From<bool> for Value {
    fn from(v: bool) -> Value {
        Value::Bool(v)
    }
}

impl From<f64> for Value {
    fn from(v: f64) -> Value {
        Value::Float(v)
    }
}

impl From<f32> for Value {
    fn from(v: f32) -> Value {
        Value::Float(f64::from(v))
    }
}

impl From<&str> for Value {
    fn from(v: &str) -> Value {
        Value::String(v.to_string())
    }
}

impl From<String> for Value {
    fn from(v: String) -> Value {
        Value::String(v)
    }
}

impl From<Struct> for Value {
    fn from(v: Struct) -> Value {
        Value::Struct(v)
    }
}

impl<T: Into<Value>> From<Vec<T>> for Value {
    fn from(v: Vec<T>) -> Value {
        Value::Array(v.into_iter().map(Into::into).collect())
    }
}

/// As JSON would have it: a message is an object of its fields in order, an array a list.
impl Serialize for Value {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Value::Bool(b) => s.serialize_bool(*b),
            Value::Int(i) => s.serialize_i64(*i),
            Value::UInt(u) => s.serialize_u64(*u),
            Value::Float(f) => s.serialize_f64(*f),
            Value::String(t) => s.serialize_str(t),
            Value::Array(a) => {
                let mut seq = s.serialize_seq(Some(a.len()))?;
                a.iter().try_for_each(|v| seq.serialize_element(v))?;
                seq.end()
            }
            Value::Struct(st) => st.serialize(s),
        }
    }
}

impl Serialize for Struct {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(self.len()))?;
        self.iter().try_for_each(|(n, v)| map.serialize_entry(n, v))?;
        map.end()
    }
}

/// As JSON, compact.
impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = serde_json::to_string(self).map_err(|_| fmt::Error)?;
        f.write_str(&text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accessors_and_builders() {
        let v: Value = Struct::new()
            .with("header", Struct::new().with("frame_id", "map"))
            .with("n", -3i32)
            .with("xs", vec![1.5f64, 2.0])
            .into();
        assert_eq!(v.path("header.frame_id").and_then(Value::as_str), Some("map"));
        assert_eq!(v.get("n").and_then(Value::as_i64), Some(-3));
        assert_eq!(v.get("n").and_then(Value::as_u64), None);
        assert_eq!(v.get("xs").and_then(|x| x.at(1)).and_then(Value::as_f64), Some(2.0));
        assert_eq!(Value::UInt(u64::MAX).as_i64(), None);
        assert_eq!(v.to_string(), r#"{"header":{"frame_id":"map"},"n":-3,"xs":[1.5,2.0]}"#);
        let mut s = v.as_struct().cloned().unwrap();
        s.set("n", 4u8);
        assert_eq!(s.iter().map(|(n, _)| n).collect::<Vec<_>>(), ["header", "n", "xs"]);
        assert_eq!(s.get("n"), Some(&Value::UInt(4)));
        let t = Value::structure([("a", Value::Bool(true))]);
        assert_eq!(t.get("a").and_then(Value::as_bool), Some(true));
    }
}
