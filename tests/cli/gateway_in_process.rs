//! `tutti host DDF --gateway`: the gateway in the framework's process, on both engines,
//! against the Cyclone peer. The framework's own PUBLISH sets go to DDS from its step (every
//! step of a synchronous set once and in order), DDS samples reach its SUBSCRIBE set, and a
//! set an external component writes still reaches DDS through the poller. Each test has its
//! own DDS domain (126-128, 176-178 on rustdds) and namespace.

use crate::gateway;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use gateway::*;
use tutti_core::ddf::Role;
use tutti_core::shm::segment::Segment;
use tutti_test_support::RemoveSegments;

fn every_synchronous_step_reaches_a_reader_once_and_in_order(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(126), e.ns("gwinproc126"));
    let (mut host, _segments) = host_with_gateway(e, DDF, dom, &ns, &["--set", "gw_sync/x=1.5"]);
    let mut sub = peer(
        &py,
        "sub sync publish",
        dom,
        "sub",
        &["--topic", "rt/gw_sync/publish", "--type", "gw_msgs::msg::dds_::GwSyncPublish_", "--fields", SYNC_PUB]
            .into_iter()
            .chain(["--count", "150", "--timeout", "60"])
            .collect::<Vec<_>>(),
    );
    let rc = sub.wait(SECS(90));
    assert_eq!(rc, Some(0), "{}\n{}", sub.dump(), host.dump());
    let steps: Vec<u64> = json_lines(&sub, "step").iter().map(|v| v["step"].as_u64().unwrap()).collect();
    assert!(steps.len() >= 150, "{}", sub.dump());
    for pair in steps.windows(2) {
        assert_eq!(pair[1], pair[0] + 1, "a step lost, repeated or out of order: {steps:?}");
    }
    let first = &json_lines(&sub, "step")[0];
    assert_eq!(first["x"], 1.5, "the step's own PUBLISH set");
    let k = first["step"].as_f64().unwrap();
    // The host skips the deadlines it is late for: its time is at least the step's.
    assert!(first["sim_time"].as_f64().unwrap() >= (k - 1.0) * 0.005 - 1e-9, "the step's own time: {first}");
    // Its last status line, as it stops, counts no step lost.
    let from = host.lines().len();
    assert_eq!(host.interrupt(SECS(60)), Some(0), "{}", host.dump());
    crate::gateway_reliable::assert_no_step_lost_after(&host, from, false);
}

fn a_dds_writers_samples_reach_the_subscribe_set(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(127), e.ns("gwinproc127"));
    let (host, _segments) = host_with_gateway(e, DDF, dom, &ns, &[]);
    let values = r#"[{"y": 3.25, "n": 11}, {"y": 3.25, "n": 12}, {"y": 3.25, "n": 13}]"#;
    let mut writer = peer(
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
            values,
            "--period-ms",
            "100",
            "--linger",
            "2",
        ],
    );
    let seg = Segment::open(&ns, "gw_async").expect("the host's segment");
    let (y_at, n_at) = (leaf_offset("gw_async", Role::Subscribe, "y"), leaf_offset("gw_async", Role::Subscribe, "n"));
    let mut set = vec![0u8; seg.info.subscribe.size as usize];
    let seen = tutti_test_support::poll_for(SECS(60), || {
        if seg.try_read_set(Role::Subscribe, &mut set, 1 << 16).is_some() && f64_at(&set, y_at) == 3.25 {
            return Some(i32::from_ne_bytes(set[n_at..n_at + 4].try_into().unwrap()));
        }
        None
    });
    let rc = writer.wait(SECS(60));
    assert!(
        seen.is_some_and(|n| (11..=13).contains(&n)),
        "no DDS sample in the SUBSCRIBE set\n{}\n{}",
        writer.dump(),
        host.dump()
    );
    assert_eq!(rc, Some(0), "{}", writer.dump());
}

