//! Hashes and bytes pinned by ROS 2 itself, checked without Python: the hashes ROS 2 Jazzy
//! installs for the stock types, those rosidl's generator computes for the messages of the
//! simulation services and action (tests/ros2/interface_hashes.py; `hashes.rs` compares every
//! type), and the CDR of two messages written out by hand, byte by byte.

use tutti_ros2::{registry, Struct, Value};

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
    ("rcl_interfaces/msg/ParameterEvent", "RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204"),
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
    ("action_msgs/srv/CancelGoal_Response", "RIHS01_35e682cf3f510e83c70a82a4aac888496dedee56773bf9d8e5e0aa81f9e1c960"),
    ("action_msgs/msg/GoalStatusArray", "RIHS01_6c1684b00f177d37438febe6e709fc4e2b0d4248dca4854946f9ed8b30cda83e"),
];

/// What the same generator writes for the two messages the entity-state services carry.
const JAZZY_ENTITY: &[(&str, &str)] = &[
    ("geometry_msgs/msg/PoseStamped", "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"),
    (
        "simulation_interfaces/msg/EntityState",
        "RIHS01_2e0464a85eb80a939025075d6c20761eca6a4cb9d6baf2c0ba373467c8b598d0",
    ),
];

#[test]
fn stock_types_hash_as_ros2_jazzy_hashes_them() {
    for (name, expected) in JAZZY {
        let d = registry().description(name).unwrap_or_else(|| panic!("{name} is not described"));
        assert_eq!(d.hash().to_string(), *expected, "{name}: {}", d.canonical_json());
    }
}

#[test]
fn the_simulation_services_messages_hash_as_ros2_jazzy_hashes_them() {
    for (name, expected) in JAZZY_SIMULATION {
        let d = registry().description(name).unwrap_or_else(|| panic!("{name} is not described"));
        assert_eq!(d.hash().to_string(), *expected, "{name}: {}", d.canonical_json());
    }
    assert_eq!(
        registry().hash_of_dds_type("simulation_interfaces::srv::dds_::StepSimulation_Request_").map(|h| h.to_string()),
        Some(JAZZY_SIMULATION[3].1.to_string())
    );
}

#[test]
fn dds_names_map_to_ros2_names_and_stock_hashes() {
    assert_eq!(
        registry().hash_of_dds_type("rosgraph_msgs::msg::dds_::Clock_").map(|h| h.user_data()),
        Some("typehash=RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564;".to_string())
    );
    // Every message of the embedded packages has its hash, std_msgs/String as Float64.
    assert!(registry().hash_of_dds_type("std_msgs::msg::dds_::String_").is_some());
    assert_eq!(registry().hash_of_dds_type("nobody_msgs::msg::dds_::Nothing_"), None);
    assert_eq!(registry().hash_of_dds_type("std_msgs/msg/Float64"), None);
    let by_dds = registry().message("simulation_interfaces::action::dds_::SimulateSteps_SendGoal_Request_").unwrap();
    assert_eq!(by_dds.name().to_string(), "simulation_interfaces/action/SimulateSteps_SendGoal_Request");
}

#[test]
fn services_actions_and_constants_are_found_by_name() {
    let r = registry();
    let step = r.service("simulation_interfaces/srv/StepSimulation").unwrap();
    assert_eq!(step.request().name().to_string(), "simulation_interfaces/srv/StepSimulation_Request");
    assert_eq!(step.request().spec().field("steps").and_then(|f| f.default.clone()), Some(Value::UInt(1)));
    assert_eq!(
        step.response().nested("result").map(|m| m.name().to_string()).as_deref(),
        Some("simulation_interfaces/msg/Result")
    );
    assert_eq!(
        step.event().spec().fields.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(),
        ["info", "request", "response"]
    );
    let result = r.message("simulation_interfaces/msg/Result").unwrap();
    assert_eq!(result.constant("RESULT_OK"), Some(&Value::UInt(1)));
    assert_eq!(result.constant("RESULT_OPERATION_FAILED"), Some(&Value::UInt(4)));
    let steps = r.action("simulation_interfaces/action/SimulateSteps").unwrap();
    assert_eq!(
        steps.send_goal().request().name().to_string(),
        "simulation_interfaces/action/SimulateSteps_SendGoal_Request"
    );
    assert_eq!(steps.get_result().response().spec().fields[0].name, "status");
    assert_eq!(steps.feedback_message().nested("feedback").unwrap().name(), steps.feedback().name());
    let empty = r.message("simulation_interfaces/srv/GetSimulatorFeatures_Request").unwrap();
    assert!(empty.spec().is_empty());
    assert_eq!(empty.encode(&Struct::new().into()).unwrap(), [0]);
}

