//! `tutti-bench scale` in small (N <= 8, few steps): every shape runs to its end next to
//! HELICS (fan-out next to iceoryx2), and every participant and federate answered every step
//! and every reader read every write (the benchmark checks the counts and fails otherwise).
//! No time is asserted: the figures are docs/benchmarks.md's.

use tutti_test_support as common;

use std::process::Command;
use std::time::Duration;

/// `tutti-bench scale ARGS --json` in namespace prefix `ns` (its runs' segments removed
/// whatever happens, and checked gone after it): what it printed, which must be JSON.
fn scale(ns: &str, namespaces: &[String], args: &[&str], limit: Duration) -> serde_json::Value {
    let _segments: Vec<_> = namespaces.iter().cloned().map(common::RemoveSegments).collect();
    let mut cmd = Command::new(common::workspace_bin("tutti-bench", "tutti-bench"));
    cmd.arg("scale").args(args).arg("--json").env("TUTTI_NAMESPACE", ns);
    let (status, out, err) = common::run_with_timeout(cmd, limit);
    assert!(status.success(), "tutti-bench scale {args:?} failed ({status}):\n{out}\n{err}");
    for ns in namespaces {
        let left = common::segments_of(ns);
        assert!(left.is_empty(), "{ns} left {left:?}");
    }
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"))
}

#[test]
fn bench_scale_runs_every_shape_next_to_its_peer_with_every_step_answered() {
    let Some(_) = common::python(&["helics"]) else { return };
    let Some(_) = common::require_tool("cc", "gcc") else { return };
    let ns = common::namespace("scale");
    let shapes = ["barrier", "hub", "leaves", "ring"];
    let ns_of = |shape: &str, n: u64| format!("{ns}{shape}x{n}");
    let mut namespaces: Vec<String> = shapes.iter().flat_map(|s| [2, 8].map(|n| ns_of(s, n))).collect();
    namespaces.extend([1, 10].map(|r| ns_of("fanout", r)));
    let args = ["--n", "2,8", "--steps", "200", "--readers", "1,10", "--writes", "500"];
    let v = scale(&ns, &namespaces, &args, Duration::from_secs(600));
    assert!(v["helics"].as_str().is_some_and(|h| h.starts_with("3.")), "{v}");
    let runs = v["runs"].as_array().expect("runs");
    for shape in shapes {
        for n in [2u64, 8] {
            for system in ["tutti", "HELICS"] {
                let found = runs.iter().filter(|r| r["shape"] == shape && r["n"] == n && r["system"] == system).count();
                let want = usize::from(system == "tutti" || shape != "leaves");
                assert_eq!(found, want, "{system} {shape} N={n} in {v}");
            }
        }
    }
    assert!(runs.iter().all(|r| r["steps"] == 200 && r["steps_per_s"].as_f64().is_some_and(|s| s > 0.0)), "{v}");
    let fan = v["fan_out"].as_array().expect("fan_out");
    for r in [1u64, 10] {
        for system in ["tutti", "iceoryx2"] {
            let found: Vec<_> = fan.iter().filter(|f| f["readers"] == r && f["system"] == system).collect();
            assert_eq!(found.len(), 1, "{system} fan-out to {r} in {v}");
            assert_eq!(found[0]["writes"], 500, "{v}");
        }
    }
}

/// The same with every participant a process of its own (`--processes`): each answered every
/// step, and each process ended.
#[test]
fn bench_scale_with_participant_processes_answers_every_step() {
    let ns = common::namespace("scaleproc");
    let namespaces: Vec<String> = [2, 8].map(|n| format!("{ns}hubx{n}")).to_vec();
    let args = ["--shapes", "hub", "--n", "2,8", "--steps", "100", "--processes", "--no-helics"];
    let v = scale(&ns, &namespaces, &args, Duration::from_secs(300));
    let runs = v["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 2, "{v}");
    assert!(runs.iter().all(|r| r["system"] == "tutti (processes)" && r["steps"] == 100), "{v}");
}
