//! The gateway against Cyclone DDS (Python), the stand-in for an rclpy node: typed and
//! per-item samples both ways, the QoS on the wire, the ROS 2 node, bad input, and a DDS
//! writer in lock-step. Each test has its own DDS domain and namespace.

use crate::gateway;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use gateway::*;
use tutti_core::ddf::Role;
use tutti_test_support::{lazy, wait_until};

/// A component commits SUBSCRIBE values through shared memory (repeatedly, until stopped).
fn keep_committing(ns: &str, y: f64, n: i32) -> (Arc<AtomicBool>, thread::JoinHandle<()>) {
    let stop = Arc::new(AtomicBool::new(false));
    let (s, ns) = (stop.clone(), ns.to_string());
    let t = thread::spawn(move || {
        let mut p = connect(&ns, "gw_async");
        p.stage("y", &y.to_ne_bytes()).unwrap();
        p.stage("n", &n.to_ne_bytes()).unwrap();
        p.commit().unwrap();
        while !s.load(Ordering::Acquire) {
            p.stage("y", &y.to_ne_bytes()).unwrap();
            p.commit().unwrap();
            thread::sleep(Duration::from_millis(50));
        }
    });
    (stop, t)
}

fn async_publish(k: u64) -> Vec<u8> {
    let mut b = vec![0u8; 40];
    b[0..8].copy_from_slice(&4.5f64.to_ne_bytes());
    b[8] = 1;
    for i in 0..3 {
        b[16 + 8 * i..24 + 8 * i].copy_from_slice(&(k as f64 + i as f64).to_ne_bytes());
    }
    b
}

fn shared_memory_values_reach_a_cyclone_reader_as_typed_samples(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(101), e.ns("gwtest101"));
    let ns = ns.as_str();
    let _host = Host::start(ns, "gw_async", Duration::from_millis(10), async_publish);
    let gw = e.gateway(DDF, dom, ns, &[]);
    let (stop, t) = keep_committing(ns, 2.5, 7);
    let mut sub = peer(
        &py,
        "sub subscribe",
        dom,
        "sub",
        &["--topic", "rt/gw_async/subscribe", "--type", "gw_msgs::msg::dds_::GwAsyncSubscribe_", "--fields", ASYNC_SUB],
    );
    let mut pubs = peer(
        &py,
        "sub publish",
        dom,
        "sub",
        &[
            "--topic",
            "rt/gw_async/publish",
            "--type",
            "gw_msgs::msg::dds_::GwAsyncPublish_",
            "--fields",
            ASYNC_PUB,
            "--count",
            "3",
        ],
    );
    let rc = sub.wait(SECS(75));
    let rc2 = pubs.wait(SECS(75));
    stop.store(true, Ordering::Release);
    t.join().unwrap();
    assert_eq!(rc, Some(0), "{}\n{}", sub.dump(), gw.dump());
    let got = json_lines(&sub, "y");
    assert_eq!(got[0]["y"], 2.5, "{}", sub.dump());
    assert_eq!(got[0]["n"], 7);
    assert_eq!(rc2, Some(0), "{}\n{}", pubs.dump(), gw.dump());
    let got = json_lines(&pubs, "x");
    let s = &got[got.len() - 1];
    assert_eq!(s["x"], 4.5);
    assert_eq!(s["flag"], true);
    let k = s["step"].as_u64().unwrap();
    assert!(k > 0);
    assert_eq!(
        s["v"],
        serde_json::json!([k as f64, k as f64 + 1.0, k as f64 + 2.0]),
        "step and values from the same step"
    );
    // Its log went to a pipe, not a terminal: plain text, no colour codes.
    assert!(!gw.dump().contains('\u{1b}'), "ANSI escapes in a piped log:\n{}", gw.dump());
}

