//! An FMI 3.0 co-simulation FMU written in C against the FMI 3.0 headers of the `fmi-sys`
//! crate (tests/fmu/c/Integrator.c, built by the test into its temp dir): `tutti fmu inspect`
//! reads its typed variables, and, run as a participant of a synchronous domain, its recorded
//! trajectory equals fmpy's standalone one within 1e-9 relative at every step.

use tutti_test_support as common;
use tutti_test_support::fmu as fmu_common;

use std::time::Duration;

use fmu_common::{build_integrator, close, python};

const H: f64 = 0.01;
const OUTPUTS: [&str; 3] = ["y", "steps", "rising"];

fn tutti(args: &[&std::ffi::OsStr]) -> (i32, String, String) {
    common::tutti(args)
}

#[test]
fn an_fmi3_fmu_built_from_c_is_inspected_with_its_types() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = build_integrator(dir.path());
    let (code, out, err) = tutti(&["fmu".as_ref(), "inspect".as_ref(), fmu.as_os_str(), "--json".as_ref()]);
    assert_eq!(code, 0, "{err}");
    let json: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(json["fmi_version"], "3.0");
    assert_eq!(json["co_simulation"]["model_identifier"], "Integrator");
    let types: Vec<(String, String)> = json["variables"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| (v["name"].as_str().unwrap().to_string(), v["type"].as_str().unwrap().to_string()))
        .collect();
    assert!(types.contains(&("steps".into(), "Int32".into())) && types.contains(&("rising".into(), "Boolean".into())));
    let (code, out, _) = tutti(&["fmu".as_ref(), "inspect".as_ref(), fmu.as_os_str()]);
    assert_eq!(code, 0);
    assert!(out.contains("FMI version:    3.0") && out.contains("step 0.01"), "{out}");
}

#[test]
fn an_fmi3_fmu_in_a_synchronous_domain_matches_fmpy_at_every_step() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmu3sync");
    let fmu = build_integrator(dir.path());
    let ddf = dir.path().join("integrator.ddf");
    let (code, _, err) = tutti(&["fmu".as_ref(), "ddf".as_ref(), fmu.as_os_str(), "--out".as_ref(), ddf.as_os_str()]);
    assert_eq!(code, 0, "{err}");
    let csv = dir.path().join("run.csv");
    let host = fmu_common::host(&ns, &ddf, &csv, "2s", "integrator/u=2");
    let mut cmd = common::tutti_command();
    cmd.args(["fmu", "run"])
        .arg(&fmu)
        .arg("--ddf")
        .arg(&ddf)
        .args(["--domain", "integrator", "--connect-timeout", "20s", "--param", "k=0.5"])
        .env("TUTTI_NAMESPACE", &ns)
        .env("TMPDIR", dir.path());
    let (status, _, err) = common::run_with_timeout(cmd, Duration::from_secs(120));
    let (host_status, _, host_err) = host.join().unwrap();
    assert!(host_status.success(), "tutti host failed: {host_err}");
    assert!(status.success(), "tutti fmu run failed: {err}");
    let rows = fmu_common::recorded(&csv, &OUTPUTS, 1);
    let counts: Vec<u64> = rows.keys().copied().collect();
    assert!(counts.len() > 50, "only {} steps recorded", counts.len());
    // Every row, repeats kept: a framework step answered with a stale count shows here.
    let every = fmu_common::recorded_counts(&csv, OUTPUTS[1]);
    assert!(every.windows(2).skip(1).all(|w| w[1] == w[0] + 1), "a step is missing or repeated: {every:?}");
    // From the FMU's second step on, lock-step: every step is a row (see fmu_run.rs).
    assert!(counts.windows(2).skip(1).all(|w| w[1] == w[0] + 1), "a step is missing or repeated: {counts:?}");
    let start = rows.values().next().unwrap().0 - (counts[0] - 1) as f64 * H;
    let reference =
        fmu_common::reference(&py, &fmu, start, *counts.last().unwrap(), H, ("u", 2.0), r#"{"k": 0.5}"#, &OUTPUTS);
    let compared = fmu_common::compare(&rows, &reference, &OUTPUTS);
    assert!(compared + 1 >= counts.len(), "compared {compared} of {} steps", counts.len());
    assert!(close(rows[&50].1[0], 50.0 * H * 0.5 * 2.0), "y after 50 steps: {:?}", rows[&50]);
}

#[test]
fn bad_parameters_are_refused_before_connecting() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = build_integrator(dir.path());
    let ddf = dir.path().join("integrator.ddf");
    let (code, _, err) = tutti(&["fmu".as_ref(), "ddf".as_ref(), fmu.as_os_str(), "--out".as_ref(), ddf.as_os_str()]);
    assert_eq!(code, 0, "{err}");
    for (param, expected) in [
        ("nope=1", "model 'Integrator' has no such variable"),
        ("k=abc", "'abc' is not a float64 value"),
        ("y=1", "the variable is output, not a parameter or input"),
        ("k", "expected NAME=VALUE"),
    ] {
        let mut cmd = common::tutti_command();
        cmd.args(["fmu", "run"])
            .arg(&fmu)
            .arg("--ddf")
            .arg(&ddf)
            .args(["--domain", "integrator", "--connect-timeout", "100ms", "--param", param])
            .env("TUTTI_NAMESPACE", tutti_test_support::namespace("fmu3param"))
            .env("TMPDIR", dir.path());
        let (status, _, err) = common::run_with_timeout(cmd, Duration::from_secs(60));
        assert_eq!(status.code(), Some(2), "--param {param}: {err}");
        assert!(err.contains(expected), "--param {param}: {err}");
    }
}