#[test]
fn pose_stamped_encodes_decodes_and_hashes_with_no_code_of_its_own() {
    let msg = registry().message("geometry_msgs/msg/PoseStamped").unwrap();
    assert_eq!(msg.hash().to_string(), JAZZY_ENTITY[0].1, "{}", msg.description().canonical_json());
    let value: Value = Struct::new()
        .with(
            "header",
            Struct::new().with("stamp", Struct::new().with("sec", -5i32).with("nanosec", 7u32)).with("frame_id", "map"),
        )
        .with(
            "pose",
            Struct::new()
                .with("position", Struct::new().with("x", 1.5).with("y", -2.0).with("z", 0.25))
                .with("orientation", Struct::new().with("z", 0.5)),
        )
        .into();
    let body = msg.encode(&value).unwrap();
    let mut want = Vec::new();
    want.extend_from_slice(&(-5i32).to_le_bytes());
    want.extend_from_slice(&7u32.to_le_bytes());
    want.extend_from_slice(&[4, 0, 0, 0, b'm', b'a', b'p', 0]);
    // 16 bytes so far: the doubles need no padding.
    for x in [1.5f64, -2.0, 0.25, 0.0, 0.0, 0.5, 1.0] {
        want.extend_from_slice(&x.to_le_bytes());
    }
    assert_eq!(body, want, "the orientation's w takes its .msg default, 1");
    let back = msg.decode(&body, true).unwrap();
    assert_eq!(back.path("header.frame_id").and_then(Value::as_str), Some("map"));
    assert_eq!(back.path("header.stamp.sec").and_then(Value::as_i64), Some(-5));
    assert_eq!(back.path("pose.orientation.w").and_then(Value::as_f64), Some(1.0));
    assert_eq!(msg.encode(&back).unwrap(), body);
}

#[test]
fn entity_state_encodes_decodes_and_hashes_with_no_code_of_its_own() {
    let msg = registry().message("simulation_interfaces/msg/EntityState").unwrap();
    assert_eq!(msg.hash().to_string(), JAZZY_ENTITY[1].1, "{}", msg.description().canonical_json());
    let mut value = msg.default_value();
    let s = value.as_struct_mut().unwrap();
    s.set("header", Struct::new().with("frame_id", "world"));
    s.set("twist", Struct::new().with("linear", Struct::new().with("x", 3.0)));
    s.set("acceleration", Struct::new().with("angular", Struct::new().with("z", -1.0)));
    let body = msg.encode(&value).unwrap();
    // header: time (8), "world" (4 + 6), padded to 24; pose: 7 doubles; twist, accel: 6 each.
    assert_eq!(body.len(), 24 + 8 * (7 + 6 + 6));
    assert_eq!(&body[8..18], &[6, 0, 0, 0, b'w', b'o', b'r', b'l', b'd', 0]);
    let twist_x = 24 + 7 * 8;
    assert_eq!(body[twist_x..twist_x + 8], 3.0f64.to_le_bytes());
    let back = msg.decode(&body, true).unwrap();
    assert_eq!(back.path("twist.linear.x").and_then(Value::as_f64), Some(3.0));
    assert_eq!(back.path("acceleration.angular.z").and_then(Value::as_f64), Some(-1.0));
    assert_eq!(back.path("pose.orientation.w").and_then(Value::as_f64), Some(1.0));
    assert_eq!(back.path("header.frame_id").and_then(Value::as_str), Some("world"));
}
