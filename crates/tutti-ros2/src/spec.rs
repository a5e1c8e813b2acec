//! What a `.msg` file says, parsed: a message's fields (each with its type and default value)
//! and constants, and the names of types. A service and an action are names of the messages
//! rosidl makes of them (`registry`).

use std::fmt;

use crate::value::Value;

/// The three kinds of interface file, and the middle part of a type's name (`PKG/KIND/NAME`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Kind {
    Msg,
    Srv,
    Action,
}

impl Kind {
    /// `msg`, `srv` or `action`: the folder and the file extension.
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Msg => "msg",
            Kind::Srv => "srv",
            Kind::Action => "action",
        }
    }

    /// The kind named `s` (`msg`, `srv`, `action`).
    pub fn parse(s: &str) -> Option<Kind> {
        match s {
            "msg" => Some(Kind::Msg),
            "srv" => Some(Kind::Srv),
            "action" => Some(Kind::Action),
            _ => None,
        }
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A type's name: `PKG/KIND/NAME` in ROS 2, `PKG::KIND::dds_::NAME_` on DDS.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TypeName {
    pub package: String,
    pub kind: Kind,
    pub name: String,
}

impl TypeName {
    pub fn new(package: &str, kind: Kind, name: &str) -> TypeName {
        TypeName { package: package.to_string(), kind, name: name.to_string() }
    }

    /// `PKG/KIND/NAME`, or `PKG/NAME` for a message.
    pub fn parse(ros: &str) -> Option<TypeName> {
        let parts: Vec<&str> = ros.split('/').collect();
        let (package, kind, name) = match parts[..] {
            [p, k, n] => (p, Kind::parse(k)?, n),
            [p, n] => (p, Kind::Msg, n),
            _ => return None,
        };
        (!package.is_empty() && !name.is_empty()).then(|| TypeName::new(package, kind, name))
    }

    /// The name of a ROS 2-mangled DDS type (`PKG::KIND::dds_::NAME_`).
    pub fn from_dds(dds: &str) -> Option<TypeName> {
        let (package, rest) = dds.split_once("::")?;
        let (kind, rest) = rest.split_once("::dds_::")?;
        let name = rest.strip_suffix('_')?;
        if package.is_empty() || name.is_empty() || name.contains("::") {
            return None;
        }
        Some(TypeName::new(package, Kind::parse(kind)?, name))
    }

    /// The name on DDS: `PKG::KIND::dds_::NAME_`.
    pub fn dds(&self) -> String {
        format!("{}::{}::dds_::{}_", self.package, self.kind, self.name)
    }
}

impl fmt::Display for TypeName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}/{}", self.package, self.kind, self.name)
    }
}

/// A primitive type other than the strings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Primitive {
    Bool,
    /// An octet (IDL `octet`).
    Byte,
    /// An unsigned 8-bit character: rosidl makes it IDL `uint8`.
    Char,
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
}

impl Primitive {
    /// Every primitive, as `.msg` names them.
    pub const ALL: [Primitive; 13] = [
        Primitive::Bool,
        Primitive::Byte,
        Primitive::Char,
        Primitive::Int8,
        Primitive::UInt8,
        Primitive::Int16,
        Primitive::UInt16,
        Primitive::Int32,
        Primitive::UInt32,
        Primitive::Int64,
        Primitive::UInt64,
        Primitive::Float32,
        Primitive::Float64,
    ];