fn a_set_an_external_component_writes_still_reaches_dds(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(128), e.ns("gwinproc128"));
    let (host, _segments) = host_with_gateway(e, DDF, dom, &ns, &[]);
    let stop = Arc::new(AtomicBool::new(false));
    let (s, ns2) = (stop.clone(), ns.clone());
    let component = thread::spawn(move || {
        let mut p = connect(&ns2, "gw_async");
        while !s.load(Ordering::Acquire) {
            p.stage("y", &2.5f64.to_ne_bytes()).unwrap();
            p.stage("n", &7i32.to_ne_bytes()).unwrap();
            p.commit().unwrap();
            thread::sleep(Duration::from_millis(50));
        }
    });
    let mut sub = peer(
        &py,
        "sub subscribe",
        dom,
        "sub",
        &["--topic", "rt/gw_async/subscribe", "--type", "gw_msgs::msg::dds_::GwAsyncSubscribe_", "--fields", ASYNC_SUB]
            .into_iter()
            .chain(["--count", "3", "--timeout", "60"])
            .collect::<Vec<_>>(),
    );
    let rc = sub.wait(SECS(90));
    stop.store(true, Ordering::Release);
    component.join().unwrap();
    assert_eq!(rc, Some(0), "{}\n{}", sub.dump(), host.dump());
    let got = json_lines(&sub, "y");
    assert_eq!((got[0]["y"].as_f64(), got[0]["n"].as_i64()), (Some(2.5), Some(7)), "{}", sub.dump());
}

per_engine!(
    every_synchronous_step_reaches_a_reader_once_and_in_order,
    a_dds_writers_samples_reach_the_subscribe_set,
    a_set_an_external_component_writes_still_reaches_dds,
);

/// `tutti run` with a `gateway` key runs the gateway in the framework's process: a DDS reader
/// gets the framework's PUBLISH set, and `tutti ctl stop` ends the run with nothing left.
#[test]
fn a_launch_files_gateway_runs_in_the_framework_process() {
    let Some(py) = python() else { return };
    let (dom, ns) = (Eng::CYCLONE.dom(129), Eng::CYCLONE.ns("gwinproc129"));
    let _segments = RemoveSegments(ns.clone());
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(tutti_test_support::repo_root().join(DDF), dir.path().join("gw.ddf")).unwrap();
    let file = dir.path().join("run.json5");
    std::fs::write(
        &file,
        format!(
            r#"{{
  ddf: "gw.ddf",
  framework: {{ step: "5ms", set: ["gw_sync/x=2.5"] }},
  gateway: {{ ros_domain_id: {dom}, interface: ["127.0.0.1"], dds: "cyclone" }},
}}"#
        ),
    )
    .unwrap();
    let mut cmd = tutti_test_support::tutti_command();
    cmd.arg("run").arg(&file).env("TUTTI_NAMESPACE", &ns).env("RUST_LOG", "info");
    let mut run = Proc::spawn("tutti run", cmd, SECS(180));
    assert!(run.wait_line("run: gateway: up", SECS(60)).is_some(), "the gateway did not start\n{}", run.dump());
    let args = ["--topic", "rt/gw_sync/publish", "--type", "gw_msgs::msg::dds_::GwSyncPublish_", "--fields", SYNC_PUB];
    let mut sub = peer(&py, "sub", dom, "sub", &[&args[..], &["--count", "20", "--timeout", "60"]].concat());
    assert_eq!(sub.wait(SECS(90)), Some(0), "{}\n{}", sub.dump(), run.dump());
    assert!(json_lines(&sub, "x").iter().all(|v| v["x"] == 2.5), "{}", sub.dump());
    let mut ctl = tutti_test_support::tutti_command();
    ctl.args(["ctl", "stop"]).env("TUTTI_NAMESPACE", &ns);
    let (status, _, err) = tutti_test_support::run_with_timeout(ctl, SECS(60));
    assert!(status.success(), "{err}");
    assert_eq!(run.wait(SECS(60)), Some(0), "{}", run.dump());
    assert!(tutti_test_support::segments_of(&ns).is_empty());
}
