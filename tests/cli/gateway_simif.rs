//! ROS 2 `simulation_interfaces` services on the gateway (docs/ros2.md), driven by the Cyclone
//! peer (`dds_peer.py service`) in rmw_cyclonedds's request and reply layout, each request
//! checked byte for byte against that layout: against `tutti host --gateway` with a
//! synchronous domain (every service, the exact steps, the refusals and repeated
//! transitions) and with asynchronous domains only (stepping refused, with the reason); the
//! action `simulate_steps` (`dds_peer.py action`: feedback after each step, cancel, the
//! refusals); a passive gateway offers none. Each test has its own namespace and DDS domain
//! (40-44).

use crate::gateway;

use std::time::Duration;

use gateway::*;
use serde_json::Value;
use tutti_test_support::{namespace, RemoveSegments};

/// `tutti ctl state --json` in namespace `ns`.
fn ctl_state(ns: &str) -> Value {
    let mut cmd = tutti_test_support::tutti_command();
    cmd.args(["ctl", "state", "--json"]).env("TUTTI_NAMESPACE", ns);
    let (status, out, err) = tutti_test_support::run_with_timeout(cmd, Duration::from_secs(60));
    assert!(status.success(), "tutti ctl state: {err}");
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("tutti ctl state: {e}: {out}"))
}

/// Makes `calls` (JSON: `[["NAME", ARG], ...]`) with the Cyclone client; each call's response.
fn calls(py: &std::path::Path, dom: u16, calls: &str) -> Vec<Value> {
    let mut p = peer(py, "simulation client", dom, "service", &["--calls", calls, "--timeout", "60"]);
    assert_eq!(p.wait(SECS(100)), Some(0), "the client failed\n{}", p.dump());
    json_lines(&p, "call")
}

/// A response's (result code, error message).
fn result(v: &Value) -> (u64, String) {
    let r = &v["result"];
    (r["result"].as_u64().unwrap_or(999), r["error_message"].as_str().unwrap_or("").to_string())
}

const STATE_STOPPED: u64 = 0;
const STATE_PLAYING: u64 = 1;
const STATE_PAUSED: u64 = 2;
const OK: u64 = 1;
const FEATURE_UNSUPPORTED: u64 = 0;
const ALREADY_IN_TARGET_STATE: u64 = 101;
const INCORRECT_TRANSITION: u64 = 103;

