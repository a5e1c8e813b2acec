//! The gateway on its Zenoh engine (`--engine zenoh`), judged by ROS 2 nodes written in
//! rmw_zenoh's wire format with Zenoh's own Python binding (`tests/gateway/zenoh_peer.py`,
//! eclipse-zenoh), through a Zenoh router of the test's own (the `zenoh` crate's, as
//! `rmw_zenohd` runs it): a domain's samples reach an rmw_zenoh subscription with rmw_zenoh's
//! payload and attachment, an rmw_zenoh publisher's samples reach a SUBSCRIBE set, and the
//! simulation services answer an rmw_zenoh client's query.

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use serde_json::Value;
use tutti_core::ddf::Role;
use tutti_engine::rmw_zenoh::{gid_of_key, Entity, EntityKind};
use tutti_ros2::Struct;
use tutti_test_support::{hex, lazy, namespace, unhex, wait_until, Proc, ZenohRouter};

use crate::gateway::{self, f64_at, host_with_gateway_by, json_lines, leaf_offset, Eng, Host, DDF};
use crate::gateway_citizen::{async_publish, ConfigRun};
use crate::gateway_simif::ctl_state;

const ZENOH: Eng = Eng::ZENOH;
const PEER: &str = "tests/gateway/zenoh_peer.py";

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

/// The `.venv` Python with Zenoh's binding.
fn python() -> Option<PathBuf> {
    tutti_test_support::python(&["zenoh"])
}

/// `zenoh_peer.py MODE` on `router`, in ROS domain `dom`.
fn peer(py: &std::path::Path, name: &str, router: &ZenohRouter, dom: u16, mode: &str, args: &[&str]) -> Proc {
    let mut cmd = Command::new(py);
    cmd.arg(PEER).arg(mode).args(["--router", router.endpoint(), "--domain", &dom.to_string()]).args(args);
    cmd.current_dir(tutti_test_support::repo_root());
    Proc::spawn(name, cmd, secs(120))
}

/// The gateway's token `key` read back: the entity, and its GID as rmw_zenoh derives it.
fn entity(key: &str) -> (Entity, [u8; 16]) {
    (Entity::parse(key).unwrap_or_else(|e| panic!("the gateway's token {key}: {e}")), gid_of_key(key))
}

/// Every step of a synchronous domain reaches an rmw_zenoh subscription as rmw_zenoh writes a
/// sample: the CDR encapsulation header then the set, and an attachment whose sequence
/// numbers count up by one and whose GID is the XXH3-128 of the publisher's token key; each
/// sample's `x` is the one the framework wrote at that step.
#[test]
fn a_domain_reaches_an_rmw_zenoh_subscription_in_rmw_zenohs_form() {
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (11, namespace("zgwsub_"));
    let _host = Host::start(&ns, "gw_sync", Duration::from_millis(5), |k| (k as f64).to_ne_bytes().to_vec());
    let gw = ZENOH.gateway(DDF, dom, &ns, &["--zenoh-connect", router.endpoint()]);
    let mut sub =
        peer(&py, "rmw_zenoh subscription", &router, dom, "sub", &["--topic", "/gw_sync/publish", "--count", "50"]);
    assert_eq!(sub.wait(secs(90)), Some(0), "{}\n{}", sub.dump(), gw.dump());

    let token = json_lines(&sub, "token")[0]["token"].as_str().expect("the publisher's token").to_string();
    let (e, gid) = entity(&token);
    match &e.kind {
        EntityKind::Publisher(t) => {
            assert_eq!(t.type_name, "gw_msgs::msg::dds_::GwSyncPublish_");
            assert!(t.type_hash.starts_with("RIHS01_") && t.type_hash != format!("RIHS01_{}", "0".repeat(64)));
        }
        other => panic!("not a publisher's token: {other:?}"),
    }
    assert_eq!((e.node.name.as_str(), e.node.namespace.as_str()), ("tutti_gateway", "/"));
    let samples = json_lines(&sub, "seq");
    assert_eq!(samples.len(), 50, "{}", sub.dump());
    let mut last: Option<(i64, u64)> = None;
    for s in &samples {
        assert_eq!(s["header"], "00010000", "plain CDR, little-endian: {s}");
        assert_eq!(s["gid"].as_str(), Some(hex(&gid).as_str()), "the GID of the publisher's token: {s}");
        let (seq, step) = (s["seq"].as_i64().expect("a sequence number"), s["step"].as_u64().expect("a step"));
        if let Some((seq0, step0)) = last {
            assert_eq!(seq, seq0 + 1, "sequence numbers count up by one: {samples:?}");
            assert!(step > step0, "steps in order: {samples:?}");
        }
        last = Some((seq, step));
        let body = unhex(s["body"].as_str().expect("a body"));
        // step, sim_time, then the set's x.
        assert_eq!(f64_at(&body, 16), step as f64, "the framework's x of step {step}: {s}");
    }
}

