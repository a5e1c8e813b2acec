//! The gateway as a citizen of a shared ROS 2 graph, against Cyclone DDS (Python) on both
//! engines: a DDS reader is a passive observer (no participant, never paces a domain), two
//! co-simulations with their own namespaces share a DDS domain without seeing each other, a
//! gateway bridges only the domains a framework hosts, and a DDS writer that leaves a
//! synchronous domain (cleanly, or killed) costs no step timeout. Each test has its own DDS
//! domain and shared-memory namespaces.

use crate::gateway;

use std::thread;
use std::time::Duration;

use gateway::*;
use tutti_core::ddf::Role;
use tutti_test_support::{lazy, wait_until};

/// An asynchronous PUBLISH set whose `x` is `x`.
pub(crate) fn async_publish(x: f64) -> impl Fn(u64) -> Vec<u8> + Send + 'static {
    move |_| {
        let mut b = vec![0u8; 40];
        b[0..8].copy_from_slice(&x.to_ne_bytes());
        b
    }
}

/// A Cyclone reader of `topic` that prints `count` samples.
fn sub(py: &std::path::Path, dom: u16, topic: &str, ty: &str, fields: &str, count: u32) -> Proc {
    let count = count.to_string();
    let args = ["--topic", topic, "--type", ty, "--fields", fields, "--count", &count, "--timeout", "90"];
    peer(py, &format!("sub {topic}"), dom, "sub", &args)
}

/// While a Cyclone reader takes every step of a synchronous domain's PUBLISH topic, the
/// domain has no participant and no connection the framework waits for: the reader is
/// listed as a DDS reader of the gateway's observer connection, in `tutti status` too.
fn a_dds_reader_of_a_synchronous_domain_is_an_observer_not_a_participant(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(120), e.ns("gwcit120"));
    let ns = ns.as_str();
    let host = Host::start(ns, "gw_sync", Duration::from_millis(5), |k| (k as f64).to_ne_bytes().to_vec());
    let gw = e.gateway(DDF, dom, ns, &[]);
    let mut reader = sub(&py, dom, "rt/gw_sync/publish", "gw_msgs::msg::dds_::GwSyncPublish_", SYNC_PUB, 400);
    let (mut looks, mut readers_seen, mut cli_checked) = (0u32, 0u64, false);
    let too_few = lazy(|| format!("the reader got too few samples\n{}\n{}", reader.dump(), gw.dump()));
    wait_until(too_few, SECS(90), || {
        if json_lines(&reader, "step").len() >= 400 {
            return true;
        }
        let s = status_without_participants(ns, "gw_sync");
        readers_seen = readers_seen.max(s.dds_readers);
        looks += 1;
        if s.dds_readers == 1 && !cli_checked {
            // What a user sees: `tutti status --json` lists the DDS reader apart.
            let out = tutti_test_support::tutti_command()
                .args(["status", "--json"])
                .env("TUTTI_NAMESPACE", ns)
                .output()
                .unwrap();
            let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("status --json");
            let d = v.as_array().unwrap().iter().find(|d| d["domain"] == "gw_sync").cloned().unwrap();
            assert_eq!(d["connection_count"], 0, "{d}\n{}", gw.dump());
            assert_eq!(d["dds_readers"], 1, "{d}\n{}", gw.dump());
            cli_checked = true;
        }
        false
    });
    assert_eq!(reader.wait(SECS(30)), Some(0), "{}", reader.dump());
    assert!(looks > 0 && readers_seen == 1, "the observer never showed the DDS reader ({readers_seen})\n{}", gw.dump());
    assert!(cli_checked, "tutti status never showed the DDS reader");
    let steps: Vec<u64> = json_lines(&reader, "step").iter().map(|v| v["step"].as_u64().unwrap()).collect();
    for (v, k) in json_lines(&reader, "step").iter().zip(&steps) {
        assert_eq!(v["x"].as_f64(), Some(*k as f64), "step {k} carries another step's value: {v}");
    }
    assert!(steps.windows(2).all(|w| w[1] > w[0]), "steps out of order: {steps:?}");
    assert_eq!(status(ns, "gw_sync").step_timeouts, 0);
    crate::gateway_reliable::assert_no_step_lost(&gw, false);
    drop(host);
}

