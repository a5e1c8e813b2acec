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
//! The descriptions here are those of the types the gateway announces: each set's message
//! (built from the DDF by `idl`, the same types `tutti idl` writes) and the stock types of
//! [`stock`]. Pure computation: no DDS crate.

use std::collections::BTreeMap;
use std::fmt::{self, Write as _};

use sha2::{Digest, Sha256};

use crate::ddf::ScalarType;

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
    pub const BOUNDED_STRING: u8 = 21;
    /// Added to a kind for a fixed-size array of it.
    pub const ARRAY: u8 = 48;
    /// Added to a kind for a bounded sequence of it.
    pub const BOUNDED_SEQUENCE: u8 = 96;
    /// Added to a kind for an unbounded sequence of it.
    pub const UNBOUNDED_SEQUENCE: u8 = 144;
}

/// The type id of a DDF scalar type (its `.msg` primitive: `bool`, `int8`, … `float64`).
pub fn scalar_type_id(ty: ScalarType) -> u8 {
    use type_id::*;
    use ScalarType::*;
    match ty {
        Boolean => BOOLEAN,
        Int8 => INT8,
        Int16 => INT16,
        Int32 => INT32,
        Int64 => INT64,
        UInt8 => UINT8,
        UInt16 => UINT16,
        UInt32 => UINT32,
        UInt64 => UINT64,
        Float32 => FLOAT,
        Float64 => DOUBLE,
    }
}

/// The type of one field.
#[derive(Debug, Clone, PartialEq, Eq)]
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

    /// A value of kind `type_id`, or a fixed-size array of `length` of them when `length` is
    /// not 1 (as `.msg` writes `float64[3]`).
    pub fn scalar(type_id: u8, length: u64) -> FieldType {
        if length == 1 {
            FieldType::plain(type_id)
        } else {
            FieldType { capacity: length, ..FieldType::plain(type_id + type_id::ARRAY) }
        }
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
}

/// One field of a type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub name: String,
    pub ty: FieldType,
}

impl Field {
    pub fn new(name: &str, ty: FieldType) -> Field {
        Field { name: name.to_string(), ty }
    }
}

/// One type on its own: its name (`PKG/msg/TYPE`) and its fields, in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IndividualType {
    pub type_name: String,
    pub fields: Vec<Field>,
}

/// A type with every type it refers to, directly or through others: what is hashed.
#[derive(Debug, Clone, PartialEq, Eq)]
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
        let mut refs: BTreeMap<&str, &IndividualType> = BTreeMap::new();
        let mut queue: Vec<(&str, &str)> = nested_names(top).map(|n| (top.type_name.as_str(), n)).collect();
        while let Some((referrer, name)) = queue.pop() {
            if refs.contains_key(name) {
                continue;
            }
            let t = by_name
                .get(name)
                .ok_or_else(|| MissingType { referrer: referrer.to_string(), missing: name.to_string() })?;
            refs.insert(name, t);
            queue.extend(nested_names(t).map(|n| (t.type_name.as_str(), n)));
        }
        Ok(TypeDescription {
            type_description: top.clone(),
            referenced_type_descriptions: refs.into_values().cloned().collect(),
        })
    }

    /// The text that is hashed: the description as JSON with `", "` and `": "` between
    /// items, no other white space, ASCII only, keys in this order
    /// (`rosidl_generator_type_description`'s `calculate_type_hash`).
    pub fn canonical_json(&self) -> String {
        let mut s = String::from("{\"type_description\": ");
        write_type(&mut s, &self.type_description);
        s.push_str(", \"referenced_type_descriptions\": [");
        for (i, t) in self.referenced_type_descriptions.iter().enumerate() {
            if i > 0 {
                s.push_str(", ");
            }
            write_type(&mut s, t);
        }
        s.push_str("]}");
        s
    }

    /// The type's RIHS01 hash.
    pub fn hash(&self) -> TypeHash {
        TypeHash(Sha256::digest(self.canonical_json().as_bytes()).into())
    }
}

fn nested_names(t: &IndividualType) -> impl Iterator<Item = &str> {
    t.fields.iter().map(|f| f.ty.nested_type_name.as_str()).filter(|n| !n.is_empty())
}

