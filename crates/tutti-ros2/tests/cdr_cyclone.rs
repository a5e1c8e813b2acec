//! The CDR codec against Cyclone DDS's Python binding: for every message the registry holds
//! (the implicit types of services and actions included), two sample values (nested messages,
//! sequences of 0 to 3 elements, strings, negative numbers, arrays: `common::sample`) are
//! encoded here; tests/ros2/cdr_check.py builds the same types from rosidl's parse of the same
//! files, encodes the same values with Cyclone (XCDR1, as ROS 2 sends it) and must find the
//! same bytes, and decodes these bytes back to the same values. Here, each body must decode to
//! its value.
//!
//! The Python needs `cyclonedds` (launch-scripts/test.sh installs it into .venv): without it
//! the test is skipped, and fails under CI=true.

mod common;

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use tutti_ros2::{registry, CdrError};

#[test]
fn every_message_encodes_as_cyclone_encodes_it() {
    let mut cases = Vec::new();
    let mut skipped = Vec::new();
    for msg in registry().messages() {
        for seed in [0, 1] {
            let value = common::sample(msg, seed);
            let body = match msg.encode(&value) {
                Ok(body) => body,
                Err(e @ CdrError::Unsupported { .. }) => {
                    skipped.push(e.to_string());
                    continue;
                }
                Err(e) => panic!("{}: {e}", msg.name()),
            };
            assert_eq!(msg.decode(&body, true).as_ref(), Ok(&value), "{}", msg.name());
            let hex: String = body.iter().map(|b| format!("{b:02x}")).collect();
            cases.push(serde_json::json!({ "type": msg.name().to_string(), "value": value, "cdr": hex }));
        }
    }
    // No package tutti embeds has a wide string, the one type without a codec.
    assert_eq!(skipped, Vec::<String>::new());
    assert!(cases.len() > 400, "{}", cases.len());

    let Some(py) = tutti_test_support::python(&["cyclonedds"]) else { return };
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = dir.path().join("cases.json");
    std::fs::write(&file, serde_json::to_string(&cases).expect("JSON")).expect("write the cases");
    let mut cmd = Command::new(py);
    cmd.arg(tutti_test_support::repo_root().join("tests/ros2/cdr_check.py"))
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("interfaces"))
        .arg(&file);
    let (status, out, err) = tutti_test_support::run_with_timeout(cmd, Duration::from_secs(300));
    assert!(status.success(), "Cyclone disagrees:\n{out}\n{err}");
    assert!(out.starts_with(&format!("checked {} cases", cases.len())), "{out}");
}