/// Co-simulation A (no ROS namespace) and B (`--ros-namespace b`) run the same DDF on one
/// DDS domain: each reader sees its own co-simulation's values, a DDS writer reaches only
/// B, and a third gateway whose namespace hosts no framework bridges nothing and joins
/// neither (A's domains see no DDS endpoint of it).
fn two_co_simulations_with_their_own_namespaces_share_a_dds_domain(e: Eng) {
    let Some(py) = python() else { return };
    let dom = e.dom(121);
    let (ns_a, ns_b, ns_c) = (e.ns("gwcit121a"), e.ns("gwcit121b"), e.ns("gwcit121c"));
    let host_a = Host::start(&ns_a, "gw_async", Duration::from_millis(10), async_publish(1.0));
    let host_b = Host::start(&ns_b, "gw_async", Duration::from_millis(10), async_publish(2.0));
    let gw_a = e.gateway(DDF, dom, &ns_a, &[]);
    let gw_b = e.gateway(DDF, dom, &ns_b, &["--ros-namespace", "b"]);
    let gw_c = e.gateway(DDF, dom, &ns_c, &[]);
    let up = gw_c.wait_line("tutti gateway: up", SECS(1)).unwrap();
    assert!(up.contains("0 of 3 domains bridged"), "{up}");
    assert!(
        gw_c.wait_line("not bridged until a framework hosts them", SECS(10)).is_some_and(|l| l.contains(&ns_c)),
        "{}",
        gw_c.dump()
    );

    let ty = "gw_msgs::msg::dds_::GwAsyncPublish_";
    let mut sub_a = sub(&py, dom, "rt/gw_async/publish", ty, ASYNC_PUB, 5);
    let mut sub_b = sub(&py, dom, "rt/b/gw_async/publish", ty, ASYNC_PUB, 5);
    assert_eq!(sub_a.wait(SECS(90)), Some(0), "{}\n{}", sub_a.dump(), gw_a.dump());
    assert_eq!(sub_b.wait(SECS(90)), Some(0), "{}\n{}", sub_b.dump(), gw_b.dump());
    assert!(json_lines(&sub_a, "x").iter().all(|v| v["x"] == 1.0), "{}", sub_a.dump());
    assert!(json_lines(&sub_b, "x").iter().all(|v| v["x"] == 2.0), "{}", sub_b.dump());

    let values = r#"[{"y": 9.5, "n": 3}, {"y": 9.5, "n": 3}, {"y": 9.5, "n": 3}]"#;
    let args = ["--topic", "rt/b/gw_async/subscribe", "--type", "gw_msgs::msg::dds_::GwAsyncSubscribe_"];
    let mut w = peer(&py, "pub b", dom, "pub", &[&args[..], &["--fields", ASYNC_SUB, "--values", values]].concat());
    let y = leaf_offset("gw_async", Role::Subscribe, "y");
    assert!(host_b.wait_for(SECS(60), |_, b| f64_at(b, y) == 9.5).is_some(), "{}\n{}", w.dump(), gw_b.dump());
    assert_eq!(w.wait(SECS(60)), Some(0), "{}", w.dump());
    assert!(host_a.seen.lock().unwrap().iter().all(|(_, b)| f64_at(b, y) != 9.5), "B's writer reached A");

    // C created no endpoint: A's domains never had a DDS writer, and their only DDS
    // readers were the test's.
    let a = status(&ns_a, "gw_async");
    assert_eq!((a.dds_writers, a.connection_count), (0, 0), "{:?}", a.connections);
    assert!(gw_c.lines().iter().all(|l| !l.contains("joined")), "{}", gw_c.dump());
    assert!(gw_a.lines().iter().all(|l| !l.contains("joined")), "{}", gw_a.dump());
    drop((host_a, host_b));
}

/// A synchronous domain (step timeout 5 s) answered by a Cyclone writer through the
/// gateway; returns the host, the gateway and the writer once it has answered 20 steps.
fn answered_domain(
    e: Eng,
    py: &std::path::Path,
    dom: u16,
    ns: &str,
    count: &str,
    gw_args: &[&str],
) -> (Host, Proc, Proc) {
    let args = [
        "--topic",
        "rt/gw_sync/publish",
        "--type",
        "gw_msgs::msg::dds_::GwSyncPublish_",
        "--fields",
        SYNC_PUB,
        "--reply-topic",
        "rt/gw_sync/subscribe",
        "--reply-type",
        "gw_msgs::msg::dds_::GwSyncSubscribe_",
        "--reply-fields",
        SYNC_SUB,
        "--count",
        count,
        "--timeout",
        "90",
    ];
    let answer = peer(py, "answer", dom, "answer", &args);
    let host = Host::start_opts(DDF, ns, "gw_sync", Duration::from_millis(5), SECS(5), |k| {
        (k as f64 * 10.0).to_ne_bytes().to_vec()
    });
    let gw = e.gateway(DDF, dom, ns, gw_args);
    let answered = |k: u64, b: &[u8]| f64_at(b, 0) == k as f64 * 10.0 + 1.0;
    let first = host.wait_for(SECS(75), answered);
    assert!(first.is_some(), "no step was answered\n{}\n{}", answer.dump(), gw.dump());
    let count = || host.seen.lock().unwrap().iter().filter(|(k, b)| answered(*k, b)).count();
    tutti_test_support::poll_for(SECS(60), || (count() >= 20).then_some(()));
    assert!(count() >= 20, "only {} steps answered\n{}\n{}", count(), answer.dump(), gw.dump());
    (host, gw, answer)
}

