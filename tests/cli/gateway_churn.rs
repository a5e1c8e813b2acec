//! The gateway in a DDS graph that changes under it, on both engines, against Cyclone DDS
//! (Python): twenty participants joining and leaving together, round after round (some of
//! them killed), leave the gateway's routes and counts as they were; a transient-local set
//! written by several writers gives a late reader the last sample of each; and a gateway
//! killed with SIGKILL and started again takes its DDS writer's lock-step share back.
//!
//! DDS domains: 230 (churn, Cyclone), 231 (churn, rustdds), 232 (the other tests, each under
//! a ROS namespace of its own). Ids above 232 do not fit DDS's port mapping.

use crate::gateway;

use std::path::Path;
use std::thread;
use std::time::Duration;

use gateway::*;
use tutti_core::ddf::Role;
use tutti_test_support::{lazy, wait_until};

const CHURN: &str = "tests/gateway/churn_peer.py";

/// The DDS domain of this engine's run of the churn test (the others share 232).
fn churn_domain(e: Eng) -> u16 {
    if e.name == "cyclone" {
        230
    } else {
        231
    }
}

fn ns(e: Eng, tag: &str) -> String {
    tutti_test_support::namespace(&format!("gw-churn-{tag}-{}-", e.name))
}

/// The value of gauge or counter `name` (without labels) on the gateway's `/metrics`.
fn metric(addr: &str, name: &str) -> u64 {
    let text = http_get(addr, "/metrics");
    let v = text.lines().find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.trim().parse::<f64>().ok());
    v.unwrap_or_else(|| panic!("no {name} in\n{text}")) as u64
}

/// What the test counts after each join and each leave: the gateway's DDS writers and
/// readers (`/metrics`) and the domain's (its segment, as `tutti status` reads it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Counts {
    gw_writers: u64,
    gw_readers: u64,
    dds_writers: u32,
    dds_readers: u64,
}

fn counts(addr: &str, ns: &str) -> Counts {
    let s = status(ns, "gw_async");
    Counts {
        gw_writers: metric(addr, "tutti_gateway_remote_writers"),
        gw_readers: metric(addr, "tutti_gateway_remote_readers"),
        dds_writers: s.dds_writers,
        dds_readers: s.dds_readers,
    }
}

/// Waits until the counts are `want` (a watchdog of 30 s, not a timing); panics with what
/// they were.
fn wait_counts(addr: &str, ns: &str, want: Counts, what: &str, dump: &dyn Fn() -> String) {
    let failed = lazy(|| format!("{what}: counts {:?}, expected {want:?}\n{}", counts(addr, ns), dump()));
    wait_until(failed, SECS(30), || counts(addr, ns) == want);
}

/// `churn_peer.py` on DDS domain `dom`, with a watchdog of `watchdog`.
fn churn_peer(py: &Path, dom: u16, name: &str, extra: &[&str], watchdog: Duration) -> Proc {
    let mut cmd = std::process::Command::new(py);
    cmd.arg(CHURN).args(["--domain", &dom.to_string()]);
    cmd.args(["--writer-topic", "rt/gw_async/subscribe", "--writer-type", "gw_msgs::msg::dds_::GwAsyncSubscribe_"]);
    cmd.args(["--writer-fields", ASYNC_SUB, "--reader-topic", "rt/gw_async/publish"]);
    cmd.args(["--reader-type", "gw_msgs::msg::dds_::GwAsyncPublish_", "--reader-fields", ASYNC_PUB]);
    cmd.args(extra);
    Proc::spawn(name, cmd, watchdog)
}

/// Rounds of the churn test (`TUTTI_CHURN_ROUNDS` runs more or fewer); after every
/// `KILL_EVERY`th, `PEERS` more participants join and are killed.
const ROUNDS: u32 = 100;
const KILL_EVERY: u32 = 20;
const PEERS: u64 = 20;

