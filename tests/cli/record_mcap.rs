//! `tutti host --record run.mcap` beside `--record run.csv` in the same run: the MCAP file is
//! read with the ROS ecosystem's own Python libraries (`mcap`, `mcap-ros2-support`), every
//! schema parses, and every step's messages equal that step's CSV row, element by element.

use tutti_test_support as common;

use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use tutti_core::shm::{ConnectOptions, Participant};

/// The venv's Python with the MCAP libraries, or None (skipped; a failure under CI=true).
fn python() -> Option<PathBuf> {
    common::python(&["mcap", "mcap_ros2"])
}

#[test]
fn an_mcap_recording_reads_back_with_ros_tools_and_equals_the_csv_of_the_same_run() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("recmcap");
    let (csv, mcap) = (dir.path().join("run.csv"), dir.path().join("run.mcap"));
    let mut host = common::tutti_command();
    host.args(["host", "ddf/product-sample.ddf", "--step", "5ms", "--duration", "1500ms", "--timeout", "200ms", "-q"])
        .arg("--record")
        .arg(&csv)
        .arg("--record")
        .arg(&mcap)
        .args(["--set", "grid_feeder/voltage_abc=230.5", "--set", "grid_feeder/meter/samples=7"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("TUTTI_NAMESPACE", &ns);
    // A component that writes a changing SUBSCRIBE value for part of the run (its first 140
    // steps of 300), so that the recording has values that move and connection events.
    let stop = Arc::new(AtomicBool::new(false));
    let (s, ns2) = (stop.clone(), ns.clone());
    let component = thread::spawn(move || {
        let opts = ConnectOptions {
            namespace: ns2.clone(),
            name: "recorded-component".into(),
            connect_timeout: Duration::from_secs(20),
            skip_wait_to_go: true,
            ..Default::default()
        };
        let mut p = Participant::connect("grid_feeder", opts).map_err(|e| e.to_string())?;
        let domain = tutti_core::shm::Segment::open(&ns2, "grid_feeder").map_err(|e| e.to_string())?;
        let (mut n, mut commits) = (0u32, 0u32);
        while domain.status().step < 140 && !s.load(Ordering::Acquire) {
            n += 1;
            p.stage("setpoint_kw", &(f64::from(n) * 0.25).to_ne_bytes()).map_err(|e| e.to_string())?;
            p.stage("mode", &[(n % 3) as u8]).map_err(|e| e.to_string())?;
            if p.commit().is_ok() {
                commits += 1;
            }
            thread::sleep(Duration::from_millis(3));
        }
        Ok::<u32, String>(commits)
    });
    let (status, _, err) = common::run_with_timeout(host, Duration::from_secs(120));
    stop.store(true, Ordering::Release);
    let commits = component.join().unwrap();
    assert!(status.success(), "tutti host failed: {err}");
    let commits = commits.unwrap_or_else(|e| panic!("the component failed: {e}"));
    assert!(commits > 10, "the component committed {commits} times");
    // Its values moved in the recording: the setpoint takes several values.
    let text = std::fs::read_to_string(dir.path().join("run-grid_feeder.csv")).unwrap();
    let head: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = head.iter().position(|h| h.contains("subscribe.setpoint_kw")).expect("the setpoint column");
    let setpoints: std::collections::BTreeSet<&str> =
        text.lines().skip(1).filter_map(|l| l.split(',').nth(col)).collect();
    assert!(setpoints.len() > 2, "the setpoint never moved in the recording: {setpoints:?}");
    let mut check = Command::new(py);
    check
        .arg("tests/record/check_mcap.py")
        .arg(&mcap)
        .arg(&csv)
        .args(["grid_feeder", "grid_clock"])
        .current_dir(env!("CARGO_MANIFEST_DIR"));
    let (status, out, err) = common::run_with_timeout(check, Duration::from_secs(120));
    assert!(status.success(), "the MCAP recording does not match the CSV:\n{out}\n{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).expect("one JSON line");
    let rows = v["rows"].as_u64().unwrap();
    assert!(rows > 100, "{v}");
    assert_eq!(v["messages"].as_u64().unwrap(), 2 * rows, "a message per set and step: {v}");
    assert_eq!(v["schemas"], 4, "{v}");
    // The component connects during the seed wait or the first steps, and leaves mid-run:
    // its departure is an event of its own, beside the recorder's start events.
    assert!(v["events"]["grid_feeder/disconnect"].as_u64().unwrap_or(0) >= 1, "the component's departure: {v}");
}

/// `tutti record` beside a running host: a passive observer (the host's recording shows no
/// connection for it), whose MCAP steps equal the host's own CSV rows for the same steps.
#[test]
fn tutti_record_follows_a_live_run_without_taking_part() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("recpassive");
    let (csv, mcap) = (dir.path().join("host.csv"), dir.path().join("observed.mcap"));
    let tutti = |args: &[&str]| {
        let mut c = common::tutti_command();
        c.args(args).current_dir(env!("CARGO_MANIFEST_DIR")).env("TUTTI_NAMESPACE", &ns);
        c
    };
    let mut host =
        tutti(&["host", "ddf/product-sample.ddf", "--step", "10ms", "--duration", "4s", "--timeout", "50ms"]);
    host.args(["-q", "--set", "grid_feeder/voltage_abc=231.25", "--record"]).arg(&csv);
    let host = thread::spawn(move || common::run_with_timeout(host, Duration::from_secs(120)));
    let mut record = tutti(&["record", "ddf/product-sample.ddf", "--duration", "2500ms", "--out"]);
    record.arg(&mcap);
    let (status, _, err) = common::run_with_timeout(record, Duration::from_secs(120));
    assert!(status.success(), "tutti record failed: {err}");
    assert!(err.contains("following its framework"), "{err}");
    let (status, _, herr) = host.join().unwrap();
    assert!(status.success(), "tutti host failed: {herr}");
    // Not a participant: no connection during the whole run.
    let text = std::fs::read_to_string(dir.path().join("host-grid_feeder.csv")).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "connections").unwrap();
    assert!(text.lines().skip(1).all(|l| l.split(',').nth(col) == Some("0")), "the recorder took part");
    let mut check = Command::new(py);
    check
        .arg("tests/record/check_mcap.py")
        .arg("--subset")
        .arg(&mcap)
        .arg(&csv)
        .args(["grid_feeder", "grid_clock"])
        .current_dir(env!("CARGO_MANIFEST_DIR"));
    let (status, out, err) = common::run_with_timeout(check, Duration::from_secs(120));
    assert!(status.success(), "the observed recording differs from the host's:\n{out}\n{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).expect("one JSON line");
    assert!(v["messages"].as_u64().unwrap() > 2 * 2 * 50, "at least 50 steps of each domain observed: {v}");
}
