//! `tutti idl`: the typed DDS / ROS 2 interface of a DDF (`docs/gateway.md`) as source text.
//!
//! For a DDF whose ROS 2 package is `PKG`, every set of every domain becomes one message
//! `TYPE` (`mapping::set_names`), with the fields `uint64 step`, `float64 sim_time` and then
//! the set's items in DDF order (`mapping::field_names`), arrays as fixed-size arrays, each
//! bus as a nested message of its own (`mapping::bus_type_name`), the DDF's defaults as
//! default values and where it comes from (domain, set, bus) as its comment. That message is
//! a [`MessageSpec`], as a parsed `.msg` file is one: its description and type hash, its CDR
//! ([`registry`]) and its text come from the code that serves ROS 2's own interfaces. Every
//! type is written three ways, all under the directory `PKG/` (`write`):
//!
//! * `msg/TYPE.idl`: OMG IDL 4 exactly as ROS 2's `rosidl_adapter` writes it from a `.msg`
//!   (`module PKG { module msg { struct TYPE { … }; }; };`, nested types `#include`d as
//!   `"PKG/msg/BUS.idl"`);
//! * `msg/dds_/TYPE_.idl`: the same type under the name ROS 2 gives it on the wire
//!   (`PKG::msg::dds_::TYPE_`, as `rosidl_generator_dds_idl` writes it), for plain DDS
//!   programs that talk to the gateway's typed topics without ROS 2;
//! * `msg/TYPE.msg`: the ROS 2 message, listed in `CMakeLists.txt` next to a format 3
//!   `package.xml`, so that `PKG/` is an interface package `colcon build` builds.
//!
//! The IDL uses the IDL 4.2 integer keywords `int8`, `uint8`, … `uint64`, as rosidl does.
//! Both code generators the tests run accept them: Cyclone DDS `idlc` 0.10 and eProsima
//! `fastddsgen` 2.3. Defaults from the DDF become `.msg` default values and, for scalars,
//! `@default` annotations as rosidl writes them (`idlc` accepts them and warns that its C
//! generator ignores the value); rosidl writes an array's default as a string literal, which
//! `idlc` rejects, so arrays have none in IDL. No extensibility annotation is written, as
//! rosidl writes none: both tools then take `@final`, the plain CDR that ROS 2 sends.
//!
//! Each file names, in a comment, the ROS 2 type hash of its type ([`type_hashes`], as rosidl
//! computes it from the `.msg`: `crate::typehash`), which is what the gateway announces for
//! it; comments and defaults are not part of the hash.
//!
//! IDL identifiers are case-insensitive, so two type names that differ only in case, or a
//! field named like a type, would make IDL that `idlc` rejects; [`generate`] refuses such a
//! DDF with an error naming both culprits instead of writing it.

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use tutti_core::ddf::model::join_path;
use tutti_core::ddf::{self, Item, ItemKind, Model, Role, ScalarType};
use tutti_core::mapping;

use crate::registry::Registry;
use crate::spec::{Field, FieldType, Kind, MessageSpec, Primitive, Shape, TypeName};
use crate::typehash::{TypeDescription, TypeHash};
use crate::value::Value;

pub mod ros2msg;
pub mod write;

pub use write::Flavor;

/// The version written into `package.xml`. Fixed, so that the generated package only
/// changes when the DDF does.
pub const PACKAGE_VERSION: &str = "0.1.0";

/// One file to write, relative to the output directory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GeneratedFile {
    /// Relative path, e.g. `multiuav_msgs/msg/MultiuavUav1Publish.idl`.
    pub path: PathBuf,
    pub contents: String,
}

/// Why the interface of a DDF cannot be generated.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{source_file}: {message}")]
pub struct IdlError {
    /// The DDF, as the model names it.
    pub source_file: String,
    pub message: String,
}

