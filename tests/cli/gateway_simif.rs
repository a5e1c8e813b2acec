//! ROS 2 `simulation_interfaces` services on the gateway (docs/ros2.md), driven in both wire
//! forms, one suite over three ways of reaching them ([`Way`]): the Cyclone peer
//! (`dds_peer.py service` and `action`, rmw_cyclonedds's request and reply layout, each request
//! checked byte for byte against it) against the gateway in the framework's process on either
//! engine, and ros2-client's own `Client` and `ActionClient` in Fast DDS's form
//! (`ServiceMapping::Enhanced`, [`crate::simif_client`]) against `tutti gateway --dds rustdds`
//! beside a framework. Each checks every service with a synchronous domain (the exact steps,
//! the refusals and repeated transitions) and with asynchronous domains only (stepping
//! refused, with the reason), the action `simulate_steps` (feedback after each step, cancel,
//! the refusals), and that a passive gateway and a mirror offer none. Each run has its own namespace
//! and DDS domain (40-44 Cyclone, 90-94 rustdds, 45-49 Fast DDS's form); a Fast DDS client in rmw_fastrtps's
//! manner (`fastdds_requester.cpp`) is answered on the rustdds engine (50).

use crate::gateway;
use crate::simif_client;

use std::path::PathBuf;
use std::time::Duration;

use gateway::*;
use serde_json::Value;
use tutti_test_support::{lazy, namespace, wait_until, Output, RemoveSegments};

/// The wire form of a test's client.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// rmw_cyclonedds's: the Cyclone peer, in the framework's process.
    Cyclone,
    /// Fast DDS's: ros2-client's clients, against a gateway beside the framework.
    Enhanced,
}

/// One way of reaching the services: the gateway's engine, the client's wire form, and the
/// DDS domains of its runs (the test's base number plus `offset`).
#[derive(Debug, Clone, Copy)]
pub struct Way {
    eng: Eng,
    form: Form,
    offset: u16,
}

impl Way {
    pub const CYCLONE: Way = Way { eng: Eng::CYCLONE, form: Form::Cyclone, offset: 0 };
    pub const RUSTDDS: Way = Way { eng: Eng::RUSTDDS, form: Form::Cyclone, offset: 50 };
    pub const ENHANCED: Way = Way { eng: Eng::RUSTDDS, form: Form::Enhanced, offset: 5 };

    /// The test numbered `base`'s client and run names, None when its client is missing
    /// (skipped; a failure under CI=true).
    fn client(self, base: u16) -> Option<Caller> {
        let dom = base + self.offset;
        let py = match self.form {
            Form::Cyclone => Some(python()?),
            Form::Enhanced => None,
        };
        Some(Caller { way: self, py, dom, ns: namespace(&format!("simif{dom}_")), server: Default::default() })
    }
}

/// Turns each named `fn NAME(w: Way)` into three tests, `NAME::cyclone`, `NAME::rustdds` and
/// `NAME::rustdds_enhanced`.
macro_rules! per_way {
    ($($name:ident),* $(,)?) => {$(
        mod $name {
            #[test]
            fn cyclone() {
                super::$name(super::Way::CYCLONE)
            }
            #[test]
            fn rustdds() {
                super::$name(super::Way::RUSTDDS)
            }
            #[test]
            fn rustdds_enhanced() {
                super::$name(super::Way::ENHANCED)
            }
        }
    )*};
}

/// A test's client, its DDS domain and namespace.
struct Caller {
    way: Way,
    /// The Cyclone peer's Python (rmw_cyclonedds's form).
    py: Option<PathBuf>,
    dom: u16,
    ns: String,
    /// What the gateway of the run started last prints (the framework's, with the gateway in
    /// it), shown when a call fails.
    server: std::cell::RefCell<Vec<Output>>,
}

/// A run: the framework, the gateway beside it (Fast DDS's form) and its segments.
struct Run {
    host: Proc,
    _gateway: Option<Proc>,
    _segments: RemoveSegments,
}

