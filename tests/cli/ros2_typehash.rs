//! ROS 2 type hashes (docs/gateway.md, "Type hashes"), checked against ROS 2's own code:
//! rosidl's type-description generator (tests/ros2/rosidl/, run by tests/ros2/typehash.py)
//! hashes the package `tutti idl` writes, and must find the hashes tutti computes and names in
//! the generated files; the same generator (run by tests/ros2/interface_hashes.py) hashes the
//! real interface files of ROS 2 Jazzy's `simulation_interfaces`, `action_msgs`, … (from
//! tests/ros2/jazzy/jazzy-src.tar.xz), and must find tutti's hashes of every message of the
//! simulation services and action. Then, on both engines, every endpoint a gateway announces
//! (typed sets, per-item topics, `/clock`, `ros_discovery_info`, ros2-client's
//! `/parameter_events`, the simulation services' request and reply topics and the action's
//! services and topics) must carry `typehash=RIHS01_…;` in its USER_DATA with that same hash,
//! as a Cyclone DDS peer (as rmw_cyclonedds) reads it in discovery. DDS domains 78-81,
//! namespaces `typehash*`.
//!
//! The Python needs `lark` (rosidl's parser; launch-scripts/test.sh installs it into .venv)
//! and `cyclonedds`: without them the tests are skipped, and fail under CI=true.

use crate::gateway;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use gateway::*;
use tutti_test_support::Proc;

/// Every scalar type, arrays, a bus inside a bus, and an absent (empty) set.
const ALL_TYPES_DDF: &str = r#"<?xml version="1.0"?>
<orchestra>
  <domain name="all_types">
    <synchronous>yes</synchronous>
    <multiplePublishAllowed>no</multiplePublishAllowed>
    <states>no</states>
    <set name="PUBLISH">
      <item name="flag"><type>boolean</type><default>yes</default></item>
      <item name="flags"><type>boolean</type><length>4</length><default>no</default></item>
      <item name="i8"><type>int8</type><default>-128</default></item>
      <item name="i16"><type>int16</type><length>2</length></item>
      <item name="i32"><type>int32</type><default>-7</default></item>
      <item name="i64"><type>int64</type></item>
      <item name="u8"><type>unsigned int8</type><length>16</length><default>255</default></item>
      <item name="u16"><type>uint16</type></item>
      <item name="u32"><type>uint32</type></item>
      <item name="u64"><type>unsigned int64</type></item>
      <item name="gain"><type>float32</type><length>3</length><default>0.1</default></item>
      <item name="voltageABC"><type>float64</type><length>3</length></item>
      <item name="gps">
        <type>bus</type>
        <item name="fix">
          <type>bus</type>
          <item name="Latitude"><type>double</type></item>
          <item name="Longitude"><type>double</type></item>
        </item>
        <item name="satellites"><type>uchar</type></item>
      </item>
    </set>
  </domain>
</orchestra>
"#;

/// The hashes ROS 2 Jazzy gives the stock types the gateway announces (rosidl writes them into
/// `share/PKG/msg/TYPE.json` of an installed ROS 2; fixed by ROS 2), by DDS type name.
const STOCK: &[(&str, &str)] = &[
    ("std_msgs::msg::dds_::Float64_", "RIHS01_705ba9c3d1a09df43737eb67095534de36fd426c0587779bda2bc51fe790182a"),
    ("std_msgs::msg::dds_::Bool_", "RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9"),
    (
        "std_msgs::msg::dds_::Float64MultiArray_",
        "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f",
    ),
    ("rosgraph_msgs::msg::dds_::Clock_", "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564"),
    (
        "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_",
        "RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e",
    ),
    (
        "rcl_interfaces::msg::dds_::ParameterEvent_",
        "RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204",
    ),
];

/// The interface packages of the simulation services and action, in
/// tests/ros2/jazzy/jazzy-src.tar.xz, each after those it depends on.
const INTERFACE_PACKAGES: &[&str] = &[
    "ros2/rcl_interfaces/builtin_interfaces",
    "ros2/unique_identifier_msgs",
    "ros2/rcl_interfaces/service_msgs",
    "ros2/rcl_interfaces/action_msgs",
    "ros2/common_interfaces/std_msgs",
    "ros2/common_interfaces/geometry_msgs",
    "ros-simulation/simulation_interfaces",
];

/// The services the gateway offers (docs/ros2.md), the action's three included.
const SERVICES: &[&str] = &[
    "get_simulator_features",
    "get_simulation_state",
    "set_simulation_state",
    "step_simulation",
    "reset_simulation",
    "simulate_steps/_action/send_goal",
    "simulate_steps/_action/get_result",
    "simulate_steps/_action/cancel_goal",
];

/// The Python with rosidl's parser's one dependency.
fn rosidl_python() -> Option<PathBuf> {
    tutti_test_support::python(&["lark"])
}