/// Twenty DDS participants (a writer of `gw_async/subscribe` and a reader of
/// `gw_async/publish` each) join and leave together, 100 times; after every 20th round,
/// twenty others join and are killed (SIGKILL, no goodbye): their 2 s lease runs out in the
/// gateway's DDS (on rustdds, its lease checks drop them). After each join the
/// gateway has a connection per writer and counts every reader, on its stats endpoint and
/// in the domain's segment (`tutti status`); after each leave both are back to where they
/// started. Afterwards a new reader and a new writer still exchange samples with the
/// framework through the gateway.
fn twenty_participants_joining_and_leaving_leave_the_routes_as_they_were(e: Eng) {
    let Some(py) = python() else { return };
    let dom = churn_domain(e);
    let ns = ns(e, "churn");
    let ns = ns.as_str();
    let rounds: u32 = std::env::var("TUTTI_CHURN_ROUNDS").ok().and_then(|v| v.parse().ok()).unwrap_or(ROUNDS);
    let host = Host::start(ns, "gw_async", Duration::from_millis(5), |k| {
        let mut b = vec![0u8; 40];
        b[0..8].copy_from_slice(&(k as f64).to_ne_bytes());
        b
    });
    let gw = e.gateway(DDF, dom, ns, &["--http", "127.0.0.1:0"]);
    let addr = stats_addr(&gw);
    let base = Counts { gw_writers: 0, gw_readers: 0, dds_writers: 0, dds_readers: 0 };
    wait_counts(&addr, ns, base, "before the first round", &|| gw.dump());
    let joined = Counts { gw_writers: PEERS, gw_readers: PEERS, dds_writers: PEERS as u32, dds_readers: PEERS };

    let watchdog = SECS(120 + 3 * u64::from(rounds));
    let mut clean = churn_peer(&py, dom, "churn", &["--rounds", &rounds.to_string()], watchdog);
    let mut at = 0usize;
    for r in 1..=rounds {
        let dump = || format!("round {r}\n{}\n{}", clean.dump(), gw.dump());
        assert!(clean.next_line(&mut at, &format!("\"joined\": {r}}}"), SECS(60)).is_some(), "{}", dump());
        wait_counts(&addr, ns, joined, "after the join", &dump);
        clean.signal("USR1");
        assert!(clean.next_line(&mut at, &format!("\"left\": {r}}}"), SECS(60)).is_some(), "{}", dump());
        wait_counts(&addr, ns, base, "after the leave", &dump);
        if r % KILL_EVERY == 0 {
            // Twenty more, while the others are away, that vanish without goodbye: their
            // lease (2 s) runs out in the gateway's DDS.
            let mut killed = churn_peer(&py, dom, "churn killed", &["--hold"], SECS(120));
            let joined_line = killed.wait_line("\"joined\": 1", SECS(60));
            assert!(joined_line.is_some(), "{}", killed.dump());
            wait_counts(&addr, ns, joined, "after the join", &|| format!("{}\n{}", killed.dump(), gw.dump()));
            killed.kill9();
            wait_counts(&addr, ns, base, "after the kill", &|| format!("round {r}\n{}", gw.dump()));
        }
        clean.signal("USR1");
    }
    assert_eq!(clean.wait(SECS(30)), Some(0), "{}", clean.dump());

    // What a user sees in `tutti status --json`, after it all.
    let out = tutti_test_support::tutti_command().args(["status", "--json"]).env("TUTTI_NAMESPACE", ns).output();
    let v: serde_json::Value = serde_json::from_slice(&out.unwrap().stdout).expect("status --json");
    let d = v.as_array().unwrap().iter().find(|d| d["domain"] == "gw_async").cloned().unwrap();
    assert_eq!((d["dds_writers"].as_u64(), d["dds_readers"].as_u64()), (Some(0), Some(0)), "{d}");

    // No route was lost: a new reader gets the framework's set, a new writer reaches it.
    let ty = "gw_msgs::msg::dds_::GwAsyncPublish_";
    let args =
        ["--topic", "rt/gw_async/publish", "--type", ty, "--fields", ASYNC_PUB, "--count", "3", "--timeout", "60"];
    let mut reader = peer(&py, "sub after churn", dom, "sub", &args);
    assert_eq!(reader.wait(SECS(90)), Some(0), "{}\n{}", reader.dump(), gw.dump());
    assert!(json_lines(&reader, "x").iter().all(|v| v["x"].as_f64().is_some_and(|x| x > 0.0)), "{}", reader.dump());
    let values = r#"[{"y": 7.25, "n": 3}, {"y": 7.25, "n": 3}, {"y": 7.25, "n": 3}]"#;
    let args = ["--topic", "rt/gw_async/subscribe", "--type", "gw_msgs::msg::dds_::GwAsyncSubscribe_"];
    let mut w =
        peer(&py, "pub after churn", dom, "pub", &[&args[..], &["--fields", ASYNC_SUB, "--values", values]].concat());
    let y = leaf_offset("gw_async", Role::Subscribe, "y");
    assert!(host.wait_for(SECS(60), |_, b| f64_at(b, y) == 7.25).is_some(), "{}\n{}", w.dump(), gw.dump());
    assert_eq!(w.wait(SECS(60)), Some(0), "{}", w.dump());
    drop(host);
}

