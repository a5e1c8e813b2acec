//! A message spec written back as text: its `.msg`, and its OMG IDL 4 in either of the two
//! spellings of its type (rosidl's `PKG::msg::TYPE`, or the name on the wire
//! `PKG::msg::dds_::TYPE_`). The same code writes a DDF set's message (`super::generate`) and
//! any message of the registry.
//!
//! The IDL is laid out as `rosidl_adapter` lays it out: one `module` per name part, nested
//! types `#include`d, the constants in a module `TYPE_Constants`, a fixed-size array as
//! `T name[N]`, a sequence as `sequence<T>` or `sequence<T, N>`, integer keywords `int8` …
//! `uint64` (IDL 4.2), `char` as `uint8`, `byte` as `octet`. A scalar's default becomes a
//! `@default` annotation; an array's does not (rosidl writes it as a string literal, which
//! Cyclone's `idlc` rejects), nor does an integer below -(2^31 - 1), which `idlc` 0.10
//! reports as an overflow even for an `int64`. No extensibility annotation is written, as
//! rosidl writes none: the tools then take `@final`, the plain CDR that ROS 2 sends.

use std::fmt::Write as _;

use crate::spec::{BaseType, MessageSpec, Primitive, Shape, TypeName};
use crate::value::Value;

/// The two spellings of a type in IDL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flavor {
    /// `PKG::msg::TYPE`, in `PKG/msg/TYPE.idl` (what rosidl_adapter writes).
    Rosidl,
    /// `PKG::msg::dds_::TYPE_`, in `PKG/msg/dds_/TYPE_.idl` (the name on the wire).
    Dds,
}

impl Flavor {
    fn type_name(self, name: &str) -> String {
        match self {
            Flavor::Rosidl => name.to_string(),
            Flavor::Dds => format!("{name}_"),
        }
    }

    fn scoped(self, t: &TypeName) -> String {
        match self {
            Flavor::Rosidl => format!("{}::{}::{}", t.package, t.kind, t.name),
            Flavor::Dds => t.dds(),
        }
    }

    fn include(self, t: &TypeName) -> String {
        match self {
            Flavor::Rosidl => format!("{}/{}/{}.idl", t.package, t.kind, t.name),
            Flavor::Dds => format!("{}/{}/dds_/{}_.idl", t.package, t.kind, t.name),
        }
    }

    /// The file the type is written to, relative to the package's parent directory.
    pub fn path(self, t: &TypeName) -> String {
        self.include(t)
    }
}

/// A value as a literal: `true`/`false` in a `.msg`, `TRUE`/`FALSE` in IDL; a float as its
/// shortest round-tripping decimal (of an `f32` for `float32`); a string in double quotes.
fn literal(base: &BaseType, v: &Value, idl: bool) -> String {
    match base {
        BaseType::Primitive(Primitive::Bool) => {
            let b = v.as_bool().unwrap_or_default();
            match (idl, b) {
                (true, true) => "TRUE".into(),
                (true, false) => "FALSE".into(),
                (false, true) => "true".into(),
                (false, false) => "false".into(),
            }
        }
        BaseType::Primitive(Primitive::Float32) => format!("{:?}", v.as_f64().unwrap_or_default() as f32),
        BaseType::Primitive(Primitive::Float64) => format!("{:?}", v.as_f64().unwrap_or_default()),
        BaseType::Primitive(p) if p.is_signed() => v.as_i64().unwrap_or_default().to_string(),
        BaseType::Primitive(_) => v.as_u64().unwrap_or_default().to_string(),
        BaseType::String { .. } | BaseType::WString { .. } => {
            let s = v.as_str().unwrap_or_default();
            format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
        }
        BaseType::Nested(_) => String::new(),
    }
}

/// The `@default` value of a scalar, when the IDL tools can read it.
fn idl_default(base: &BaseType, v: &Value) -> Option<String> {
    match base {
        BaseType::Primitive(p) if p.is_signed() && v.as_i64().unwrap_or_default() < -i64::from(i32::MAX) => None,
        BaseType::Nested(_) => None,
        _ => Some(literal(base, v, true)),
    }
}