/// Waits until the host has made `n` more steps (a watchdog, not a timing).
fn steps_on(host: &Host, n: usize, why: &str) {
    let start = host.seen.lock().unwrap().len();
    wait_until(format!("the domain stopped stepping {why}"), SECS(90), || host.seen.lock().unwrap().len() >= start + n);
}

/// A DDS writer that answers 40 steps and exits cleanly: its connection goes as discovery
/// sees it leave (the lease is set far beyond the step timeout, so only that can help).
fn a_dds_writer_that_exits_cleanly_costs_no_step_timeout(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(122), e.ns("gwcit122"));
    let (host, gw, mut answer) = answered_domain(e, &py, dom, &ns, "40", &["--lease", "60s"]);
    assert_eq!(answer.wait(SECS(60)), Some(0), "{}", answer.dump());
    steps_on(&host, 400, "after the DDS writer left");
    let s = status(&ns, "gw_sync");
    assert_eq!(s.step_timeouts, 0, "{}", gw.dump());
    assert_eq!(s.dds_writers, 0, "{:?}", s.connections);
    assert!(gw.wait_line("left: its connection is released", SECS(1)).is_some(), "{}", gw.dump());
    crate::gateway_reliable::assert_no_step_lost(&gw, false);
    drop(host);
}

/// A DDS writer killed while the domain runs: the step it owes waits at most the lease
/// (1 s) before the gateway lets it go, well inside the 5 s step timeout.
fn a_killed_dds_writer_costs_no_more_than_the_lease(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(123), e.ns("gwcit123"));
    let (host, gw, mut answer) = answered_domain(e, &py, dom, &ns, "1000000", &["--lease", "1s"]);
    answer.kill9();
    steps_on(&host, 400, "after the DDS writer was killed");
    let s = status(&ns, "gw_sync");
    assert_eq!(s.step_timeouts, 0, "{}", gw.dump());
    assert!(
        gw.wait_line("while step", SECS(1)).is_some_and(|l| l.contains("lock-step share is released")),
        "{}",
        gw.dump()
    );
    crate::gateway_reliable::assert_no_step_lost(&gw, false);
    drop(host);
}

/// With `--every-step`, a reader of a synchronous PUBLISH set gets every step: the gateway
/// reads it in lock-step through an observer connection (still not a participant), so the
/// framework, stepping every millisecond with nobody else to wait for, cannot outrun it as
/// it can outrun the passive pump on a loaded machine; and none is lost.
fn with_every_step_a_dds_reader_gets_every_step(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(125), e.ns("gwcit125"));
    let ns = ns.as_str();
    let host = Host::start(ns, "gw_sync", Duration::from_millis(1), |k| (k as f64).to_ne_bytes().to_vec());
    let gw = e.gateway(DDF, dom, ns, &["--every-step"]);
    let mut reader = sub(&py, dom, "rt/gw_sync/publish", "gw_msgs::msg::dds_::GwSyncPublish_", SYNC_PUB, 500);
    let mut observed = false;
    let too_few = lazy(|| format!("too few samples\n{}\n{}", reader.dump(), gw.dump()));
    wait_until(too_few, SECS(90), || {
        if json_lines(&reader, "step").len() >= 500 {
            return true;
        }
        let s = status(ns, "gw_sync");
        assert_eq!(s.connection_count, 0, "{:?}", s.connections);
        observed |= s.connections.iter().any(|c| c.observer && c.sync_reader);
        false
    });
    assert_eq!(reader.wait(SECS(30)), Some(0), "{}", reader.dump());
    assert!(observed, "no lock-step observer connection was seen");
    let steps: Vec<u64> = json_lines(&reader, "step").iter().map(|v| v["step"].as_u64().unwrap()).collect();
    assert!(steps.windows(2).all(|w| w[1] == w[0] + 1), "a step is missing: {steps:?}");
    crate::gateway_reliable::assert_no_step_lost(&gw, true);
    drop(host);
}