/// `tutti idl DDF --out DIR`; returns the package's name.
fn tutti_idl(ddf: &Path, out: &Path) -> String {
    let mut cmd = tutti_test_support::tutti_command();
    cmd.arg("idl").arg(ddf).arg("--out").arg(out);
    let mut p = Proc::spawn("tutti idl", cmd, SECS(60));
    assert_eq!(p.wait(SECS(60)), Some(0), "{}", p.dump());
    tutti_core::mapping::package_name(ddf)
}

/// Runs a rosidl hashing script (`cmd`, named `what` in messages; it prints `NAME HASH`
/// lines) to its end: its hashes by name, and its output for failure messages.
fn script_hashes(what: &str, cmd: Command) -> (BTreeMap<String, String>, String) {
    let mut p = Proc::spawn(what, cmd, SECS(120));
    assert_eq!(p.wait(SECS(120)), Some(0), "{what} failed:\n{}", p.dump());
    let hashes = p
        .stdout()
        .lines()
        .filter_map(|l| l.split_once(' '))
        .map(|(name, hash)| (name.to_string(), hash.to_string()))
        .collect();
    (hashes, p.dump())
}

/// rosidl's hash of every type of the package `tutti idl` writes for `ddf` (tmp: where it
/// writes it), by ROS 2 name (`PKG/msg/TYPE`).
fn rosidl_hashes(py: &Path, ddf: &Path, tmp: &Path) -> BTreeMap<String, String> {
    let pkg = tutti_idl(ddf, tmp);
    let mut cmd = Command::new(py);
    cmd.arg(tutti_test_support::repo_root().join("tests/ros2/typehash.py")).arg(tmp).arg(&pkg);
    let (hashes, out) = script_hashes("rosidl type hashes (the .msg and .idl files must agree)", cmd);
    assert!(!hashes.is_empty(), "no hash from rosidl:\n{out}");
    hashes
}

/// rosidl's hash of every type of [`INTERFACE_PACKAGES`] (the implicit types of each
/// service and action included), by ROS 2 name (`PKG/srv/NAME_Request`).
fn rosidl_interface_hashes(py: &Path) -> BTreeMap<String, String> {
    let root = tutti_test_support::repo_root();
    let mut cmd = Command::new(py);
    cmd.arg(root.join("tests/ros2/interface_hashes.py"))
        .arg(root.join("tests/ros2/jazzy/jazzy-src.tar.xz"))
        .args(INTERFACE_PACKAGES);
    let (hashes, out) = script_hashes("rosidl interface hashes", cmd);
    assert!(hashes.contains_key("simulation_interfaces/srv/StepSimulation_Request"), "{out}");
    hashes
}

#[test]
fn rosidl_hashes_the_simulation_interfaces_as_tutti_does() {
    let Some(py) = rosidl_python() else { return };
    let theirs = rosidl_interface_hashes(&py);
    // Every message of the services and the action the gateway offers, and every type of the
    // packages they come from (tutti-ros2's own tests compare every type it holds).
    let registry = tutti_ros2::registry();
    let described: Vec<&str> = registry
        .type_names()
        .into_iter()
        .filter(|n| n.starts_with("simulation_interfaces/") || n.starts_with("action_msgs/"))
        .collect();
    assert!(described.len() > 20, "{described:?}");
    for name in described {
        let ours = registry.description(name).unwrap_or_else(|| panic!("{name} is not described"));
        assert_eq!(Some(ours.hash().to_string()).as_ref(), theirs.get(name), "{name}: {}", ours.canonical_json());
    }
    for (name, hash) in &theirs {
        assert_eq!(registry.hash(name).map(|h| h.to_string()).as_ref(), Some(hash), "{name}");
    }
}

#[test]
fn rosidl_hashes_every_generated_message_as_tutti_does() {
    let Some(py) = rosidl_python() else { return };
    let dir = tempfile::tempdir().expect("temporary directory");
    let all_types = dir.path().join("all-types.ddf");
    std::fs::write(&all_types, ALL_TYPES_DDF).expect("write the DDF");
    let shipped = tutti_test_support::repo_root().join("ddf/multiuav.ddf");
    for ddf in [all_types, shipped] {
        let out = tempfile::tempdir().expect("temporary directory");
        let theirs = rosidl_hashes(&py, &ddf, out.path());
        let model = tutti_core::ddf::load(&ddf).unwrap_or_else(|e| panic!("{}: {e}", ddf.display()));
        let pkg = tutti_core::mapping::package_name(&ddf);
        let ours: BTreeMap<String, String> = tutti_ros2::idl::type_hashes(&model, &pkg)
            .expect("every type is described")
            .into_iter()
            .map(|(name, h)| (name, h.to_string()))
            .collect();
        assert_eq!(ours, theirs, "{}", ddf.display());
        // Each generated .msg names the hash of its type.
        for (name, hash) in &theirs {
            let msg = out.path().join(format!("{name}.msg"));
            let text = std::fs::read_to_string(&msg).unwrap_or_else(|e| panic!("{}: {e}", msg.display()));
            assert!(text.contains(&format!("\n# ROS 2 type hash {hash}\n")), "{}:\n{text}", msg.display());
        }
    }
}

