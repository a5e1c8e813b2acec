//! The validated DDF model: what both dialects mean, with the byte layout of every set.

use std::fmt;

use serde::Serialize;

use super::layout::SetLayout;
use super::Pos;

/// A validated Data Description File.
#[derive(Debug, Clone, Serialize)]
pub struct Model {
    /// The path the model was read from, as given.
    pub source: String,
    pub domains: Vec<Domain>,
}

impl Model {
    pub fn domain(&self, name: &str) -> Option<&Domain> {
        self.domains.iter().find(|d| d.name == name)
    }
}

/// The QoS flags of a domain (`docs/domains.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Flags {
    /// Lock-step (`yes`), or event-driven (`event`, which is synchronous too).
    pub synchronous: bool,
    /// `<synchronous>event</synchronous>`: the framework waits at each step only for the
    /// participants due at it (`docs/timing.md`). Implies `synchronous`.
    pub event: bool,
    pub multiple_publish_allowed: bool,
    pub states: bool,
}

/// A named data space with a PUBLISH set (written by the framework) and a SUBSCRIBE set
/// (written by external participants).
#[derive(Debug, Clone, Serialize)]
pub struct Domain {
    pub name: String,
    pub flags: Flags,
    /// The optional `<connection …/>` element, kept as written.
    pub connection: Option<Connection>,
    pub publish: Set,
    pub subscribe: Set,
    /// Stable hash of the flags and of the byte layout of both sets.
    pub layout_hash: u64,
    #[serde(skip)]
    pub pos: Pos,
}

impl Domain {
    pub fn set(&self, role: Role) -> &Set {
        match role {
            Role::Publish => &self.publish,
            Role::Subscribe => &self.subscribe,
        }
    }

    /// All leaves of the domain, PUBLISH first; the index is the RTAPI item key.
    pub fn leaves(&self) -> impl Iterator<Item = (Role, &Leaf)> {
        self.publish
            .layout
            .leaves
            .iter()
            .map(|l| (Role::Publish, l))
            .chain(self.subscribe.layout.leaves.iter().map(|l| (Role::Subscribe, l)))
    }

    /// The item key of a leaf: its index in [`Domain::leaves`].
    pub fn item_key(&self, role: Role, path: &str) -> Option<u16> {
        let base = match role {
            Role::Publish => 0,
            Role::Subscribe => self.publish.layout.leaves.len(),
        };
        let idx = self.set(role).layout.leaves.iter().position(|l| l.path == path)?;
        u16::try_from(base + idx).ok()
    }

    /// The leaf behind an item key.
    pub fn leaf_by_key(&self, key: u16) -> Option<(Role, &Leaf)> {
        self.leaves().nth(usize::from(key))
    }
}

/// The `<connection>` element of the product dialect: how the product's clients reach the
/// framework. tutti keeps it (and writes it back) but moves data the same way for every kind:
/// shared memory on the framework's machine, DDS through a gateway between machines
/// (`docs/ddf.md`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Connection {
    #[serde(rename = "type")]
    pub kind: ConnectionKind,
    /// The attributes as written, in document order (`type` included; the `local` form's
    /// `extcomm`, `addrframework`, `portframework`, `nicframework`, `nicclient`,
    /// `coreframework`, `coreclient`).
    pub attributes: Vec<(String, String)>,
    /// The child elements as written, name and text, in document order (`remote`: `card`,
    /// `pciindex`; `dolphin`: `nodeIdFramework`, `segmentId`).
    pub settings: Vec<(String, String)>,
}

/// The kinds of `<connection>` the product's tools write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ConnectionKind {
    /// A client on the framework's machine (attributes: the external communication process).
    Local,
    /// A client on another machine, through a reflective-memory card (`card`, `pciindex`).
    Remote,
    /// A client on another machine, through a Dolphin interconnect (`nodeIdFramework`, `segmentId`).
    Dolphin,
}

impl ConnectionKind {
    pub fn as_str(self) -> &'static str {
        match self {
            ConnectionKind::Local => "local",
            ConnectionKind::Remote => "remote",
            ConnectionKind::Dolphin => "dolphin",
        }
    }
}

impl Connection {
    /// The value of setting (child element) `name`.
    pub fn setting(&self, name: &str) -> Option<&str> {
        self.settings.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }

    /// The value of attribute `name`.
    pub fn attribute(&self, name: &str) -> Option<&str> {
        self.attributes.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }
}