/// One message of the package: a set, or a bus inside a set.
#[derive(Debug)]
struct SetType<'a> {
    spec: MessageSpec,
    /// Where it comes from, for comments and errors: `domain grid_feeder, set PUBLISH, bus meter`.
    origin: String,
    /// DDS topic of the set: set types only, which also get `step` and `sim_time`.
    topic: Option<String>,
    /// Each field that is an item (after `step` and `sim_time`), with its item, for errors.
    items: Vec<(String, &'a Item)>,
}

/// Generates every file of the interface package `package` (see the module documentation),
/// in a stable order: per domain and set, the set's files then its buses' files; then
/// `package.xml` and `CMakeLists.txt`.
pub fn generate(model: &Model, package: &str) -> Result<Vec<GeneratedFile>, IdlError> {
    let source_name = Path::new(&model.source)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| model.source.clone());
    let types = collect_types(model, package);
    check_identifiers(&types, &model.source)?;
    let hashes = hashes_of(&types, &model.source)?;

    let pkg_dir = PathBuf::from(package);
    let mut files = Vec::new();
    for (ty, hash) in types.iter().zip(&hashes) {
        let name = &ty.spec.name.name;
        let mut header = vec![format!("generated by tutti idl from {source_name}"), ty.origin.clone()];
        let mut idl_header = header.clone();
        if let Some(topic) = &ty.topic {
            idl_header.push(format!("DDS topic {topic}, type {}", ty.spec.name.dds()));
            header.push(format!("DDS topic {topic}"));
        }
        idl_header.push(format!("ROS 2 type hash {hash}"));
        idl_header.push("generated code does not contain a copyright notice".into());
        header.push(format!("ROS 2 type hash {hash}"));
        files.push(GeneratedFile {
            path: pkg_dir.join("msg").join(format!("{name}.idl")),
            contents: write::idl_text(&ty.spec, Flavor::Rosidl, &idl_header),
        });
        files.push(GeneratedFile {
            path: pkg_dir.join("msg").join("dds_").join(format!("{name}_.idl")),
            contents: write::idl_text(&ty.spec, Flavor::Dds, &idl_header),
        });
        files.push(GeneratedFile {
            path: pkg_dir.join("msg").join(format!("{name}.msg")),
            contents: write::msg_text(&ty.spec, &header),
        });
    }
    files.push(GeneratedFile { path: pkg_dir.join("package.xml"), contents: package_xml(package, &source_name) });
    files.push(GeneratedFile { path: pkg_dir.join("CMakeLists.txt"), contents: cmake_lists(package, &types) });
    Ok(files)
}

/// The messages of package `package` for `model` (each set's, each bus's) in a registry of
/// their own: their specs, descriptions, hashes and CDR codec.
pub fn registry(model: &Model, package: &str) -> Result<Registry, IdlError> {
    registry_of(collect_types(model, package), &model.source)
}

fn registry_of(types: Vec<SetType<'_>>, source: &str) -> Result<Registry, IdlError> {
    let mut b = Registry::builder();
    for t in types {
        b.message(t.spec);
    }
    b.build().map_err(|e| IdlError { source_file: source.to_string(), message: e.to_string() })
}

/// The ROS 2 type hash (`typehash`) of every message type of package `package` (each set's,
/// each bus's), by its ROS 2 name `PKG/msg/TYPE`: the types [`generate`] writes, hashed as
/// ROS 2 hashes the `.msg` files (`docs/gateway.md`, "Type hashes").
pub fn type_hashes(model: &Model, package: &str) -> Result<BTreeMap<String, TypeHash>, IdlError> {
    let types = collect_types(model, package);
    let names: Vec<String> = types.iter().map(|t| t.spec.name.to_string()).collect();
    let hashes = hashes_of(&types, &model.source)?;
    Ok(names.into_iter().zip(hashes).collect())
}

/// The type description of every type of the package, as ROS 2 describes its `.msg`.
pub fn type_descriptions(model: &Model, package: &str) -> Result<Vec<TypeDescription>, IdlError> {
    let r = registry(model, package)?;
    Ok(r.messages().map(|m| m.description()).collect())
}