impl Caller {
    /// A run of `ddf`: `tutti host --gateway` (rmw_cyclonedds's form), or `tutti host` and
    /// `tutti gateway --dds rustdds` beside it (Fast DDS's form).
    fn start(&self, ddf: &str) -> Run {
        if self.way.form == Form::Cyclone {
            let (host, segments) = host_with_gateway(self.way.eng, ddf, self.dom, &self.ns, &[]);
            *self.server.borrow_mut() = vec![host.output()];
            return Run { host, _gateway: None, _segments: segments };
        }
        let segments = RemoveSegments(self.ns.clone());
        let mut cmd = tutti_test_support::tutti_command();
        cmd.args(["host", ddf, "--step", "5ms", "-q"]).env("TUTTI_NAMESPACE", &self.ns);
        let host = Proc::spawn(&format!("host {}", self.ns), cmd, SECS(180));
        let socket = tutti_host::control::socket_path(&self.ns);
        wait_until(lazy(|| format!("no control socket\n{}", host.dump())), SECS(30), || socket.exists());
        let gw = self.way.eng.gateway(ddf, self.dom, &self.ns, &[]);
        *self.server.borrow_mut() = vec![host.output(), gw.output()];
        Run { host, _gateway: Some(gw), _segments: segments }
    }

    /// Makes `calls` (JSON: `[["NAME", ARG], ...]`); each call's response.
    fn calls(&self, calls: &str) -> Vec<Value> {
        match &self.py {
            Some(py) => {
                let mut p = peer(py, "simulation client", self.dom, "service", &["--calls", calls, "--timeout", "60"]);
                assert_eq!(p.wait(SECS(100)), Some(0), "the client failed\n{}\n{}", p.dump(), self.server());
                json_lines(&p, "call")
            }
            None => simif_client::calls(self.dom, calls)
                .unwrap_or_else(|e| panic!("the ros2-client client: {e}\n{}", self.server())),
        }
    }

    /// Whether the client finds the services within a few seconds.
    fn finds_services(&self) -> bool {
        match &self.py {
            Some(py) => {
                let args = ["--calls", r#"[["get_simulation_state"]]"#, "--timeout", "5"];
                let mut p = peer(py, "simulation client", self.dom, "service", &args);
                match p.wait(SECS(60)) {
                    Some(0) => true,
                    Some(3) if p.stdout().contains("no service") => false,
                    other => panic!("the client ended with {other:?}\n{}", p.dump()),
                }
            }
            None => simif_client::finds_services(self.dom, SECS(5))
                .unwrap_or_else(|e| panic!("the ros2-client client: {e}")),
        }
    }

    /// A goal of `steps` steps of the action, canceled after `cancel_after` feedback samples
    /// (0: never): the client's output lines.
    fn simulate_steps(&self, steps: u64, cancel_after: u64) -> Vec<Value> {
        match &self.py {
            Some(py) => {
                let (steps, cancel) = (steps.to_string(), cancel_after.to_string());
                let args = ["--steps", steps.as_str(), "--cancel-after", cancel.as_str(), "--timeout", "60"];
                let mut p = peer(py, "action client", self.dom, "action", &args);
                assert_eq!(p.wait(SECS(100)), Some(0), "the action client failed\n{}\n{}", p.dump(), self.server());
                p.lines().iter().filter_map(|l| serde_json::from_str::<Value>(l).ok()).collect()
            }
            None => simif_client::simulate_steps(self.dom, steps, cancel_after)
                .unwrap_or_else(|e| panic!("the ros2-client action client: {e}\n{}", self.server())),
        }
    }

    /// What the run's framework and gateway printed so far.
    fn server(&self) -> String {
        self.server.borrow().iter().map(Output::dump).collect::<Vec<_>>().join("\n")
    }
}

/// `tutti ctl state --json` in namespace `ns`.
pub(crate) fn ctl_state(ns: &str) -> Value {
    let mut cmd = tutti_test_support::tutti_command();
    cmd.args(["ctl", "state", "--json"]).env("TUTTI_NAMESPACE", ns);
    let (status, out, err) = tutti_test_support::run_with_timeout(cmd, Duration::from_secs(60));
    assert!(status.success(), "tutti ctl state: {err}");
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("tutti ctl state: {e}: {out}"))
}

/// A response's (result code, error message).
fn result(v: &Value) -> (u64, String) {
    let r = &v["result"];
    (r["result"].as_u64().unwrap_or(999), r["error_message"].as_str().unwrap_or("").to_string())
}

// The constants of simulation_interfaces (`SimulationState`, `Result`) and action_msgs
// (`GoalStatus`) the tests compare with; `tests/cli/ros2_real.rs` uses them too.
const STATE_STOPPED: u64 = 0;
const STATE_PLAYING: u64 = 1;
const STATE_PAUSED: u64 = 2;
pub(crate) const OK: u64 = 1;
pub(crate) const FEATURE_UNSUPPORTED: u64 = 0;
pub(crate) const INCORRECT_STATE: u64 = 4;
pub(crate) const ALREADY_IN_TARGET_STATE: u64 = 101;
const INCORRECT_TRANSITION: u64 = 103;