/// Which side writes a set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum Role {
    /// Written by the framework, read by external participants.
    Publish,
    /// Written by external participants, read by the framework.
    Subscribe,
}

impl Role {
    pub const ALL: [Role; 2] = [Role::Publish, Role::Subscribe];

    pub fn as_str(self) -> &'static str {
        match self {
            Role::Publish => "PUBLISH",
            Role::Subscribe => "SUBSCRIBE",
        }
    }

    /// Lower-case name, as used in topic names.
    pub fn lower(self) -> &'static str {
        match self {
            Role::Publish => "publish",
            Role::Subscribe => "subscribe",
        }
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One set of a domain: its items as a tree, and their byte layout.
#[derive(Debug, Clone, Serialize)]
pub struct Set {
    pub role: Role,
    pub items: Vec<Item>,
    pub layout: SetLayout,
    /// Where the set was declared (`None` when the DDF omits it: the set is empty).
    #[serde(skip)]
    pub pos: Option<Pos>,
}

/// An item: a scalar or array of a scalar type, or a bus of nested items.
#[derive(Debug, Clone, Serialize)]
pub struct Item {
    pub name: String,
    #[serde(flatten)]
    pub kind: ItemKind,
    #[serde(skip)]
    pub pos: Pos,
}

/// The path of item `name` inside a bus at `prefix` (`""` at the top of a set): `BUS/ITEM`.
pub fn join_path(prefix: &str, name: &str) -> String {
    if prefix.is_empty() {
        name.to_string()
    } else {
        // Not `format!`, whose machinery cost more than the copy (this runs for every
        // member of every bus).
        [prefix, name].join("/")
    }
}

#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum ItemKind {
    Scalar {
        #[serde(rename = "type")]
        ty: ScalarType,
        /// Element count (1 for a scalar).
        length: u16,
        default: Option<Value>,
    },
    Bus {
        items: Vec<Item>,
    },
}

/// The scalar types of `docs/ddf.md` section 2, canonical names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum ScalarType {
    #[serde(rename = "boolean")]
    Boolean,
    #[serde(rename = "int8")]
    Int8,
    #[serde(rename = "int16")]
    Int16,
    #[serde(rename = "int32")]
    Int32,
    #[serde(rename = "int64")]
    Int64,
    #[serde(rename = "unsigned int8")]
    UInt8,
    #[serde(rename = "unsigned int16")]
    UInt16,
    #[serde(rename = "unsigned int32")]
    UInt32,
    #[serde(rename = "unsigned int64")]
    UInt64,
    #[serde(rename = "float32")]
    Float32,
    #[serde(rename = "float64")]
    Float64,
}

/// What a `<type>` names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TypeName {
    Scalar(ScalarType),
    Bus,
}

impl TypeName {
    /// Parses a type name: canonical names, `uintN`, and the C aliases. Case-insensitive,
    /// inner whitespace folded (`unsigned  int8`).
    pub fn parse(text: &str) -> Option<TypeName> {
        // Most DDFs write the names as listed; only the others need folding.
        Self::canonical(text).or_else(|| Self::canonical(Self::fold(text, &mut [0; 16])?))
    }

    /// `text` with its words joined by one space and lower-cased, in `buf`; `None` when
    /// that does not fit, which means longer than any type name. (A buffer on the stack:
    /// building the folded name as a String cost three allocations per item.)
    fn fold<'b>(text: &str, buf: &'b mut [u8; 16]) -> Option<&'b str> {
        let mut len = 0;
        for (i, word) in text.split_whitespace().enumerate() {
            let sep: &[u8] = if i == 0 { b"" } else { b" " };
            for &b in sep.iter().chain(word.as_bytes()) {
                *buf.get_mut(len)? = b.to_ascii_lowercase();
                len += 1;
            }
        }
        std::str::from_utf8(&buf[..len]).ok()
    }

    /// The type a folded name names.
    fn canonical(folded: &str) -> Option<TypeName> {
        use ScalarType::*;
        Some(TypeName::Scalar(match folded {
            "bus" => return Some(TypeName::Bus),
            "boolean" | "bool" => Boolean,
            "int8" | "char" => Int8,
            "int16" | "short" => Int16,
            "int32" | "int" => Int32,
            "int64" | "long" => Int64,
            "unsigned int8" | "uint8" | "uchar" => UInt8,
            "unsigned int16" | "uint16" => UInt16,
            "unsigned int32" | "uint32" => UInt32,
            "unsigned int64" | "uint64" => UInt64,
            "float32" | "float" => Float32,
            "float64" | "double" => Float64,
            _ => return None,
        }))
    }
}