/// An rmw_zenoh publisher on a SUBSCRIBE set's topic (its token, then samples with rmw_zenoh's
/// attachment) writes into the set: the framework reads its value. A sample without the
/// attachment, sent before each, is dropped and counted as bad input.
#[test]
fn an_rmw_zenoh_publisher_writes_into_a_subscribe_set() {
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (12, namespace("zgwpub_"));
    let host = Host::start(&ns, "gw_async", Duration::from_millis(10), |_| vec![0; 40]);
    let gw = ZENOH.gateway(DDF, dom, &ns, &["--zenoh-connect", router.endpoint()]);
    // GwAsyncSubscribe: step, sim_time, y = 9.5, n = 3.
    let body = [&0u64.to_le_bytes()[..], &0f64.to_le_bytes(), &9.5f64.to_le_bytes(), &3i32.to_le_bytes()].concat();
    let args = ["--topic", "/gw_async/subscribe", "--body", &hex(&body), "--count", "40", "--bad"];
    let mut w = peer(&py, "rmw_zenoh publisher", &router, dom, "pub", &args);
    let y = leaf_offset("gw_async", Role::Subscribe, "y");
    let seen = host.wait_for(secs(60), |_, b| f64_at(b, y) == 9.5);
    assert!(seen.is_some(), "the framework never read y = 9.5\n{}\n{}", w.dump(), gw.dump());
    assert_eq!(w.wait(secs(60)), Some(0), "{}", w.dump());
    let counted = lazy(|| format!("the gateway counted no sample read\n{}", gw.dump()));
    wait_until(counted, secs(10), || gateway::counter(&gw, "from_dds") > 0);
    let bad = lazy(|| format!("the samples without an attachment were not counted\n{}", gw.dump()));
    wait_until(bad, secs(10), || gateway::counter(&gw, "bad_input") >= 3);
}

