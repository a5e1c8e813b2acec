//! Nothing lost on a synchronous set, on both engines: a framework steps `gw_sync` flat out
//! while a Cyclone DDS reader with the domain's QoS (reliable, keep-all) reads its PUBLISH
//! topic, through a separate gateway in lock-step (`--every-step`) and through the gateway in
//! the framework's process. Every step from the reader's first on must arrive once, in order
//! and with its own data, and the gateway must count no step lost (docs/gateway.md, "Nothing
//! lost on a synchronous set"). Also what a Cyclone peer (as rmw_cyclonedds, so rclpy) sees
//! of the history of each engine's writers and readers (docs/gateway.md, "The history a ROS 2
//! tool shows"). DDS domains 220-225 and 131-132, namespaces `rel-rustdds-*`.

use crate::gateway;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use gateway::*;
use tutti_core::shm::{Framework, FrameworkOptions};
use tutti_gateway::in_process::GatewaySink;
use tutti_gateway::{EngineKind, GatewayOptions};
use tutti_test_support::{RemoveSegments, Worker};

/// Steps stepped flat out once the reader has its first sample.
const FLAT_OUT_STEPS: u64 = 20_000;

/// Asserts that the gateway whose output `p` holds counts no synchronous step lost in its
/// next status line: `lost=0` (a step its DDS writer refused for the whole step timeout) and
/// `errors=0`; with `every_step` (the gateway reads in lock-step) also `skipped=0`.
pub fn assert_no_step_lost(p: &Proc, every_step: bool) {
    assert_no_step_lost_after(p, p.lines().len(), every_step);
}

/// As [`assert_no_step_lost`], in the first status line from line `from` of `p`'s output on.
pub fn assert_no_step_lost_after(p: &Proc, mut from: usize, every_step: bool) {
    let line = p.next_line(&mut from, " lost=", SECS(30)).unwrap_or_else(|| panic!("no status line\n{}", p.dump()));
    let count = |name: &str| -> u64 {
        let key = format!(" {name}=");
        let v = line.split_once(&key).and_then(|(_, rest)| rest.split_whitespace().next()?.parse().ok());
        v.unwrap_or_else(|| panic!("no {name} in the status line: {line}"))
    };
    assert_eq!(count("lost"), 0, "synchronous steps lost: {line}\n{}", p.dump());
    assert_eq!(count("errors"), 0, "{line}\n{}", p.dump());
    if every_step {
        assert_eq!(count("skipped"), 0, "synchronous steps skipped: {line}\n{}", p.dump());
    }
}

/// What the stepping thread did: steps made, and the errors of those that failed.
#[derive(Default)]
struct Stepped {
    steps: u64,
    errors: Vec<String>,
}

/// Steps domain `gw_sync` of `fw`: every 5 ms until `go`, then [`FLAT_OUT_STEPS`] flat out,
/// then a last step whose `x` is -1 (the reader's end mark); every other step's `x` is its
/// step number. An in-process gateway's `sink` is handed each step as `tutti host` does.
fn stepper(mut fw: Framework, mut sink: Option<GatewaySink>, go: Arc<AtomicBool>, out: Arc<Mutex<Stepped>>) -> Worker {
    Worker::spawn(move |stop| {
        let di = fw.domains.iter().position(|d| d.info().name == "gw_sync").expect("gw_sync");
        let mut flat_out = 0u64;
        let mut k = 0u64;
        while !stop.load(Ordering::Acquire) && flat_out <= FLAT_OUT_STEPS {
            k += 1;
            let fast = go.load(Ordering::Acquire);
            flat_out += u64::from(fast);
            let x = if flat_out > FLAT_OUT_STEPS { -1.0 } else { k as f64 };
            let host = &mut fw.domains[di];
            let r = host.publish_step(&x.to_ne_bytes(), k as f64 * 0.001).map(|_| {
                if let Some(s) = sink.as_mut() {
                    s.send(di, host.current_step(), k as f64 * 0.001, &x.to_ne_bytes(), fast);
                }
            });
            let r = r.and_then(|()| host.complete_step().map(drop));
            let mut o = out.lock().unwrap();
            o.steps = k;
            if let Err(e) = r {
                o.errors.push(format!("step {k}: {e}"));
            }
            drop(o);
            if !fast {
                thread::sleep(Duration::from_millis(5));
            }
        }
        if let Some(s) = sink.as_mut() {
            s.flush();
        }
        while !stop.load(Ordering::Acquire) {
            thread::sleep(Duration::from_millis(10));
        }
        drop(sink);
    })
}