    /// Its name in a `.msg` file.
    pub fn msg_name(self) -> &'static str {
        use Primitive::*;
        match self {
            Bool => "bool",
            Byte => "byte",
            Char => "char",
            Int8 => "int8",
            UInt8 => "uint8",
            Int16 => "int16",
            UInt16 => "uint16",
            Int32 => "int32",
            UInt32 => "uint32",
            Int64 => "int64",
            UInt64 => "uint64",
            Float32 => "float32",
            Float64 => "float64",
        }
    }

    /// Its IDL type, as rosidl_adapter writes it (`char` is `uint8`, `byte` is `octet`).
    pub fn idl_name(self) -> &'static str {
        use Primitive::*;
        match self {
            Bool => "boolean",
            Byte => "octet",
            Char | UInt8 => "uint8",
            Int8 => "int8",
            Int16 => "int16",
            UInt16 => "uint16",
            Int32 => "int32",
            UInt32 => "uint32",
            Int64 => "int64",
            UInt64 => "uint64",
            Float32 => "float",
            Float64 => "double",
        }
    }

    /// The primitive a `.msg` file names `name`.
    pub fn from_msg_name(name: &str) -> Option<Primitive> {
        Primitive::ALL.into_iter().find(|p| p.msg_name() == name)
    }

    /// Its size in bytes, which is also its CDR alignment.
    pub fn size(self) -> usize {
        use Primitive::*;
        match self {
            Bool | Byte | Char | Int8 | UInt8 => 1,
            Int16 | UInt16 => 2,
            Int32 | UInt32 | Float32 => 4,
            Int64 | UInt64 | Float64 => 8,
        }
    }

    /// A signed integer.
    pub fn is_signed(self) -> bool {
        matches!(self, Primitive::Int8 | Primitive::Int16 | Primitive::Int32 | Primitive::Int64)
    }

    /// An unsigned integer (`byte` and `char` included).
    pub fn is_unsigned(self) -> bool {
        matches!(
            self,
            Primitive::Byte
                | Primitive::Char
                | Primitive::UInt8
                | Primitive::UInt16
                | Primitive::UInt32
                | Primitive::UInt64
        )
    }

    /// A floating-point number.
    pub fn is_float(self) -> bool {
        matches!(self, Primitive::Float32 | Primitive::Float64)
    }

    /// The smallest and largest value of an integer type, as i128.
    pub fn int_range(self) -> Option<(i128, i128)> {
        use Primitive::*;
        Some(match self {
            Byte | Char | UInt8 => (0, 0xff),
            UInt16 => (0, 0xffff),
            UInt32 => (0, 0xffff_ffff),
            UInt64 => (0, i128::from(u64::MAX)),
            Int8 => (i128::from(i8::MIN), i128::from(i8::MAX)),
            Int16 => (i128::from(i16::MIN), i128::from(i16::MAX)),
            Int32 => (i128::from(i32::MIN), i128::from(i32::MAX)),
            Int64 => (i128::from(i64::MIN), i128::from(i64::MAX)),
            Bool | Float32 | Float64 => return None,
        })
    }
}

/// The type of one value: a primitive, a string or a nested message.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum BaseType {
    Primitive(Primitive),
    /// `string`, or `string<=N` with `bound` N (bytes).
    String {
        bound: Option<u64>,
    },
    /// `wstring`, or `wstring<=N`.
    WString {
        bound: Option<u64>,
    },
    /// A message: `PKG/Type` or `Type` of the same package in a `.msg` file.
    Nested(TypeName),
}

/// How many values a field holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Shape {
    /// One value.
    Single,
    /// `T[N]`: exactly N.
    Array(u64),
    /// `T[<=N]`: up to N.
    Bounded(u64),
    /// `T[]`: any number.
    Unbounded,
}

/// A field's type: its base type and its shape.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct FieldType {
    pub base: BaseType,
    pub shape: Shape,
}

impl FieldType {
    /// One value of `base`.
    pub fn single(base: BaseType) -> FieldType {
        FieldType { base, shape: Shape::Single }
    }

    /// One primitive.
    pub fn primitive(p: Primitive) -> FieldType {
        FieldType::single(BaseType::Primitive(p))
    }

    /// One nested message.
    pub fn nested(name: TypeName) -> FieldType {
        FieldType::single(BaseType::Nested(name))
    }
}

/// One field of a message.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    pub name: String,
    pub ty: FieldType,
    /// Its value when none is given (the `.msg` default); `None`: zero, empty, or the nested
    /// message's own defaults.
    pub default: Option<Value>,
    /// The comments the `.msg` file gives it, without their `#`.
    pub comments: Vec<String>,
}

impl Field {
    /// A field without default or comments.
    pub fn new(name: &str, ty: FieldType) -> Field {
        Field { name: name.to_string(), ty, default: None, comments: Vec::new() }
    }
}

/// A constant of a message (`TYPE NAME=VALUE`): a primitive or a string.
#[derive(Debug, Clone, PartialEq)]
pub struct Constant {
    pub name: String,
    pub ty: BaseType,
    pub value: Value,
    pub comments: Vec<String>,
}

/// The name of the one field rosidl gives a message without fields.
pub const EMPTY_MESSAGE_FIELD: &str = "structure_needs_at_least_one_member";

/// One message: its name, fields in order and constants.
#[derive(Debug, Clone, PartialEq)]
pub struct MessageSpec {
    pub name: TypeName,
    /// In order. A message without fields has the one field `uint8
    /// structure_needs_at_least_one_member`, as rosidl gives it ([`MessageSpec::new`]).
    pub fields: Vec<Field>,
    pub constants: Vec<Constant>,
    /// The comment lines at the top of its file (or half of a `.srv`, third of an `.action`),
    /// without their `#`.
    pub comments: Vec<String>,
}