fn write_type(s: &mut String, t: &IndividualType) {
    s.push_str("{\"type_name\": ");
    json_string(s, &t.type_name);
    s.push_str(", \"fields\": [");
    for (i, f) in t.fields.iter().enumerate() {
        if i > 0 {
            s.push_str(", ");
        }
        s.push_str("{\"name\": ");
        json_string(s, &f.name);
        let _ = write!(
            s,
            ", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": {}, \"nested_type_name\": ",
            f.ty.type_id, f.ty.capacity, f.ty.string_capacity
        );
        json_string(s, &f.ty.nested_type_name);
        s.push_str("}}");
    }
    s.push_str("]}");
}

/// A JSON string as Python's `json.dumps(ensure_ascii=True)` writes it.
fn json_string(s: &mut String, text: &str) {
    s.push('"');
    for c in text.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '\r' => s.push_str("\\r"),
            '\t' => s.push_str("\\t"),
            '\u{8}' => s.push_str("\\b"),
            '\u{c}' => s.push_str("\\f"),
            c if (' '..='\u{7f}').contains(&c) => s.push(c),
            c => {
                let mut units = [0u16; 2];
                for u in c.encode_utf16(&mut units) {
                    let _ = write!(s, "\\u{u:04x}");
                }
            }
        }
    }
    s.push('"');
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
    let (pkg, rest) = dds_type.split_once("::")?;
    let (kind, rest) = rest.split_once("::dds_::")?;
    let short = rest.strip_suffix('_')?;
    if pkg.is_empty() || kind.is_empty() || short.is_empty() || short.contains("::") {
        return None;
    }
    Some(format!("{pkg}/{kind}/{short}"))
}

/// The stock ROS 2 types the gateway announces besides its sets, as ROS 2 Jazzy defines them:
/// the per-item `std_msgs` types, `/clock`'s `rosgraph_msgs/msg/Clock`,
/// `ros_discovery_info`'s `rmw_dds_common/msg/ParticipantEntitiesInfo`, the
/// `rcl_interfaces/msg/ParameterEvent` of `/parameter_events` (which ros2-client's node
/// announces on the rustdds engine), and the messages of the `simulation_interfaces` services
/// and of the action `simulate_steps` ([`stock::simulation_types`]).
///
/// A service or an action is no type of its own on DDS: rosidl makes messages of it, and
/// each of its topics carries one of those, hashed as any message. Service `PKG/srv/NAME` is
/// the messages `PKG/srv/NAME_Request` (its request topic) and `…_Response` (its reply
/// topic); action `PKG/action/NAME` is the services `NAME_SendGoal` (request: `goal_id` and
/// the `NAME_Goal`; response: `accepted` and a `stamp`) and `NAME_GetResult` (request:
/// `goal_id`; response: `status` and the `NAME_Result`), `action_msgs/srv/CancelGoal`, the
/// feedback topic's `NAME_FeedbackMessage` (`goal_id` and the `NAME_Feedback`) and the status
/// topic's `action_msgs/msg/GoalStatusArray`. A message without fields gets the one field
/// `uint8 structure_needs_at_least_one_member`, as rosidl gives it; constants are no fields.
pub mod stock {
    use super::type_id::*;
    use super::{Field, FieldType, IndividualType, TypeDescription, TypeHash};

    fn t(name: &str, fields: Vec<Field>) -> IndividualType {
        IndividualType { type_name: name.to_string(), fields }
    }

    fn f(name: &str, type_id: u8) -> Field {
        Field::new(name, FieldType::plain(type_id))
    }

    fn n(name: &str, ty: &str) -> Field {
        Field::new(name, FieldType::nested(ty, 0, 0))
    }

    fn seq_of(name: &str, ty: &str) -> Field {
        Field::new(name, FieldType::nested(ty, UNBOUNDED_SEQUENCE, 0))
    }

