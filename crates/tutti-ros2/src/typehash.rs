//! ROS 2 type hashes (`RIHS01_…`): what a ROS 2 Jazzy endpoint announces of its type in its
//! USER_DATA (`typehash=RIHS01_…;`), computed as ROS 2 computes it (`docs/gateway.md`,
//! "Type hashes").
//!
//! A type's hash is the SHA-256 of its *type description* written as compact JSON: the type
//! (its name `PKG/msg/TYPE` and its fields) and every type it refers to, directly or not,
//! sorted by name. Each field has its name and its type: a type id (the kind of value, plus
//! 48 for a fixed-size array, 96 for a bounded and 144 for an unbounded sequence), the
//! array's or sequence's capacity, a bounded string's capacity and the name of a nested type.
//! Default values and comments are not part of it, so a `.msg` file's defaults do not change
//! its hash. [`TypeDescription::canonical_json`] writes the exact text that is hashed.
//!
//! The descriptions are made from parsed specs ([`IndividualType::of_message`]): the
//! registry's (`crate::Registry::description`) and those of a DDF's sets (`crate::idl`).
//! Pure computation: no DDS crate.

use std::collections::BTreeMap;
use std::fmt;
use std::io;

use serde::Serialize;
use sha2::{Digest, Sha256};

use crate::spec::{BaseType, MessageSpec, Primitive, Shape};

/// The prefix of a version 1 type hash (the only version ROS 2 Jazzy knows).
pub const RIHS01_PREFIX: &str = "RIHS01_";

/// A type id of ROS 2's `type_description_interfaces/msg/FieldType`: the kind of value.
pub mod type_id {
    /// A nested type (`nested_type_name` names it).
    pub const NESTED_TYPE: u8 = 1;
    pub const INT8: u8 = 2;
    pub const UINT8: u8 = 3;
    pub const INT16: u8 = 4;
    pub const UINT16: u8 = 5;
    pub const INT32: u8 = 6;
    pub const UINT32: u8 = 7;
    pub const INT64: u8 = 8;
    pub const UINT64: u8 = 9;
    pub const FLOAT: u8 = 10;
    pub const DOUBLE: u8 = 11;
    pub const BOOLEAN: u8 = 15;
    pub const BYTE: u8 = 16;
    pub const STRING: u8 = 17;
    pub const WSTRING: u8 = 18;
    pub const BOUNDED_STRING: u8 = 21;
    pub const BOUNDED_WSTRING: u8 = 22;
    /// Added to a kind for a fixed-size array of it.
    pub const ARRAY: u8 = 48;
    /// Added to a kind for a bounded sequence of it.
    pub const BOUNDED_SEQUENCE: u8 = 96;
    /// Added to a kind for an unbounded sequence of it.
    pub const UNBOUNDED_SEQUENCE: u8 = 144;
}

/// The type id of a primitive, as rosidl gives it from the IDL type: `char` is IDL `uint8`,
/// `byte` IDL `octet`.
pub fn primitive_type_id(p: Primitive) -> u8 {
    use type_id::*;
    use Primitive::*;
    match p {
        Bool => BOOLEAN,
        Byte => BYTE,
        Char | UInt8 => UINT8,
        Int8 => INT8,
        Int16 => INT16,
        UInt16 => UINT16,
        Int32 => INT32,
        UInt32 => UINT32,
        Int64 => INT64,
        UInt64 => UINT64,
        Float32 => FLOAT,
        Float64 => DOUBLE,
    }
}

/// The type of one field.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FieldType {
    /// The kind of value, with the array or sequence offset ([`type_id`]).
    pub type_id: u8,
    /// Elements of a fixed-size array, most elements of a bounded sequence; else 0.
    pub capacity: u64,
    /// Most characters of a bounded string; else 0.
    pub string_capacity: u64,
    /// `PKG/msg/TYPE` of a nested type; else empty.
    pub nested_type_name: String,
}

impl FieldType {
    /// A plain value of kind `type_id`.
    pub fn plain(type_id: u8) -> FieldType {
        FieldType { type_id, capacity: 0, string_capacity: 0, nested_type_name: String::new() }
    }

    /// A nested type `PKG/msg/TYPE`, plus `offset` for an array or a sequence of it.
    pub fn nested(name: &str, offset: u8, capacity: u64) -> FieldType {
        FieldType {
            type_id: type_id::NESTED_TYPE + offset,
            capacity,
            string_capacity: 0,
            nested_type_name: name.to_string(),
        }
    }