impl MessageSpec {
    /// A message of these fields and constants; without fields it gets the one field
    /// `uint8 structure_needs_at_least_one_member`, as rosidl makes it.
    pub fn new(name: TypeName, mut fields: Vec<Field>, constants: Vec<Constant>) -> MessageSpec {
        if fields.is_empty() {
            fields.push(Field::new(EMPTY_MESSAGE_FIELD, FieldType::primitive(Primitive::UInt8)));
        }
        MessageSpec { name, fields, constants, comments: Vec::new() }
    }

    /// The field named `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The value of the constant named `name`.
    pub fn constant(&self, name: &str) -> Option<&Value> {
        self.constants.iter().find(|c| c.name == name).map(|c| &c.value)
    }

    /// Whether its only field is the one rosidl adds to a message without fields.
    pub fn is_empty(&self) -> bool {
        matches!(&self.fields[..], [f] if f.name == EMPTY_MESSAGE_FIELD)
    }

    /// The nested types its fields name, each once, in field order.
    pub fn nested_types(&self) -> Vec<&TypeName> {
        let mut out: Vec<&TypeName> = Vec::new();
        for f in &self.fields {
            if let BaseType::Nested(n) = &f.ty.base {
                if !out.contains(&n) {
                    out.push(n);
                }
            }
        }
        out
    }
}

/// A service `PKG/srv/NAME`: the names of its messages.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServiceSpec {
    pub name: TypeName,
    /// `NAME_Request`.
    pub request: TypeName,
    /// `NAME_Response`.
    pub response: TypeName,
    /// `NAME_Event`: `service_msgs/msg/ServiceEventInfo info`, `NAME_Request[<=1] request`,
    /// `NAME_Response[<=1] response`.
    pub event: TypeName,
}

impl ServiceSpec {
    /// The service `name`, its messages named as rosidl names them (`NAME_Request`, …, in
    /// `name`'s package and kind: an action's services are `PKG/action/NAME_SendGoal`).
    pub fn named(name: TypeName) -> ServiceSpec {
        let part = |suffix: &str| TypeName::new(&name.package, name.kind, &format!("{}{suffix}", name.name));
        ServiceSpec { request: part("_Request"), response: part("_Response"), event: part("_Event"), name }
    }
}

/// An action `PKG/action/NAME`: the names of its messages and services.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ActionSpec {
    pub name: TypeName,
    /// `NAME_Goal`, `NAME_Result`, `NAME_Feedback`: the three parts of the file.
    pub goal: TypeName,
    pub result: TypeName,
    pub feedback: TypeName,
    /// `NAME_SendGoal`: request `goal_id` and `goal`; response `accepted` and `stamp`.
    pub send_goal: ServiceSpec,
    /// `NAME_GetResult`: request `goal_id`; response `status` and `result`.
    pub get_result: ServiceSpec,
    /// `NAME_FeedbackMessage`: `goal_id` and `feedback`.
    pub feedback_message: TypeName,
}

impl ActionSpec {
    /// The action `name`, its messages and services named as rosidl names them.
    pub fn named(name: TypeName) -> ActionSpec {
        let part = |suffix: &str| TypeName::new(&name.package, name.kind, &format!("{}{suffix}", name.name));
        ActionSpec {
            goal: part("_Goal"),
            result: part("_Result"),
            feedback: part("_Feedback"),
            send_goal: ServiceSpec::named(part("_SendGoal")),
            get_result: ServiceSpec::named(part("_GetResult")),
            feedback_message: part("_FeedbackMessage"),
            name,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_read_and_write_both_ways() {
        let n = TypeName::parse("simulation_interfaces/srv/StepSimulation_Request").unwrap();
        assert_eq!(n.dds(), "simulation_interfaces::srv::dds_::StepSimulation_Request_");
        assert_eq!(TypeName::from_dds(&n.dds()), Some(n.clone()));
        assert_eq!(n.to_string(), "simulation_interfaces/srv/StepSimulation_Request");
        assert_eq!(TypeName::parse("std_msgs/Header").unwrap().to_string(), "std_msgs/msg/Header");
        for bad in ["", "a", "a/b/c/d", "/msg/X", "a/msg/", "a/typ/X"] {
            assert_eq!(TypeName::parse(bad), None, "{bad}");
        }
        for bad in ["Float64", "a::msg::dds_::_", "a::msg::X_", "::msg::dds_::X_", "a::x::dds_::X_"] {
            assert_eq!(TypeName::from_dds(bad), None, "{bad}");
        }
    }

    #[test]
    fn an_action_names_its_parts_as_rosidl_does() {
        let a = ActionSpec::named(TypeName::new("p", Kind::Action, "Go"));
        assert_eq!(a.send_goal.request.to_string(), "p/action/Go_SendGoal_Request");
        assert_eq!(a.get_result.event.to_string(), "p/action/Go_GetResult_Event");
        assert_eq!(a.feedback_message.to_string(), "p/action/Go_FeedbackMessage");
    }
}