fn per_item_mode_uses_stock_types_both_ways(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(102), e.ns("gwtest102"));
    let ns = ns.as_str();
    let host = Host::start(ns, "gw_async", Duration::from_millis(10), async_publish);
    let gw = e.gateway(DDF, dom, ns, &["--ros2-types", "per-item"]);
    // A shared-memory writer's value reaches DDS; it then leaves, so that a DDS writer may
    // own the (exclusive) SUBSCRIBE set.
    let (stop, t) = keep_committing(ns, 6.25, 0);
    let mut y = peer(
        &py,
        "sub y",
        dom,
        "sub",
        &[
            "--topic",
            "rt/gw_async/subscribe/y",
            "--type",
            "std_msgs::msg::dds_::Float64_",
            "--fields",
            r#"[["data","float64"]]"#,
        ],
    );
    let rc = y.wait(SECS(75));
    stop.store(true, Ordering::Release);
    t.join().unwrap();
    assert_eq!(rc, Some(0), "{}\n{}", y.dump(), gw.dump());
    assert_eq!(json_lines(&y, "data")[0]["data"], 6.25);
    let mut v = peer(
        &py,
        "sub v",
        dom,
        "sub",
        &[
            "--topic",
            "rt/gw_async/publish/v",
            "--type",
            "std_msgs::msg::dds_::Float64MultiArray_",
            "--fields",
            r#"[["dim_len","uint32"],["data_offset","uint32"],["data","float64[]"]]"#,
        ],
    );
    let mut flag = peer(
        &py,
        "sub flag",
        dom,
        "sub",
        &[
            "--topic",
            "rt/gw_async/publish/flag",
            "--type",
            "std_msgs::msg::dds_::Bool_",
            "--fields",
            r#"[["data","bool"]]"#,
        ],
    );
    let mut w = peer(
        &py,
        "pub n",
        dom,
        "pub",
        &[
            "--topic",
            "rt/gw_async/subscribe/n",
            "--type",
            "std_msgs::msg::dds_::Float64_",
            "--fields",
            r#"[["data","float64"]]"#,
            "--values",
            r#"[{"data": 41}, {"data": 42}, {"data": 42}, {"data": 42}]"#,
        ],
    );
    let rcs = [v.wait(SECS(75)), flag.wait(SECS(75)), w.wait(SECS(75))];
    assert_eq!(rcs, [Some(0); 3], "{}\n{}\n{}\n{}", v.dump(), flag.dump(), w.dump(), gw.dump());
    assert_eq!(json_lines(&flag, "data")[0]["data"], true);
    // Float64MultiArray: an empty layout (no dims), then the array.
    let arr = &json_lines(&v, "data")[0];
    assert_eq!(arr["dim_len"], 0);
    assert_eq!(arr["data"].as_array().map(Vec::len), Some(3));
    let off = leaf_offset("gw_async", Role::Subscribe, "n");
    let k = host.wait_for(SECS(15), |_, b| i32::from_ne_bytes(b[off..off + 4].try_into().unwrap()) == 42);
    assert!(k.is_some(), "the framework never read n=42\n{}", gw.dump());
}