    /// Every stock type this module describes (those referred to included).
    pub fn types() -> Vec<IndividualType> {
        vec![
            t("std_msgs/msg/Bool", vec![f("data", BOOLEAN)]),
            t("std_msgs/msg/Float64", vec![f("data", DOUBLE)]),
            t(
                "std_msgs/msg/Float64MultiArray",
                vec![n("layout", "std_msgs/msg/MultiArrayLayout"), f("data", DOUBLE + UNBOUNDED_SEQUENCE)],
            ),
            t(
                "std_msgs/msg/MultiArrayLayout",
                vec![seq_of("dim", "std_msgs/msg/MultiArrayDimension"), f("data_offset", UINT32)],
            ),
            t("std_msgs/msg/MultiArrayDimension", vec![f("label", STRING), f("size", UINT32), f("stride", UINT32)]),
            t("builtin_interfaces/msg/Time", vec![f("sec", INT32), f("nanosec", UINT32)]),
            t("rosgraph_msgs/msg/Clock", vec![n("clock", "builtin_interfaces/msg/Time")]),
            t(
                "rmw_dds_common/msg/ParticipantEntitiesInfo",
                vec![
                    n("gid", "rmw_dds_common/msg/Gid"),
                    seq_of("node_entities_info_seq", "rmw_dds_common/msg/NodeEntitiesInfo"),
                ],
            ),
            t("rmw_dds_common/msg/Gid", vec![Field::new("data", FieldType::scalar(UINT8, 16))]),
            t(
                "rmw_dds_common/msg/NodeEntitiesInfo",
                vec![
                    Field::new(
                        "node_namespace",
                        FieldType { string_capacity: 256, ..FieldType::plain(BOUNDED_STRING) },
                    ),
                    Field::new("node_name", FieldType { string_capacity: 256, ..FieldType::plain(BOUNDED_STRING) }),
                    seq_of("reader_gid_seq", "rmw_dds_common/msg/Gid"),
                    seq_of("writer_gid_seq", "rmw_dds_common/msg/Gid"),
                ],
            ),
            t(
                "rcl_interfaces/msg/ParameterEvent",
                vec![
                    n("stamp", "builtin_interfaces/msg/Time"),
                    f("node", STRING),
                    seq_of("new_parameters", "rcl_interfaces/msg/Parameter"),
                    seq_of("changed_parameters", "rcl_interfaces/msg/Parameter"),
                    seq_of("deleted_parameters", "rcl_interfaces/msg/Parameter"),
                ],
            ),
            t("rcl_interfaces/msg/Parameter", vec![f("name", STRING), n("value", "rcl_interfaces/msg/ParameterValue")]),
            t(
                "rcl_interfaces/msg/ParameterValue",
                vec![
                    f("type", UINT8),
                    f("bool_value", BOOLEAN),
                    f("integer_value", INT64),
                    f("double_value", DOUBLE),
                    f("string_value", STRING),
                    f("byte_array_value", BYTE + UNBOUNDED_SEQUENCE),
                    f("bool_array_value", BOOLEAN + UNBOUNDED_SEQUENCE),
                    f("integer_array_value", INT64 + UNBOUNDED_SEQUENCE),
                    f("double_array_value", DOUBLE + UNBOUNDED_SEQUENCE),
                    f("string_array_value", STRING + UNBOUNDED_SEQUENCE),
                ],
            ),
        ]
    }

