//! `tutti-bench scale` in small (N <= 8, few steps): every shape runs to its end next to
//! HELICS, and every participant and federate answered every step (the benchmark checks the
//! counts and fails otherwise). No time is asserted: the figures are docs/benchmarks.md's.

use tutti_test_support as common;

use std::process::Command;
use std::time::Duration;

#[test]
fn bench_scale_runs_every_shape_next_to_helics_with_every_step_answered() {
    let Some(_) = common::python(&["helics"]) else { return };
    let Some(_) = common::require_tool("cc", "gcc") else { return };
    let ns = common::namespace("scale");
    let shapes = ["barrier", "hub", "leaves", "ring"];
    let ns_of = |shape: &str, n: u64| format!("{ns}{shape}x{n}");
    let _segments: Vec<_> = shapes.iter().flat_map(|s| [2, 8].map(|n| common::RemoveSegments(ns_of(s, n)))).collect();
    let mut cmd = Command::new(common::workspace_bin("tutti-bench", "tutti-bench"));
    cmd.args(["scale", "--n", "2,8", "--steps", "200", "--json"]).env("TUTTI_NAMESPACE", &ns);
    let (status, out, err) = common::run_with_timeout(cmd, Duration::from_secs(600));
    assert!(status.success(), "tutti-bench scale failed ({status}):\n{out}\n{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"));
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
    for shape in shapes {
        for n in [2, 8] {
            let left = common::segments_of(&ns_of(shape, n));
            assert!(left.is_empty(), "{shape} N={n} left {left:?}");
        }
    }
}
