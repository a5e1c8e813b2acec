//! The UAV demo's aircraft as ROS 2 entities (docs/ros2.md, "Entities"), through a real
//! rclpy (`tests/ros2/entities_rclpy.py`): its clients of the entity services and tf2_ros's
//! listener of `/tf`, during `tutti-demo uav` (its gateway with examples/uav/gateway.json5).
//! Every pose is checked against the UAV's own log (`uavN.csv`: the latitude, longitude,
//! altitude and heading it wrote at that step), converted here to the demo's East-North-Up
//! frame independently of the gateway's code. And `set_entity_state` on the entities of
//! tests/gateway/entities.json5: one tutti may write, one it may not.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use serde_json::Value;
use tutti_test_support::{namespace, workspace_bin};

use super::{result, Eng, Proc, Ros2, SECS};

/// The demo's ENU origin (examples/uav/gateway.json5).
const ORIGIN: [f64; 3] = [45.5, -73.6, 36.0];

/// A geodetic point in the ENU frame about [`ORIGIN`]: here through the rotation of the
/// origin's ECEF axes, written without the gateway's code (WGS-84).
fn enu(lat: f64, lon: f64, h: f64) -> [f64; 3] {
    let ecef = |lat: f64, lon: f64, h: f64| {
        let (a, f) = (6_378_137.0_f64, 1.0 / 298.257_223_563);
        let b = a * (1.0 - f);
        let (p, l) = (lat.to_radians(), lon.to_radians());
        // The radius of curvature in the prime vertical, from the two semi-axes.
        let n = a * a / (a * a * p.cos().powi(2) + b * b * p.sin().powi(2)).sqrt();
        [(n + h) * p.cos() * l.cos(), (n + h) * p.cos() * l.sin(), (b * b / (a * a) * n + h) * p.sin()]
    };
    let (o, x) = (ecef(ORIGIN[0], ORIGIN[1], ORIGIN[2]), ecef(lat, lon, h));
    let d = [x[0] - o[0], x[1] - o[1], x[2] - o[2]];
    let (p, l) = (ORIGIN[0].to_radians(), ORIGIN[1].to_radians());
    let east = [-l.sin(), l.cos(), 0.0];
    let north = [-p.sin() * l.cos(), -p.sin() * l.sin(), p.cos()];
    let up = [p.cos() * l.cos(), p.cos() * l.sin(), p.sin()];
    let dot = |u: [f64; 3]| u[0] * d[0] + u[1] * d[1] + u[2] * d[2];
    [dot(east), dot(north), dot(up)]
}

/// One row of a UAV's log: (latitude, longitude, altitude, heading, airspeed, connected).
type Row = [f64; 6];