    /// The messages of the `simulation_interfaces` services (`PKG/srv/NAME_Request` and
    /// `…_Response`) and of its action `SimulateSteps` (`PKG/action/SimulateSteps_…`, with
    /// `action_msgs`' `CancelGoal` and `GoalStatusArray`), and the types they refer to, as
    /// ROS 2 Jazzy's `simulation_interfaces`, `action_msgs` and `unique_identifier_msgs`
    /// define them.
    pub fn simulation_types() -> Vec<IndividualType> {
        const SI: &str = "simulation_interfaces";
        let result = "simulation_interfaces/msg/Result";
        let state = "simulation_interfaces/msg/SimulationState";
        let (uuid, time) = ("unique_identifier_msgs/msg/UUID", "builtin_interfaces/msg/Time");
        let goal_info = "action_msgs/msg/GoalInfo";
        // A message without fields, as rosidl makes it.
        let empty = || vec![f("structure_needs_at_least_one_member", UINT8)];
        let srv = |name: &str, request: Vec<Field>, response: Vec<Field>| {
            [t(&format!("{SI}/srv/{name}_Request"), request), t(&format!("{SI}/srv/{name}_Response"), response)]
        };
        let action = |suffix: &str, fields: Vec<Field>| t(&format!("{SI}/action/SimulateSteps_{suffix}"), fields);
        let mut all = vec![
            t(result, vec![f("result", UINT8), f("error_message", STRING)]),
            t(state, vec![f("state", UINT8)]),
            t(
                "simulation_interfaces/msg/SimulatorFeatures",
                vec![
                    f("features", UINT16 + UNBOUNDED_SEQUENCE),
                    f("spawn_formats", STRING + UNBOUNDED_SEQUENCE),
                    f("custom_info", STRING),
                ],
            ),
            t(uuid, vec![Field::new("uuid", FieldType::scalar(UINT8, 16))]),
            t(goal_info, vec![n("goal_id", uuid), n("stamp", time)]),
            t("action_msgs/msg/GoalStatus", vec![n("goal_info", goal_info), f("status", INT8)]),
            t("action_msgs/msg/GoalStatusArray", vec![seq_of("status_list", "action_msgs/msg/GoalStatus")]),
            t("action_msgs/srv/CancelGoal_Request", vec![n("goal_info", goal_info)]),
            t(
                "action_msgs/srv/CancelGoal_Response",
                vec![f("return_code", INT8), seq_of("goals_canceling", goal_info)],
            ),
            action("Goal", vec![f("steps", UINT64)]),
            action("Result", vec![n("result", result)]),
            action("Feedback", vec![f("completed_steps", UINT64), f("remaining_steps", UINT64)]),
            action(
                "SendGoal_Request",
                vec![n("goal_id", uuid), n("goal", "simulation_interfaces/action/SimulateSteps_Goal")],
            ),
            action("SendGoal_Response", vec![f("accepted", BOOLEAN), n("stamp", time)]),
            action("GetResult_Request", vec![n("goal_id", uuid)]),
            action(
                "GetResult_Response",
                vec![f("status", INT8), n("result", "simulation_interfaces/action/SimulateSteps_Result")],
            ),
            action(
                "FeedbackMessage",
                vec![n("goal_id", uuid), n("feedback", "simulation_interfaces/action/SimulateSteps_Feedback")],
            ),
        ];
        all.extend(srv(
            "GetSimulatorFeatures",
            empty(),
            vec![n("features", "simulation_interfaces/msg/SimulatorFeatures")],
        ));
        all.extend(srv("GetSimulationState", empty(), vec![n("state", state), n("result", result)]));
        all.extend(srv("SetSimulationState", vec![n("state", state)], vec![n("result", result)]));
        all.extend(srv("StepSimulation", vec![f("steps", UINT64)], vec![n("result", result)]));
        all.extend(srv("ResetSimulation", vec![f("scope", UINT8)], vec![n("result", result)]));
        all
    }

    /// The description of stock type `name` (`PKG/msg/TYPE`, `PKG/srv/NAME_Request`, …), if
    /// it is one of [`types`] or [`simulation_types`].
    pub fn description(name: &str) -> Option<TypeDescription> {
        let mut all = types();
        all.extend(simulation_types());
        let top = all.iter().find(|t| t.type_name == name)?;
        TypeDescription::of(top, &all).ok()
    }