/// A TRANSIENT_LOCAL set (`states=yes`) is kept in the publisher's cache as rmw_zenoh keeps
/// it: a subscription that joins late, as rmw_zenoh makes one (an advanced subscriber that
/// queries late publishers' caches), gets a sample written before it subscribed.
///
/// The framework is held (its step blocks) and the gateway seen to have written its last
/// sample before the late subscription is made: while samples keep coming, the advanced
/// subscriber delivers a live sample that overtakes the cache's reply and then drops the
/// older cached one (it delivers each publisher's samples in order), so the cache could not
/// be told from the live stream.
#[test]
fn a_late_transient_local_subscription_gets_a_state_from_the_cache() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (14, namespace("zgwlate_"));
    let (hold, held) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicBool::new(false)));
    let (h, d) = (hold.clone(), held.clone());
    let _host = Host::start(&ns, "gw_states", Duration::from_millis(20), move |k| {
        // Held: the step waits here (at most a minute, so that a failing test still ends).
        let since = std::time::Instant::now();
        while h.load(Ordering::Acquire) && since.elapsed() < secs(60) {
            d.store(true, Ordering::Release);
            std::thread::sleep(Duration::from_millis(5));
        }
        (k as f64).to_ne_bytes().to_vec()
    });
    // Dropped before the host: a held step is let go before the host stops.
    struct Release(Arc<AtomicBool>);
    impl Drop for Release {
        fn drop(&mut self) {
            self.0.store(false, Ordering::Release);
        }
    }
    let _release = Release(hold.clone());
    let gw = ZENOH.gateway(DDF, dom, &ns, &["--zenoh-connect", router.endpoint()]);
    let topic = ["--topic", "/gw_states/publish"];
    let mut first = peer(&py, "first subscription", &router, dom, "sub", &[&topic[..], &["--count", "5"]].concat());
    assert_eq!(first.wait(secs(90)), Some(0), "{}\n{}", first.dump(), gw.dump());

    hold.store(true, Ordering::Release);
    wait_until(lazy(|| "the framework's step was never held".into()), secs(30), || held.load(Ordering::Acquire));
    // The gateway has written the last step once two status lines in a row count the same
    // samples written.
    let written = |gw: &Proc| -> Vec<u64> {
        gw.lines().iter().filter(|l| l.contains(" to_dds=")).map(|l| gateway::counter_in(l, "to_dds")).collect()
    };
    let from = written(&gw).len();
    let quiet = lazy(|| format!("the gateway kept writing\n{}", gw.dump()));
    wait_until(quiet, secs(30), || {
        let w = written(&gw);
        w.len() >= from + 2 && w[w.len() - 1] == w[w.len() - 2]
    });

    let mut late = peer(&py, "late subscription", &router, dom, "late", &[&topic[..], &["--count", "1"]].concat());
    assert_eq!(late.wait(secs(90)), Some(0), "no sample reached the late subscription\n{}\n{}", late.dump(), gw.dump());
    let declared = json_lines(&late, "declared_at")[0]["declared_at"].as_i64().expect("when it subscribed");
    let samples = json_lines(&late, "seq");
    assert!(samples.iter().all(|s| s["header"] == "00010000"), "{samples:?}");
    assert!(
        samples.iter().any(|s| s["ts"].as_i64().is_some_and(|ts| ts < declared)),
        "no sample from before the subscription (the cache): {samples:?}\n{}",
        late.dump()
    );
}