fn a_reader_joining_one_item_late_in_per_item_mode_gets_items_that_never_change(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(113), e.ns("gwtest113"));
    let ns = ns.as_str();
    let _host = Host::start(ns, "gw_async", Duration::from_millis(10), async_publish);
    let gw = e.gateway(DDF, dom, ns, &["--ros2-types", "per-item"]);
    // The first reader (of v, which changes every step) turns the PUBLISH route on and gets
    // every item sent once; flag (always true) never changes after that. v's reader stays,
    // so the route stays on while flag's reader joins.
    let v_fields = r#"[["dim_len","uint32"],["data_offset","uint32"],["data","float64[]"]]"#;
    let v_args = ["--topic", "rt/gw_async/publish/v", "--type", "std_msgs::msg::dds_::Float64MultiArray_"];
    let v = peer(&py, "sub v", dom, "sub", &[&v_args[..], &["--fields", v_fields, "--count", "1000000"]].concat());
    assert!(v.wait_line("\"data\"", SECS(75)).is_some(), "v never arrived\n{}\n{}", v.dump(), gw.dump());
    let flag_args = ["--topic", "rt/gw_async/publish/flag", "--type", "std_msgs::msg::dds_::Bool_"];
    let mut flag = peer(&py, "sub flag", dom, "sub", &[&flag_args[..], &["--fields", r#"[["data","bool"]]"#]].concat());
    let rc = flag.wait(SECS(75));
    assert_eq!(rc, Some(0), "a late reader of an unchanging item got nothing\n{}\n{}", flag.dump(), gw.dump());
    assert_eq!(json_lines(&flag, "data")[0]["data"], true);
}

fn a_cyclone_writer_is_read_by_the_framework_through_a_remote_connection(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(103), e.ns("gwtest103"));
    let ns = ns.as_str();
    let host = Host::start(ns, "gw_async", Duration::from_millis(10), async_publish);
    let gw = e.gateway(DDF, dom, ns, &[]);
    let mut w = peer(
        &py,
        "pub subscribe",
        dom,
        "pub",
        &[
            "--topic",
            "rt/gw_async/subscribe",
            "--type",
            "gw_msgs::msg::dds_::GwAsyncSubscribe_",
            "--fields",
            ASYNC_SUB,
            "--values",
            r#"[{"y": 9.5, "n": 3}, {"y": 9.5, "n": 3}, {"y": 9.5, "n": 3}, {"y": 9.5, "n": 3}]"#,
            "--period-ms",
            "200",
        ],
    );
    let got =
        host.wait_for(SECS(60), |_, b| f64_at(b, 0) == 9.5 && i32::from_ne_bytes(b[8..12].try_into().unwrap()) == 3);
    // While the DDS writer is there, the domain lists it as a remote writer connection.
    let seg = tutti_core::shm::segment::Segment::open(ns, "gw_async").unwrap();
    let remote_writers = seg.status().connections.iter().filter(|c| c.remote && c.writer).count();
    assert_eq!(w.wait(SECS(60)), Some(0), "{}\n{}", w.dump(), gw.dump());
    assert!(got.is_some(), "the framework never read the DDS sample\n{}", gw.dump());
    assert_eq!(remote_writers, 1, "{:?}", seg.status().connections);
}

fn the_gateway_writers_offer_the_qos_table_on_the_wire(e: Eng) {
    let Some(py) = python() else { return };
    for (dom, ns, profile) in [(104, "gwtest104", "ros2"), (105, "gwtest105", "dds")] {
        // No framework: --all-domains bridges the domains all the same.
        let gw = e.gateway(DDF, dom, ns, &["--qos-profile", profile, "--strength", "9", "--all-domains"]);
        let q = |topic: &str| {
            let mut p = peer(&py, &format!("qos {topic}"), dom, "qos", &["--topic", topic, "--timeout", "45"]);
            assert_eq!(p.wait(SECS(60)), Some(0), "{}\n{}", p.dump(), gw.dump());
            json_lines(&p, "reliability").remove(0)
        };
        let sync = q("rt/gw_sync/publish");
        assert_eq!(sync["type_name"], "gw_msgs::msg::dds_::GwSyncPublish_");
        assert_eq!(sync["reliability"], "Reliable");
        assert_eq!(sync["durability"], "Volatile");
        let states = q("rt/gw_states/subscribe");
        assert_eq!(states["reliability"], "Reliable");
        assert_eq!(states["durability"], "TransientLocal");
        assert_eq!(states["ownership"], "Shared", "multiplePublishAllowed=yes is SHARED in both profiles");
        let excl = q("rt/gw_async/publish");
        if profile == "ros2" {
            assert_eq!(excl["ownership"], "Shared");
        } else {
            assert_eq!(excl["ownership"], "Exclusive");
            assert_eq!(excl["strength"], 9);
        }
    }
}

fn the_gateway_is_a_ros2_node_in_ros_discovery_info(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(106), e.ns("gwtest106"));
    let ns = ns.as_str();
    let gw = e.gateway(DDF, dom, ns, &["--node-name", "tutti_gw_test", "--all-domains"]);
    let mut p = peer(&py, "nodes", dom, "nodes", &["--name", "tutti_gw_test", "--timeout", "45"]);
    assert_eq!(p.wait(SECS(60)), Some(0), "{}\n{}", p.dump(), gw.dump());
    let n = &json_lines(&p, "name")[0];
    assert_eq!(n["namespace"], "/");
    // 3 domains: 2 writers (PUBLISH, SUBSCRIBE) and 1 reader (SUBSCRIBE) each, besides
    // the node's own (parameter events); on Cyclone, the simulation services' too
    // (docs/ros2.md): 13 request readers and reply writers (the 5 of run control, the 5 of
    // entities, the action's 3), and the action's feedback and status writers.
    let (readers, writers) = if e.name == "cyclone" { (13, 15) } else { (0, 0) };
    assert!(n["writers"].as_u64() >= Some(6 + writers), "{n}");
    assert_eq!(n["readers"], 3 + readers, "{n}");
}