#[test]
fn the_simulation_services_drive_the_run_and_refuse_with_the_standard_codes() {
    let Some(py) = python() else { return };
    let (dom, ns) = (40, namespace("simif40_"));
    let (mut host, _segments) = host_with_gateway(Eng::CYCLONE, DDF, dom, &ns, &[]);

    let r = calls(&py, dom, r#"[["get_simulator_features"], ["get_simulation_state"], ["set_simulation_state", 2]]"#);
    assert_eq!(r.len(), 3, "{r:?}");
    let features: Vec<u64> =
        r[0]["features"]["features"].as_array().expect("features").iter().filter_map(Value::as_u64).collect();
    for f in [20, 21, 24, 25, 26, 31, 32] {
        assert!(features.contains(&f), "feature {f} missing: {features:?}");
    }
    assert!(!features.contains(&22) && !features.contains(&23), "tutti resets no state nor spawns: {features:?}");
    assert_eq!(r[1]["state"]["state"].as_u64(), Some(STATE_PLAYING), "{:?}", r[1]);
    assert_eq!(result(&r[1]).0, OK);
    assert_eq!(result(&r[2]).0, OK, "{:?}", r[2]);
    let paused = ctl_state(&ns);
    assert_eq!(paused["state"], "paused");
    let at = paused["step"].as_u64().expect("a step");

    let r = calls(&py, dom, r#"[["step_simulation", 3], ["get_simulation_state"], ["set_simulation_state", 2]]"#);
    assert_eq!(result(&r[0]).0, OK, "{:?}", r[0]);
    let after = ctl_state(&ns);
    assert_eq!((after["state"].as_str(), after["step"].as_u64()), (Some("paused"), Some(at + 3)), "exactly 3 steps");
    assert_eq!(r[1]["state"]["state"].as_u64(), Some(STATE_PAUSED));
    assert_eq!(result(&r[2]), (ALREADY_IN_TARGET_STATE, "already paused".to_string()));

    let r = calls(
        &py,
        dom,
        r#"[["set_simulation_state", 1], ["set_simulation_state", 1], ["step_simulation", 2],
            ["reset_simulation", 1], ["reset_simulation", 0], ["reset_simulation", 2], ["reset_simulation", 255],
            ["set_simulation_state", 0], ["get_simulation_state"], ["set_simulation_state", 2],
            ["set_simulation_state", 4], ["set_simulation_state", 1], ["get_simulation_state"]]"#,
    );
    assert_eq!(r.len(), 13, "{r:?}");
    assert_eq!(result(&r[0]).0, OK);
    assert_eq!(result(&r[1]), (ALREADY_IN_TARGET_STATE, "already playing".to_string()));
    let (code, why) = result(&r[2]);
    assert!(code == 4 && why.contains("playing") && why.contains("paused"), "stepping a playing run: {code} {why}");
    assert_eq!(result(&r[3]).0, OK, "SCOPE_TIME: {:?}", r[3]);
    assert_eq!(result(&r[4]).0, OK, "SCOPE_DEFAULT: {:?}", r[4]);
    for unsupported in &r[5..7] {
        let (code, why) = result(unsupported);
        assert!(code == FEATURE_UNSUPPORTED && why.contains("only SCOPE_DEFAULT and SCOPE_TIME"), "{unsupported:?}");
    }
    assert_eq!(result(&r[7]).0, OK, "STOPPED: {:?}", r[7]);
    assert_eq!(r[8]["state"]["state"].as_u64(), Some(STATE_STOPPED));
    let (code, why) = result(&r[9]);
    assert!(code == INCORRECT_TRANSITION && why.contains("stopped"), "pausing a stopped run: {code} {why}");
    assert_eq!(result(&r[10]).0, FEATURE_UNSUPPORTED, "NO_WORLD: {:?}", r[10]);
    assert_eq!(result(&r[11]).0, OK);
    assert_eq!(r[12]["state"]["state"].as_u64(), Some(STATE_PLAYING));
    assert_eq!(ctl_state(&ns)["state"], "playing");

    // QUITTING ends the run.
    let r = calls(&py, dom, r#"[["set_simulation_state", 3]]"#);
    assert_eq!(result(&r[0]).0, OK, "{:?}", r[0]);
    assert!(host.wait(SECS(60)).is_some(), "the run did not end\n{}", host.dump());
}

#[test]
fn stepping_a_run_of_asynchronous_domains_is_refused_with_the_reason() {
    let Some(py) = python() else { return };
    let (dom, ns) = (41, namespace("simif41_"));
    let (_host, _segments) = host_with_gateway(Eng::CYCLONE, "tests/gateway/async-only.ddf", dom, &ns, &[]);
    let r = calls(
        &py,
        dom,
        r#"[["get_simulator_features"], ["set_simulation_state", 2], ["step_simulation", 1], ["step_simulation", 5],
            ["set_simulation_state", 1]]"#,
    );
    assert_eq!(r.len(), 5, "{r:?}");
    let features: Vec<u64> =
        r[0]["features"]["features"].as_array().expect("features").iter().filter_map(Value::as_u64).collect();
    assert!(features.contains(&26) && !features.contains(&31) && !features.contains(&32), "{features:?}");
    assert_eq!(result(&r[1]).0, OK);
    for refused in &r[2..4] {
        let (code, why) = result(refused);
        assert_eq!(code, FEATURE_UNSUPPORTED, "{refused:?}");
        assert!(why.contains("asynchronous (simif_async)") && why.contains("no step to count"), "{why}");
    }
    assert_eq!(result(&r[4]).0, OK);
    assert_eq!(ctl_state(&ns)["state"], "playing");
}

#[test]
fn a_passive_gateway_offers_no_simulation_services() {
    let Some(py) = python() else { return };
    let (dom, ns) = (42, namespace("simif42_"));
    let _segments = RemoveSegments(ns.clone());
    let _host = Host::start(&ns, "gw_sync", Duration::from_millis(10), |_| vec![0; 8]);
    let _gw = gateway(DDF, dom, &ns, &["--passive"]);
    let mut p =
        peer(&py, "simulation client", dom, "service", &["--calls", r#"[["get_simulation_state"]]"#, "--timeout", "5"]);
    assert_eq!(p.wait(SECS(60)), Some(3), "a passive gateway answered\n{}", p.dump());
    assert!(p.stdout().contains("no service"), "{}", p.dump());
}

/// The action client (`dds_peer.py action`) for `steps` steps, canceling after `cancel_after`
/// feedback samples (0: never): its output lines.
fn simulate_steps(py: &std::path::Path, dom: u16, steps: u64, cancel_after: u64) -> Vec<Value> {
    let (steps, cancel) = (steps.to_string(), cancel_after.to_string());
    let args = ["--steps", steps.as_str(), "--cancel-after", cancel.as_str(), "--timeout", "60"];
    let mut p = peer(py, "action client", dom, "action", &args);
    assert_eq!(p.wait(SECS(100)), Some(0), "the action client failed\n{}", p.dump());
    p.lines().iter().filter_map(|l| serde_json::from_str::<Value>(l).ok()).collect()
}

fn feedback(lines: &[Value]) -> Vec<(u64, u64)> {
    lines
        .iter()
        .filter_map(|l| l["feedback"].as_array().map(|f| (f[0].as_u64().unwrap_or(0), f[1].as_u64().unwrap_or(0))))
        .collect()
}

fn line<'a>(lines: &'a [Value], key: &str) -> &'a Value {
    lines.iter().find(|l| l.get(key).is_some()).unwrap_or_else(|| panic!("no {key} in {lines:?}"))
}

const SUCCEEDED: u64 = 4;
const CANCELED: u64 = 5;
const ABORTED: u64 = 6;

#[test]
fn the_simulate_steps_action_gives_feedback_after_each_step_and_cancels() {
    let Some(py) = python() else { return };
    let (dom, ns) = (43, namespace("simif43_"));
    let (_host, _segments) = host_with_gateway(Eng::CYCLONE, DDF, dom, &ns, &[]);

    // Playing: the goal is accepted and aborted with the call's result.
    let lines = simulate_steps(&py, dom, 3, 0);
    assert_eq!(line(&lines, "accepted")["accepted"], true);
    let end = line(&lines, "status");
    assert_eq!((end["status"].as_u64(), end["result"]["result"].as_u64()), (Some(ABORTED), Some(4)), "{end}");
    assert!(end["result"]["error_message"].as_str().unwrap_or("").contains("playing"), "{end}");
    assert!(feedback(&lines).is_empty());

    let r = calls(&py, dom, r#"[["get_simulator_features"], ["set_simulation_state", 2]]"#);
    let features = &r[0]["features"]["features"];
    assert!(features.as_array().is_some_and(|f| f.contains(&Value::from(33))), "STEP_SIMULATION_ACTION: {features}");
    let at = ctl_state(&ns)["step"].as_u64().expect("a step");

    let lines = simulate_steps(&py, dom, 4, 0);
    assert_eq!(feedback(&lines), vec![(1, 3), (2, 2), (3, 1), (4, 0)], "feedback after each step");
    let end = line(&lines, "status");
    assert_eq!((end["status"].as_u64(), end["result"]["result"].as_u64()), (Some(SUCCEEDED), Some(OK)), "{end}");
    assert_eq!(end["last_status"].as_u64(), Some(SUCCEEDED), "the status topic: {end}");
    assert_eq!(ctl_state(&ns)["step"].as_u64(), Some(at + 4), "exactly 4 steps");

    // Canceled after the second feedback: the goal ends between two steps, well before its 100000.
    let at = at + 4;
    let lines = simulate_steps(&py, dom, 100_000, 2);
    let c = line(&lines, "cancel");
    assert_eq!((c["cancel"].as_u64(), c["canceling"].as_u64()), (Some(0), Some(1)), "ERROR_NONE, one goal: {c}");
    let end = line(&lines, "status");
    assert_eq!(end["status"].as_u64(), Some(CANCELED), "{end}");
    assert_eq!(end["last_status"].as_u64(), Some(CANCELED), "{end}");
    let made = ctl_state(&ns)["step"].as_u64().expect("a step") - at;
    let fb = feedback(&lines);
    assert!((2..100_000).contains(&made), "{made} steps");
    assert_eq!(fb.last().map(|f| f.0), Some(made), "the last feedback is the last step made: {fb:?}");
    assert!(fb.iter().enumerate().all(|(i, f)| *f == (i as u64 + 1, 100_000 - i as u64 - 1)), "{fb:?}");
    let why = end["result"]["error_message"].as_str().unwrap_or("");
    assert_eq!(why, format!("canceled after {made} of 100000 steps"));
}

#[test]
fn the_action_refuses_to_step_a_run_of_asynchronous_domains() {
    let Some(py) = python() else { return };
    let (dom, ns) = (44, namespace("simif44_"));
    let (_host, _segments) = host_with_gateway(Eng::CYCLONE, "tests/gateway/async-only.ddf", dom, &ns, &[]);
    let r = calls(&py, dom, r#"[["set_simulation_state", 2]]"#);
    assert_eq!(result(&r[0]).0, OK);
    let lines = simulate_steps(&py, dom, 2, 0);
    let end = line(&lines, "status");
    assert_eq!((end["status"].as_u64(), end["result"]["result"].as_u64()), (Some(ABORTED), Some(FEATURE_UNSUPPORTED)));
    assert!(end["result"]["error_message"].as_str().unwrap_or("").contains("asynchronous (simif_async)"), "{end}");
    assert!(feedback(&lines).is_empty());
}