/// `get_simulation_state` asked by an rmw_zenoh client (a query on the service's key, the
/// request after the CDR header, rmw_zenoh's attachment) is answered with the run's state,
/// and the reply's attachment carries the request's sequence number and the client's GID.
#[test]
fn the_simulation_services_answer_an_rmw_zenoh_client() {
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (13, namespace("zgwsrv_"));
    let mut cmd = tutti_test_support::tutti_command();
    cmd.env("ZENOH_CONFIG_OVERRIDE", format!(r#"connect/endpoints=["{}"]"#, router.endpoint()));
    let (host, _segments) = host_with_gateway_by(cmd, ZENOH, DDF, dom, &ns, &[]);
    // GetSimulationState_Request: one uint8 (ROS 2's member of an empty message).
    let args = ["--service", "/get_simulation_state", "--request", "00"];
    let mut c = peer(&py, "rmw_zenoh client", &router, dom, "call", &args);
    assert_eq!(c.wait(secs(90)), Some(0), "{}\n{}", c.dump(), host.dump());
    let r = &json_lines(&c, "reply")[0];
    assert_eq!(r["header"], "00010000", "{r}");
    assert_eq!((r["reply_seq"].as_i64(), r["reply_gid"].as_str()), (r["seq"].as_i64(), r["gid"].as_str()), "{r}");
    let (e, _) = entity(r["token"].as_str().expect("the service's token"));
    assert!(
        matches!(&e.kind, EntityKind::Service(t) if t.type_name == "simulation_interfaces::srv::dds_::GetSimulationState_"),
        "{e:?}"
    );
    let response = tutti_ros2::registry()
        .service("simulation_interfaces/srv/GetSimulationState")
        .expect("the service's interface")
        .response()
        .decode(&unhex(r["reply"].as_str().unwrap()), true)
        .expect("a GetSimulationState response");
    let field = |v: &Value| v.as_u64();
    let result = serde_json::to_value(&response).map(|v| (field(&v["result"]["result"]), field(&v["state"]["state"])));
    assert_eq!(result.ok(), Some((Some(1), Some(1))), "RESULT_OK and STATE_PLAYING: {response:?}");
}

/// A call of service `name` (of interface `srv`) by an rmw_zenoh client: the request `value`
/// encoded by the interface, the response decoded by it, as JSON.
fn call(
    py: &std::path::Path,
    router: &ZenohRouter,
    dom: u16,
    name: &str,
    srv: tutti_ros2::Service<'_>,
    value: tutti_ros2::Value,
) -> Value {
    let body = srv.request().encode(&value).expect("a request");
    let mut c = peer(py, name, router, dom, "call", &["--service", name, "--request", &hex(&body)]);
    assert_eq!(c.wait(secs(90)), Some(0), "{}", c.dump());
    let reply = unhex(json_lines(&c, "reply")[0]["reply"].as_str().expect("a reply"));
    let response = srv.response().decode(&reply, true).unwrap_or_else(|e| panic!("{name}: {e}"));
    serde_json::to_value(&response).expect("JSON")
}

/// The action `simulate_steps` for an rmw_zenoh client, its services as queries: paused by
/// `set_simulation_state`, a goal of 5 steps is accepted, `get_result` (a query the gateway
/// holds until the goal ends) says SUCCEEDED with RESULT_OK, and the run made exactly 5 steps.
#[test]
fn the_simulate_steps_action_runs_for_an_rmw_zenoh_client() {
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (15, namespace("zgwact_"));
    let mut cmd = tutti_test_support::tutti_command();
    cmd.env("ZENOH_CONFIG_OVERRIDE", format!(r#"connect/endpoints=["{}"]"#, router.endpoint()));
    let (host, _segments) = host_with_gateway_by(cmd, ZENOH, DDF, dom, &ns, &[]);
    let reg = tutti_ros2::registry();
    let set_state = reg.service("simulation_interfaces/srv/SetSimulationState").expect("SetSimulationState");
    let paused = Struct::new().with("state", Struct::new().with("state", 2u8)).into();
    let r = call(&py, &router, dom, "/set_simulation_state", set_state, paused);
    assert_eq!(r["result"]["result"], 1, "RESULT_OK: {r}\n{}", host.dump());
    let at = ctl_state(&ns)["step"].as_u64().expect("a step");

    let action = reg.action("simulation_interfaces/action/SimulateSteps").expect("SimulateSteps");
    let goal_id = || Struct::new().with("uuid", (1..=16u8).map(tutti_ros2::Value::from).collect::<Vec<_>>());
    let goal = Struct::new().with("goal_id", goal_id()).with("goal", Struct::new().with("steps", 5u64)).into();
    let r = call(&py, &router, dom, "/simulate_steps/_action/send_goal", action.send_goal(), goal);
    assert_eq!(r["accepted"], true, "{r}\n{}", host.dump());
    let r = call(
        &py,
        &router,
        dom,
        "/simulate_steps/_action/get_result",
        action.get_result(),
        Struct::new().with("goal_id", goal_id()).into(),
    );
    assert_eq!(
        (r["status"].as_u64(), r["result"]["result"]["result"].as_u64()),
        (Some(4), Some(1)),
        "SUCCEEDED, RESULT_OK: {r}"
    );
    assert_eq!(ctl_state(&ns)["step"].as_u64(), Some(at + 5), "exactly 5 steps");
}

/// While an rmw_zenoh subscription takes every step of a synchronous domain's PUBLISH topic,
/// the domain has no participant and no connection the framework waits for: the
/// subscription, known from its token, is counted as a remote reader of the gateway's
/// observer connection (passive, as on DDS), and its steps come in order, each with its own
/// value.
#[test]
fn an_rmw_zenoh_subscription_is_an_observer_not_a_participant() {
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (16, namespace("zgwobs_"));
    let host = Host::start(&ns, "gw_sync", Duration::from_millis(5), |k| (k as f64).to_ne_bytes().to_vec());
    let gw = ZENOH.gateway(DDF, dom, &ns, &["--zenoh-connect", router.endpoint()]);
    let args = ["--topic", "/gw_sync/publish", "--count", "400", "--timeout", "90"];
    let mut reader = peer(&py, "rmw_zenoh subscription", &router, dom, "sub", &args);
    let mut readers_seen = 0;
    let done = lazy(|| format!("the subscription never ended\n{}", gw.dump()));
    wait_until(done, secs(120), || {
        let s = gateway::status_without_participants(&ns, "gw_sync");
        readers_seen = readers_seen.max(s.dds_readers);
        reader.exited().is_some()
    });
    assert_eq!(reader.wait(secs(10)), Some(0), "{}\n{}", reader.dump(), gw.dump());
    assert_eq!(readers_seen, 1, "the subscription was never counted as a remote reader\n{}", gw.dump());
    let samples = json_lines(&reader, "seq");
    let steps: Vec<u64> = samples.iter().map(|s| s["step"].as_u64().expect("a step")).collect();
    for (s, k) in samples.iter().zip(&steps) {
        let body = unhex(s["body"].as_str().expect("a body"));
        assert_eq!(f64_at(&body, 16), *k as f64, "step {k} carries another step's value: {s}");
    }
    assert!(steps.windows(2).all(|w| w[1] > w[0]), "steps out of order: {steps:?}");
    assert_eq!(gateway::status(&ns, "gw_sync").step_timeouts, 0);
    crate::gateway_reliable::assert_no_step_lost(&gw, false);
    drop(host);
}

/// A gateway config file on Zenoh: the sets not allowed or denied have no token and no key,
/// the remapped set is published under its new name only, its QoS override is in its token
/// (best effort, as rmw_zenoh writes it), its rate limit thins a set changing every 5 ms, and
/// the stats endpoint counts what went out, under the set.
#[test]
fn a_config_file_changes_what_an_rmw_zenoh_node_sees_and_the_stats_endpoint_counts_it() {
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (17, namespace("zgwcfg_"));
    let connect = ["--zenoh-connect", router.endpoint()];
    let run = ConfigRun::start(&ns, |cfg| ZENOH.gateway(DDF, dom, &ns, &[&connect[..], &["--config", cfg]].concat()));
    let gw = &run.gw;

    // The graph as an rmw_zenoh node sees it: the gateway's publishers and subscriptions.
    let mut graph = peer(&py, "graph", &router, dom, "graph", &["--count", "2"]);
    assert_eq!(graph.wait(secs(60)), Some(0), "{}\n{}", graph.dump(), gw.dump());
    let entities: Vec<Entity> =
        json_lines(&graph, "token").iter().map(|t| entity(t["token"].as_str().unwrap()).0).collect();
    let topic = |kind: &str, name: &str| {
        entities.iter().find_map(|e| match (&e.kind, kind) {
            (EntityKind::Publisher(t), "MP") | (EntityKind::Subscription(t), "MS") if t.name == name => Some(t.clone()),
            _ => None,
        })
    };
    let renamed =
        topic("MP", "/renamed/state").unwrap_or_else(|| panic!("no publisher of /renamed/state: {entities:#?}"));
    assert_eq!(renamed.qos.reliability, tutti_engine::rmw_zenoh::qos::Reliability::BestEffort, "{renamed:?}");
    assert!(topic("MP", "/gw_sync/publish").is_some(), "an allowed set has no publisher: {entities:#?}");
    for (kind, name) in [("MP", "/gw_async/publish"), ("MP", "/gw_states/publish"), ("MS", "/gw_states/subscribe")] {
        assert!(topic(kind, name).is_none(), "{kind} {name} is left out, yet has a token: {entities:#?}");
    }
    assert!(topic("MS", "/gw_sync/subscribe").is_none(), "a denied set has a subscription: {entities:#?}");

    // Readers of the new and the old name, for 4 s each (they stop at their timeout).
    let args = |t: &'static str| ["--topic", t, "--count", "100000", "--timeout", "4"];
    let mut new_name = peer(&py, "sub renamed", &router, dom, "sub", &args("/renamed/state"));
    let mut old_name = peer(&py, "sub old name", &router, dom, "sub", &args("/gw_async/publish"));
    assert_eq!(new_name.wait(secs(60)), Some(3), "{}", new_name.dump());
    assert_eq!(old_name.wait(secs(60)), Some(3), "{}", old_name.dump());
    let got = json_lines(&new_name, "seq");
    // At most 4 a second in a 4 s window (one more at its edge), where the set changed about
    // 200 times a second: the rate limit, not the machine, sets the count.
    assert!(!got.is_empty() && got.len() <= 17, "{} samples in 4 s\n{}", got.len(), new_name.dump());
    assert!(json_lines(&old_name, "seq").is_empty(), "the old name still carries samples: {}", old_name.dump());

    let stats: Value = serde_json::from_str(&gateway::http_get(&run.addr, "/stats")).unwrap();
    let topics = stats["topics"].as_array().unwrap_or_else(|| panic!("{stats}"));
    let t = topics.iter().find(|t| t["set"] == "gw_async/publish").unwrap_or_else(|| panic!("{stats}"));
    assert!(t["topic"].as_str().is_some_and(|n| n.ends_with("renamed/state")), "{t}");
    assert!(t["samples_out"].as_u64().unwrap() >= got.len() as u64, "{t}");
    assert!(topics.iter().all(|t| !t["set"].as_str().unwrap().starts_with("gw_states")), "{stats}");
}

/// Per-item topics under a ROS namespace on Zenoh: the item `x` of an asynchronous PUBLISH set
/// reaches an rmw_zenoh subscription as `std_msgs/Float64` on `/sim/gw_async/publish/x`, from a
/// publisher whose token names the node's namespace; an rmw_zenoh publisher of
/// `std_msgs/Float64` on `/sim/gw_async/subscribe/y` writes the item `y` of the SUBSCRIBE set.
#[test]
fn per_item_topics_under_a_ros_namespace_go_both_ways() {
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (18, namespace("zgwitem_"));
    let host = Host::start(&ns, "gw_async", Duration::from_millis(10), async_publish(2.5));
    let args = ["--zenoh-connect", router.endpoint(), "--ros2-types", "per-item", "--ros-namespace", "sim"];
    let gw = ZENOH.gateway(DDF, dom, &ns, &args);
    let mut x = peer(&py, "sub x", &router, dom, "sub", &["--topic", "/sim/gw_async/publish/x", "--count", "1"]);
    assert_eq!(x.wait(secs(90)), Some(0), "{}\n{}", x.dump(), gw.dump());
    let (e, _) = entity(json_lines(&x, "token")[0]["token"].as_str().expect("the publisher's token"));
    assert_eq!(e.node.namespace, "/sim", "{e:?}");
    assert!(matches!(&e.kind, EntityKind::Publisher(t) if t.type_name == "std_msgs::msg::dds_::Float64_"), "{e:?}");
    let body = unhex(json_lines(&x, "seq")[0]["body"].as_str().expect("a body"));
    assert_eq!(f64_at(&body, 0), 2.5, "std_msgs/Float64 holds x");

    let y = 9.5f64.to_le_bytes();
    let args = ["--topic", "/sim/gw_async/subscribe/y", "--body", &hex(&y), "--count", "40"];
    let mut w = peer(&py, "pub y", &router, dom, "pub", &args);
    let off = leaf_offset("gw_async", Role::Subscribe, "y");
    let seen = host.wait_for(secs(60), |_, b| f64_at(b, off) == 9.5);
    assert!(seen.is_some(), "the framework never read y = 9.5\n{}\n{}", w.dump(), gw.dump());
    assert_eq!(w.wait(secs(60)), Some(0), "{}", w.dump());
}