/// The Cyclone peer that answers each step of `gw_sync` under ROS namespace `ros_ns` (its
/// writer keeping all its samples until acknowledged, or with `depth` the last `depth`; its
/// reader all it has not taken, or with `read_depth` the last `read_depth`).
fn answer_peer(py: &Path, ros_ns: &str, depth: u32, read_depth: u32) -> Proc {
    let (topic, reply) = (format!("rt/{ros_ns}/gw_sync/publish"), format!("rt/{ros_ns}/gw_sync/subscribe"));
    let (depth, read_depth) = (depth.to_string(), read_depth.to_string());
    let args = [
        "--topic",
        &topic,
        "--type",
        "gw_msgs::msg::dds_::GwSyncPublish_",
        "--fields",
        SYNC_PUB,
        "--reply-topic",
        &reply,
        "--reply-type",
        "gw_msgs::msg::dds_::GwSyncSubscribe_",
        "--reply-fields",
        SYNC_SUB,
        "--count",
        "1000000",
        "--timeout",
        "150",
        "--reply-depth",
        &depth,
        "--read-depth",
        &read_depth,
    ];
    peer(py, "answer", 232, "answer", &args)
}

/// A synchronous domain (step timeout 5 s) under ROS namespace `ros_ns`, answered by a
/// Cyclone peer (`depth`: its writer's and reader's, as [`answer_peer`] takes them) through a gateway started with `gw_args`; returns the host, the gateway and the
/// writer once 20 steps were answered.
fn answered(e: Eng, py: &Path, ns: &str, ros_ns: &str, depth: (u32, u32), gw_args: &[&str]) -> (Host, Proc, Proc) {
    answered_within(e, py, ns, ros_ns, depth, gw_args, SECS(5))
}

/// [`answered`] with a step timeout of `timeout`.
fn answered_within(
    e: Eng,
    py: &Path,
    ns: &str,
    ros_ns: &str,
    depth: (u32, u32),
    gw_args: &[&str],
    timeout: Duration,
) -> (Host, Proc, Proc) {
    let answer = answer_peer(py, ros_ns, depth.0, depth.1);
    let host = Host::start_opts(DDF, ns, "gw_sync", Duration::from_millis(5), timeout, |k| {
        (k as f64 * 10.0).to_ne_bytes().to_vec()
    });
    let gw = e.gateway(DDF, 232, ns, gw_args);
    let first = host.wait_for(SECS(75), is_answer);
    assert!(first.is_some(), "no step was answered\n{}\n{}", answer.dump(), gw.dump());
    answered_more(&host, 0, 20, &|| format!("{}\n{}", answer.dump(), gw.dump()));
    (host, gw, answer)
}

/// Whether step `k`'s SUBSCRIBE set is the DDS writer's answer to it.
fn is_answer(k: u64, b: &[u8]) -> bool {
    f64_at(b, 0) == k as f64 * 10.0 + 1.0
}