fn bad_samples_and_a_second_writer_are_dropped_and_counted(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(107), e.ns("gwtest107"));
    let ns = ns.as_str();
    let host = Host::start(ns, "gw_async", Duration::from_millis(10), async_publish);
    let mut gw = e.gateway(DDF, dom, ns, &[]);
    // Truncated: the right type name, but only the header fields.
    let mut bad = peer(
        &py,
        "pub truncated",
        dom,
        "pub",
        &[
            "--topic",
            "rt/gw_async/subscribe",
            "--type",
            "gw_msgs::msg::dds_::GwAsyncSubscribe_",
            "--fields",
            r#"[["step","uint64"]]"#,
            "--values",
            r#"[{"step": 1}, {"step": 2}]"#,
        ],
    );
    assert_eq!(bad.wait(SECS(60)), Some(0), "{}", bad.dump());
    // Two writers on an exclusive set: the first to publish owns it.
    let vals =
        |y: f64| format!(r#"[{{"y": {y}}}, {{"y": {y}}}, {{"y": {y}}}, {{"y": {y}}}, {{"y": {y}}}, {{"y": {y}}}]"#);
    let (v1, v2) = (vals(1.0), vals(2.0));
    let a =
        ["--topic", "rt/gw_async/subscribe", "--type", "gw_msgs::msg::dds_::GwAsyncSubscribe_", "--fields", ASYNC_SUB];
    let mut first = peer(&py, "first writer", dom, "pub", &[&a[..], &["--values", &v1, "--period-ms", "300"]].concat());
    assert!(host.wait_for(SECS(60), |_, b| f64_at(b, 0) == 1.0).is_some(), "{}\n{}", first.dump(), gw.dump());
    let mut second =
        peer(&py, "second writer", dom, "pub", &[&a[..], &["--values", &v2, "--period-ms", "100"]].concat());
    assert_eq!(second.wait(SECS(60)), Some(0), "{}", second.dump());
    assert_eq!(first.wait(SECS(60)), Some(0), "{}", first.dump());
    // A window for a late sample of the second writer, counted in the framework's reads of
    // the set rather than in time: each of the next 70 steps (0.7 s of 10 ms steps) would
    // show it.
    let at = host.seen.lock().unwrap().last().map_or(0, |(k, _)| *k);
    assert!(host.wait_for(SECS(60), |k, _| k >= at + 70).is_some(), "the framework stopped stepping");
    assert!(host.seen.lock().unwrap().iter().all(|(_, b)| f64_at(b, 0) != 2.0), "the second writer got through");
    let rejected = tutti_core::shm::segment::Segment::open(ns, "gw_async").unwrap().status().rejected;
    assert_eq!(gw.interrupt(SECS(30)), Some(0), "{}", gw.dump());
    assert!(counter(&gw, "bad_samples") >= 1, "{}", gw.dump());
    assert!(counter(&gw, "refused") >= 1, "{}", gw.dump());
    assert!(rejected >= 1, "the domain header counts the refused commits");
}

