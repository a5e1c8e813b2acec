//! `tutti host` and `tutti status` as a user runs them: every segment of a large DDF
//! appears, status lists domains and connections, the recording is written, and Ctrl-C
//! removes every segment.

use std::process::Command;
use std::time::Duration;

use tutti_core::shm::os;
use tutti_test_support::{lazy, tutti_command, wait_until, Proc, RemoveSegments, Spawn};

/// `tutti host` in namespace `ns`, with what a failed test may have left of it removed when
/// dropped (after the host).
struct Guard {
    host: Proc,
    _segments: RemoveSegments,
}

impl Guard {
    fn spawn(cmd: Command, ns: &str) -> Guard {
        // No clean stop on drop: the test has failed, and the segments go anyway.
        let opts = Spawn { grace: Duration::ZERO, ..Spawn::default() };
        Guard { host: Proc::spawn_with("tutti host", cmd, opts), _segments: RemoveSegments(ns.to_string()) }
    }
}

fn segments(ns: &str) -> usize {
    os::list_shm(&format!("tutti.{ns}.")).map_or(0, |names| names.len())
}

fn interrupt_and_wait(g: &mut Guard) -> std::process::ExitStatus {
    g.host.signal("INT");
    g.host.wait_status(Duration::from_secs(30)).expect("host did not stop on SIGINT")
}

fn tutti() -> Command {
    tutti_command()
}

#[test]
fn host_creates_every_segment_of_the_large_ddf_and_removes_them_on_ctrl_c() {
    let ns = tutti_test_support::namespace("hc-large-");
    let mut host = tutti();
    host.args(["host", "ddf/large-1000.ddf", "--step", "20ms", "--timeout", "100ms", "--quiet"])
        .env("TUTTI_NAMESPACE", &ns);
    let mut g = Guard::spawn(host, &ns);
    let only = lazy(|| format!("only {} of 1000 segments appeared", segments(&ns)));
    wait_until(only, Duration::from_secs(60), || segments(&ns) >= 1000);
    let out = tutti().args(["status", "--json"]).env("TUTTI_NAMESPACE", &ns).output().unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let domains = v.as_array().unwrap();
    assert_eq!(domains.len(), 1000);
    assert!(domains.iter().all(|d| d["framework_alive"] == true), "every domain has a live framework");
    let status = interrupt_and_wait(&mut g);
    assert!(status.success(), "{status}");
    assert_eq!(segments(&ns), 0, "segments left after Ctrl-C");
}

#[test]
fn host_records_both_sets_and_status_shows_connections() {
    let ns = tutti_test_support::namespace("hc-rec-");
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let mut host = tutti();
    host.args(["host", "ddf/product-sample.ddf", "--step", "5ms", "--set", "grid_clock/tick=7", "--record"])
        .arg(&csv)
        .env("TUTTI_NAMESPACE", &ns);
    let mut g = Guard::spawn(host, &ns);
    wait_until("segments never appeared", Duration::from_secs(60), || segments(&ns) >= 2);
    // The first recorded step must read the default: commit only once the host has stepped
    // (segments appear before the first step, and a slow machine may commit before it).
    let step = || tutti_core::shm::Segment::open(&ns, "grid_feeder").map_or(0, |s| s.status().step);
    wait_until("the host never stepped", Duration::from_secs(30), || step() >= 2);
    // A participant of the core library, connected while the host runs, shows in status.
    let opts = tutti_core::shm::ConnectOptions { namespace: ns.clone(), name: "probe".into(), ..Default::default() };
    let mut p = tutti_core::shm::Participant::connect("grid_feeder", opts).unwrap();
    p.publish_lock().unwrap();
    p.stage("setpoint_kw", &9.5f64.to_ne_bytes()).unwrap();
    p.commit().unwrap();
    let out = tutti().args(["status"]).env("TUTTI_NAMESPACE", &ns).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("grid_feeder [async,states]"), "{text}");
    assert!(text.contains("probe") && text.contains("writer"), "{text}");
    // Stop the host once it has stepped past the commit: the step after the one under way
    // now reads the committed value, and is recorded once the host has gone on to the next.
    let committed_at = step();
    wait_until("the host never stepped past the commit", Duration::from_secs(30), || step() >= committed_at + 2);
    drop(p);
    let status = interrupt_and_wait(&mut g);
    assert!(status.success());
    let feeder = std::fs::read_to_string(dir.path().join("run-grid_feeder.csv")).unwrap();
    let header = feeder.lines().next().unwrap();
    assert!(
        header.starts_with("step,sim_time,wall_s,connections,publish.breaker_closed,publish.voltage_abc[0]"),
        "{header}"
    );
    assert!(header.contains("publish.meter/power_kw") && header.contains("subscribe.setpoint_kw"));
    let col = header.split(',').position(|c| c == "subscribe.setpoint_kw").unwrap();
    let values: Vec<f64> = feeder.lines().skip(1).map(|l| l.split(',').nth(col).unwrap().parse().unwrap()).collect();
    assert_eq!(values.first(), Some(&1.5), "the default before the commit");
    assert_eq!(values.last(), Some(&9.5), "the committed value");
    let clock = std::fs::read_to_string(dir.path().join("run-grid_clock.csv")).unwrap();
    let tick_col = clock.lines().next().unwrap().split(',').position(|c| c == "publish.tick").unwrap();
    assert!(clock.lines().count() > 1, "no row recorded for grid_clock");
    assert!(clock.lines().skip(1).all(|l| l.split(',').nth(tick_col) == Some("7")));
    assert_eq!(segments(&ns), 0);
}