fn hashes_of(types: &[SetType<'_>], source: &str) -> Result<Vec<TypeHash>, IdlError> {
    let mut b = Registry::builder();
    for t in types {
        b.message(t.spec.clone());
    }
    let r = b.build().map_err(|e| IdlError { source_file: source.to_string(), message: e.to_string() })?;
    types
        .iter()
        .map(|t| {
            r.hash(&t.spec.name.to_string()).ok_or_else(|| IdlError {
                source_file: source.to_string(),
                message: format!("{} is not described", t.spec.name),
            })
        })
        .collect()
}

/// The `.msg` primitive of a DDF scalar type (its IDL and `.msg` names: `Primitive::idl_name`,
/// `msg_name`).
pub fn primitive(ty: ScalarType) -> Primitive {
    use ScalarType::*;
    match ty {
        Boolean => Primitive::Bool,
        Int8 => Primitive::Int8,
        Int16 => Primitive::Int16,
        Int32 => Primitive::Int32,
        Int64 => Primitive::Int64,
        UInt8 => Primitive::UInt8,
        UInt16 => Primitive::UInt16,
        UInt32 => Primitive::UInt32,
        UInt64 => Primitive::UInt64,
        Float32 => Primitive::Float32,
        Float64 => Primitive::Float64,
    }
}

/// A DDF default as the value of a field of `length` elements of type `ty`.
fn default_value(ty: ScalarType, value: ddf::Value, length: u16) -> Value {
    let one = match ty {
        ScalarType::Boolean => Value::Bool(value.as_f64() != 0.0),
        ScalarType::Float32 | ScalarType::Float64 => Value::Float(value.as_f64()),
        t if t.is_signed_int() => Value::Int(value.as_i64()),
        _ => Value::UInt(value.as_u64()),
    };
    if length == 1 {
        one
    } else {
        Value::Array(vec![one; usize::from(length)])
    }
}

/// Every message of the package: per domain, PUBLISH then SUBSCRIBE, each set followed by its
/// buses depth-first.
fn collect_types<'a>(model: &'a Model, package: &str) -> Vec<SetType<'a>> {
    let mut types = Vec::new();
    for domain in &model.domains {
        for role in Role::ALL {
            let names = mapping::set_names(package, &domain.name, role);
            let set = SetContext {
                package,
                type_name: &names.type_name,
                origin: format!("domain {}, set {role}", domain.name),
            };
            collect_struct(
                &domain.set(role).items,
                names.type_name.clone(),
                &set,
                "",
                Some(names.topic.clone()),
                &mut types,
            );
        }
    }
    types
}

/// The set a message belongs to.
#[derive(Debug)]
struct SetContext<'s> {
    package: &'s str,
    type_name: &'s str,
    origin: String,
}

/// Pushes the message `name` of `items` (the set itself when `bus_path` is empty, with its
/// `step` and `sim_time`), then the messages of its buses.
fn collect_struct<'a>(
    items: &'a [Item],
    name: String,
    set: &SetContext<'_>,
    bus_path: &str,
    topic: Option<String>,
    out: &mut Vec<SetType<'a>>,
) {
    let mut nested = Vec::new();
    let mut fields = Vec::new();
    if topic.is_some() {
        fields.push(Field::new("step", FieldType::primitive(Primitive::UInt64)));
        fields.push(Field::new("sim_time", FieldType::primitive(Primitive::Float64)));
    }
    let mut item_fields = Vec::new();
    for (item, field) in items.iter().zip(mapping::field_names(items)) {
        let f = match &item.kind {
            ItemKind::Scalar { ty, length, default } => Field {
                default: default.map(|v| default_value(*ty, v, *length)),
                ..Field::new(&field, scalar_type(*ty, *length))
            },
            ItemKind::Bus { items } => {
                let path = join_path(bus_path, &item.name);
                let ty = mapping::bus_type_name(set.type_name, &path);
                let f = Field::new(&field, FieldType::nested(TypeName::new(set.package, Kind::Msg, &ty)));
                nested.push((items, ty, path));
                f
            }
        };
        fields.push(f);
        item_fields.push((field, item));
    }
    let origin = if bus_path.is_empty() { set.origin.clone() } else { format!("{}, bus {bus_path}", set.origin) };
    let mut spec = MessageSpec::new(TypeName::new(set.package, Kind::Msg, &name), fields, Vec::new());
    spec.comments = vec![origin.clone()];
    out.push(SetType { spec, origin, topic, items: item_fields });
    for (items, ty, path) in nested {
        collect_struct(items, ty, set, &path, None, out);
    }
}