    /// The hash of the stock type whose DDS name is `dds_type` (`std_msgs::msg::dds_::Float64_`).
    pub fn hash_of_dds_type(dds_type: &str) -> Option<TypeHash> {
        description(&super::ros2_type_name(dds_type)?).map(|d| d.hash())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hashes ROS 2 Jazzy's rosidl writes for these types (`type_hashes` in
    /// `share/PKG/msg/TYPE.json` of an installed ROS 2): fixed by ROS 2.
    const JAZZY: &[(&str, &str)] = &[
        ("std_msgs/msg/Float64", "RIHS01_705ba9c3d1a09df43737eb67095534de36fd426c0587779bda2bc51fe790182a"),
        ("std_msgs/msg/Bool", "RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9"),
        ("std_msgs/msg/Float64MultiArray", "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f"),
        ("rosgraph_msgs/msg/Clock", "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564"),
        ("builtin_interfaces/msg/Time", "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197"),
        (
            "rmw_dds_common/msg/ParticipantEntitiesInfo",
            "RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e",
        ),
        (
            "rcl_interfaces/msg/ParameterEvent",
            "RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204",
        ),
    ];

    /// What rosidl's type-description generator (`rosidl_generator_type_description`, run by
    /// tests/ros2/interface_hashes.py over ROS 2 Jazzy's `simulation_interfaces`,
    /// `action_msgs` and `unique_identifier_msgs`) writes for these messages of the
    /// services and the action.
    const JAZZY_SIMULATION: &[(&str, &str)] = &[
        (
            "simulation_interfaces/srv/GetSimulatorFeatures_Request",
            "RIHS01_982b8c1adef1d556f6ecdc019d1269fc39413626a9222d73b4fc874bd798b7db",
        ),
        (
            "simulation_interfaces/srv/GetSimulatorFeatures_Response",
            "RIHS01_ede4dc8227cbb2f86a24612c999dcaa67d17dab21dab566cefdc233e7a2a65d1",
        ),
        (
            "simulation_interfaces/srv/GetSimulationState_Response",
            "RIHS01_dc80ce852a5ab04c2b23cdd47910cee1bcc46e0f1931cac85825e6916b15517f",
        ),
        (
            "simulation_interfaces/srv/StepSimulation_Request",
            "RIHS01_cda33f6887815f3dce0f90e61fd8efd39bda13ae264ddede15c33fbad890630e",
        ),
        (
            "simulation_interfaces/srv/ResetSimulation_Request",
            "RIHS01_2c766d09c3aa30f01fadc55a42fd760b63db358c7d1d3b6a64ea9978225ffbc7",
        ),
        (
            "simulation_interfaces/action/SimulateSteps_SendGoal_Request",
            "RIHS01_275e6fd2fafc5d33dcdc83bdea6de5cf29f30b9df74a3b9514a8c5d501fd0fe3",
        ),
        (
            "simulation_interfaces/action/SimulateSteps_GetResult_Response",
            "RIHS01_5658172e771cb145a986a8ef4c2b80b5407b741038453b8539e35bed5ff23207",
        ),
        (
            "simulation_interfaces/action/SimulateSteps_FeedbackMessage",
            "RIHS01_a30dee7ee7380769e616406ec5067b238aa2b27e1dbd7a5957fba1d908d7754d",
        ),
        (
            "action_msgs/srv/CancelGoal_Response",
            "RIHS01_35e682cf3f510e83c70a82a4aac888496dedee56773bf9d8e5e0aa81f9e1c960",
        ),
        ("action_msgs/msg/GoalStatusArray", "RIHS01_6c1684b00f177d37438febe6e709fc4e2b0d4248dca4854946f9ed8b30cda83e"),
    ];

    #[test]
    fn the_simulation_services_messages_hash_as_ros2_jazzy_hashes_them() {
        for (name, expected) in JAZZY_SIMULATION {
            let d = stock::description(name).unwrap_or_else(|| panic!("{name} is not described"));
            assert_eq!(d.hash().to_string(), *expected, "{name}: {}", d.canonical_json());
        }
        // Every type refers only to described ones.
        for t in stock::simulation_types() {
            assert!(stock::description(&t.type_name).is_some(), "{} refers to an undescribed type", t.type_name);
        }
        assert_eq!(
            stock::hash_of_dds_type("simulation_interfaces::srv::dds_::StepSimulation_Request_").map(|h| h.to_string()),
            Some(JAZZY_SIMULATION[3].1.to_string())
        );
    }

    #[test]
    fn stock_types_hash_as_ros2_jazzy_hashes_them() {
        for (name, expected) in JAZZY {
            let d = stock::description(name).unwrap_or_else(|| panic!("{name} is not described"));
            assert_eq!(d.hash().to_string(), *expected, "{name}: {}", d.canonical_json());
        }
    }

    #[test]
    fn the_hashed_text_is_rosidls_compact_json() {
        let d = stock::description("rosgraph_msgs/msg/Clock").unwrap();
        assert_eq!(
            d.canonical_json(),
            "{\"type_description\": {\"type_name\": \"rosgraph_msgs/msg/Clock\", \"fields\": [{\"name\": \"clock\", \
             \"type\": {\"type_id\": 1, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \
             \"builtin_interfaces/msg/Time\"}}]}, \"referenced_type_descriptions\": [{\"type_name\": \
             \"builtin_interfaces/msg/Time\", \"fields\": [{\"name\": \"sec\", \"type\": {\"type_id\": 6, \"capacity\": 0, \
             \"string_capacity\": 0, \"nested_type_name\": \"\"}}, {\"name\": \"nanosec\", \"type\": {\"type_id\": 7, \
             \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}]}]}"
        );
    }

    #[test]
    fn dds_names_map_to_ros2_names_and_stock_hashes() {
        assert_eq!(ros2_type_name("std_msgs::msg::dds_::Float64_").as_deref(), Some("std_msgs/msg/Float64"));
        assert_eq!(ros2_type_name("Float64"), None);
        assert_eq!(ros2_type_name("a::msg::dds_::_"), None);
        assert_eq!(
            stock::hash_of_dds_type("rosgraph_msgs::msg::dds_::Clock_").map(|h| h.user_data()),
            Some("typehash=RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564;".to_string())
        );
        assert_eq!(stock::hash_of_dds_type("std_msgs::msg::dds_::String_"), None);
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
}
