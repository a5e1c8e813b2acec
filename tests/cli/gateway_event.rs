//! The gateway's DDS writers in an event-driven domain (docs/timing.md, docs/gateway.md), on
//! both engines, through the gateway in the framework's process. A participant of `gw_tick`
//! changes `src` every 10th step, and the framework copies it to `x`; a DDS node (the Cyclone
//! peer) answers `y = x + 1` into the same domain only when the `x` it read changed. In the
//! event-driven domain (`gw_event`) the framework waits for the node only at those steps: no
//! step times out, and the recording shows each answer at the step of its change. In lock-step
//! (`gw_lock`) the same node makes every step where `x` kept time out. As fast as possible,
//! `/clock` jumps from due step to due step. DDS domains 136-141.

use crate::gateway;

use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::Ordering;

use gateway::*;
use tutti_core::shm::ShmError;
use tutti_test_support::Worker;

/// The domains of this test (tests/gateway/event.ddf).
const EVENT_DDF: &str = "tests/gateway/event.ddf";
/// The framework's step, in seconds (`host_with_gateway`'s 5 ms).
const STEP: f64 = 0.005;
/// `src` changes every this many steps.
const EVERY: u64 = 10;

/// The participant of `gw_tick`: due every `EVERY` steps (`set_period`), where it writes
/// `src` = its step's index over `EVERY`, a new value each time. It ends when the framework
/// stops or the worker is dropped.
fn ticker(ns: &str) -> Worker {
    let mut p = connect(ns, "gw_tick");
    p.set_period(EVERY as f64 * STEP).expect("a period of EVERY steps");
    Worker::spawn(move |stop| {
        while !stop.load(Ordering::Acquire) {
            match p.subscribe_lock() {
                Ok(_) => {}
                Err(ShmError::Timeout { .. }) => continue,
                // The framework stopped.
                Err(_) => return,
            }
            let src = ((p.simulation_time() / STEP).round() as u64 / EVERY) as f64;
            let wrote = p.publish_lock().and_then(|_| p.stage("src", &src.to_ne_bytes())).and_then(|()| p.commit());
            if wrote.is_err() {
                return;
            }
        }
    })
}

/// `tutti host tests/gateway/event.ddf --gateway` on engine `e` (DDS domain `base` or the one
/// beside it), with `src` connected to the `x` of `domain` and steps at their own times
/// (`--catch-up`: a loaded machine does not make the times jump), step timeout `timeout`,
/// recording into `run.csv` of the directory returned; with the ticker, and the node
/// answering the changes of `domain`'s `x`, until the node has answered `answers` changes.
/// Returns the host, stopped, and the directory; None without the Python peer.
fn run(e: Eng, base: u16, domain: &str, timeout: &str, answers: usize) -> Option<(Proc, tempfile::TempDir)> {
    let py = python()?;
    let (dom, ns) = (e.dom_beside(base), e.ns(&format!("gwevent{base}")));
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let csv = csv.to_str().expect("a UTF-8 path");
    let connection = format!("gw_tick/subscribe/src -> {domain}/publish/x");
    let args = ["--timeout", timeout, "--catch-up", "--connect", &connection, "--record", csv];
    let (mut host, _segments) = host_with_gateway(e, EVENT_DDF, dom, &ns, &args);
    let ticker = ticker(&ns);
    let (topic, reply) = (format!("rt/{domain}/publish"), format!("rt/{domain}/subscribe"));
    // gw_event -> GwEvent, the stem of its types' names.
    let stem: String = domain.split('_').map(|w| w[..1].to_uppercase() + &w[1..]).collect();
    let (ty, reply_ty) =
        (format!("event_msgs::msg::dds_::{stem}Publish_"), format!("event_msgs::msg::dds_::{stem}Subscribe_"));
    let node = peer(
        &py,
        "node answering changes",
        dom,
        "answer",
        &["--topic", &topic, "--type", &ty, "--fields", SYNC_PUB, "--reply-topic", &reply, "--reply-type", &reply_ty]
            .into_iter()
            .chain(["--reply-fields", SYNC_SUB, "--on-change", "--count", "1000000", "--timeout", "120"])
            .collect::<Vec<_>>(),
    );
    let mut from = 0;
    for i in 0..answers {
        let line = node.next_line(&mut from, r#""in""#, SECS(90));
        assert!(line.is_some(), "the node answered {i} changes\n{}\n{}", node.dump(), host.dump());
    }
    // Stopped while the node still runs, so that no change goes unanswered.
    assert_eq!(host.interrupt(SECS(60)), Some(0), "{}", host.dump());
    drop(ticker);
    Some((host, dir))
}

/// The rows of a CSV recording: column name -> value, in order.
fn rows(csv: &Path) -> Vec<HashMap<String, f64>> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().expect("a header").split(',').collect();
    lines
        .map(|l| head.iter().zip(l.split(',')).filter_map(|(h, v)| Some((h.to_string(), v.parse().ok()?))).collect())
        .collect()
}