    /// The description of a spec's field type.
    pub fn of(ty: &crate::spec::FieldType) -> FieldType {
        let (base, string_capacity, nested_type_name) = match &ty.base {
            BaseType::Primitive(p) => (primitive_type_id(*p), 0, String::new()),
            BaseType::String { bound: None } => (type_id::STRING, 0, String::new()),
            BaseType::String { bound: Some(b) } => (type_id::BOUNDED_STRING, *b, String::new()),
            BaseType::WString { bound: None } => (type_id::WSTRING, 0, String::new()),
            BaseType::WString { bound: Some(b) } => (type_id::BOUNDED_WSTRING, *b, String::new()),
            BaseType::Nested(n) => (type_id::NESTED_TYPE, 0, n.to_string()),
        };
        let (offset, capacity) = match ty.shape {
            Shape::Single => (0, 0),
            Shape::Array(n) => (type_id::ARRAY, n),
            Shape::Bounded(n) => (type_id::BOUNDED_SEQUENCE, n),
            Shape::Unbounded => (type_id::UNBOUNDED_SEQUENCE, 0),
        };
        FieldType { type_id: base + offset, capacity, string_capacity, nested_type_name }
    }
}

/// One field of a type.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Field {
    pub name: String,
    #[serde(rename = "type")]
    pub ty: FieldType,
}

impl Field {
    pub fn new(name: &str, ty: FieldType) -> Field {
        Field { name: name.to_string(), ty }
    }
}

/// One type on its own: its name (`PKG/msg/TYPE`) and its fields, in order.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct IndividualType {
    pub type_name: String,
    pub fields: Vec<Field>,
}

impl IndividualType {
    /// A message as rosidl describes it (its constants are no fields).
    pub fn of_message(spec: &MessageSpec) -> IndividualType {
        IndividualType {
            type_name: spec.name.to_string(),
            fields: spec.fields.iter().map(|f| Field::new(&f.name, FieldType::of(&f.ty))).collect(),
        }
    }
}

/// A type with every type it refers to, directly or through others: what is hashed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct TypeDescription {
    pub type_description: IndividualType,
    /// Sorted by name, each once.
    pub referenced_type_descriptions: Vec<IndividualType>,
}

/// A nested type that is not among the types given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("type {referrer} refers to {missing}, which is not described")]
pub struct MissingType {
    pub referrer: String,
    pub missing: String,
}

impl TypeDescription {
    /// The description of `top`, with the types it refers to taken from `known` (any order;
    /// those it does not refer to are left out).
    pub fn of(top: &IndividualType, known: &[IndividualType]) -> Result<TypeDescription, MissingType> {
        let by_name: BTreeMap<&str, &IndividualType> = known.iter().map(|t| (t.type_name.as_str(), t)).collect();
        TypeDescription::resolve(top.clone(), |name| by_name.get(name).map(|t| (*t).clone()))
    }

    /// The description of `top`, with the types it refers to found by `lookup` (by name).
    pub fn resolve(
        top: IndividualType,
        lookup: impl Fn(&str) -> Option<IndividualType>,
    ) -> Result<TypeDescription, MissingType> {
        let mut refs: BTreeMap<String, IndividualType> = BTreeMap::new();
        let mut queue: Vec<(String, String)> = nested_names(&top).map(|n| (top.type_name.clone(), n)).collect();
        while let Some((referrer, name)) = queue.pop() {
            if refs.contains_key(&name) {
                continue;
            }
            let t = lookup(&name).ok_or_else(|| MissingType { referrer, missing: name.clone() })?;
            queue.extend(nested_names(&t).map(|n| (t.type_name.clone(), n)));
            refs.insert(name, t);
        }
        Ok(TypeDescription { type_description: top, referenced_type_descriptions: refs.into_values().collect() })
    }

    /// The text that is hashed: the description as JSON with `", "` and `": "` between
    /// items, no other white space, ASCII only, keys in this order
    /// (`rosidl_generator_type_description`'s `calculate_type_hash`, which writes it with
    /// Python's `json.dumps(…, ensure_ascii=True, separators=(', ', ': '))`).
    pub fn canonical_json(&self) -> String {
        let mut out = Vec::new();
        let mut ser = serde_json::Serializer::with_formatter(&mut out, PythonJson);
        // Only strings and integers: writing them into memory cannot fail.
        let _ = self.serialize(&mut ser);
        // PythonJson writes ASCII only.
        String::from_utf8_lossy(&out).into_owned()
    }

    /// The type's RIHS01 hash.
    pub fn hash(&self) -> TypeHash {
        TypeHash(Sha256::digest(self.canonical_json().as_bytes()).into())
    }
}

fn nested_names(t: &IndividualType) -> impl Iterator<Item = String> + '_ {
    t.fields.iter().map(|f| f.ty.nested_type_name.clone()).filter(|n| !n.is_empty())
}

/// JSON as Python's `json.dumps(ensure_ascii=True, separators=(', ', ': '))` writes it:
/// serde_json's compact output already escapes what Python escapes (`"`, `\`, the control
/// characters, with the same short forms and lowercase `\u00XX`); this adds the spaces after
/// the separators and writes every character outside `' '..='~'` as `\uXXXX` (UTF-16).
#[derive(Debug, Clone, Copy)]
struct PythonJson;

impl serde_json::ser::Formatter for PythonJson {
    fn begin_array_value<W: ?Sized + io::Write>(&mut self, w: &mut W, first: bool) -> io::Result<()> {
        if first {
            Ok(())
        } else {
            w.write_all(b", ")
        }
    }