#[test]
fn host_refuses_bad_arguments_with_status_2() {
    for args in [
        vec!["host", "ddf/multiuav.ddf", "--step", "fast"],
        vec!["host", "ddf/multiuav.ddf", "--set", "nosuch/X=1"],
        vec!["host", "ddf/multiuav.ddf", "--set", "multiuav_uav1/Nope=1"],
        vec!["host", "tests/ddf-invalid/does-not-exist.ddf"],
    ] {
        let out = tutti().args(&args).env("TUTTI_NAMESPACE", "hc-bad").output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(!out.stderr.is_empty());
    }
}

/// Errors a new user meets first say it once, in the user's words.
#[test]
fn first_errors_are_said_once_and_plainly() {
    let run = |args: &[&str]| {
        let out = tutti().args(args).env("TUTTI_NAMESPACE", "hc-words").output().unwrap();
        (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    for cmd in ["host", "show", "gateway", "check"] {
        let (code, err) = run(&[cmd, "nofile.ddf"]);
        assert_eq!(code, Some(2), "{cmd}: {err}");
        assert_eq!(err.matches("No such file or directory").count(), 1, "{cmd}: the OS error once: {err}");
        assert!(err.contains("nofile.ddf"), "{err}");
    }
    let (code, err) = run(&["host", "ddf/multiuav.ddf", "--step", "fast"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("'fast' is not a duration: a number and a unit, like 10ms"), "{err}");
    assert!(!err.contains("expected number at"), "the parser's own wording: {err}");
    let (code, err) = run(&["gateway", "ddf/multiuav.ddf", "--ros-domain-id", "300"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("300") && err.contains("0..=232"), "{err}");
}

#[test]
fn a_segment_shrunk_under_the_host_ends_it_with_a_clean_error() {
    // Another process truncates a live segment: the host must not die of SIGBUS, but stop
    // with an error naming the domain and the file, and remove its segments.
    use std::os::unix::process::ExitStatusExt;
    let ns = tutti_test_support::namespace("hc-shrunk-");
    let mut host = tutti();
    host.args(["host", "ddf/multiuav.ddf", "--step", "5ms", "--timeout", "100ms", "--quiet"])
        .env("TUTTI_NAMESPACE", &ns);
    let mut g = Guard::spawn(host, &ns);
    let path = tutti_core::shm::segment::segment_path(&ns, "multiuav_uav1");
    wait_until(format!("{} did not appear", path.display()), Duration::from_secs(30), || path.exists());
    tutti_test_support::shrink_segment(&ns, "multiuav_uav1", 0);
    let status = g.host.wait_status(Duration::from_secs(30)).expect("the host went on over a shrunk segment");
    assert_eq!(status.signal(), None, "the host was killed by a signal: {status}\n{}", g.host.dump());
    assert_eq!(status.code(), Some(1), "{}", g.host.dump());
    let err = g.host.stderr();
    assert!(
        err.contains("multiuav_uav1") && err.contains("shrank") && err.contains(&path.display().to_string()),
        "{err}"
    );
    assert_eq!(segments(&ns), 0, "segments left after the error");
}