/// `uavN.csv` of the demo's output `out`: simulated time (ns) -> row.
fn uav_log(out: &Path, n: u32) -> BTreeMap<i64, Row> {
    let path = out.join(format!("uav{n}.csv"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut rows = BTreeMap::new();
    for l in text.lines().skip(1) {
        let f: Vec<f64> = l.split(',').filter_map(|v| v.parse().ok()).collect();
        if let [t, lat, lon, alt, heading, speed, connected] = f[..] {
            rows.insert((t * 1e9).round() as i64, [lat, lon, alt, heading, speed, connected]);
        }
    }
    rows
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().map(|a| a.iter().filter_map(Value::as_f64).collect()).unwrap_or_default()
}

/// Checks a pose (position `p`, orientation `q`, velocity `v` if given) of `uav` against its
/// log at `stamp`: Some(()) when it was connected then and everything agrees; None when the
/// log has no connected row at that time. Panics on a disagreement.
fn check_pose(
    logs: &BTreeMap<u32, BTreeMap<i64, Row>>,
    uav: u32,
    stamp: f64,
    p: &[f64],
    q: &[f64],
    v: Option<&[f64]>,
) -> Option<()> {
    let row = logs[&uav].get(&((stamp * 1e9).round() as i64)).filter(|r| r[5] == 1.0)?;
    let want = enu(row[0], row[1], row[2]);
    assert!(
        (0..3).all(|k| (p[k] - want[k]).abs() < 1e-6),
        "uav{uav} at {stamp} s: position {p:?}, its log {want:?} ({row:?})"
    );
    // Heading clockwise from north is REP-103's yaw from east, counter-clockwise; level flight.
    let yaw = std::f64::consts::FRAC_PI_2 - row[3].to_radians();
    let want = [0.0, 0.0, (yaw / 2.0).sin(), (yaw / 2.0).cos()];
    let sign = if q[3] * want[3] + q[2] * want[2] < 0.0 { -1.0 } else { 1.0 };
    assert!(
        (0..4).all(|k| (sign * q[k] - want[k]).abs() < 1e-9),
        "uav{uav} at {stamp} s: orientation {q:?}, heading {} ({want:?})",
        row[3]
    );
    if let Some(v) = v {
        let h = row[3].to_radians();
        let want = [row[4] * h.sin(), row[4] * h.cos(), 0.0];
        assert!((0..3).all(|k| (v[k] - want[k]).abs() < 1e-6), "uav{uav} at {stamp} s: velocity {v:?}, {want:?}");
    }
    Some(())
}

#[test]
fn rclpy_reads_the_uav_entities_and_their_tf_during_the_demo_cyclone() {
    let dom = 217;
    let Some(ros) = Ros2::get(Eng::CYCLONE) else { return };
    let dir = tempfile::tempdir().expect("a temporary directory");
    let out = dir.path().join("uav");
    let client = ros.python(
        dom,
        "tests/ros2/entities_rclpy.py",
        &["--states", "12", "--every", "0.4", "--pose", "uav2", "--timeout", "120"],
    );
    let mut client = Proc::spawn("entities_rclpy", client, SECS(240));
    let mut demo = Command::new(workspace_bin("tutti-uav-demo", "tutti-demo"));
    demo.args(["uav", "--scenario", "short", "--duration", "30", "--speed", "1"])
        .arg("--out")
        .arg(&out)
        .args(["--ros-domain-id", &dom.to_string()])
        .env("TUTTI_NAMESPACE", namespace("ros2ent"))
        .current_dir(dir.path());
    let mut demo = Proc::spawn("tutti-demo uav", demo, SECS(240));
    let code = client.wait(SECS(200));
    assert_eq!(code, Some(0), "the rclpy client failed\n{}", client.dump());
    let status = demo.wait_status(SECS(200)).unwrap_or_else(|| panic!("the demo did not end\n{}", demo.dump()));
    assert!(status.success(), "the demo failed\n{}", demo.dump());

    let logs: BTreeMap<u32, _> = (1..=4).map(|n| (n, uav_log(&out, n))).collect();
    let calls: Vec<Value> = client.lines().iter().filter_map(|l| serde_json::from_str(l).ok()).collect();
    let of = |name: &'static str| calls.iter().filter(move |c| c["call"] == name);
    let names = |c: &Value| -> Vec<String> {
        c["entities"].as_array().unwrap().iter().map(|e| e.as_str().unwrap().to_string()).collect()
    };
    // The entity features beside the run's: tags, box bounds, categories, state and info
    // getting; not state setting (no aircraft can be moved).
    let features = of("get_simulator_features").next().expect("get_simulator_features");
    let features: Vec<u64> = features["features"].as_array().unwrap().iter().filter_map(Value::as_u64).collect();
    assert_eq!(&features[..5], [4, 6, 8, 10, 12], "{features:?}");
    assert!(!features.contains(&11) && features.contains(&20), "{features:?}");
    // The list, and its filters: by name, by category, by tag.
    let lists: Vec<(String, Vec<String>)> =
        of("get_entities").map(|c| (c["filter"].as_str().unwrap().to_string(), names(c))).collect();
    let uavs = |ns: &[u32]| ns.iter().map(|n| format!("uav{n}")).collect::<Vec<_>>();
    assert_eq!(
        lists,
        [
            (String::new(), uavs(&[1, 2, 3, 4])),
            ("uav[12]$".into(), uavs(&[1, 2])),
            ("robots".into(), uavs(&[1, 2, 3, 4])),
            ("human".into(), vec![]),
            ("tag leader".into(), uavs(&[1])),
        ]
    );
    let info = of("get_entity_info").next().expect("get_entity_info");
    assert_eq!(
        (info["category"].as_u64(), info["tags"].clone()),
        (Some(1), serde_json::json!(["uav", "leader"])),
        "{info}"
    );
    // Every state is the UAV's own at its step; those of one call are of one step.
    let (mut checked, mut one_step) = (0, 0);
    for c in of("get_entities_states") {
        assert_eq!(result(c).0, 1, "{c}");
        assert_eq!(names(c), uavs(&[1, 2, 3, 4]));
        let states = c["states"].as_array().unwrap();
        let mut stamps = Vec::new();
        for (n, s) in (1..=4).zip(states) {
            assert_eq!(s["frame"], "map");
            let stamp = s["stamp"].as_f64().unwrap();
            if check_pose(&logs, n, stamp, &floats(&s["p"]), &floats(&s["q"]), Some(&floats(&s["v"]))).is_some() {
                checked += 1;
                stamps.push(stamp);
            }
        }
        if stamps.len() == 4 {
            assert!(stamps.iter().all(|t| *t == stamps[0]), "one call, two steps: {c}");
            one_step += 1;
        }
    }
    assert!(
        checked >= 20 && one_step >= 3,
        "{checked} states and {one_step} whole calls checked against the logs\n{}",
        client.dump()
    );
    let state: Vec<&Value> = of("get_entity_state").collect();
    assert_eq!((result(state[0]).0, result(state[1]).0), (1, 2), "uav1, then NOT_FOUND: {state:?}");
    assert!(
        check_pose(
            &logs,
            1,
            state[0]["state"]["stamp"].as_f64().unwrap(),
            &floats(&state[0]["state"]["p"]),
            &floats(&state[0]["state"]["q"]),
            None
        )
        .is_some(),
        "{:?}",
        state[0]
    );
    // The UAVs' domains are synchronous: their items are the UAVs' to write.
    let set = of("set_entity_state").next().expect("set_entity_state");
    assert_eq!(result(set).0, 0, "RESULT_FEATURE_UNSUPPORTED: {set}");
    assert!(result(set).1.contains("synchronous"), "{set}");
    // tf2_ros's buffer holds each UAV's transform, at a step of its log.
    let mut transforms = 0;
    for t in of("tf") {
        let n: u32 = t["child"].as_str().unwrap().trim_start_matches("uav").parse().unwrap();
        assert!(t.get("error").is_none(), "{t}");
        let stamp = t["stamp"].as_f64().unwrap();
        if check_pose(&logs, n, stamp, &floats(&t["t"]), &floats(&t["q"]), None).is_some() {
            transforms += 1;
        }
    }
    assert!(
        transforms >= 3,
        "{transforms} of the 4 transforms are at a connected step of their UAV's log\n{}",
        client.dump()
    );
    // UAV 2's pose topic, as its log has it.
    let pose = of("pose").next().expect("the pose call");
    assert_eq!(pose["frame"], "map", "{pose}");
    let stamp = pose["stamp"].as_f64().unwrap_or_else(|| panic!("no pose heard: {pose}"));
    assert!(check_pose(&logs, 2, stamp, &floats(&pose["p"]), &floats(&pose["q"]), None).is_some(), "{pose}");
}

/// `set_entity_state` moves the cart, whose items tutti may write (an asynchronous domain's
/// SUBSCRIBE set): `get_entity_state` and the framework (its recording) read the new values.
/// The beacon, in the PUBLISH set only the framework writes, is refused with the reason.
#[test]
fn rclpy_moves_an_entity_tutti_may_write_and_is_refused_one_it_may_not_cyclone() {
    moves_an_entity_and_is_refused_one(Eng::CYCLONE, 218);
}

/// The same on the rustdds engine (rmw_cyclonedds's wire form of services).
#[test]
fn rclpy_moves_an_entity_tutti_may_write_and_is_refused_one_it_may_not_rustdds() {
    moves_an_entity_and_is_refused_one(Eng::RUSTDDS, 219);
}

/// The same over rmw_zenoh, on the Zenoh engine.
#[test]
fn rclpy_moves_an_entity_tutti_may_write_and_is_refused_one_it_may_not_zenoh() {
    moves_an_entity_and_is_refused_one(Eng::ZENOH, 64);
}

fn moves_an_entity_and_is_refused_one(e: Eng, dom: u16) {
    let Some(ros) = Ros2::get(e) else { return };
    let ns = namespace(&format!("ros2setent{dom}_"));
    let dir = tempfile::tempdir().expect("a temporary directory");
    let rec = dir.path().join("rec.csv");
    let config = tutti_test_support::repo_root().join("tests/gateway/entities.json5");
    let (config, rec_arg) = (config.display().to_string(), rec.display().to_string());
    let extra = [&config, "--record", &rec_arg, "--set", "arena/bx=4", "--set", "arena/by=5", "--set", "arena/bz=6"];
    let (mut host, _segments) = ros.host(e, "tests/gateway/entities.ddf", dom, &ns, &extra);
    let calls = |args: &[&str]| -> Vec<Value> {
        let cmd = ros.python(dom, "tests/ros2/set_entity_rclpy.py", args);
        super::run_quietly("rclpy set_entity_state", cmd, SECS(120))
            .iter()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect()
    };
    let moved = calls(&["cart", "1.5", "-2.25", "3", "0.5"]);
    assert_eq!(result(&moved[0]).0, 1, "{moved:?}");
    let (p, q) = (floats(&moved[1]["p"]), floats(&moved[1]["q"]));
    assert_eq!(p, [1.5, -2.25, 3.0], "{moved:?}");
    let want = [0.0, 0.0, 0.25f64.sin(), 0.25f64.cos()];
    assert!((0..4).all(|k| (q[k] - want[k]).abs() < 1e-12), "yaw 0.5: {q:?}");
    let refused = calls(&["beacon", "0", "0", "0", "0"]);
    assert_eq!(result(&refused[0]).0, 0, "RESULT_FEATURE_UNSUPPORTED: {refused:?}");
    assert!(result(&refused[0]).1.contains("PUBLISH set of domain 'arena'"), "{refused:?}");
    assert!(host.interrupt(SECS(30)).is_some(), "{}", host.dump());
    // The framework read the cart's new place.
    // One domain: the recording is the file named (several: one file per domain).
    let text = std::fs::read_to_string(&rec).expect("the recording");
    let head: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |n: &str| head.iter().position(|h| *h == n).unwrap_or_else(|| panic!("no {n} in {head:?}"));
    let (x, y, z, yaw) = (col("subscribe.x"), col("subscribe.y"), col("subscribe.z"), col("subscribe.yaw"));
    let read = text.lines().skip(1).any(|l| {
        let f: Vec<f64> = l.split(',').map(|v| v.parse().unwrap_or(f64::NAN)).collect();
        [f[x], f[y], f[z]] == [1.5, -2.25, 3.0] && (f[yaw] - 0.5).abs() < 1e-12
    });
    assert!(read, "no step of the recording has the cart at (1.5, -2.25, 3), yaw 0.5\n{text}");
}