/// Waits until `n` steps after step `after` were answered (a watchdog, not a timing).
fn answered_more(host: &Host, after: u64, n: usize, dump: &dyn Fn() -> String) {
    let count = || host.seen.lock().unwrap().iter().filter(|(k, b)| *k > after && is_answer(*k, b)).count();
    wait_until(lazy(|| format!("{} steps after step {after} answered\n{}", count(), dump())), SECS(90), || {
        count() >= n
    });
}

fn last_step(host: &Host) -> u64 {
    host.seen.lock().unwrap().last().map_or(0, |(k, _)| *k)
}

/// A gateway whose DDS writer answers every step of a synchronous domain is killed with
/// SIGKILL: the framework goes on without it (its connections are swept), and a gateway
/// started again on the same DDF gives the same DDS writer a connection again and commits
/// its answers in lock-step, with no step timeout.
///
/// The killed gateway's readers stay matched in the DDS writer's participant until the lease
/// the gateway's participant announced runs out, and a reliable writer keeps for them every
/// sample they never acknowledge. On Cyclone the gateway announces `--lease` (at least 2 s),
/// so a writer that keeps all its samples (KEEP_ALL, whose writes block once its history is
/// full) answers the new gateway within that lease. rustdds 0.15 announces 50 s whatever the
/// gateway asks, so there the writer keeps its last 10 samples (rclpy's default), which
/// a killed reader cannot block; the lease each engine announces is checked as well.
fn a_gateway_restarted_after_kill_9_takes_its_dds_writer_back(e: Eng) {
    let Some(py) = python() else { return };
    let ns = ns(e, "restart");
    let ns = ns.as_str();
    let ros_ns = format!("restart_{}", e.name);
    let gw_args = ["--ros-namespace", ros_ns.as_str(), "--lease", "1s"];
    let (depth, lease) = if e.name == "cyclone" { (0, 2.0) } else { (10, 50.0) };
    let (host, mut gw, mut answer) = answered(e, &py, ns, &ros_ns, (depth, 0), &gw_args);
    let node_ns = format!("/{ros_ns}");
    let args = ["--name", "tutti_gateway", "--node-namespace", &node_ns, "--timeout", "60"];
    let mut announced = peer(&py, "lease", 232, "lease", &args);
    assert_eq!(announced.wait(SECS(90)), Some(0), "{}", announced.dump());
    assert_eq!(json_lines(&announced, "lease_s")[0]["lease_s"].as_f64(), Some(lease), "{}", announced.dump());

    gw.kill9();
    let killed_at = last_step(&host);
    let failed = lazy(|| format!("the framework did not go on without the gateway: {:?}", status(ns, "gw_sync")));
    wait_until(failed, SECS(60), || last_step(&host) >= killed_at + 200 && status(ns, "gw_sync").dds_writers == 0);

    let gw2 = e.gateway(DDF, 232, ns, &gw_args);
    let restarted_at = last_step(&host);
    // 3000 steps: well past the time the DDS writer's history takes to fill with what the
    // killed gateway's reader never acknowledged.
    answered_more(&host, restarted_at, 3000, &|| format!("{}\n{}", answer.dump(), gw2.dump()));
    assert!(answer.exited().is_none(), "the DDS writer failed\n{}", answer.dump());
    let seen = host.seen.lock().unwrap().clone();
    // Lock-step from the first answered step after the gateway's lease (the killed one's
    // readers may hold the writer back until then).
    let first = seen.iter().find(|(k, b)| *k > restarted_at + 1000 && is_answer(*k, b)).map_or(0, |(k, _)| *k);
    assert_lock_step(&seen, first, is_answer);
    let s = status(ns, "gw_sync");
    assert_eq!(s.step_timeouts, 0, "{}", gw2.dump());
    let remote: Vec<_> = s.connections.iter().filter(|c| c.remote).collect();
    assert!(remote.len() == 1 && remote[0].pid == gw2.id(), "{:?}\n{}", s.connections, gw2.dump());
    drop(host);
}

