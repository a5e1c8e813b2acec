//! The gateway's Foxglove WebSocket server (`foxglove` key, `--foxglove ADDR`): a client of
//! the protocol from npm (`@foxglove/ws-protocol`, `tests/foxglove/client.mjs`) against
//! `tutti host --gateway`, `tutti run` and a separate `tutti gateway --foxglove` beside a
//! recording `tutti host` (its messages are the recording's, step for
//! step; what it publishes into a SUBSCRIBE set is read by the framework; the step service
//! makes exactly the steps asked for), and the WebSocket handshake of a separate
//! `tutti gateway` (both names of the protocol accepted, any other refused). Each test has
//! its own namespace and DDS domain (61-76, 148-150); the servers listen on a port the system
//! chooses (`127.0.0.1:0`), read back from their log.

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

use serde_json::Value;
use tutti_core::cdr::{SetCodec, HEADER_LE};
use tutti_core::ddf::Role;
use tutti_test_support::{dds_domain_in, hex, namespace, require, require_tool, unhex, Proc, RemoveSegments};

const DDF: &str = "tests/gateway/gw.ddf";
const SECS: fn(u64) -> Duration = Duration::from_secs;

/// The address the Foxglove server logged (`foxglove on ws://ADDR`).
fn foxglove_addr(p: &Proc) -> SocketAddr {
    let line = p.wait_line("Foxglove WebSocket server on ws://", SECS(60));
    let line = line.unwrap_or_else(|| panic!("the Foxglove server did not start\n{}", p.dump()));
    let at = line.find("ws://").map(|i| i + 5).unwrap_or(0);
    let addr: String = line[at..].chars().take_while(|c| !c.is_whitespace() && *c != '/').collect();
    addr.parse().unwrap_or_else(|e| panic!("{addr}: {e}\n{line}"))
}

/// A gateway config file in `dir` with `keys`.
fn config(dir: &Path, keys: &str) -> String {
    let path = dir.join("gateway.json5");
    std::fs::write(&path, keys).expect("the config file");
    path.display().to_string()
}

/// The recording's messages of `topic`, by step (the first 8 bytes of the CDR body).
fn recorded(mcap: &Path, topic: &str) -> BTreeMap<u64, (u64, Vec<u8>)> {
    let bytes = std::fs::read(mcap).expect("the recording");
    let file = tutti_record::mcap::read::McapFile::parse(&bytes).expect("an MCAP file");
    let mut out = BTreeMap::new();
    for m in file.messages() {
        let m = m.expect("a message");
        if m.channel.topic == topic {
            let step = u64::from_le_bytes(m.data[4..12].try_into().expect("a step"));
            out.insert(step, (m.publish_time, m.data));
        }
    }
    out
}

fn codec(role: Role, domain: &str) -> SetCodec {
    let model = tutti_core::ddf::load(Path::new(DDF)).expect("the DDF");
    let d = model.domains.iter().find(|d| d.name == domain).expect("the domain");
    SetCodec::new(&d.set(role).layout)
}

/// What runs the gateway with the Foxglove server: `tutti host --gateway CONFIG`, `tutti
/// run` of a launch file with a `gateway` section, or `tutti gateway --foxglove` beside
/// `tutti host`.
#[derive(Debug, Clone, Copy)]
enum Runner {
    Host,
    Run,
    Separate,
}

#[test]
fn a_foxglove_client_sees_the_recorded_values_writes_a_subscribe_set_and_steps_the_run() {
    foxglove_client_against(Runner::Host, "fgx61_", 61..=68);
}

#[test]
fn a_foxglove_client_does_the_same_against_the_gateway_of_a_launch_file() {
    foxglove_client_against(Runner::Run, "fgxrun_", 148..=149);
}

#[test]
fn a_foxglove_client_does_the_same_against_a_separate_gateway() {
    foxglove_client_against(Runner::Separate, "fgxsep_", 150..=150);
}