/// Runs the flat-out stepping against the `steps` reader in DDS domain `dom` and asserts
/// that every step from its first on arrived once, in order, with its own data, and that
/// the framework's steps all completed.
fn every_step_arrives(dom: u16, fw: Framework, sink: Option<GatewaySink>, others: &dyn Fn() -> String) {
    let Some(py) = python() else { return };
    let args = ["--topic", "rt/gw_sync/publish", "--type", "gw_msgs::msg::dds_::GwSyncPublish_"];
    // A slow reader: it holds at most 64 samples and takes them every 5 ms, so that the
    // gateway's writer must wait for its acknowledgements.
    let slow = ["--max-samples", "64", "--pause-ms", "5"];
    let args: Vec<&str> = args.into_iter().chain(["--fields", SYNC_PUB, "--timeout", "240"]).chain(slow).collect();
    let mut reader = peer(&py, "steps of gw_sync", dom, "steps", &args);
    let go = Arc::new(AtomicBool::new(false));
    let stepped = Arc::new(Mutex::new(Stepped::default()));
    let worker = stepper(fw, sink, go.clone(), stepped.clone());
    let first = reader.wait_line("\"first\"", SECS(90));
    assert!(first.is_some(), "the reader got no step\n{}\n{}", reader.dump(), others());
    go.store(true, Ordering::Release);
    let ended = tutti_test_support::poll_for(SECS(240), || {
        (!json_lines(&reader, "summary").is_empty() || reader.exited().is_some()).then_some(())
    });
    assert!(ended.is_some(), "the reader never got the last step\n{}\n{}", reader.dump(), others());
    assert_eq!(reader.wait(SECS(30)), Some(0), "{}\n{}", reader.dump(), others());
    let s = json_lines(&reader, "summary").remove(0);
    assert_eq!(s["ended"], true, "{s}");
    for what in ["missing", "gaps", "misordered", "wrong"] {
        assert_eq!(s[what], 0, "{what}: {s}\n{}", others());
    }
    let (first, last, received) = (s["first"].as_u64().unwrap(), s["last"].as_u64().unwrap(), s["received"].as_u64());
    assert_eq!(received, Some(last - first + 1), "{s}");
    assert!(last - first >= FLAT_OUT_STEPS, "{s}");
    drop(worker);
    let stepped = stepped.lock().unwrap();
    assert!(stepped.errors.is_empty(), "the framework's steps failed: {:?}\n{}", stepped.errors, others());
    assert!(stepped.steps > FLAT_OUT_STEPS);
}

/// The framework of `gw.ddf` in namespace `ns` (step timeout 60 s: a step waiting for DDS
/// is back-pressure here, not a failure), and the guard that removes its segments.
fn framework(ns: &str) -> (Framework, RemoveSegments) {
    let guard = RemoveSegments(ns.to_string());
    let opts = FrameworkOptions { namespace: ns.into(), timeout: SECS(60), ..Default::default() };
    (Framework::create(&model(), &opts).expect("framework"), guard)
}

/// A separate gateway reading the synchronous set in lock-step (`--every-step`): a write DDS
/// refuses holds the gateway's answer, and so the framework.
fn a_separate_gateway_in_lock_step_loses_no_step(e: Eng) {
    if python().is_none() {
        return;
    }
    let (dom, ns) = (e.dom_beside(220), e.ns("rel-rustdds-sep"));
    let (fw, _segments) = framework(&ns);
    let gw = e.gateway(DDF, dom, &ns, &["--every-step", "--timeout", "5s"]);
    every_step_arrives(dom, fw, None, &|| gw.dump());
    assert_no_step_lost(&gw, true);
}