fn a_dds_writer_takes_part_in_lock_step_through_the_gateway(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(108), e.ns("gwtest108"));
    let ns = ns.as_str();
    let mut answer = peer(
        &py,
        "answer",
        dom,
        "answer",
        &[
            "--topic",
            "rt/gw_sync/publish",
            "--type",
            "gw_msgs::msg::dds_::GwSyncPublish_",
            "--fields",
            r#"[["step","uint64"],["sim_time","float64"],["x","float64"]]"#,
            "--reply-topic",
            "rt/gw_sync/subscribe",
            "--reply-type",
            "gw_msgs::msg::dds_::GwSyncSubscribe_",
            "--reply-fields",
            r#"[["step","uint64"],["sim_time","float64"],["y","float64"]]"#,
            "--count",
            "100000",
            "--timeout",
            "60",
        ],
    );
    let host = Host::start(ns, "gw_sync", Duration::from_millis(5), |k| (k as f64 * 10.0).to_ne_bytes().to_vec());
    let gw = e.gateway(DDF, dom, ns, &[]);
    // In lock-step, the SUBSCRIBE set read at the end of step k answers step k's PUBLISH set.
    let answered = |k: u64, b: &[u8]| f64_at(b, 0) == k as f64 * 10.0 + 1.0;
    let first = host.wait_for(SECS(75), answered);
    assert!(first.is_some(), "no step was answered in lock-step\n{}\n{}", answer.dump(), gw.dump());
    // Lock-step is judged over the 100 steps (0.5 s) after the first answered one.
    assert!(host.wait_for(SECS(60), |k, _| k >= first.unwrap() + 100).is_some(), "the framework stopped stepping");
    let seen = host.seen.lock().unwrap().clone();
    assert_lock_step(&seen, first.unwrap(), answered);
    crate::gateway_reliable::assert_no_step_lost(&gw, false);
    drop(host);
    let _ = answer.interrupt(SECS(15));
}

fn the_cyclone_uav_listener_prints_the_states_a_uav_model_commits(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(112), e.ns("gwtest112"));
    let ns = ns.as_str();
    let host = Host::start_with("ddf/multiuav.ddf", ns, "multiuav_uav1", Duration::from_millis(10), |_| vec![0; 56]);
    let gw = e.gateway("ddf/multiuav.ddf", dom, ns, &[]);
    // The UAV model: in lock-step, answers every step with its state.
    let stop = Arc::new(AtomicBool::new(false));
    let (s, ns2) = (stop.clone(), ns.to_string());
    let uav = thread::spawn(move || {
        let mut p = connect(&ns2, "multiuav_uav1");
        while !s.load(Ordering::Acquire) {
            if p.subscribe_lock().is_ok() && p.publish_lock().is_ok() {
                p.stage("Latitude", &45.5f64.to_ne_bytes()).unwrap();
                p.stage("Elevation", &120.0f64.to_ne_bytes()).unwrap();
                p.commit().unwrap();
            }
        }
    });
    let mut cmd = std::process::Command::new(&py);
    cmd.args(["launch-scripts/cyclone_uav_listener.py", "--domain", &dom.to_string(), "--uavs", "1", "--count", "2"]);
    cmd.args(["--timeout", "60"]);
    let mut l = Proc::spawn("uav listener", cmd, Duration::from_secs(90));
    let rc = l.wait(SECS(75));
    stop.store(true, Ordering::Release);
    uav.join().unwrap();
    drop(host);
    assert_eq!(rc, Some(0), "{}\n{}", l.dump(), gw.dump());
    let s = &json_lines(&l, "uav")[0];
    assert_eq!(s["latitude"], 45.5);
    assert_eq!(s["elevation"], 120.0);
}