/// A type as a `.msg` names it: a message of the same package by its name alone.
fn msg_base(base: &BaseType, package: &str) -> String {
    match base {
        BaseType::Primitive(p) => p.msg_name().to_string(),
        BaseType::String { bound: None } => "string".into(),
        BaseType::String { bound: Some(b) } => format!("string<={b}"),
        BaseType::WString { bound: None } => "wstring".into(),
        BaseType::WString { bound: Some(b) } => format!("wstring<={b}"),
        BaseType::Nested(t) if t.package == package => t.name.clone(),
        BaseType::Nested(t) => format!("{}/{}", t.package, t.name),
    }
}

fn idl_base(base: &BaseType, flavor: Flavor) -> String {
    match base {
        BaseType::Primitive(p) => p.idl_name().to_string(),
        BaseType::String { bound: None } => "string".into(),
        BaseType::String { bound: Some(b) } => format!("string<{b}>"),
        BaseType::WString { bound: None } => "wstring".into(),
        BaseType::WString { bound: Some(b) } => format!("wstring<{b}>"),
        BaseType::Nested(t) => flavor.scoped(t),
    }
}

/// The `.msg` of `spec`: `header` as comment lines and a blank line, then its constants and
/// its fields (with their defaults).
pub fn msg_text(spec: &MessageSpec, header: &[String]) -> String {
    let mut s = String::new();
    for line in header {
        let _ = writeln!(s, "# {line}");
    }
    if !header.is_empty() {
        s.push('\n');
    }
    let package = &spec.name.package;
    for c in &spec.constants {
        let _ = writeln!(s, "{} {}={}", msg_base(&c.ty, package), c.name, literal(&c.ty, &c.value, false));
    }
    if spec.is_empty() {
        return s;
    }
    for f in &spec.fields {
        let dims = match f.ty.shape {
            Shape::Single => String::new(),
            Shape::Array(n) => format!("[{n}]"),
            Shape::Bounded(n) => format!("[<={n}]"),
            Shape::Unbounded => "[]".into(),
        };
        let default = match (&f.default, f.ty.shape) {
            (None, _) => String::new(),
            (Some(v), Shape::Single) => format!(" {}", literal(&f.ty.base, v, false)),
            (Some(v), _) => {
                let items: Vec<String> =
                    v.as_array().unwrap_or_default().iter().map(|e| literal(&f.ty.base, e, false)).collect();
                format!(" [{}]", items.join(", "))
            }
        };
        let _ = writeln!(s, "{}{dims} {}{default}", msg_base(&f.ty.base, package), f.name);
    }
    s
}