/// A recorded run with the gateway's Foxglove server, started by `runner`: its address, the
/// run's process, a separate gateway's, and the recording. Each steps every 5 ms and copies
/// the simulated time into gw_sync/publish/x and gw_async/subscribe/y into gw_async/publish/x.
fn start_run(runner: Runner, ns: &str, dom: u16, dir: &Path) -> (SocketAddr, Proc, Option<Proc>, std::path::PathBuf) {
    let mcap = dir.join("run.mcap");
    const CONNECT: [&str; 2] = ["@sim_time -> gw_sync/publish/x", "gw_async/subscribe/y -> gw_async/publish/x"];
    let mut cmd = tutti_test_support::tutti_command();
    match runner {
        Runner::Host | Runner::Separate => {
            cmd.args(["host", DDF, "--step", "5ms", "--record"]).arg(&mcap);
            if let Runner::Host = runner {
                cmd.arg("--gateway")
                    .arg(config(dir, &format!(r#"{{ foxglove: "127.0.0.1:0", clock: "gw_sync", {ENTITIES} }}"#)));
            }
            for c in CONNECT {
                cmd.args(["--connect", c]);
            }
        }
        Runner::Run => {
            let ddf = tutti_test_support::repo_root().join(DDF);
            let launch = serde_json::json!({
                "ddf": ddf,
                "framework": { "step": "5ms", "record": ["run.mcap"] },
                "connections": CONNECT,
                "components": [],
                "gateway": { "foxglove": "127.0.0.1:0", "clock": "gw_sync", "entities": [probe()] },
            });
            let file = dir.join("run.json5");
            std::fs::write(&file, launch.to_string()).expect("the launch file");
            cmd.arg("run").arg(&file);
        }
    }
    cmd.env("TUTTI_NAMESPACE", ns)
        .env("ROS_DOMAIN_ID", dom.to_string())
        .env("TUTTI_GATEWAY_INTERFACE", "127.0.0.1")
        .env("RUST_LOG", "info,rustdds=off,ros2_client=off");
    let host = Proc::spawn(&format!("{runner:?} with the Foxglove server"), cmd, SECS(240));
    if let Runner::Separate = runner {
        let mut gw = tutti_test_support::tutti_command();
        gw.args(["gateway", DDF, "--foxglove", "127.0.0.1:0", "--clock", "gw_sync", "--interface", "127.0.0.1"])
            .arg("--config")
            .arg(config(dir, &format!("{{ {ENTITIES} }}")))
            .args(["--ros-domain-id", &dom.to_string()])
            .env("TUTTI_NAMESPACE", ns)
            .env("RUST_LOG", "info,rustdds=off,ros2_client=off");
        let gw = Proc::spawn("tutti gateway --foxglove", gw, SECS(240));
        return (foxglove_addr(&gw), host, Some(gw), mcap);
    }
    (foxglove_addr(&host), host, None, mcap)
}

/// An entity placed by gw_sync's PUBLISH item x, which is the simulated time (`@sim_time`):
/// on `/tf` its translation is (t, t, t) at time t.
const ENTITIES: &str = r#"entities: [{ name: "probe", frame: "world", domain: "gw_sync", set: "publish", cartesian: { x: "x", y: "x", z: "x" } }]"#;

fn probe() -> Value {
    serde_json::json!({ "name": "probe", "frame": "world", "domain": "gw_sync", "set": "publish",
                        "cartesian": { "x": "x", "y": "x", "z": "x" } })
}

/// The steps the client asks the step service for while the run is paused.
const STEPS: u64 = 7;

/// A run started by `runner` (see [`start_run`]) and the protocol's client from npm against
/// its Foxglove server: the channels, messages, client publishing, services, connection graph
/// and time the client saw are checked against the run's recording.
fn foxglove_client_against(runner: Runner, tag: &str, doms: std::ops::RangeInclusive<u16>) {
    let Some(node) = require_tool("node", "nodejs") else { return };
    let modules = tutti_test_support::repo_root().join("tests/foxglove/node_modules/@foxglove/ws-protocol");
    let found = if modules.is_dir() { Ok(()) } else { Err(format!("no {}", modules.display())) };
    if require("the npm packages of tests/foxglove (npm ci there)", found).is_none() {
        return;
    }
    let ns = namespace(tag);
    let _segments = RemoveSegments(ns.clone());
    let dom = dds_domain_in(doms);
    let dir = tempfile::tempdir().expect("a temporary directory");
    let (addr, mut host, gateway, mcap) = start_run(runner, &ns, dom, dir.path());

    let mut client = start_client(&node, addr);
    let rc = client.wait(SECS(180));
    assert_eq!(rc, Some(0), "the client failed\n{}\n{}", client.dump(), host.dump());
    let lines: Vec<Value> = client.stdout().lines().filter_map(|l| serde_json::from_str(l).ok()).collect();
    if let Some(mut gw) = gateway {
        assert_eq!(gw.interrupt(SECS(60)), Some(0), "{}", gw.dump());
    }
    assert_eq!(host.interrupt(SECS(60)), Some(0), "{}", host.dump());

    the_channels_are_the_sets_with_the_recordings_schemas(&lines);
    let rec = recorded(&mcap, "/gw_sync/publish");
    each_message_is_the_recordings_of_its_step(&lines, &rec, &client);
    the_entity_is_on_tf_where_its_set_places_it(&lines, &rec, &client);
    the_published_value_reached_the_framework(&lines, &mcap, &client);
    the_step_service_made_exactly_the_steps_asked_for(&lines);
    playback_control_pauses_plays_and_sets_the_runs_speed(&lines);
    the_graph_and_the_time_are_the_runs(&lines, &rec);
}

/// Foxglove's playback controls on `tutti replay --gateway`: a recording of 600 steps of
/// gw_sync (x is the simulated time, 1.5 s of wall time) replayed at a quarter of its pace; the npm client
/// (`tests/foxglove/replay.mjs`) reads its messages, pauses, seeks back to 0.1 s and plays.
/// The seek is answered with the step it went to; the messages after it go back there and on,
/// in order; the range the server offers is the recording's; the entity's transforms are
/// where the replayed set places it.
#[test]
fn a_foxglove_client_pauses_seeks_and_plays_a_replay() {
    let Some(node) = require_tool("node", "nodejs") else { return };
    let ns = namespace("fgreplay");
    let _segments = RemoveSegments(ns.clone());
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mcap = dir.path().join("run.mcap");
    let mut rec = tutti_test_support::tutti_command();
    // At twice real time: the replay paces by the recording's wall clock.
    rec.args(["host", DDF, "--step", "5ms", "--steps", "600", "--speed", "2", "-q", "--record"])
        .arg(&mcap)
        .args(["--connect", "@sim_time -> gw_sync/publish/x"])
        .env("TUTTI_NAMESPACE", &ns);
    let (status, _, err) = tutti_test_support::run_with_timeout(rec, SECS(120));
    assert!(status.success(), "the recording run: {err}");
    let mut replay = tutti_test_support::tutti_command();
    replay
        .args(["replay", "--speed", "0.25", "--domain", "gw_sync"])
        .arg(&mcap)
        .arg(format!(
            "--gateway={}",
            config(dir.path(), &format!(r#"{{ foxglove: "127.0.0.1:0", clock: "gw_sync", {ENTITIES} }}"#))
        ))
        .env("TUTTI_NAMESPACE", &ns)
        .env("ROS_DOMAIN_ID", dds_domain_in(61..=76).to_string())
        .env("TUTTI_GATEWAY_INTERFACE", "127.0.0.1")
        .env("RUST_LOG", "info,rustdds=off,ros2_client=off");
    let mut replay = Proc::spawn("tutti replay --gateway", replay, SECS(240));
    let addr = foxglove_addr(&replay);
    let mut client = Command::new(node);
    client.current_dir(tutti_test_support::repo_root().join("tests/foxglove")).args([
        "replay.mjs",
        &format!("ws://{addr}/"),
        "/gw_sync/publish",
        "100000000",
        "/tf",
    ]);
    let mut client = Proc::spawn("foxglove replay client", client, SECS(180));
    assert_eq!(client.wait(SECS(150)), Some(0), "the client failed\n{}\n{}", client.dump(), replay.dump());
    let lines: Vec<Value> = client.stdout().lines().filter_map(|l| serde_json::from_str(l).ok()).collect();
    let _ = replay.interrupt(SECS(60));

    let info = &of(&lines, "serverInfo")[0];
    assert!(info["capabilities"].as_array().unwrap().iter().any(|c| c == "playbackControl"), "{info}");
    let times: Vec<u64> = recorded(&mcap, "/gw_sync/publish").values().map(|(t, _)| *t).collect();
    let end = *times.iter().max().unwrap();
    let end = serde_json::json!({ "sec": end / 1_000_000_000, "nsec": end % 1_000_000_000 });
    assert_eq!(info["dataEndTime"], end, "the last recorded step's time: {info}");
    let target = *times.iter().filter(|&&t| t >= 100_000_000).min().unwrap();
    let states = of(&lines, "playback");
    let by =
        |id: &str| states.iter().find(|s| s["request"] == id).cloned().unwrap_or_else(|| panic!("no {id}: {states:?}"));
    let (pause, seek, play) = (by("pause"), by("seek"), by("play"));
    assert_eq!(pause["status"].as_u64(), Some(1), "{pause}");
    assert_eq!((seek["status"].as_u64(), seek["didSeek"].as_bool()), (Some(1), Some(true)), "{seek}");
    assert_eq!(seek["currentTime"], target.to_string(), "the recorded step at 0.1 s: {seek}");
    assert_eq!(play["status"].as_u64(), Some(0), "{play}");
    let stamps = |phase: &str| -> Vec<u64> {
        of(&lines, "message")
            .iter()
            .filter(|m| m["phase"] == phase)
            .map(|m| m["timestamp"].as_str().unwrap().parse().unwrap())
            .collect()
    };
    // The entity on /tf, where the replayed set places it.
    the_entity_is_on_tf_where_its_set_places_it(&lines, &recorded(&mcap, "/gw_sync/publish"), &client);
    let (before, after) = (stamps("before"), stamps("after"));
    assert!(before.last().is_some_and(|&t| t > 200_000_000), "{before:?}");
    // After the seek the replay goes on from there, in order: the messages go back to the
    // target, and on (the server sends the latest value it finds: a loaded machine may skip
    // a step, never send one out of order).
    let last_before = *before.last().unwrap();
    assert!(after.first().is_some_and(|&t| t >= target && t < last_before), "went back to {target}: {after:?}");
    assert!(after.windows(2).all(|w| w[0] < w[1]), "{after:?}");
}

/// Foxglove's playback control (requests sent as raw frames beside the npm client): the
/// server offers it with the run's range; pause and play are the run's, the speed becomes the
/// run's, a seek is refused with a status (a live run has no other time), and each request is
/// answered with a playback state that has its id.
fn playback_control_pauses_plays_and_sets_the_runs_speed(lines: &[Value]) {
    let info = &of(lines, "serverInfo")[0];
    assert!(info["capabilities"].as_array().unwrap().iter().any(|c| c == "playbackControl"), "{info}");
    assert_eq!(info["dataStartTime"], serde_json::json!({ "sec": 0, "nsec": 0 }), "{info}");
    assert!(info["dataEndTime"]["sec"].as_u64().unwrap() >= 86_400, "a run without an end: a day ahead: {info}");
    let states = of(lines, "playback");
    let by =
        |id: &str| states.iter().find(|s| s["request"] == id).cloned().unwrap_or_else(|| panic!("no {id}: {states:?}"));
    let (pause, play2, seek, play1) = (by("pause"), by("play2x"), by("seek"), by("play1x"));
    assert_eq!((pause["status"].as_u64(), pause["run"]["state"].as_str()), (Some(1), Some("paused")), "{pause}");
    assert_eq!((play2["status"].as_u64(), play2["speed"].as_f64()), (Some(0), Some(2.0)), "{play2}");
    assert_eq!(
        (play2["run"]["state"].as_str(), play2["run"]["speed"].as_f64()),
        (Some("playing"), Some(2.0)),
        "{play2}"
    );
    assert_eq!((seek["didSeek"].as_bool(), seek["run"]["speed"].as_f64()), (Some(false), Some(2.0)), "{seek}");
    let refused =
        of(lines, "status").into_iter().any(|s| s["message"].as_str().unwrap_or("").starts_with("seek: a live run"));
    assert!(refused, "no status refusing the seek: {lines:?}");
    assert_eq!((play1["run"]["speed"].as_f64(), play1["speed"].as_f64()), (Some(1.0), Some(1.0)), "{play1}");
    let paused_at: u64 = pause["currentTime"].as_str().unwrap().parse().unwrap();
    assert!(paused_at > 0, "the time the run paused at: {pause}");
}

/// The client's lines of kind `kind`.
fn of(lines: &[Value], kind: &str) -> Vec<Value> {
    lines.iter().filter(|v| v["kind"] == kind).cloned().collect()
}

/// `tests/foxglove/client.mjs` (run by `node`) against the server at `addr`: it reads 40
/// messages of gw_sync's PUBLISH set, publishes y = 4.75, n = 7 into gw_async's SUBSCRIBE set
/// and watches for it in gw_async/publish/x, and calls the services (stepping [`STEPS`]).
fn start_client(node: &Path, addr: SocketAddr) -> Proc {
    // The sample the client publishes into gw_async's SUBSCRIBE set: y = 4.75, n = 7.
    let sub = codec(Role::Subscribe, "gw_async");
    let mut set = vec![0u8; sub.shm_size()];
    set[0..8].copy_from_slice(&4.75f64.to_ne_bytes());
    set[8..12].copy_from_slice(&7i32.to_ne_bytes());
    let mut body = Vec::new();
    sub.encode(0, 0.0, &set, &mut body);
    let sample = [&HEADER_LE[..], &body].concat();
    let client_cfg = serde_json::json!({
        "subscribe": "/gw_sync/publish",
        "count": 40,
        "publish": "/gw_async/subscribe",
        "schemaName": "gw_msgs/msg/GwAsyncSubscribe",
        "sampleHex": hex(&sample),
        // gw_async/publish/x, after the header, step and sim_time.
        "watch": "/gw_async/publish",
        "watchAt": 4 + 16,
        "watchHex": hex(&4.75f64.to_le_bytes()),
        "step": STEPS,
        "tf": "/tf",
        "tfCount": 10,
        "playback": true,
    });
    let mut client = Command::new(node);
    client.current_dir(tutti_test_support::repo_root().join("tests/foxglove")).args([
        "client.mjs",
        &format!("ws://{addr}/"),
        &client_cfg.to_string(),
    ]);
    Proc::spawn("foxglove client", client, SECS(180))
}

/// The channels: one per set, on its ROS 2 topic, in CDR, with the recording's schema.
fn the_channels_are_the_sets_with_the_recordings_schemas(lines: &[Value]) {
    let info = &of(lines, "serverInfo")[0];
    assert_eq!(info["protocol"], "foxglove.websocket.v1");
    for cap in ["clientPublish", "services", "connectionGraph", "time"] {
        assert!(info["capabilities"].as_array().unwrap().iter().any(|c| c == cap), "{info}");
    }
    let chans = &of(lines, "channels")[0];
    let channel = |topic: &str| -> Value {
        chans["channels"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["topic"] == topic)
            .cloned()
            .unwrap_or_else(|| panic!("no {topic}: {chans}"))
    };
    for topic in
        ["/gw_async/publish", "/gw_async/subscribe", "/gw_sync/publish", "/gw_sync/subscribe", "/gw_states/publish"]
    {
        let c = channel(topic);
        assert_eq!((c["encoding"].as_str(), c["schemaEncoding"].as_str()), (Some("cdr"), Some("ros2msg")), "{c}");
    }
    assert_eq!(channel("/gw_sync/publish")["schemaName"], "gw_msgs/msg/GwSyncPublish");
    let tf = channel("/tf");
    assert_eq!(
        (tf["schemaName"].as_str(), tf["encoding"].as_str()),
        (Some("tf2_msgs/msg/TFMessage"), Some("cdr")),
        "{tf}"
    );
    assert!(tf["schema"].as_str().unwrap().contains("MSG: geometry_msgs/msg/TransformStamped"), "{tf}");
    assert!(channel("/gw_async/publish")["schema"].as_str().unwrap().contains("float64[3] v"), "{chans}");
}

/// Each message is the recording's message of its step (`rec`), stamped with its simulated
/// time, in order, and the values are live.
fn each_message_is_the_recordings_of_its_step(lines: &[Value], rec: &BTreeMap<u64, (u64, Vec<u8>)>, client: &Proc) {
    let msgs = of(lines, "message");
    assert_eq!(msgs.len(), 40, "{}", client.dump());
    let mut steps = Vec::new();
    for m in &msgs {
        let data = unhex(m["hex"].as_str().unwrap());
        let step = u64::from_le_bytes(data[4..12].try_into().unwrap());
        let (publish_time, recorded) = rec.get(&step).unwrap_or_else(|| panic!("step {step} is not in the recording"));
        assert_eq!(&data, recorded, "step {step}: the message differs from the recording's");
        assert_eq!(m["timestamp"].as_str().unwrap(), publish_time.to_string(), "step {step}: not its simulated time");
        steps.push(step);
    }
    assert!(steps.windows(2).all(|w| w[0] < w[1]), "steps out of order: {steps:?}");
    // The set changes at every step (x is the simulated time): the values are live.
    let xs: std::collections::BTreeSet<u64> = msgs
        .iter()
        .map(|m| u64::from_le_bytes(unhex(m["hex"].as_str().unwrap())[20..28].try_into().unwrap()))
        .collect();
    assert!(xs.len() > 1, "one value only: {xs:?}");
}

/// The entity's transforms on `/tf` (what Foxglove's 3D panel draws): `world` to `probe`, at
/// (t, t, t) for its step's simulated time t (`rec`: gw_sync's recorded steps), stamped t.
fn the_entity_is_on_tf_where_its_set_places_it(lines: &[Value], rec: &BTreeMap<u64, (u64, Vec<u8>)>, client: &Proc) {
    let tfs = of(lines, "tf");
    assert_eq!(tfs.len(), 10, "{}", client.dump());
    let m = tutti_ros2::registry().message("tf2_msgs/msg/TFMessage").unwrap();
    let times: std::collections::BTreeSet<u64> = rec.values().map(|(t, _)| *t).collect();
    let mut stamps = Vec::new();
    for tf in &tfs {
        let data = unhex(tf["hex"].as_str().unwrap());
        let v = m.decode(&data[4..], true).unwrap_or_else(|e| panic!("not a TFMessage: {e}: {tf}"));
        let t = &v.get("transforms").and_then(tutti_ros2::Value::as_array).expect("transforms")[0];
        let f =
            |path: &str| t.path(path).and_then(tutti_ros2::Value::as_f64).unwrap_or_else(|| panic!("{path} in {t:?}"));
        let text = |path: &str| t.path(path).and_then(tutti_ros2::Value::as_str).unwrap_or_default().to_string();
        assert_eq!((text("header.frame_id"), text("child_frame_id")), ("world".into(), "probe".into()), "{t:?}");
        let ns = t.path("header.stamp.sec").and_then(tutti_ros2::Value::as_i64).unwrap() as u64 * 1_000_000_000
            + t.path("header.stamp.nanosec").and_then(tutti_ros2::Value::as_u64).unwrap();
        assert!(times.contains(&ns), "{ns} ns is no recorded step's time");
        let x = f("transform.translation.x");
        assert_eq!((x, f("transform.translation.y"), f("transform.translation.z")), (x, x, x), "{t:?}");
        assert!((x * 1e9 - ns as f64).abs() < 1.0, "at {ns} ns the probe is at {x}: its item x is the time");
        assert_eq!(f("transform.rotation.w"), 1.0, "{t:?}");
        assert_eq!(tf["timestamp"].as_str().unwrap(), ns.to_string(), "the message's time is its stamp");
        stamps.push(ns);
    }
    assert!(stamps.windows(2).all(|w| w[0] < w[1]), "not one per step, in order: {stamps:?}");
}

/// The published value reached the framework: it copied y into gw_async/publish/x, and
/// the recording's SUBSCRIBE set holds it.
fn the_published_value_reached_the_framework(lines: &[Value], mcap: &Path, client: &Proc) {
    assert_eq!(of(lines, "seen").len(), 1, "{}", client.dump());
    let subs = recorded(mcap, "/gw_async/subscribe");
    let want = [&4.75f64.to_le_bytes()[..], &7i32.to_le_bytes()].concat();
    assert!(
        subs.values().any(|(_, d)| d[4 + 16..4 + 28] == want[..]),
        "the recording never shows y = 4.75, n = 7 in gw_async/subscribe"
    );
}

/// The step service made exactly the steps asked for while the run was paused.
fn the_step_service_made_exactly_the_steps_asked_for(lines: &[Value]) {
    let calls = of(lines, "service");
    let status = |name: &str| calls.iter().find(|c| c["name"] == name).map(|c| c["status"].clone()).unwrap();
    let (paused, stepped, state) = (status("/tutti/pause"), status("/tutti/step"), status("/tutti/state"));
    assert_eq!(paused["state"], "paused", "{paused}");
    assert_eq!(stepped["state"], "paused", "{stepped}");
    assert_eq!(stepped["step"].as_u64().unwrap(), paused["step"].as_u64().unwrap() + STEPS, "{paused} then {stepped}");
    assert_eq!(state["step"], stepped["step"], "a step made while paused: {state}");
    assert_eq!(status("/tutti/resume")["state"], "playing");
}

/// The connection graph shows the framework of each domain and the services; time messages
/// carry the simulated time of gw_sync (`rec`, its recorded messages).
fn the_graph_and_the_time_are_the_runs(lines: &[Value], rec: &BTreeMap<u64, (u64, Vec<u8>)>) {
    let graph = &of(lines, "graph")[0];
    let published = graph["publishedTopics"].as_array().unwrap();
    let sync_pub = published.iter().find(|t| t["name"] == "/gw_sync/publish").expect("gw_sync's PUBLISH topic");
    assert!(sync_pub["publisherIds"][0].as_str().unwrap().starts_with("framework of gw_sync"), "{graph}");
    assert!(graph["advertisedServices"].as_array().unwrap().iter().any(|s| s["name"] == "/tutti/step"), "{graph}");

    // Time messages carry the simulated time of gw_sync.
    let time = &of(lines, "time")[0];
    assert!(time["count"].as_u64().unwrap() > 0, "no time message: {time}");
    let last: u64 = time["last"].as_str().unwrap().parse().unwrap();
    let last_step = *rec.keys().last().unwrap();
    assert!(last > 0 && last <= rec[&last_step].0, "time {last} is not a simulated time of the run");
}

/// The status line and headers of the answer to a WebSocket upgrade offering `protocols`.
fn upgrade(addr: SocketAddr, protocols: Option<&str>) -> String {
    let mut s = TcpStream::connect(addr).expect("a connection to the server");
    s.set_read_timeout(Some(SECS(30))).expect("a read timeout");
    let offer = protocols.map(|p| format!("Sec-WebSocket-Protocol: {p}\r\n")).unwrap_or_default();
    let req = format!(
        "GET / HTTP/1.1\r\nHost: {addr}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n{offer}\r\n"
    );
    s.write_all(req.as_bytes()).expect("the request");
    let mut head = Vec::new();
    let mut byte = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        match s.read(&mut byte) {
            Ok(1) => head.push(byte[0]),
            _ => break,
        }
    }
    String::from_utf8_lossy(&head).to_lowercase()
}

#[test]
fn the_handshake_takes_both_names_of_the_protocol_and_refuses_others() {
    let ns = namespace("fgx69_");
    let _segments = RemoveSegments(ns.clone());
    let dom = dds_domain_in(69..=76);
    let mut cmd = tutti_test_support::tutti_command();
    cmd.args(["gateway", DDF, "--foxglove", "127.0.0.1:0", "--all-domains"])
        .env("TUTTI_NAMESPACE", &ns)
        .env("ROS_DOMAIN_ID", dom.to_string())
        .env("TUTTI_GATEWAY_INTERFACE", "127.0.0.1")
        .env("RUST_LOG", "info,rustdds=off,ros2_client=off");
    let mut gw = Proc::spawn("gateway --foxglove", cmd, SECS(120));
    let addr = foxglove_addr(&gw);
    for name in ["foxglove.websocket.v1", "foxglove.sdk.v1"] {
        let head = upgrade(addr, Some(name));
        assert!(head.starts_with("http/1.1 101"), "{name} refused: {head}");
        assert!(head.contains(&format!("sec-websocket-protocol: {name}\r\n")), "{name} not chosen: {head}");
    }
    // Both offered: one of them is chosen.
    let head = upgrade(addr, Some("foxglove.sdk.v1, foxglove.websocket.v1"));
    assert!(head.starts_with("http/1.1 101") && head.contains("sec-websocket-protocol: foxglove."), "{head}");
    for offer in [Some("foxglove.sdk.v2"), Some("graphql-ws"), None] {
        let head = upgrade(addr, offer);
        assert!(head.starts_with("http/1.1 400"), "{offer:?} accepted: {head}");
    }
    assert_eq!(gw.interrupt(SECS(60)), Some(0), "{}", gw.dump());
}