/// The other way round: the DDS peer that answers every step of a synchronous domain (a
/// reliable writer keeping its last sample, a reader its last 8) is killed with SIGKILL and
/// started again at once. The framework goes on once the gateway's `--lease` has released the
/// killed writer's share of the step. The killed peer's reader, which never leaves, holds the
/// gateway's RELIABLE, KEEP_ALL writer back until DDS drops it at its participant's lease
/// (Cyclone's default, 10 s: docs/gateway.md, "Nothing lost on a synchronous set"); the
/// steps refused meanwhile are reported as lost, naming the topic. From then on the restarted
/// peer's writer has a connection and the run is in lock-step with it again.
fn a_dds_peer_killed_and_started_again_answers_every_step_again(e: Eng) {
    let Some(py) = python() else { return };
    let (ns, host, gw, _again) = peer_killed_and_started_again(e, &py, "peerkill", &[], SECS(5));
    let s = status(&ns, "gw_sync");
    assert_eq!(s.connections.iter().filter(|c| c.remote).count(), 1, "{}", gw.dump());
    drop(host);
}

/// As above, with the run told to wait rather than go on without the killed reader: the
/// gateway holds the framework until each step is written (`--every-step`), and both its
/// `--timeout` and the framework's step timeout are above the killed peer's lease (10 s). The
/// run waits at the step the killed reader holds back, and goes on in lock-step with the
/// restarted peer once DDS drops the killed one: no step lost, skipped or timed out.
fn a_dds_peer_killed_and_started_again_with_the_run_waiting_loses_no_step(e: Eng) {
    let Some(py) = python() else { return };
    let waits = ["--every-step", "--timeout", "30s"];
    let (ns, host, gw, _again) = peer_killed_and_started_again(e, &py, "peerwait", &waits, SECS(40));
    assert_eq!(status(&ns, "gw_sync").step_timeouts, 0, "{}", gw.dump());
    crate::gateway_reliable::assert_no_step_lost(&gw, true);
    drop(host);
}

/// The run of the two tests above: a synchronous domain (step timeout `timeout`) answered by
/// a Cyclone peer (a writer keeping its last sample, a reader its last 8) through a gateway
/// with `--lease 1s` and `gw_args`; the peer killed with SIGKILL and started again at once.
/// Once DDS drops the killed peer (the gateway logs that its writer left), every step from
/// the restarted peer's first answer on is answered in lock-step (500 of them). Returns the
/// namespace, the framework, the gateway and the restarted peer.
fn peer_killed_and_started_again(
    e: Eng,
    py: &Path,
    tag: &str,
    gw_args: &[&str],
    timeout: Duration,
) -> (String, Host, Proc, Proc) {
    let ns = ns(e, tag);
    let ros_ns = format!("{tag}_{}", e.name);
    let gw_args = [&["--ros-namespace", ros_ns.as_str(), "--lease", "1s"], gw_args].concat();
    let (host, gw, mut answer) = answered_within(e, py, &ns, &ros_ns, (1, 8), &gw_args, timeout);
    answer.kill9();
    let again = answer_peer(py, &ros_ns, 1, 8);
    let dump = || format!("{:?}\n{}\n{}", status(&ns, "gw_sync"), again.dump(), gw.dump());
    // DDS drops the killed peer (its lease ran out): its writer leaves, and its reader with it.
    let left = gw.wait_line(" left: its connection is released", SECS(60));
    assert!(left.is_some(), "DDS never dropped the killed peer\n{}", dump());
    let dropped_at = last_step(&host);
    answered_more(&host, dropped_at, 500, &dump);
    let seen = host.seen.lock().unwrap().clone();
    let first = seen.iter().find(|(k, b)| *k > dropped_at && is_answer(*k, b)).map_or(0, |(k, _)| *k);
    let after: Vec<_> = seen.iter().filter(|(k, _)| *k > first).collect();
    let missed: Vec<u64> = after.iter().filter(|(k, b)| !is_answer(*k, b)).map(|(k, _)| *k).collect();
    assert!(
        missed.is_empty(),
        "{} of {} steps from step {first} not answered in lock-step: {:?}\n{}",
        missed.len(),
        after.len(),
        &missed[..missed.len().min(20)],
        dump()
    );
    (ns, host, gw, again)
}

