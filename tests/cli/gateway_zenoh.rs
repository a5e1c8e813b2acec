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
#[test]
fn a_late_transient_local_subscription_gets_a_state_from_the_cache() {
    let Some(py) = python() else { return };
    let router = ZenohRouter::start();
    let (dom, ns) = (14, namespace("zgwlate_"));
    let _host = Host::start(&ns, "gw_states", Duration::from_millis(20), |k| (k as f64).to_ne_bytes().to_vec());
    let gw = ZENOH.gateway(DDF, dom, &ns, &["--zenoh-connect", router.endpoint()]);
    let topic = ["--topic", "/gw_states/publish"];
    let mut first = peer(&py, "first subscription", &router, dom, "sub", &[&topic[..], &["--count", "5"]].concat());
    assert_eq!(first.wait(secs(90)), Some(0), "{}\n{}", first.dump(), gw.dump());
    let mut late = peer(&py, "late subscription", &router, dom, "late", &[&topic[..], &["--count", "3"]].concat());
    assert_eq!(late.wait(secs(90)), Some(0), "{}\n{}", late.dump(), gw.dump());
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