/// A config file changes what a Cyclone peer sees: sets not allowed or denied have no topics, a
/// remapped set is read under its new name only, its QoS override is on the wire and its
/// rate limit thins an asynchronous set changing every 5 ms; the stats endpoint counts per
/// topic what went out, in JSON and in the Prometheus text format.
fn a_config_file_changes_what_a_dds_peer_sees_and_the_stats_endpoint_counts_it(e: Eng) {
    let Some(py) = python() else { return };
    let (dom, ns) = (e.dom(124), e.ns("gwcit124"));
    let run = ConfigRun::start(&ns, |cfg| e.gateway(DDF, dom, &ns, &["--config", cfg]));

    let (_peers, got) = the_renamed_set_is_best_effort_and_rate_limited(&py, dom, &run.gw);
    let _kept = the_sets_left_out_have_no_writer_and_an_allowed_one_has(&py, dom);
    the_stats_endpoint_counts_the_renamed_topic(&run.addr, got.len());
}

/// A run of the config-file tests (this one and its Zenoh twin): a framework whose
/// asynchronous PUBLISH set changes every 5 ms (x = the step), and a gateway under the config
/// file of [`write_gateway_config`] with its stats endpoint up.
pub(crate) struct ConfigRun {
    pub gw: Proc,
    /// The stats endpoint's address.
    pub addr: String,
    _host: Host,
    _dir: tempfile::TempDir,
}

impl ConfigRun {
    /// Starts the framework in namespace `ns`, then the gateway, by `gateway(CONFIG_PATH)`.
    pub(crate) fn start(ns: &str, gateway: impl FnOnce(&str) -> Proc) -> ConfigRun {
        let dir = tempfile::tempdir().unwrap();
        let cfg = write_gateway_config(dir.path());
        let host = Host::start(ns, "gw_async", Duration::from_millis(5), |k| {
            let mut b = vec![0u8; 40];
            b[0..8].copy_from_slice(&(k as f64).to_ne_bytes());
            b
        });
        let gw = gateway(cfg.to_str().unwrap());
        let addr = stats_addr(&gw);
        ConfigRun { gw, addr, _host: host, _dir: dir }
    }
}

/// The gateway config file of the test above, written in `dir`: gw_states not allowed,
/// gw_sync's SUBSCRIBE set denied, gw_async's PUBLISH set remapped, best-effort, 4 a second,
/// and the stats endpoint on. Its path.
fn write_gateway_config(dir: &std::path::Path) -> std::path::PathBuf {
    let cfg = dir.join("gateway.json5");
    std::fs::write(
        &cfg,
        r#"{
          // gw_states stays off DDS (not allowed), and so does gw_sync's SUBSCRIBE set (denied);
          // gw_async's PUBLISH set is renamed, best-effort, 4 a second.
          allow: ["gw_async/.*", "gw_sync/.*"],
          deny: ["gw_sync/subscribe"],
          topics: { "gw_async/publish": { remap: "renamed/state", max_rate: 4, qos: { reliability: "best_effort" } } },
          http: "127.0.0.1:0",
        }"#,
    )
    .unwrap();
    cfg
}

/// gw_async's PUBLISH set is read under its new name only, best-effort on the wire, at most
/// 4 a second. Returns the peers (renamed, old name, QoS; they end with the test) and the
/// samples the reader of the new name got.
fn the_renamed_set_is_best_effort_and_rate_limited(
    py: &std::path::Path,
    dom: u16,
    gw: &Proc,
) -> ([Proc; 3], Vec<serde_json::Value>) {
    let ty = "gw_msgs::msg::dds_::GwAsyncPublish_";
    // Readers of the new and the old name, for 4 s each (they stop at their timeout).
    let args = |topic: &'static str| {
        ["--topic", topic, "--type", ty, "--fields", ASYNC_PUB, "--count", "100000", "--timeout", "4"]
    };
    // Best effort: a reliable reader does not match the overridden (best-effort) writer.
    let mut renamed =
        peer(py, "sub renamed", dom, "sub", &[&args("rt/renamed/state")[..], &["--best-effort"]].concat());
    // Best effort too: a reliable reader would not match a (best-effort) writer still there.
    let mut old =
        peer(py, "sub old name", dom, "sub", &[&args("rt/gw_async/publish")[..], &["--best-effort"]].concat());
    let mut wire = peer(py, "qos renamed", dom, "qos", &["--topic", "rt/renamed/state", "--timeout", "45"]);
    assert_eq!(wire.wait(SECS(60)), Some(0), "{}\n{}", wire.dump(), gw.dump());
    assert_eq!(json_lines(&wire, "reliability")[0]["reliability"], "BestEffort");
    renamed.wait(SECS(60));
    old.wait(SECS(60));
    let got = json_lines(&renamed, "x");
    // At most 4 a second in any 4 s window (one more at its edge), where the set changed
    // about 200 times a second: the rate limit, not the machine, sets the count.
    assert!(!got.is_empty() && got.len() <= 17, "{} samples in 4 s\n{}", got.len(), renamed.dump());
    assert!(json_lines(&old, "x").is_empty(), "the old name still carries samples: {}", old.dump());
    ([renamed, old, wire], got)
}