fn scalar_type(ty: ScalarType, length: u16) -> FieldType {
    let shape = if length == 1 { Shape::Single } else { Shape::Array(u64::from(length)) };
    FieldType { shape, ..FieldType::primitive(primitive(ty)) }
}

/// IDL identifiers collide regardless of case (OMG IDL 4.2, 7.2.3): refuse type names that
/// differ only in case, and fields named like a type.
fn check_identifiers(types: &[SetType<'_>], source_file: &str) -> Result<(), IdlError> {
    let clash = |message: String| IdlError { source_file: source_file.to_string(), message };
    let mut seen: HashMap<String, &SetType<'_>> = HashMap::new();
    for ty in types {
        if let Some(first) = seen.insert(ty.spec.name.name.to_ascii_lowercase(), ty) {
            return Err(clash(format!(
                "type name {} ({}) clashes with type name {} ({}): IDL names are case-insensitive; rename one of them in the DDF",
                ty.spec.name.name, ty.origin, first.spec.name.name, first.origin
            )));
        }
    }
    for ty in types {
        for (field, item) in &ty.items {
            if let Some(other) = seen.get(&field.to_ascii_lowercase()) {
                return Err(clash(format!(
                    "field {field} of {} ({}, item {}) is named like the type {} ({}): IDL names are case-insensitive; rename the item in the DDF",
                    ty.spec.name.name, ty.origin, item.name, other.spec.name.name, other.origin
                )));
            }
        }
    }
    Ok(())
}

fn package_xml(package: &str, source_name: &str) -> String {
    format!(
        r#"<?xml version="1.0"?>
<?xml-model href="http://download.ros.org/schema/package_format3.xsd" schematypens="http://www.w3.org/2001/XMLSchema"?>
<!-- generated by tutti idl from {source_name} -->
<package format="3">
  <name>{package}</name>
  <version>{PACKAGE_VERSION}</version>
  <description>ROS 2 messages of the tutti domains described by {source_name}: one message per set, as the tutti gateway publishes and subscribes them.</description>
  <maintainer email="tutti@example.invalid">tutti</maintainer>
  <license>Apache-2.0</license>

  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>

  <exec_depend>rosidl_default_runtime</exec_depend>

  <member_of_group>rosidl_interface_packages</member_of_group>

  <export>
    <build_type>ament_cmake</build_type>
  </export>
</package>
"#
    )
}

fn cmake_lists(package: &str, types: &[SetType<'_>]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# generated by tutti idl");
    let _ = writeln!(s, "cmake_minimum_required(VERSION 3.8)");
    let _ = writeln!(s, "project({package})");
    s.push('\n');
    let _ = writeln!(s, "find_package(ament_cmake REQUIRED)");
    let _ = writeln!(s, "find_package(rosidl_default_generators REQUIRED)");
    s.push('\n');
    let _ = writeln!(s, "rosidl_generate_interfaces(${{PROJECT_NAME}}");
    for ty in types {
        let _ = writeln!(s, "  \"msg/{}.msg\"", ty.spec.name.name);
    }
    let _ = writeln!(s, ")");
    s.push('\n');
    let _ = writeln!(s, "ament_export_dependencies(rosidl_default_runtime)");
    let _ = writeln!(s, "ament_package()");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use tutti_core::ddf::parse_str;

    const FIGURE2: &str = include_str!("../../../ddf/paper-figure2.ddf");
    const PRODUCT: &str = include_str!("../../../ddf/product-sample.ddf");

    fn files(text: &str, source: &str) -> Vec<GeneratedFile> {
        let model = parse_str(text, source).unwrap();
        let pkg = mapping::package_name(Path::new(source));
        generate(&model, &pkg).unwrap()
    }

    fn file<'a>(files: &'a [GeneratedFile], path: &str) -> &'a str {
        files
            .iter()
            .find(|f| f.path == Path::new(path))
            .map(|f| f.contents.as_str())
            .unwrap_or_else(|| panic!("no {path} among {:?}", files.iter().map(|f| &f.path).collect::<Vec<_>>()))
    }

    #[test]
    fn figure2_publish_set_is_a_rosidl_struct() {
        let f = files(FIGURE2, "ddf/paper-figure2.ddf");
        let idl = file(&f, "paper_figure2_msgs/msg/MultiuavUav1Publish.idl");
        assert_eq!(
            idl,
            "// generated by tutti idl from paper-figure2.ddf
// domain multiuav_uav1, set PUBLISH
// DDS topic rt/multiuav_uav1/publish, type paper_figure2_msgs::msg::dds_::MultiuavUav1Publish_
// ROS 2 type hash RIHS01_2a73821045b3fd05022bdd1d1143e95e0cea190be90714b1fa4dee7bdb3b935c
// generated code does not contain a copyright notice

module paper_figure2_msgs {
  module msg {
    struct MultiuavUav1Publish {
      uint64 step;

      double sim_time;

      double autopilot;

      double x;
    };
  };
};
"
        );
        let msg = file(&f, "paper_figure2_msgs/msg/MultiuavUav1Subscribe.msg");
        assert!(
            msg.ends_with("\nuint64 step\nfloat64 sim_time\nfloat64 latitude\nfloat64 longitude\nfloat64 elevation\n"),
            "{msg}"
        );
        let dds = file(&f, "paper_figure2_msgs/msg/dds_/MultiuavUav1Subscribe_.idl");
        assert!(dds.contains("module paper_figure2_msgs {\n  module msg {\n    module dds_ {\n      struct MultiuavUav1Subscribe_ {\n"), "{dds}");
        assert!(dds.ends_with("      double elevation;\n      };\n    };\n  };\n};\n"), "{dds}");
    }

    #[test]
    fn type_hashes_are_those_of_the_generated_messages() {
        let model = parse_str(PRODUCT, "ddf/product-sample.ddf").unwrap();
        let hashes = type_hashes(&model, "product_sample_msgs").unwrap();
        // As ROS 2's rosidl computes them from the generated package (tests/cli/ros2_typehash.rs
        // runs rosidl itself on it).
        assert_eq!(
            hashes.get("product_sample_msgs/msg/GridFeederPublish").map(|h| h.to_string()).as_deref(),
            Some("RIHS01_d60c8e6bde94bfc79e43e1dedefdd3e7a9c99fdc6685ef140e8359f39f57017d")
        );
        assert_eq!(
            hashes.get("product_sample_msgs/msg/GridFeederPublishMeter").map(|h| h.to_string()).as_deref(),
            Some("RIHS01_2c282cec40697e791a8687e59aad935575a9bb4811e127a4275c33edc442d316")
        );
        let set = type_descriptions(&model, "product_sample_msgs")
            .unwrap()
            .into_iter()
            .find(|d| d.type_description.type_name == "product_sample_msgs/msg/GridFeederPublish")
            .unwrap();
        let names: Vec<&str> = set.referenced_type_descriptions.iter().map(|t| t.type_name.as_str()).collect();
        assert_eq!(names, ["product_sample_msgs/msg/GridFeederPublishMeter"]);
        // Every generated file names its type's hash, which the defaults do not change.
        let f = files(PRODUCT, "ddf/product-sample.ddf");
        for (path, ty) in [
            ("product_sample_msgs/msg/GridFeederPublish.msg", "GridFeederPublish"),
            ("product_sample_msgs/msg/GridFeederPublishMeter.idl", "GridFeederPublishMeter"),
            ("product_sample_msgs/msg/dds_/GridFeederSubscribe_.idl", "GridFeederSubscribe"),
        ] {
            let hash = hashes[&format!("product_sample_msgs/msg/{ty}")];
            assert!(file(&f, path).contains(&format!(" ROS 2 type hash {hash}\n")), "{path}");
        }
    }

    #[test]
    fn figure2_package_lists_every_message() {
        let f = files(FIGURE2, "ddf/paper-figure2.ddf");
        let paths: Vec<String> = f.iter().map(|f| f.path.display().to_string()).collect();
        assert_eq!(
            paths,
            [
                "paper_figure2_msgs/msg/MultiuavUav1Publish.idl",
                "paper_figure2_msgs/msg/dds_/MultiuavUav1Publish_.idl",
                "paper_figure2_msgs/msg/MultiuavUav1Publish.msg",
                "paper_figure2_msgs/msg/MultiuavUav1Subscribe.idl",
                "paper_figure2_msgs/msg/dds_/MultiuavUav1Subscribe_.idl",
                "paper_figure2_msgs/msg/MultiuavUav1Subscribe.msg",
                "paper_figure2_msgs/package.xml",
                "paper_figure2_msgs/CMakeLists.txt",
            ]
        );
        let cmake = file(&f, "paper_figure2_msgs/CMakeLists.txt");
        assert!(cmake.contains(
            "rosidl_generate_interfaces(${PROJECT_NAME}\n  \"msg/MultiuavUav1Publish.msg\"\n  \"msg/MultiuavUav1Subscribe.msg\"\n)\n"
        ));
        let xml = file(&f, "paper_figure2_msgs/package.xml");
        assert!(xml.contains("<package format=\"3\">"));
        assert!(xml.contains("<name>paper_figure2_msgs</name>"));
        assert!(xml.contains("<buildtool_depend>rosidl_default_generators</buildtool_depend>"));
        assert!(xml.contains("<member_of_group>rosidl_interface_packages</member_of_group>"));
    }

    #[test]
    fn product_bus_is_a_nested_struct_with_defaults_and_arrays() {
        let f = files(PRODUCT, "ddf/product-sample.ddf");
        let set = file(&f, "product_sample_msgs/msg/GridFeederPublish.idl");
        assert!(
            set.contains(
                "\n#include \"product_sample_msgs/msg/GridFeederPublishMeter.idl\"\n\nmodule product_sample_msgs {\n"
            ),
            "{set}"
        );
        assert!(set.contains("      @default (value=TRUE)\n      boolean breaker_closed;\n"), "{set}");
        assert!(set.contains("      double voltage_abc[3];\n"), "{set}");
        assert!(set.contains("      product_sample_msgs::msg::GridFeederPublishMeter meter;\n    };\n"), "{set}");
        let bus = file(&f, "product_sample_msgs/msg/GridFeederPublishMeter.idl");
        assert!(bus.contains("// domain grid_feeder, set PUBLISH, bus meter\n"), "{bus}");
        assert!(
            bus.contains(
                "    struct GridFeederPublishMeter {\n      float power_kw;\n\n      uint32 samples;\n    };\n"
            ),
            "{bus}"
        );
        assert!(!bus.contains("step"), "a bus has no header fields: {bus}");
        let dds = file(&f, "product_sample_msgs/msg/dds_/GridFeederPublish_.idl");
        assert!(dds.contains("#include \"product_sample_msgs/msg/dds_/GridFeederPublishMeter_.idl\"\n"), "{dds}");
        assert!(dds.contains("        product_sample_msgs::msg::dds_::GridFeederPublishMeter_ meter;\n"), "{dds}");
        assert_eq!(
            file(&f, "product_sample_msgs/msg/GridFeederPublish.msg")
                .lines()
                .skip_while(|l| l.starts_with('#') || l.is_empty())
                .collect::<Vec<_>>(),
            [
                "uint64 step",
                "float64 sim_time",
                "bool breaker_closed true",
                "float64[3] voltage_abc",
                "GridFeederPublishMeter meter"
            ]
        );
        assert_eq!(
            file(&f, "product_sample_msgs/msg/GridFeederSubscribe.msg")
                .lines()
                .skip_while(|l| l.starts_with('#') || l.is_empty())
                .collect::<Vec<_>>(),
            ["uint64 step", "float64 sim_time", "float64 setpoint_kw 1.5", "int8 mode 0"]
        );
        assert!(file(&f, "product_sample_msgs/CMakeLists.txt").contains("  \"msg/GridFeederPublishMeter.msg\"\n"));
    }

    #[test]
    fn every_type_nested_buses_and_array_defaults() {
        let f = files(
            r#"<orchestra><domain name="all"><set name="PUBLISH">
                 <item name="b"><type>bool</type><length>2</length><default>no</default></item>
                 <item name="i8"><type>int8</type><default>-3</default></item>
                 <item name="i64"><type>int64</type><default>-9223372036854775808</default></item>
                 <item name="u64"><type>uint64</type><default>18446744073709551615</default></item>
                 <item name="f"><type>float</type><length>2</length><default>0.1</default></item>
                 <item name="gps"><type>bus</type>
                   <item name="fix"><type>bus</type><item name="Latitude"><type>double</type></item></item>
                 </item>
               </set></domain></orchestra>"#,
            "t/All Types.ddf",
        );
        let set = file(&f, "all_types_msgs/msg/AllPublish.idl");
        assert!(set.contains("      double sim_time;\n\n      boolean b[2];\n"), "{set}");
        assert!(set.contains("      @default (value=-3)\n      int8 i8;\n"), "{set}");
        assert!(set.contains("      int8 i8;\n\n      int64 i64;\n"), "{set}");
        assert!(set.contains("      @default (value=18446744073709551615)\n      uint64 u64;\n"), "{set}");
        assert!(set.contains("      uint64 u64;\n\n      float f[2];\n"), "{set}");
        let msg = file(&f, "all_types_msgs/msg/AllPublish.msg");
        assert!(msg.contains("\nbool[2] b [false, false]\nint8 i8 -3\nint64 i64 -9223372036854775808\nuint64 u64 18446744073709551615\nfloat32[2] f [0.1, 0.1]\nAllPublishGps gps\n"), "{msg}");
        let gps = file(&f, "all_types_msgs/msg/AllPublishGps.idl");
        assert!(gps.contains("#include \"all_types_msgs/msg/AllPublishGpsFix.idl\""), "{gps}");
        assert!(file(&f, "all_types_msgs/msg/AllPublishGpsFix.msg").ends_with("\nfloat64 latitude\n"));
        // The SUBSCRIBE set is absent: an empty set still has its header fields.
        assert!(file(&f, "all_types_msgs/msg/AllSubscribe.msg").ends_with("\nuint64 step\nfloat64 sim_time\n"));
    }

    #[test]
    fn names_that_clash_in_idl_are_refused() {
        let clash = |text: &str| {
            let model = parse_str(text, "c.ddf").unwrap();
            generate(&model, "c_msgs").unwrap_err().to_string()
        };
        let e = clash(
            r#"<orchestra><domain name="grid_feeder"><set name="PUBLISH"><item name="x"><type>double</type></item></set></domain>
               <domain name="gridFeeder"><set name="PUBLISH"><item name="x"><type>double</type></item></set></domain></orchestra>"#,
        );
        assert!(e.contains("type name GridFeederPublish (domain gridFeeder, set PUBLISH) clashes"), "{e}");
        let e = clash(
            r#"<orchestra><domain name="a"><set name="PUBLISH"><item name="apublish"><type>double</type></item></set></domain></orchestra>"#,
        );
        assert!(e.starts_with("c.ddf: field apublish of APublish"), "{e}");
        assert!(e.contains("item apublish) is named like the type APublish"), "{e}");
    }
}