/// Every endpoint `gw` announces, as the Cyclone peer reads it in discovery once at least
/// `count` are known: (kind, topic, type, USER_DATA).
fn endpoints(py: &Path, gw: &Proc, dom: u16, count: usize) -> Vec<(String, String, String, Option<String>)> {
    let mut p = peer(py, "endpoints", dom, "endpoints", &["--count", &count.to_string(), "--timeout", "45"]);
    assert_eq!(p.wait(SECS(60)), Some(0), "{}\n{}", p.dump(), gw.dump());
    let text = |v: &serde_json::Value, k: &str| v[k].as_str().map(str::to_string);
    json_lines(&p, "topic")
        .iter()
        .map(|v| {
            let s = |k| text(v, k).unwrap_or_default();
            (s("kind"), s("topic"), s("type_name"), text(v, "user_data"))
        })
        .collect()
}

/// Asserts that each of `eps` announces `typehash=HASH;` with the hash of its type: a set's
/// or a service's message's as rosidl computes it (`rosidl`, by ROS 2 name), a stock type's
/// as ROS 2 gives it; and that every one of `expected` (kind, topic) is among them.
fn assert_hashes(
    eps: &[(String, String, String, Option<String>)],
    rosidl: &BTreeMap<String, String>,
    expected: &[(&str, String)],
    gw: &Proc,
) {
    let stock: BTreeMap<&str, &str> = STOCK.iter().copied().collect();
    for (kind, topic, ty, user_data) in eps {
        let want = match tutti_ros2::typehash::ros2_type_name(ty).and_then(|n| rosidl.get(&n)) {
            Some(h) => h.as_str(),
            None => stock.get(ty.as_str()).copied().unwrap_or_else(|| panic!("{kind} on {topic}: unknown type {ty}")),
        };
        assert_eq!(
            user_data.as_deref(),
            Some(format!("typehash={want};").as_str()),
            "the {kind} on {topic} ({ty})\n{}",
            gw.dump()
        );
    }
    for (kind, topic) in expected {
        assert!(
            eps.iter().any(|(k, t, _, _)| k == kind && t == topic),
            "no {kind} on {topic} among {eps:?}\n{}",
            gw.dump()
        );
    }
}

/// The endpoints of the simulation services and action that a gateway offers on either
/// engine: each service's request reader and reply writer, the action's feedback and status
/// writers.
fn service_endpoints() -> Vec<(&'static str, String)> {
    let mut eps: Vec<(&str, String)> = SERVICES
        .iter()
        .flat_map(|s| [("reader", format!("rq/{s}Request")), ("writer", format!("rr/{s}Reply"))])
        .collect();
    eps.push(("writer", "rt/simulate_steps/_action/feedback".to_string()));
    eps.push(("writer", "rt/simulate_steps/_action/status".to_string()));
    eps
}

fn every_endpoint_of_the_gateway_announces_its_type_hash(e: Eng) {
    let Some(py) = python() else { return };
    let Some(rosidl) = rosidl_python() else { return };
    let out = tempfile::tempdir().expect("temporary directory");
    let mut hashes = rosidl_hashes(&rosidl, &tutti_test_support::repo_root().join(DDF), out.path());
    hashes.extend(rosidl_interface_hashes(&rosidl));
    let dom = 78 + if e.name == "rustdds" { 2 } else { 0 };
    let mut discovery = vec![("writer", "ros_discovery_info".to_string()), ("writer", "rt/clock".to_string())];
    if e.name == "rustdds" {
        // ros2-client's node announces its parameter events.
        discovery.push(("writer", "rt/parameter_events".to_string()));
    }

    // Typed: a writer per PUBLISH set, a reader per SUBSCRIBE set.
    let gw = e.gateway(DDF, dom, &e.ns("typehash"), &["--all-domains"]);
    let mut expected = discovery.clone();
    expected.extend(service_endpoints());
    for d in ["gw_async", "gw_sync", "gw_states"] {
        expected.push(("writer", format!("rt/{d}/publish")));
        expected.push(("reader", format!("rt/{d}/subscribe")));
    }
    let eps = endpoints(&py, &gw, dom, expected.len());
    assert_hashes(&eps, &hashes, &expected, &gw);
    drop(gw);

    // Per item: std_msgs Float64, Bool and Float64MultiArray.
    let gw = e.gateway(DDF, dom + 1, &e.ns("typehashi"), &["--all-domains", "--ros2-types", "per-item"]);
    let mut expected = discovery;
    expected.extend(service_endpoints());
    expected.extend(
        [
            ("writer", "rt/gw_async/publish/x"),
            ("writer", "rt/gw_async/publish/flag"),
            ("writer", "rt/gw_async/publish/v"),
            ("reader", "rt/gw_async/subscribe/y"),
            ("reader", "rt/gw_async/subscribe/n"),
            ("writer", "rt/gw_sync/publish/x"),
            ("reader", "rt/gw_states/subscribe/y"),
        ]
        .map(|(k, t)| (k, t.to_string())),
    );
    let eps = endpoints(&py, &gw, dom + 1, expected.len());
    assert_hashes(&eps, &hashes, &expected, &gw);
}

per_engine!(every_endpoint_of_the_gateway_announces_its_type_hash);