impl ScalarType {
    pub const ALL: [ScalarType; 11] = [
        ScalarType::Boolean,
        ScalarType::Int8,
        ScalarType::Int16,
        ScalarType::Int32,
        ScalarType::Int64,
        ScalarType::UInt8,
        ScalarType::UInt16,
        ScalarType::UInt32,
        ScalarType::UInt64,
        ScalarType::Float32,
        ScalarType::Float64,
    ];

    /// Size in bytes of one element (also its alignment, as in C on LP64).
    pub fn size(self) -> u32 {
        use ScalarType::*;
        match self {
            Boolean | Int8 | UInt8 => 1,
            Int16 | UInt16 => 2,
            Int32 | UInt32 | Float32 => 4,
            Int64 | UInt64 | Float64 => 8,
        }
    }

    pub fn canonical(self) -> &'static str {
        use ScalarType::*;
        match self {
            Boolean => "boolean",
            Int8 => "int8",
            Int16 => "int16",
            Int32 => "int32",
            Int64 => "int64",
            UInt8 => "unsigned int8",
            UInt16 => "unsigned int16",
            UInt32 => "unsigned int32",
            UInt64 => "unsigned int64",
            Float32 => "float32",
            Float64 => "float64",
        }
    }

    pub fn is_signed_int(self) -> bool {
        use ScalarType::*;
        matches!(self, Int8 | Int16 | Int32 | Int64)
    }

    /// Parses a `<default>` text for this type; `None` when it does not fit.
    pub fn parse_value(self, text: &str) -> Option<Value> {
        use ScalarType::*;
        let t = text.trim();
        match self {
            // Compared in place rather than lower-cased into a copy: one allocation per default.
            Boolean if t.eq_ignore_ascii_case("yes") || t == "1" => Some(Value::Bool(true)),
            Boolean if t.eq_ignore_ascii_case("no") || t == "0" => Some(Value::Bool(false)),
            Boolean => None,
            Int8 => t.parse::<i8>().ok().map(|v| Value::Int(v.into())),
            Int16 => t.parse::<i16>().ok().map(|v| Value::Int(v.into())),
            Int32 => t.parse::<i32>().ok().map(|v| Value::Int(v.into())),
            Int64 => t.parse::<i64>().ok().map(Value::Int),
            UInt8 => t.parse::<u8>().ok().map(|v| Value::UInt(v.into())),
            UInt16 => t.parse::<u16>().ok().map(|v| Value::UInt(v.into())),
            UInt32 => t.parse::<u32>().ok().map(|v| Value::UInt(v.into())),
            UInt64 => t.parse::<u64>().ok().map(Value::UInt),
            Float32 => t.parse::<f32>().ok().filter(|v| v.is_finite()).map(|v| Value::Float(v.into())),
            Float64 => t.parse::<f64>().ok().filter(|v| v.is_finite()).map(Value::Float),
        }
    }

    /// Encodes `value` as one element of this type, native endianness.
    pub fn encode(self, value: Value, out: &mut [u8]) {
        use ScalarType::*;
        let n = self.size() as usize;
        let bytes: [u8; 8] = match (self, value) {
            (Boolean, v) => [u8::from(v.as_f64() != 0.0), 0, 0, 0, 0, 0, 0, 0],
            (Float32, v) => pad((v.as_f64() as f32).to_ne_bytes()),
            (Float64, v) => v.as_f64().to_ne_bytes(),
            (Int8, v) => pad((v.as_i64() as i8).to_ne_bytes()),
            (Int16, v) => pad((v.as_i64() as i16).to_ne_bytes()),
            (Int32, v) => pad((v.as_i64() as i32).to_ne_bytes()),
            (Int64, v) => v.as_i64().to_ne_bytes(),
            (UInt8, v) => pad((v.as_u64() as u8).to_ne_bytes()),
            (UInt16, v) => pad((v.as_u64() as u16).to_ne_bytes()),
            (UInt32, v) => pad((v.as_u64() as u32).to_ne_bytes()),
            (UInt64, v) => v.as_u64().to_ne_bytes(),
        };
        out[..n].copy_from_slice(&bytes[..n]);
    }

    /// Decodes one element of this type (native endianness) from `bytes`.
    pub fn decode(self, bytes: &[u8]) -> Value {
        use ScalarType::*;
        fn arr<const N: usize>(b: &[u8]) -> [u8; N] {
            let mut a = [0u8; N];
            a.copy_from_slice(&b[..N]);
            a
        }
        match self {
            Boolean => Value::Bool(bytes[0] != 0),
            Int8 => Value::Int(i8::from_ne_bytes(arr(bytes)).into()),
            Int16 => Value::Int(i16::from_ne_bytes(arr(bytes)).into()),
            Int32 => Value::Int(i32::from_ne_bytes(arr(bytes)).into()),
            Int64 => Value::Int(i64::from_ne_bytes(arr(bytes))),
            UInt8 => Value::UInt(u8::from_ne_bytes(arr(bytes)).into()),
            UInt16 => Value::UInt(u16::from_ne_bytes(arr(bytes)).into()),
            UInt32 => Value::UInt(u32::from_ne_bytes(arr(bytes)).into()),
            UInt64 => Value::UInt(u64::from_ne_bytes(arr(bytes))),
            Float32 => Value::Float(f32::from_ne_bytes(arr(bytes)).into()),
            Float64 => Value::Float(f64::from_ne_bytes(arr(bytes))),
        }
    }
}

