//! `tutti replay`: a run recorded with a C component replays against the same component with
//! no difference, and a component whose answer changes is caught at its first differing step
//! and item; a replay republishes every recorded PUBLISH set with its simulated time.

use tutti_test_support as common;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};
use std::thread;
use std::time::Duration;

use tutti_core::ddf::Role;
use tutti_core::shm::{ConnectOptions, Participant};

const LIMIT: Duration = Duration::from_secs(120);

fn tutti(ns: &str, args: &[&str]) -> Command {
    let mut c = common::tutti_command();
    c.args(args).current_dir(tutti_test_support::repo_root()).env("TUTTI_NAMESPACE", ns);
    c
}

/// The test's C component, compiled against the workspace's librtapi.
fn compile_answer(dir: &Path) -> PathBuf {
    common::compile_c(
        &tutti_test_support::repo_root().join("tests/replay/answer.c"),
        &dir.join("answer"),
        &["-std=c99", "-Wall", "-Werror"],
    )
}

/// Runs `framework` (a host or a replay, which holds its first step for one writer) beside
/// the component `answer` with the given steps, factor and deviation; returns the
/// framework's status, stdout and stderr.
fn beside_component(
    framework: Command,
    answer: &Path,
    ns: &str,
    deviate: u32,
) -> ((ExitStatus, String, String), (ExitStatus, String, String)) {
    let fw = thread::spawn(move || common::run_with_timeout(framework, LIMIT));
    let mut c = Command::new(answer);
    c.arg(tutti_test_support::repo_root().join("ddf/multiuav.ddf"))
        .args(["multiuav_uav2", "Z", "Elevation", "100", "2", &deviate.to_string()])
        .env("TUTTI_NAMESPACE", ns);
    let component = common::run_with_timeout(c, LIMIT);
    match fw.join() {
        Ok(framework) => (framework, component),
        // The framework's watchdog fired: what the component said tells why it waited.
        Err(_) => {
            panic!("the framework failed (above); the component: {:?}\n{}{}", component.0, component.1, component.2)
        }
    }
}

