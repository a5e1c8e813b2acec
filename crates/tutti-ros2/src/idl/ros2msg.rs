//! The `ros2msg` schema of a set: the `.msg` that `tutti idl` writes for its type, with the
//! `.msg` of every nested bus type appended after a `MSG: PKG/msg/BUS` separator line, as
//! ROS 2 tools (`ros2 bag`, Foxglove) expect a message definition. The MCAP recordings
//! (`docs/recording.md`) and the gateway's Foxglove server (`docs/gateway.md`) both describe
//! their channels with it, so a recorded set and a live one have one schema.

use std::collections::HashMap;

use tutti_core::ddf::{Model, Role};
use tutti_core::mapping;

use super::IdlError;

/// The separator of the message definitions in a `ros2msg` schema.
const SEPARATOR: &str = "================================================================================";

/// Why a set's `ros2msg` schema cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum SchemaError {
    #[error(transparent)]
    Idl(#[from] IdlError),
    #[error("no message definition for {ty}")]
    NoDefinition { ty: String },
    #[error("{ty} refers to {dep}, which has no definition")]
    MissingDependency { ty: String, dep: String },
}

/// `.msg` definitions by type name.
pub type Definitions = HashMap<String, String>;

/// The `.msg` definitions `tutti idl` writes for `model`, by type name.
pub fn message_definitions(model: &Model, package: &str) -> Result<Definitions, SchemaError> {
    let files = super::generate(model, package)?;
    Ok(files
        .into_iter()
        .filter(|f| f.path.extension().is_some_and(|e| e == "msg"))
        .filter_map(|f| Some((f.path.file_stem()?.to_string_lossy().into_owned(), f.contents)))
        .collect())
}

/// The types a `.msg` definition refers to (its fields' types that are not primitives).
fn referenced_types(msg: &str) -> Vec<String> {
    const PRIMITIVES: &[&str] = &[
        "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
        "uint64", "string", "wstring",
    ];
    msg.lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty())
        .filter_map(|l| {
            let ty = l.split_whitespace().next()?;
            let base = ty.split('[').next()?.rsplit('/').next()?;
            (!PRIMITIVES.contains(&base) && !l.contains('=')).then(|| base.to_string())
        })
        .collect()
}

/// The `ros2msg` schema of type `ty`: its definition, then every type it needs, each once.
pub fn ros2msg_schema(defs: &Definitions, package: &str, ty: &str) -> Result<String, SchemaError> {
    let main = defs.get(ty).ok_or_else(|| SchemaError::NoDefinition { ty: ty.to_string() })?;
    let mut out = main.clone();
    let mut seen = vec![ty.to_string()];
    let mut todo = referenced_types(main);
    while let Some(dep) = todo.pop() {
        if seen.contains(&dep) {
            continue;
        }
        let text =
            defs.get(&dep).ok_or_else(|| SchemaError::MissingDependency { ty: ty.to_string(), dep: dep.clone() })?;
        if !out.ends_with('\n') {
            out.push('\n');
        }
        out.push_str(&format!("{SEPARATOR}\nMSG: {package}/msg/{dep}\n{text}"));
        todo.extend(referenced_types(text));
        seen.push(dep);
    }
    Ok(out)
}

/// The `ros2msg` schema of a ROS 2 message of the registry (`tf2_msgs/msg/TFMessage`): its
/// `.msg` file, then that of every message it nests, each once, after its `MSG:` line.
pub fn message_schema(m: crate::Message<'_>) -> String {
    let mut out = String::new();
    let (mut seen, mut todo) = (Vec::new(), vec![m]);
    while let Some(m) = todo.pop() {
        let name = m.name();
        if seen.contains(name) {
            continue;
        }
        let text = crate::Registry::message_file(&name.package, &name.name).unwrap_or_default();
        if !seen.is_empty() {
            if !out.ends_with('\n') {
                out.push('\n');
            }
            out.push_str(&format!("{SEPARATOR}\nMSG: {name}\n"));
        }
        out.push_str(text);
        seen.push(name.clone());
        todo.extend(m.spec().fields.iter().rev().filter_map(|f| m.nested(&f.name)));
    }
    out
}

/// A set's schema as a channel names it: `PKG/msg/TYPE` and its `ros2msg` text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SetSchema {
    pub name: String,
    pub text: String,
}

/// The schema of set `role` of domain `domain` in package `package` (definitions `defs`).
pub fn set_schema(defs: &Definitions, package: &str, domain: &str, role: Role) -> Result<SetSchema, SchemaError> {
    let names = mapping::set_names(package, domain, role);
    let text = ros2msg_schema(defs, package, &names.type_name)?;
    Ok(SetSchema { name: format!("{package}/msg/{}", names.type_name), text })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interface_schema_carries_each_nested_message_once() {
        let s = message_schema(crate::registry().message("tf2_msgs/msg/TFMessage").unwrap());
        assert!(s.starts_with("geometry_msgs/TransformStamped[] transforms"), "{s}");
        for nested in [
            "geometry_msgs/msg/TransformStamped",
            "std_msgs/msg/Header",
            "builtin_interfaces/msg/Time",
            "geometry_msgs/msg/Transform",
            "geometry_msgs/msg/Vector3",
            "geometry_msgs/msg/Quaternion",
        ] {
            assert_eq!(s.matches(&format!("MSG: {nested}\n")).count(), 1, "{nested} in {s}");
        }
    }

    #[test]
    fn schemas_carry_the_nested_bus_types_once() {
        let ddf = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../ddf/product-sample.ddf");
        let m = tutti_core::ddf::load(&ddf).unwrap();
        let defs = message_definitions(&m, "product_sample_msgs").unwrap();
        let s = ros2msg_schema(&defs, "product_sample_msgs", "GridFeederPublish").unwrap();
        assert!(s.starts_with(&defs["GridFeederPublish"]));
        assert_eq!(s.matches("MSG: product_sample_msgs/msg/GridFeederPublishMeter\n").count(), 1, "{s}");
        let set = set_schema(&defs, "product_sample_msgs", "grid_feeder", Role::Publish).unwrap();
        assert_eq!((set.name.as_str(), set.text.as_str()), ("product_sample_msgs/msg/GridFeederPublish", s.as_str()));
        assert_eq!(
            referenced_types("uint64 step\nfloat64[3] v\nFoo foo # c\npkg/Bar bar\nint32 X=3\n"),
            ["Foo", "Bar"]
        );
    }
}