fn pad<const N: usize>(b: [u8; N]) -> [u8; 8] {
    let mut out = [0u8; 8];
    out[..N].copy_from_slice(&b);
    out
}

/// A scalar value: a default, or a decoded element.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Value {
    Bool(bool),
    Int(i64),
    UInt(u64),
    Float(f64),
}

impl Value {
    pub fn as_f64(self) -> f64 {
        match self {
            Value::Bool(b) => f64::from(u8::from(b)),
            Value::Int(i) => i as f64,
            Value::UInt(u) => u as f64,
            Value::Float(f) => f,
        }
    }

    pub fn as_i64(self) -> i64 {
        match self {
            Value::Bool(b) => i64::from(b),
            Value::Int(i) => i,
            Value::UInt(u) => u as i64,
            Value::Float(f) => f as i64,
        }
    }

    pub fn as_u64(self) -> u64 {
        match self {
            Value::Bool(b) => u64::from(b),
            Value::Int(i) => i as u64,
            Value::UInt(u) => u,
            Value::Float(f) => f as u64,
        }
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => f.write_str(if *b { "yes" } else { "no" }),
            Value::Int(i) => write!(f, "{i}"),
            Value::UInt(u) => write!(f, "{u}"),
            Value::Float(x) => write!(f, "{x}"),
        }
    }
}

/// One scalar or array item of a set, flattened: its `/`-joined path and its place in the
/// set's bytes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Leaf {
    pub path: String,
    #[serde(rename = "type")]
    pub ty: ScalarType,
    pub length: u16,
    /// Byte offset within the set.
    pub offset: u32,
    /// Total bytes (`length` × element size).
    pub size: u32,
    pub default: Option<Value>,
}

impl Leaf {
    /// The bytes of this leaf within a set buffer.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.offset as usize..(self.offset + self.size) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn type_names_fold_case_and_inner_whitespace() {
        assert_eq!(TypeName::parse(" Unsigned \t INT8\n"), Some(TypeName::Scalar(ScalarType::UInt8)));
        assert_eq!(TypeName::parse("double"), Some(TypeName::Scalar(ScalarType::Float64)));
        assert_eq!(TypeName::parse("BUS"), Some(TypeName::Bus));
        assert_eq!(TypeName::parse("unsigned int64"), Some(TypeName::Scalar(ScalarType::UInt64)));
        for unknown in ["", "  ", "unsignedint8", "unsigned int8 x", "unsigned  int128", "ınt8", "float64float64"] {
            assert_eq!(TypeName::parse(unknown), None, "{unknown:?}");
        }
    }

    #[test]
    fn boolean_defaults_ignore_ascii_case() {
        let parse = |t| ScalarType::Boolean.parse_value(t);
        assert_eq!(parse(" YeS "), Some(Value::Bool(true)));
        assert_eq!(parse("1"), Some(Value::Bool(true)));
        assert_eq!(parse("No"), Some(Value::Bool(false)));
        assert_eq!(parse("0"), Some(Value::Bool(false)));
        assert_eq!(parse("true"), None);
    }
}