#[test]
fn a_replay_against_the_same_c_component_shows_no_difference_and_a_changed_answer_is_found() {
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("replay");
    let _segments = common::RemoveSegments(ns.clone());
    let answer = compile_answer(dir.path());
    let run = dir.path().join("run.mcap");

    // The recorded run: the host waits for the component's first answer, then steps.
    let mut host = tutti(&ns, &["host", "ddf/multiuav.ddf", "--step", "5ms", "--duration", "1500ms", "-q"]);
    host.args(["--wait-for", "multiuav_uav2=1", "--set", "multiuav_uav2/Z=3.25", "--record"]).arg(&run);
    let ((status, _, err), (cstatus, cout, cerr)) = beside_component(host, &answer, &ns, 0);
    assert!(status.success(), "tutti host failed: {err}");
    assert!(cstatus.success(), "the component failed: {cout}{cerr}");

    // The same component: no difference.
    let mut replay = tutti(&ns, &["replay", "--speed", "0", "--wait-for", "multiuav_uav2=1", "--compare", "--json"]);
    replay.arg(&run);
    let ((status, out, err), (cstatus, cout, cerr)) = beside_component(replay, &answer, &ns, 0);
    assert!(cstatus.success(), "the component failed: {cout}{cerr}");
    assert!(status.success(), "the replay found differences or failed:\n{out}\n{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).expect("one JSON object");
    assert_eq!(v["differing_steps"], 0, "{v}");
    assert_eq!(v["steps"], v["recorded_steps"], "{v}");
    // Four domains of some 300 steps, all but the component's departure compared.
    assert!(v["compared"].as_u64().unwrap() > 4 * 200, "{v}");
    assert!(v["not_compared_other_connections"].as_u64().unwrap() <= 2, "{v}");

    // A component whose answer changes from its 31st step: its first answer (before its
    // first read) answered step 1, so its 31st is step 32's. Reported there, at its item.
    let mut replay = tutti(
        &ns,
        &[
            "replay",
            "--speed",
            "0",
            "--domain",
            "multiuav_uav2",
            "--wait-for",
            "multiuav_uav2=1",
            "--compare",
            "--json",
        ],
    );
    replay.arg(&run);
    let ((status, out, err), (cstatus, cout, cerr)) = beside_component(replay, &answer, &ns, 31);
    assert!(cstatus.success(), "the component failed: {cout}{cerr}");
    assert_eq!(status.code(), Some(1), "differences give exit status 1:\n{out}\n{err}");
    assert!(err.contains("the first is multiuav_uav2 step 32"), "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).expect("one JSON object");
    let first = &v["first"];
    assert_eq!(first["domain"], "multiuav_uav2", "{v}");
    assert_eq!(first["step"], 32, "{v}");
    assert_eq!(first["items"].as_array().unwrap().len(), 1, "{v}");
    assert_eq!(first["items"][0]["item"], "Elevation", "{v}");
    assert_eq!(first["items"][0]["recorded"], "37.5", "2 x 3.25 + 31: {v}");
    assert_eq!(first["items"][0]["replayed"], "38.5", "{v}");
    // Every step from there differs: the last (changed) answer stays after the component
    // leaves (its departure's step may not be compared).
    let (differing, total) = (v["differing_steps"].as_u64().unwrap(), v["recorded_steps"].as_u64().unwrap());
    assert!(differing + 31 == total || differing + 32 == total, "{v}");
    assert!(!Path::new(&format!("/dev/shm/tutti.{ns}.multiuav_uav2")).exists(), "the replay removes its segments");
}

/// A recording whose PUBLISH set changes every step, written through the recording library:
/// a participant of the replay reads every step's values and simulated time as recorded,
/// and its answers (copies of them) equal the recorded answers.
#[test]
fn a_replay_republishes_every_recorded_step_with_its_simulated_time() {
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("replaypub");
    let _segments = common::RemoveSegments(ns.clone());
    let ddf = tutti_test_support::repo_root().join("ddf/multiuav.ddf");
    let mut model = tutti_core::ddf::load(&ddf).unwrap();
    model.domains.retain(|d| d.name == "multiuav_uav2");
    let d = &model.domains[0];
    let run = dir.path().join("synthetic.mcap");
    let (z, elevation) =
        (d.publish.layout.leaf("Z").unwrap().clone(), d.subscribe.layout.leaf("Elevation").unwrap().clone());
    let steps = 200u64;
    let value = |k: u64| k as f64 * 0.5 - 7.0;
    {
        let mut rec = tutti_record::create(&run, &model, &ddf).unwrap();
        for k in 1..=steps {
            let mut publish = d.publish.layout.default_bytes();
            publish[z.range()].copy_from_slice(&value(k).to_ne_bytes());
            let mut subscribe = d.subscribe.layout.default_bytes();
            if k > 1 {
                subscribe[elevation.range()].copy_from_slice(&value(k).to_ne_bytes());
            }
            let s = tutti_record::Step {
                step: k,
                sim_time: k as f64 * 0.01,
                wall_ns: 1_000_000_000 + k * 1_000_000,
                elapsed_s: 0.0,
                connections: 1,
                owner_pid: None,
                publish: &publish,
                subscribe: &subscribe,
            };
            rec.step(0, &s).unwrap();
        }
        rec.finish().unwrap();
    }
    let mut replay = tutti(&ns, &["replay", "--speed", "4", "--wait-for", "multiuav_uav2=1", "--compare", "--json"]);
    replay.arg(&run);
    let replay = thread::spawn(move || common::run_with_timeout(replay, LIMIT));
    let opts = ConnectOptions {
        namespace: ns.clone(),
        name: "replay-reader".into(),
        connect_timeout: Duration::from_secs(60),
        skip_wait_to_go: true,
        ..Default::default()
    };
    let mut p = Participant::connect("multiuav_uav2", opts).expect("connecting to the replay");
    // A first answer makes this connection a writer, which the replay waits for; in a
    // synchronous domain it answers the first step (recorded as the default, 0).
    p.publish_lock().unwrap();
    p.stage("Elevation", &0f64.to_ne_bytes()).unwrap();
    p.commit().unwrap();
    p.wait_ready_to_go().unwrap();
    let mut seen = Vec::new();
    let off = p.leaf(Role::Publish, "Z").map(|(_, l)| l.offset as usize).unwrap();
    for _ in 2..=steps {
        let k = p.subscribe_lock().expect("a step");
        let v = f64::from_ne_bytes(p.snapshot()[off..off + 8].try_into().unwrap());
        seen.push((k, p.sim_time(), v));
        p.publish_lock().unwrap();
        p.stage("Elevation", &v.to_ne_bytes()).unwrap();
        p.commit().unwrap();
    }
    p.disconnect();
    let (status, out, err) = replay.join().unwrap();
    let head = |s: &str| s.chars().take(2000).collect::<String>();
    assert!(status.success(), "the replay failed or found differences:\n{}\n{err}", head(&out));
    let want: Vec<(u64, f64, f64)> = (2..=steps).map(|k| (k, k as f64 * 0.01, value(k))).collect();
    assert_eq!(seen, want);
    let v: serde_json::Value = serde_json::from_str(out.trim()).expect("one JSON object");
    assert_eq!(v["differing_steps"], 0, "{v}");
    assert!(v["compared"].as_u64().unwrap() >= steps - 2, "{v}");
}

#[test]
fn replay_refuses_what_is_not_a_recording_or_not_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("replaybad");
    let _segments = common::RemoveSegments(ns.clone());
    let junk = dir.path().join("junk.mcap");
    std::fs::write(&junk, b"not an mcap file").unwrap();
    let mut c = tutti(&ns, &["replay"]);
    c.arg(&junk);
    let (status, _, err) = common::run_with_timeout(c, LIMIT);
    assert_eq!(status.code(), Some(2), "{err}");
    assert!(err.contains("junk.mcap") && err.contains("MCAP"), "{err}");

    // A recording of one domain, asked for another.
    let ddf = tutti_test_support::repo_root().join("ddf/product-sample.ddf");
    let model = tutti_core::ddf::load(&ddf).unwrap();
    let run = dir.path().join("one.mcap");
    let mut rec = tutti_record::create(&run, &model, &ddf).unwrap();
    let d = &model.domains[0];
    let (p, s) = (d.publish.layout.default_bytes(), d.subscribe.layout.default_bytes());
    let step = tutti_record::Step {
        step: 1,
        sim_time: 0.0,
        wall_ns: 1,
        elapsed_s: 0.0,
        connections: 0,
        owner_pid: None,
        publish: &p,
        subscribe: &s,
    };
    rec.step(0, &step).unwrap();
    rec.finish().unwrap();
    let mut c = tutti(&ns, &["replay", "--domain", "nowhere"]);
    c.arg(&run);
    let (status, _, err) = common::run_with_timeout(c, LIMIT);
    assert_eq!(status.code(), Some(2), "{err}");
    assert!(err.contains("no recorded domain 'nowhere'") && err.contains(&d.name), "{err}");

    // Writers awaited in a domain the replay does not have: refused before anything is created.
    let mut c = tutti(&ns, &["replay", "--wait-for", "nowhere=1"]);
    c.arg(&run);
    let (status, _, err) = common::run_with_timeout(c, LIMIT);
    assert_eq!(status.code(), Some(2), "{err}");
    assert!(err.contains("--wait-for nowhere=1: no domain 'nowhere'") && err.contains("one.mcap"), "{err}");
    assert!(tutti_test_support::segments_of(&ns).is_empty(), "a refused replay left segments");
}