/// gw_states (not allowed) and gw_sync's SUBSCRIBE set (denied) have no DDS writer; gw_sync's
/// PUBLISH set (allowed) has one. Returns the peer that saw it (it ends with the test).
fn the_sets_left_out_have_no_writer_and_an_allowed_one_has(py: &std::path::Path, dom: u16) -> Proc {
    for topic in ["rt/gw_states/publish", "rt/gw_sync/subscribe"] {
        let mut left_out = peer(py, "qos left out", dom, "qos", &["--topic", topic, "--timeout", "3"]);
        assert_eq!(left_out.wait(SECS(30)), Some(3), "a set left out has a DDS writer: {}", left_out.dump());
    }
    let mut kept = peer(py, "qos kept", dom, "qos", &["--topic", "rt/gw_sync/publish", "--timeout", "45"]);
    assert_eq!(kept.wait(SECS(60)), Some(0), "an allowed set has no DDS writer: {}", kept.dump());
    kept
}

/// The stats endpoint at `addr` counts at least the `got` samples the reader got of
/// rt/renamed/state, under its set, nothing of gw_states, in JSON and in Prometheus text.
fn the_stats_endpoint_counts_the_renamed_topic(addr: &str, got: usize) {
    let stats: serde_json::Value = serde_json::from_str(&http_get(addr, "/stats")).unwrap();
    let topic = stats["topics"].as_array().unwrap().iter().find(|t| t["topic"] == "rt/renamed/state").cloned();
    let topic = topic.unwrap_or_else(|| panic!("{stats}"));
    assert_eq!(topic["set"], "gw_async/publish", "{topic}");
    assert!(topic["samples_out"].as_u64().unwrap() >= got as u64, "{topic}");
    assert!(stats["topics"].as_array().unwrap().iter().all(|t| !t["set"].as_str().unwrap().starts_with("gw_states")));
    let metrics = http_get(addr, "/metrics");
    assert!(
        metrics
            .lines()
            .any(|l| l.starts_with("tutti_gateway_samples_out_total{") && l.contains("topic=\"rt/renamed/state\"")),
        "{metrics}"
    );
}

per_engine!(
    a_segment_shrunk_under_the_gateway_leaves_it_running,
    with_every_step_a_dds_reader_gets_every_step,
    a_config_file_changes_what_a_dds_peer_sees_and_the_stats_endpoint_counts_it,
    a_dds_reader_of_a_synchronous_domain_is_an_observer_not_a_participant,
    two_co_simulations_with_their_own_namespaces_share_a_dds_domain,
    a_dds_writer_that_exits_cleanly_costs_no_step_timeout,
    a_killed_dds_writer_costs_no_more_than_the_lease,
);

/// Another process shrinks a bridged domain's segment: the gateway lets go of the domain,
/// says why, and runs on (it used to die of SIGBUS); Ctrl-C still stops it cleanly.
fn a_segment_shrunk_under_the_gateway_leaves_it_running(e: Eng) {
    let (dom, ns) = (e.dom(104), e.ns("gwcit104"));
    let ns = ns.as_str();
    let host = Host::start(ns, "gw_sync", Duration::from_millis(5), |k| (k as f64).to_ne_bytes().to_vec());
    let mut gw = e.gateway(DDF, dom, ns, &[]);
    tutti_test_support::shrink_segment(ns, "gw_sync", 0);
    assert!(gw.wait_line("shrank", SECS(30)).is_some(), "the gateway never said the segment was shrunk\n{}", gw.dump());
    // A window for a late death, not a wait: the gateway's threads look at a bridged domain
    // at every step (5 ms here) or after their longest pause, 200 ms, so 500 ms gives each
    // two looks at the shrunk segment had the gateway not let go of it (a death later still
    // fails the clean stop below).
    thread::sleep(Duration::from_millis(500));
    assert!(gw.exited().is_none(), "the gateway died\n{}", gw.dump());
    assert_eq!(gw.interrupt(SECS(30)), Some(0), "{}", gw.dump());
    assert!(!gw.dump().contains("panicked"), "{}", gw.dump());
    drop(host);
}