fn a_dds_writer_answering_changes_only_stalls_no_step(e: Eng) {
    let Some((host, dir)) = run(e, 136, "gw_event", "2s", 8) else { return };
    assert!(!host.dump().contains("timed out"), "a step waited for the DDS writer\n{}", host.dump());
    let rows = rows(&dir.path().join("run-gw_event.csv"));
    let (x, y) = (|r: &HashMap<String, f64>| r["publish.x"], |r: &HashMap<String, f64>| r["subscribe.y"]);
    // Every sample committed answers the step it was committed at: from the node's first
    // answer on, y is the x of the step (kept where x kept, answered where x changed).
    let first = rows.iter().position(|r| y(r) != 0.0).unwrap_or_else(|| panic!("no answer recorded\n{}", host.dump()));
    let (mut changed, mut kept) = (0, 0);
    for pair in rows[first..].windows(2) {
        let (before, now) = (&pair[0], &pair[1]);
        assert_eq!(y(now), x(now) + 1.0, "step {}: not the answer to its x ({} before)", now["step"], x(before));
        if x(now) == x(before) {
            kept += 1;
        } else {
            changed += 1;
        }
    }
    // The node answered 8 changes, the first of which may precede its first commit.
    assert!(changed >= 5, "{changed} changes answered");
    assert!(kept >= changed * (EVERY as usize - 2), "{kept} steps where x kept, {changed} where it changed");
}

fn in_lock_step_the_same_dds_writer_makes_the_steps_it_does_not_answer_time_out(e: Eng) {
    let Some((host, _dir)) = run(e, 138, "gw_lock", "50ms", 3) else { return };
    let timed_out =
        host.lines().iter().filter(|l| l.contains("of gw_lock timed out") && l.contains("dds-writer")).count();
    // At least the steps between the second and the third change.
    assert!(timed_out >= EVERY as usize - 2, "{timed_out} steps timed out\n{}", host.dump());
}

/// As fast as possible (`--speed 0`), with nobody due but the ticker every 10th step, the
/// framework jumps from due step to due step, and `/clock` shows it: every time a DDS reader
/// of `rt/clock` gets is a multiple of 10 steps, none in between.
fn clock_jumps_from_due_step_to_due_step(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom_beside(140), e.ns("gwevent140"));
    let (mut host, _segments) = host_with_gateway(e, EVENT_DDF, dom, &ns, &["--speed", "0"]);
    let ticker = ticker(&ns);
    let clock = peer(&py, "clock", dom, "clock", &["--timeout", "90"]);
    let mut from = 0;
    for i in 0..30 {
        let line = clock.next_line(&mut from, r#""clock""#, SECS(90));
        assert!(line.is_some(), "{i} /clock samples\n{}\n{}", clock.dump(), host.dump());
    }
    assert_eq!(host.interrupt(SECS(60)), Some(0), "{}", host.dump());
    drop(ticker);
    let times: Vec<f64> = json_lines(&clock, "clock").iter().map(|v| v["clock"].as_f64().unwrap()).collect();
    let period = EVERY as f64 * STEP;
    for t in &times {
        assert!((t / period - (t / period).round()).abs() < 1e-6, "/clock at {t} s, between two due steps: {times:?}");
    }
    assert!(times.windows(2).all(|w| w[1] > w[0]), "{times:?}");
}

per_engine!(
    a_dds_writer_answering_changes_only_stalls_no_step,
    in_lock_step_the_same_dds_writer_makes_the_steps_it_does_not_answer_time_out,
    clock_jumps_from_due_step_to_due_step,
);