fn the_simulation_services_drive_the_run_and_refuse_with_the_standard_codes(w: Way) {
    let Some(c) = w.client(40) else { return };
    let ns = c.ns.as_str();
    let mut run = c.start(DDF);

    let r = c.calls(r#"[["get_simulator_features"], ["get_simulation_state"], ["set_simulation_state", 2]]"#);
    assert_eq!(r.len(), 3, "{r:?}");
    let features: Vec<u64> =
        r[0]["features"]["features"].as_array().expect("features").iter().filter_map(Value::as_u64).collect();
    for f in [20, 21, 24, 25, 26, 31, 32] {
        assert!(features.contains(&f), "feature {f} missing: {features:?}");
    }
    // A run without components has its checkpoint of step 0: SCOPE_STATE goes back to it.
    assert!(features.contains(&22) && !features.contains(&23), "tutti resets state, spawns nothing: {features:?}");
    assert_eq!(r[1]["state"]["state"].as_u64(), Some(STATE_PLAYING), "{:?}", r[1]);
    assert_eq!(result(&r[1]).0, OK);
    assert_eq!(result(&r[2]).0, OK, "{:?}", r[2]);
    let paused = ctl_state(ns);
    assert_eq!(paused["state"], "paused");
    let at = paused["step"].as_u64().expect("a step");

    let r = c.calls(r#"[["step_simulation", 3], ["get_simulation_state"], ["set_simulation_state", 2]]"#);
    assert_eq!(result(&r[0]).0, OK, "{:?}", r[0]);
    let after = ctl_state(ns);
    assert_eq!((after["state"].as_str(), after["step"].as_u64()), (Some("paused"), Some(at + 3)), "exactly 3 steps");
    assert_eq!(r[1]["state"]["state"].as_u64(), Some(STATE_PAUSED));
    assert_eq!(result(&r[2]), (ALREADY_IN_TARGET_STATE, "already paused".to_string()));

    let r = c.calls(
        r#"[["set_simulation_state", 1], ["set_simulation_state", 1], ["step_simulation", 2],
            ["reset_simulation", 1], ["reset_simulation", 0], ["reset_simulation", 2], ["reset_simulation", 255],
            ["set_simulation_state", 0], ["get_simulation_state"], ["set_simulation_state", 2],
            ["set_simulation_state", 4], ["set_simulation_state", 1], ["get_simulation_state"]]"#,
    );
    assert_eq!(r.len(), 13, "{r:?}");
    assert_eq!(result(&r[0]).0, OK);
    assert_eq!(result(&r[1]), (ALREADY_IN_TARGET_STATE, "already playing".to_string()));
    let (code, why) = result(&r[2]);
    assert!(
        code == INCORRECT_STATE && why.contains("playing") && why.contains("paused"),
        "stepping a playing run: {code} {why}"
    );
    assert_eq!(result(&r[3]).0, OK, "SCOPE_TIME: {:?}", r[3]);
    assert_eq!(result(&r[4]).0, OK, "SCOPE_DEFAULT: {:?}", r[4]);
    assert_eq!(result(&r[5]).0, OK, "SCOPE_STATE: {:?}", r[5]);
    assert_eq!(result(&r[6]).0, OK, "SCOPE_ALL: {:?}", r[6]);
    assert_eq!(result(&r[7]).0, OK, "STOPPED: {:?}", r[7]);
    assert_eq!(r[8]["state"]["state"].as_u64(), Some(STATE_STOPPED));
    let (code, why) = result(&r[9]);
    assert!(code == INCORRECT_TRANSITION && why.contains("stopped"), "pausing a stopped run: {code} {why}");
    assert_eq!(result(&r[10]).0, FEATURE_UNSUPPORTED, "NO_WORLD: {:?}", r[10]);
    assert_eq!(result(&r[11]).0, OK);
    assert_eq!(r[12]["state"]["state"].as_u64(), Some(STATE_PLAYING));
    assert_eq!(ctl_state(ns)["state"], "playing");

    // QUITTING ends the run.
    let r = c.calls(r#"[["set_simulation_state", 3]]"#);
    assert_eq!(result(&r[0]).0, OK, "{:?}", r[0]);
    assert!(run.host.wait(SECS(60)).is_some(), "the run did not end\n{}", run.host.dump());
}

fn stepping_a_run_of_asynchronous_domains_is_refused_with_the_reason(w: Way) {
    let Some(c) = w.client(41) else { return };
    let _run = c.start("tests/gateway/async-only.ddf");
    let r = c.calls(
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
    assert_eq!(ctl_state(&c.ns)["state"], "playing");
}

fn a_passive_gateway_offers_no_simulation_services(w: Way) {
    let Some(c) = w.client(42) else { return };
    let _segments = RemoveSegments(c.ns.clone());
    let _host = Host::start(&c.ns, "gw_sync", Duration::from_millis(10), |_| vec![0; 8]);
    let gw = w.eng.gateway(DDF, c.dom, &c.ns, &["--passive"]);
    assert!(!c.finds_services(), "a passive gateway offers the services\n{}", gw.dump());
    drop(gw);
    // Nor does a mirror: the framework it would control is its own, fed from DDS.
    let away = format!("{}m", c.ns);
    let _away_segments = RemoveSegments(away.clone());
    let mirror = w.eng.gateway(DDF, c.dom, &away, &["--mirror"]);
    assert!(!c.finds_services(), "a mirror offers the services\n{}", mirror.dump());
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

pub(crate) const SUCCEEDED: u64 = 4;
pub(crate) const CANCELED: u64 = 5;
pub(crate) const ABORTED: u64 = 6;

fn the_simulate_steps_action_gives_feedback_after_each_step_and_cancels(w: Way) {
    let Some(c) = w.client(43) else { return };
    let ns = c.ns.as_str();
    let _run = c.start(DDF);

    // Playing: the goal is accepted and aborted with the call's result.
    let lines = c.simulate_steps(3, 0);
    assert_eq!(line(&lines, "accepted")["accepted"], true);
    let end = line(&lines, "status");
    assert_eq!((end["status"].as_u64(), end["result"]["result"].as_u64()), (Some(ABORTED), Some(4)), "{end}");
    assert!(end["result"]["error_message"].as_str().unwrap_or("").contains("playing"), "{end}");
    assert!(feedback(&lines).is_empty());

    let r = c.calls(r#"[["get_simulator_features"], ["set_simulation_state", 2]]"#);
    let features = &r[0]["features"]["features"];
    assert!(features.as_array().is_some_and(|f| f.contains(&Value::from(33))), "STEP_SIMULATION_ACTION: {features}");
    let at = ctl_state(ns)["step"].as_u64().expect("a step");

    let lines = c.simulate_steps(4, 0);
    assert_eq!(feedback(&lines), vec![(1, 3), (2, 2), (3, 1), (4, 0)], "feedback after each step");
    let end = line(&lines, "status");
    assert_eq!((end["status"].as_u64(), end["result"]["result"].as_u64()), (Some(SUCCEEDED), Some(OK)), "{end}");
    assert_eq!(end["last_status"].as_u64(), Some(SUCCEEDED), "the status topic: {end}");
    assert_eq!(ctl_state(ns)["step"].as_u64(), Some(at + 4), "exactly 4 steps");

    // Canceled after the second feedback: the goal ends between two steps, well before its 100000.
    let at = at + 4;
    let lines = c.simulate_steps(100_000, 2);
    let cancel = line(&lines, "cancel");
    let canceling = (cancel["cancel"].as_u64(), cancel["canceling"].as_u64());
    assert_eq!(canceling, (Some(0), Some(1)), "ERROR_NONE, one goal: {cancel}");
    let end = line(&lines, "status");
    assert_eq!(end["status"].as_u64(), Some(CANCELED), "{end}");
    assert_eq!(end["last_status"].as_u64(), Some(CANCELED), "{end}");
    let made = ctl_state(ns)["step"].as_u64().expect("a step") - at;
    let fb = feedback(&lines);
    assert!((2..100_000).contains(&made), "{made} steps");
    assert_eq!(fb.last().map(|f| f.0), Some(made), "the last feedback is the last step made: {fb:?}");
    assert!(fb.iter().enumerate().all(|(i, f)| *f == (i as u64 + 1, 100_000 - i as u64 - 1)), "{fb:?}");
    let why = end["result"]["error_message"].as_str().unwrap_or("");
    assert_eq!(why, format!("canceled after {made} of 100000 steps"));
}

fn the_action_refuses_to_step_a_run_of_asynchronous_domains(w: Way) {
    let Some(c) = w.client(44) else { return };
    let _run = c.start("tests/gateway/async-only.ddf");
    let r = c.calls(r#"[["set_simulation_state", 2]]"#);
    assert_eq!(result(&r[0]).0, OK);
    let lines = c.simulate_steps(2, 0);
    let end = line(&lines, "status");
    assert_eq!((end["status"].as_u64(), end["result"]["result"].as_u64()), (Some(ABORTED), Some(FEATURE_UNSUPPORTED)));
    assert!(end["result"]["error_message"].as_str().unwrap_or("").contains("asynchronous (simif_async)"), "{end}");
    assert!(feedback(&lines).is_empty());
}

per_way!(
    the_simulation_services_drive_the_run_and_refuse_with_the_standard_codes,
    stepping_a_run_of_asynchronous_domains_is_refused_with_the_reason,
    a_passive_gateway_offers_no_simulation_services,
    the_simulate_steps_action_gives_feedback_after_each_step_and_cancels,
    the_action_refuses_to_step_a_run_of_asynchronous_domains,
);

/// How much of the UDP traffic the lossy network drops, in percent.
const LOSS: u8 = 20;
/// How many clients call through it, one after the other.
const LOSSY_CLIENTS: usize = 8;

/// A reply reaches a client that is still waiting, however the network treats the first
/// datagrams between the two: the framework with its gateway and the rmw_cyclonedds-form
/// client run in a network namespace of the test's own whose loopback drops [`LOSS`] % of the
/// UDP datagrams (nftables), and each of [`LOSSY_CLIENTS`] clients, one after the other, calls
/// four services once each (a new reply reader for each, matched only just before the call:
/// where a Cyclone DDS reader that has not yet seen a heartbeat of the gateway's reply writer
/// would skip a reply lost on the way). Every call is answered, with what it asked for. The
/// clients announce themselves every second (`--announce-every 1`): under Cyclone's defaults a
/// client's discovery of the gateway rests on two datagrams (docs/ros2.md, "Services").
fn services_are_answered_through_a_lossy_network(e: Eng) {
    let Some(py) = python() else { return };
    let why = "network namespaces with nftables (root, `ip` of iproute2, `nft` of nftables)";
    let Some(net) = tutti_test_support::require(why, LossyNetns::create(&format!("loss{}", e.name), LOSS)) else {
        return;
    };
    let dom = e.dom(46);
    let ns = namespace(&format!("simifloss{dom}_"));
    let (host, _segments) =
        host_with_gateway_by(net.command(tutti_test_support::tutti_exe().as_ref()), e, DDF, dom, &ns, &[]);
    let calls = r#"[["get_simulator_features"], ["get_simulation_state"], ["set_simulation_state", 2],
                    ["step_simulation", 1], ["set_simulation_state", 1]]"#;
    for client in 1..=LOSSY_CLIENTS {
        let name = format!("simulation client {client} of {LOSSY_CLIENTS}");
        let args = ["--calls", calls, "--timeout", "60", "--announce-every", "1"];
        let mut p = peer_by(net.command(&py), &name, dom, "service", &args);
        let ended = p.wait(SECS(100));
        let failed = || format!("{name}, through {LOSS} % loss\n{}\n{}", p.dump(), host.dump());
        assert_eq!(ended, Some(0), "{}", failed());
        let r = json_lines(&p, "call");
        assert_eq!(r.len(), 5, "{}", failed());
        assert_eq!(r[1]["state"]["state"].as_u64(), Some(STATE_PLAYING), "{}", failed());
        for (i, what) in [(2, "pause"), (3, "one step"), (4, "play")] {
            assert_eq!(result(&r[i]).0, OK, "{what}: {:?}\n{}", r[i], failed());
        }
    }
    assert_eq!(ctl_state(&ns)["state"], "playing");
}

per_engine!(services_are_answered_through_a_lossy_network);

/// A Fast DDS client that sends and takes requests and replies exactly as rmw_fastrtps does
/// (`tests/gateway/fastdds_requester.cpp`: each request carries a related sample identity
/// naming its reply reader, the sequence number unknown) is answered by the rustdds engine in
/// its form: each reply's related sample identity names that reader and the request's
/// sequence number (DDS domain 50).
#[test]
fn a_client_in_rmw_fastrtps_manner_is_answered_on_the_rustdds_engine() {
    let idl = tutti_test_support::repo_root().join("tests/gateway/GetSimulationState_.idl");
    let Some((_scratch, bin)) = crate::gateway_fastdds::build_fastdds("fastdds_requester", &idl) else { return };
    let Some(c) = Way::ENHANCED.client(45) else { return };
    let _run = c.start(DDF);
    let mut cmd = std::process::Command::new(&bin);
    cmd.args([c.dom.to_string().as_str(), "3", "60"]);
    let mut p = Proc::spawn("fastdds_requester", cmd, SECS(100));
    assert_eq!(p.wait(SECS(90)), Some(0), "{}", p.dump());
    let replies: Vec<String> = p.lines().into_iter().filter(|l| l.starts_with("state=")).collect();
    assert_eq!(replies, vec!["state=1 result=1 related=reader"; 3], "{}", p.dump());
}