/// In the `dds` profile, ownership is matched on the wire: a Cyclone EXCLUSIVE reader takes
/// the gateway's EXCLUSIVE writer's samples, and the gateway's EXCLUSIVE reader takes only
/// the strongest live DDS writer's samples, so a weaker writer never reaches the framework
/// while the stronger one lives. Cyclone engine only: rustdds does not match EXCLUSIVE
/// endpoints with Cyclone's (docs/gateway.md, "Known limits").
#[test]
fn dds_profile_ownership_is_matched_on_the_wire_by_the_cyclone_engine() {
    let Some(py) = python() else { return };
    let e = Eng::CYCLONE;
    let (dom, ns) = (e.dom(114), e.ns("gwtest114"));
    let ns = ns.as_str();
    let host = Host::start(ns, "gw_async", Duration::from_millis(10), async_publish);
    let gw = e.gateway(DDF, dom, ns, &["--qos-profile", "dds", "--strength", "9"]);
    let mut reader = peer(
        &py,
        "exclusive reader",
        dom,
        "sub",
        &[
            "--topic",
            "rt/gw_async/publish",
            "--type",
            "gw_msgs::msg::dds_::GwAsyncPublish_",
            "--fields",
            ASYNC_PUB,
            "--count",
            "3",
            "--exclusive",
        ],
    );
    assert_eq!(reader.wait(SECS(75)), Some(0), "{}\n{}", reader.dump(), gw.dump());
    assert_eq!(json_lines(&reader, "x")[0]["x"], 4.5);

    let values = |y: f64, n: usize| format!("[{}]", vec![format!(r#"{{"y": {y}}}"#); n].join(","));
    let (strong_values, weak_values) = (values(1.0, 150), values(2.0, 40));
    let a =
        ["--topic", "rt/gw_async/subscribe", "--type", "gw_msgs::msg::dds_::GwAsyncSubscribe_", "--fields", ASYNC_SUB];
    let writer = |name: &str, vals: &str, strength: &str| {
        let opts = ["--values", vals, "--period-ms", "20", "--exclusive", "--strength", strength];
        peer(&py, name, dom, "pub", &[&a[..], &opts].concat())
    };
    let mut strong = writer("strong writer", &strong_values, "10");
    assert!(host.wait_for(SECS(60), |_, b| f64_at(b, 0) == 1.0).is_some(), "{}\n{}", strong.dump(), gw.dump());
    let mut weak = writer("weak writer", &weak_values, "3");
    assert_eq!(weak.wait(SECS(60)), Some(0), "{}", weak.dump());
    assert_eq!(json_lines(&weak, "wrote").len(), 40, "{}", weak.dump());
    let strong_rc = strong.wait(SECS(60));
    assert_eq!(strong_rc, Some(0), "{}", strong.dump());
    assert!(
        host.seen.lock().unwrap().iter().all(|(_, b)| f64_at(b, 0) != 2.0),
        "a weaker writer's sample reached the framework while the stronger one lived\n{}",
        gw.dump()
    );
}

/// `/clock`: the simulated time of the first synchronous domain (gw_sync, stepped every
/// 10 ms with time k × 0.01 s) reaches a reader of `rt/clock` with ROS 2's type and ClockQoS:
/// each time one the domain had, never going back, and none once the host has stopped.
fn the_simulated_time_goes_out_on_clock(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(117), e.ns("gwtest117"));
    let ns = ns.as_str();
    let host = Host::start(ns, "gw_sync", Duration::from_millis(10), |k| (k as f64).to_ne_bytes().to_vec());
    let gw = e.gateway(DDF, dom, ns, &[]);
    let mut clock = peer(&py, "clock", dom, "clock", &["--timeout", "90"]);
    let too_few = lazy(|| format!("too few /clock samples\n{}\n{}", clock.dump(), gw.dump()));
    wait_until(too_few, SECS(75), || json_lines(&clock, "clock").len() >= 30);
    let seen = host.seen.clone();
    drop(host);
    // The last step the framework made before it stopped: no /clock time may go past it,
    // however late the reader prints what it got.
    let last = seen.lock().unwrap().iter().map(|(k, _)| *k).max().unwrap();
    // A window, not a wait: a time past the last step would be written by the gateway's
    // poller, which looks at the domain at least every 200 ms, and printed by the reader
    // within a millisecond of its arrival; 1.5 s is seven such looks.
    thread::sleep(Duration::from_millis(1500));
    let times: Vec<f64> = json_lines(&clock, "clock").iter().map(|v| v["clock"].as_f64().unwrap()).collect();
    let end = last as f64 * 0.01 + 1e-6;
    assert!(times.iter().all(|&t| t <= end), "/clock went on after the host stopped at {end} s: {times:?}");
    for w in times.windows(2) {
        assert!(w[1] >= w[0], "/clock went back: {} then {}", w[0], w[1]);
    }
    for t in &times {
        let k = (t / 0.01).round();
        assert!(k >= 1.0 && (t - k * 0.01).abs() < 1e-6, "{t} is not a simulated time of the domain");
    }
    assert!(times[times.len() - 1] > times[0], "{times:?}");
    let _ = clock.interrupt(SECS(10));
}

/// A reset (`tutti ctl reset`, docs/run.md) takes `/clock` back with the run's simulated
/// time: once, to the first steps after it (made with `tutti ctl step 3`), and on from there
/// when the run resumes; each time one of the 5 ms steps, and each step's own time (a time
/// read apart from its step once went out twice).
fn clock_goes_back_once_with_a_reset(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom_beside(53), e.ns("gwtest53"));
    let (mut host, _segments) = host_with_gateway(e, DDF, dom, &ns, &[]);
    let clock = peer(&py, "clock", dom, "clock", &["--timeout", "90"]);
    let times = || -> Vec<f64> { json_lines(&clock, "clock").iter().map(|v| v["clock"].as_f64().unwrap()).collect() };
    let wait_for = |what: &str, done: &dyn Fn(&[f64]) -> bool| {
        let failed = lazy(|| format!("/clock: {what}: {:?}\n{}\n{}", times(), clock.dump(), host.dump()));
        wait_until(failed, SECS(60), || done(&times()));
    };
    let ctl = |args: &[&str]| {
        let mut cmd = tutti_test_support::tutti_command();
        cmd.arg("ctl").args(args).env("TUTTI_NAMESPACE", &ns);
        let (status, out, err) = tutti_test_support::run_with_timeout(cmd, SECS(60));
        assert!(status.success(), "tutti ctl {args:?}: {out}{err}");
    };
    wait_for("half a second of the run", &|t| t.iter().any(|&t| t >= 0.5));
    ctl(&["pause"]);
    ctl(&["reset"]);
    ctl(&["step", "3"]);
    let back = |t: &[f64]| t.windows(2).position(|w| w[1] < w[0]).map(|i| i + 1);
    wait_for("the third step after the reset", &|t| back(t).is_some_and(|i| t[i..].iter().any(|&t| t > 0.009)));
    ctl(&["resume"]);
    wait_for("0.1 s after the reset", &|t| back(t).is_some_and(|i| t[i..].iter().any(|&t| t >= 0.1)));
    assert_eq!(host.interrupt(SECS(30)), Some(0), "{}", host.dump());
    let t = times();
    let i = back(&t).unwrap();
    assert!(t[..i].windows(2).all(|w| w[0] < w[1]) && t[i..].windows(2).all(|w| w[0] < w[1]), "{t:?}");
    assert!(t[i - 1] >= 0.5 && t[i] <= 0.010 + 1e-9, "not back to the reset's first steps: {t:?}");
    assert!(t.iter().all(|t| (t / 0.005 - (t / 0.005).round()).abs() < 1e-6), "a time that is no step's: {t:?}");
}

per_engine!(
    the_simulated_time_goes_out_on_clock,
    clock_goes_back_once_with_a_reset,
    shared_memory_values_reach_a_cyclone_reader_as_typed_samples,
    per_item_mode_uses_stock_types_both_ways,
    a_reader_joining_one_item_late_in_per_item_mode_gets_items_that_never_change,
    a_cyclone_writer_is_read_by_the_framework_through_a_remote_connection,
    the_gateway_writers_offer_the_qos_table_on_the_wire,
    the_gateway_is_a_ros2_node_in_ros_discovery_info,
    bad_samples_and_a_second_writer_are_dropped_and_counted,
    a_dds_writer_takes_part_in_lock_step_through_the_gateway,
    the_cyclone_uav_listener_prints_the_states_a_uav_model_commits,
);