/// A Cyclone writer of `topic` that writes `values` (transient-local, keep last 1) and
/// stays until killed, so that late readers get its last sample from it.
fn latched_writer(py: &Path, topic: &str, values: &str) -> Proc {
    let args = ["--topic", topic, "--type", "gw_msgs::msg::dds_::GwStatesSubscribe_", "--fields", STATES_SUB];
    let rest = ["--values", values, "--period-ms", "5", "--transient-local", "--linger", "150"];
    let w = peer(py, &format!("latched {values}"), 232, "pub", &[&args[..], &rest].concat());
    assert!(w.wait_line("\"wrote\"", SECS(60)).is_some(), "{}", w.dump());
    w
}

/// A late transient-local reader of `topic`: the samples it got within 5 s (nothing is
/// written meanwhile).
fn late_reader(py: &Path, topic: &str, ty: &str) -> Vec<serde_json::Value> {
    let args = ["--topic", topic, "--type", ty, "--fields", STATES_SUB, "--count", "100", "--timeout", "5"];
    let mut r = peer(py, "late reader", 232, "sub", &[&args[..], &["--transient-local"]].concat());
    assert_eq!(r.wait(SECS(60)), Some(3), "{}", r.dump());
    json_lines(&r, "y")
}

/// `gw_states` (asynchronous, `states=yes`, `multiplePublishAllowed=yes`) keeps its last
/// state for late joiners: on `gw_states/subscribe` three DDS writers (transient-local, each
/// writing three values) and a shared-memory component (committing three values, which the
/// gateway's transient-local writer sends) are four writers; a transient-local reader that
/// joins afterwards gets exactly one sample from each, its last, and the DDS writers'
/// values are not sent again by the gateway.
fn a_late_reader_of_a_transient_local_set_gets_the_last_sample_of_each_writer(e: Eng) {
    let Some(py) = python() else { return };
    let ns = ns(e, "latched");
    let ns = ns.as_str();
    let ros_ns = format!("latched_{}", e.name);
    let sub_topic = format!("rt/{ros_ns}/gw_states/subscribe");
    let host = Host::start(ns, "gw_states", Duration::from_millis(5), |_| 4.5f64.to_ne_bytes().to_vec());
    let gw = e.gateway(DDF, 232, ns, &["--ros-namespace", &ros_ns]);
    let y = leaf_offset("gw_states", Role::Subscribe, "y");
    let mut writers = Vec::new();
    for w in 1..=3 {
        let v = |i: u32| f64::from(w * 100 + i);
        let values = format!(r#"[{{"y": {}}}, {{"y": {}}}, {{"y": {}}}]"#, v(1), v(2), v(3));
        writers.push(latched_writer(&py, &sub_topic, &values));
        let last = v(3);
        let dump = || format!("{}\n{}", writers.last().unwrap().dump(), gw.dump());
        assert!(host.wait_for(SECS(60), |_, b| f64_at(b, y) == last).is_some(), "{}", dump());
    }
    let mut component = connect(ns, "gw_states");
    for v in [7.0f64, 8.0, 9.0] {
        component.staging_mut()[y..y + 8].copy_from_slice(&v.to_ne_bytes());
        component.commit().expect("commit");
        thread::sleep(Duration::from_millis(50));
    }
    // The gateway has sent the component's last value once a reader got it.
    let got = late_reader(&py, &sub_topic, "gw_msgs::msg::dds_::GwStatesSubscribe_");
    let mut ys: Vec<f64> = got.iter().filter_map(|v| v["y"].as_f64()).collect();
    ys.sort_by(f64::total_cmp);
    assert_eq!(ys, [9.0, 103.0, 203.0, 303.0], "{got:?}\n{}", gw.dump());

    drop(writers);
    drop(host);
}

per_engine!(
    twenty_participants_joining_and_leaving_leave_the_routes_as_they_were,
    a_late_reader_of_a_transient_local_set_gets_the_last_sample_of_each_writer,
    a_gateway_restarted_after_kill_9_takes_its_dds_writer_back,
    a_dds_peer_killed_and_started_again_answers_every_step_again,
    a_dds_peer_killed_and_started_again_with_the_run_waiting_loses_no_step,
);