/// The gateway in the framework's process (as `tutti host --gateway` runs it): a write DDS
/// refuses holds the framework's own thread.
fn the_gateway_in_the_framework_process_loses_no_step(e: Eng) {
    if python().is_none() {
        return;
    }
    let (dom, ns) = (e.dom_beside(222), e.ns("rel-rustdds-inp"));
    let (fw, _segments) = framework(&ns);
    let ddf = tutti_test_support::repo_root().join(DDF);
    let mut opts = GatewayOptions::new(&ddf, model());
    opts.ros_domain_id = dom;
    opts.engine = e.name.parse::<EngineKind>().unwrap();
    opts.interfaces = vec![std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)];
    opts.timeout = SECS(5);
    let (gw, sink) = tutti_gateway::in_process::start(opts, &ns, SECS(3600), Box::new(|_| {})).expect("gateway");
    let stats = gw.stats();
    every_step_arrives(dom, fw, Some(sink), &|| format!("gateway counters: {}", stats));
    let stats = gw.stop();
    assert_eq!(stats.lost.load(Ordering::Relaxed), 0, "{stats}");
    assert_eq!(stats.errors.load(Ordering::Relaxed), 0, "{stats}");
    assert!(stats.to_dds.load(Ordering::Relaxed) > FLAT_OUT_STEPS, "{stats}");
}

/// The history of the gateway's writer of a synchronous set, as a Cyclone peer (and so
/// rmw_cyclonedds, and `ros2 topic info -v`) sees it. Cyclone announces KEEP_ALL. rustdds
/// sends no HISTORY in its discovery data (its writer does keep all: the table's terms are
/// on the endpoint, checked in `qos.rs`), and a Cyclone peer then shows the DDS default,
/// KEEP_LAST 1 (docs/gateway.md, "QoS").
fn a_synchronous_writers_history_as_a_cyclone_peer_sees_it(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom_beside(224), e.ns("rel-rustdds-qos"));
    let gw = e.gateway(DDF, dom, &ns, &["--all-domains"]);
    // Both engines announce the history (rustdds through its patch: vendor/rustdds).
    let q = announced(&py, &gw, dom, "rt/gw_sync/publish", false);
    assert_eq!(q["reliability"], "Reliable", "{q}");
    assert_eq!((q["history"].as_str(), q["depth"].as_u64()), (Some("KeepAll"), None), "{q}");
    // An asynchronous set's writer keeps the latest value only.
    let q = announced(&py, &gw, dom, "rt/gw_async/publish", false);
    assert_eq!((q["history"].as_str(), q["depth"].as_u64()), (Some("KeepLast"), Some(1)), "{q}");
}

fn a_synchronous_readers_history_as_a_cyclone_peer_sees_it(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom_beside(131), e.ns("rel-rustdds-rqos"));
    let gw = e.gateway(DDF, dom, &ns, &["--all-domains"]);
    let q = announced(&py, &gw, dom, "rt/gw_sync/subscribe", true);
    assert_eq!(q["reliability"], "Reliable", "{q}");
    assert_eq!((q["history"].as_str(), q["depth"].as_u64()), (Some("KeepAll"), None), "{q}");
    let q = announced(&py, &gw, dom, "rt/gw_async/subscribe", true);
    assert_eq!(q["reliability"], "BestEffort", "{q}");
    assert_eq!((q["history"].as_str(), q["depth"].as_u64()), (Some("KeepLast"), Some(1)), "{q}");
}

/// The QoS a Cyclone peer reads in discovery of the gateway `gw`'s writer of `topic`
/// (DCPSPublication), or with `readers` its reader (DCPSSubscription).
fn announced(py: &std::path::Path, gw: &Proc, dom: u16, topic: &str, readers: bool) -> serde_json::Value {
    let mut args = vec!["--topic", topic, "--timeout", "45"];
    if readers {
        args.push("--readers");
    }
    let mut p = peer(py, &format!("qos of {topic}"), dom, "qos", &args);
    assert_eq!(p.wait(SECS(60)), Some(0), "{}\n{}", p.dump(), gw.dump());
    json_lines(&p, "history").remove(0)
}

per_engine!(
    a_separate_gateway_in_lock_step_loses_no_step,
    the_gateway_in_the_framework_process_loses_no_step,
    a_synchronous_writers_history_as_a_cyclone_peer_sees_it,
    a_synchronous_readers_history_as_a_cyclone_peer_sees_it,
);