/// The IDL of `spec` in `flavor`: `header` as comment lines and a blank line, the includes
/// of its nested types (sorted), then its modules, constants and struct, one blank line
/// between members.
pub fn idl_text(spec: &MessageSpec, flavor: Flavor, header: &[String]) -> String {
    let mut s = String::new();
    for line in header {
        let _ = writeln!(s, "// {line}");
    }
    if !header.is_empty() {
        s.push('\n');
    }
    let mut includes = spec.nested_types();
    includes.sort_unstable();
    for inc in &includes {
        let _ = writeln!(s, "#include \"{}\"", flavor.include(inc));
    }
    if !includes.is_empty() {
        s.push('\n');
    }
    let name = &spec.name;
    let _ = writeln!(s, "module {} {{", name.package);
    let _ = writeln!(s, "  module {} {{", name.kind);
    let indent = match flavor {
        Flavor::Rosidl => "    ",
        Flavor::Dds => {
            let _ = writeln!(s, "    module dds_ {{");
            "      "
        }
    };
    if !spec.constants.is_empty() {
        let _ = writeln!(s, "{indent}module {}_Constants {{", flavor.type_name(&name.name));
        for c in &spec.constants {
            let _ = writeln!(
                s,
                "{indent}  const {} {} = {};",
                idl_base(&c.ty, flavor),
                c.name,
                literal(&c.ty, &c.value, true)
            );
        }
        let _ = writeln!(s, "{indent}}};");
    }
    let _ = writeln!(s, "{indent}struct {} {{", flavor.type_name(&name.name));
    let mut members = Vec::new();
    for f in &spec.fields {
        let mut m = String::new();
        if let (Some(v), Shape::Single) = (&f.default, f.ty.shape) {
            if let Some(v) = idl_default(&f.ty.base, v) {
                let _ = writeln!(m, "{indent}  @default (value={v})");
            }
        }
        let base = idl_base(&f.ty.base, flavor);
        let _ = match f.ty.shape {
            Shape::Single => writeln!(m, "{indent}  {base} {};", f.name),
            Shape::Array(n) => writeln!(m, "{indent}  {base} {}[{n}];", f.name),
            Shape::Bounded(n) => writeln!(m, "{indent}  sequence<{base}, {n}> {};", f.name),
            Shape::Unbounded => writeln!(m, "{indent}  sequence<{base}> {};", f.name),
        };
        members.push(m);
    }
    s.push_str(&members.join("\n"));
    let _ = writeln!(s, "{indent}}};");
    if flavor == Flavor::Dds {
        let _ = writeln!(s, "    }};");
    }
    let _ = writeln!(s, "  }};");
    let _ = writeln!(s, "}};");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registry::registry;

    #[test]
    fn a_stock_message_is_written_by_the_same_code() {
        let pose = registry().message("geometry_msgs/msg/PoseStamped").unwrap().spec();
        let idl = idl_text(pose, Flavor::Dds, &[]);
        assert_eq!(
            idl,
            "#include \"geometry_msgs/msg/dds_/Pose_.idl\"\n#include \"std_msgs/msg/dds_/Header_.idl\"\n\n\
             module geometry_msgs {\n  module msg {\n    module dds_ {\n      struct PoseStamped_ {\n        \
             std_msgs::msg::dds_::Header_ header;\n\n        geometry_msgs::msg::dds_::Pose_ pose;\n      };\n    };\n  };\n};\n"
        );
        let q = registry().message("geometry_msgs/msg/Quaternion").unwrap().spec();
        assert_eq!(msg_text(q, &[]), "float64 x 0.0\nfloat64 y 0.0\nfloat64 z 0.0\nfloat64 w 1.0\n");
        assert!(idl_text(q, Flavor::Rosidl, &[]).contains("      @default (value=1.0)\n      double w;\n"));
        let result = registry().message("simulation_interfaces/msg/Result").unwrap().spec();
        let idl = idl_text(result, Flavor::Rosidl, &["x".into()]);
        assert!(
            idl.starts_with("// x\n\nmodule simulation_interfaces {\n  module msg {\n    module Result_Constants {\n"),
            "{idl}"
        );
        assert!(idl.contains("      const uint8 RESULT_OK = 1;\n"), "{idl}");
        assert!(idl.contains("      string error_message;\n"), "{idl}");
        let empty = registry().message("simulation_interfaces/srv/GetSimulatorFeatures_Request").unwrap().spec();
        assert_eq!(msg_text(empty, &[]), "");
        assert!(idl_text(empty, Flavor::Rosidl, &[]).contains("      uint8 structure_needs_at_least_one_member;\n"));
        let nodes = registry().message("rmw_dds_common/msg/NodeEntitiesInfo").unwrap().spec();
        assert!(msg_text(nodes, &[]).starts_with("string<=256 node_namespace\n"));
        let idl = idl_text(nodes, Flavor::Rosidl, &[]);
        assert!(idl.contains("      string<256> node_namespace;\n"), "{idl}");
        assert!(idl.contains("      sequence<rmw_dds_common::msg::Gid> reader_gid_seq;\n"), "{idl}");
    }
}