    fn begin_object_key<W: ?Sized + io::Write>(&mut self, w: &mut W, first: bool) -> io::Result<()> {
        if first {
            Ok(())
        } else {
            w.write_all(b", ")
        }
    }

    fn begin_object_value<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        w.write_all(b": ")
    }

    fn write_string_fragment<W: ?Sized + io::Write>(&mut self, w: &mut W, fragment: &str) -> io::Result<()> {
        for c in fragment.chars() {
            if (' '..='~').contains(&c) {
                w.write_all(&[c as u8])?;
            } else {
                let mut units = [0u16; 2];
                for u in c.encode_utf16(&mut units) {
                    write!(w, "\\u{u:04x}")?;
                }
            }
        }
        Ok(())
    }
}

/// A RIHS01 type hash: the SHA-256 of a [`TypeDescription`]'s canonical JSON.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct TypeHash(pub [u8; 32]);

impl TypeHash {
    /// What a ROS 2 endpoint carries in its USER_DATA: `typehash=RIHS01_…;`.
    pub fn user_data(&self) -> String {
        format!("typehash={self};")
    }
}

impl fmt::Display for TypeHash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(RIHS01_PREFIX)?;
        self.0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

/// As its text, `RIHS01_…`.
impl serde::Serialize for TypeHash {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl fmt::Debug for TypeHash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// `PKG/msg/TYPE` of a ROS 2-mangled DDS type name (`PKG::msg::dds_::TYPE_`); None for a
/// name ROS 2 did not mangle.
pub fn ros2_type_name(dds_type: &str) -> Option<String> {
    crate::spec::TypeName::from_dds(dds_type).map(|n| n.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hashed_text_is_pythons_json() {
        let t = |name: &str, fields| IndividualType { type_name: name.into(), fields };
        let clock = t(
            "rosgraph_msgs/msg/Clock",
            vec![Field::new("clock", FieldType::nested("builtin_interfaces/msg/Time", 0, 0))],
        );
        let time = t(
            "builtin_interfaces/msg/Time",
            vec![
                Field::new("sec", FieldType::plain(type_id::INT32)),
                Field::new("nanosec", FieldType::plain(type_id::UINT32)),
            ],
        );
        let d = TypeDescription::of(&clock, &[time]).unwrap();
        assert_eq!(
            d.canonical_json(),
            "{\"type_description\": {\"type_name\": \"rosgraph_msgs/msg/Clock\", \"fields\": [{\"name\": \"clock\", \
             \"type\": {\"type_id\": 1, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \
             \"builtin_interfaces/msg/Time\"}}]}, \"referenced_type_descriptions\": [{\"type_name\": \
             \"builtin_interfaces/msg/Time\", \"fields\": [{\"name\": \"sec\", \"type\": {\"type_id\": 6, \"capacity\": 0, \
             \"string_capacity\": 0, \"nested_type_name\": \"\"}}, {\"name\": \"nanosec\", \"type\": {\"type_id\": 7, \
             \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}]}]}"
        );
        assert_eq!(d.hash().to_string(), "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564");
    }

    #[test]
    fn strings_are_escaped_as_python_escapes_them() {
        // json.dumps('"\\\n\t\x01\x7f é😀/', ensure_ascii=True)
        let d = TypeDescription {
            type_description: IndividualType { type_name: "\"\\\n\t\u{1}\u{7f} é😀/".into(), fields: vec![] },
            referenced_type_descriptions: vec![],
        };
        assert_eq!(
            d.canonical_json(),
            r#"{"type_description": {"type_name": "\"\\\n\t\u0001\u007f \u00e9\ud83d\ude00/", "fields": []}, "referenced_type_descriptions": []}"#
        );
    }

    #[test]
    fn a_missing_nested_type_is_an_error_and_unused_types_are_left_out() {
        let top = IndividualType {
            type_name: "p/msg/A".into(),
            fields: vec![Field::new("b", FieldType::nested("p/msg/B", 0, 0))],
        };
        let e = TypeDescription::of(&top, &[]).unwrap_err();
        assert_eq!(e.to_string(), "type p/msg/A refers to p/msg/B, which is not described");
        let b = IndividualType {
            type_name: "p/msg/B".into(),
            fields: vec![Field::new("x", FieldType::plain(type_id::DOUBLE))],
        };
        let c = IndividualType { type_name: "p/msg/C".into(), fields: vec![] };
        let d = TypeDescription::of(&top, &[c, b.clone()]).unwrap();
        assert_eq!(d.referenced_type_descriptions, vec![b]);
    }

    #[test]
    fn dds_names_map_to_ros2_names() {
        assert_eq!(ros2_type_name("std_msgs::msg::dds_::Float64_").as_deref(), Some("std_msgs/msg/Float64"));
        assert_eq!(ros2_type_name("Float64"), None);
        assert_eq!(ros2_type_name("a::msg::dds_::_"), None);
    }
}
