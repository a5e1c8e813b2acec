//! `tutti fmu run` with an FMI 2.0 co-simulation FMU exported by pythonfmu from
//! tests/fmu/python/Lag.py (built by the test into its temp dir):
//!
//! * synchronous domain: the trajectory recorded by `tutti host --record` (the FMU a
//!   participant, its input driven by the framework) equals fmpy's standalone simulation
//!   with the same input, parameters and step within 1e-9 relative, at every step;
//! * asynchronous domain: the FMU steps on its own clock and its outputs reach the
//!   framework, equal to fmpy's after as many steps;
//! * a doStep that fails ends the component with the FMU's log and exit 1, and the framework
//!   steps on.

use tutti_test_support as common;
use tutti_test_support::fmu as fmu_common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitStatus;
use std::thread;
use std::time::Duration;

use fmu_common::{build_lag, close, libpython, python};

const H: f64 = 0.01;
const OUTPUTS: [&str; 5] = ["y", "integral", "t", "count", "positive"];

/// Lag.fmu and its DDF (`tutti fmu ddf`) in `dir`.
fn setup(py: &Path, dir: &Path, synchronous: bool) -> (PathBuf, PathBuf) {
    let fmu = build_lag(py, dir);
    let ddf = dir.join("lag.ddf");
    let sync = if synchronous { "yes" } else { "no" };
    let (code, _, err) = common::tutti([
        "fmu".as_ref(),
        "ddf".as_ref(),
        fmu.as_os_str(),
        "--domain".as_ref(),
        "lag".as_ref(),
        "--synchronous".as_ref(),
        sync.as_ref(),
        "--out".as_ref(),
        ddf.as_os_str(),
    ]);
    assert_eq!(code, 0, "{err}");
    (fmu, ddf)
}

/// The FMU is unpacked under the test's temp dir (TMPDIR), which goes even if the run crashes.
fn fmu_run(ns: &str, py: &Path, fmu: &Path, ddf: &Path, args: &[&str]) -> (ExitStatus, String, String) {
    fmu_run_with(ns, fmu, ddf, args, Some(&libpython(py)), None)
}

/// `tutti fmu run`, with `--preload LIB` if given and PATH replaced by `path` if given.
fn fmu_run_with(
    ns: &str,
    fmu: &Path,
    ddf: &Path,
    args: &[&str],
    preload: Option<&Path>,
    path: Option<&Path>,
) -> (ExitStatus, String, String) {
    let tmp = fmu.parent().expect("the FMU is in the test's temp dir");
    let mut cmd = common::tutti_command();
    cmd.args(["fmu", "run"])
        .arg(fmu)
        .arg("--ddf")
        .arg(ddf)
        .args(["--domain", "lag", "--connect-timeout", "20s"])
        .args(["--param", "tau=0.25", "--param", "gain=2"])
        .args(args)
        .env("TUTTI_NAMESPACE", ns)
        .env("TMPDIR", tmp)
        .env_remove("TUTTI_FMU_PRELOAD");
    if let Some(lib) = preload {
        cmd.arg("--preload").arg(lib);
    }
    if let Some(path) = path {
        cmd.env("PATH", path);
    }
    common::run_with_timeout(cmd, Duration::from_secs(120))
}

fn host(ns: &str, ddf: &Path, csv: &Path, duration: &str) -> thread::JoinHandle<(ExitStatus, String, String)> {
    fmu_common::host(ns, ddf, csv, duration, "lag/u=1.5")
}

fn recorded(csv: &Path) -> BTreeMap<u64, (f64, Vec<f64>)> {
    fmu_common::recorded(csv, &OUTPUTS, 3)
}

fn reference(py: &Path, fmu: &Path, start: f64, steps: u64) -> BTreeMap<u64, Vec<f64>> {
    fmu_common::reference(py, fmu, start, steps, H, ("u", 1.5), r#"{"tau": 0.25, "gain": 2.0}"#, &OUTPUTS)
}

fn compare(rows: &BTreeMap<u64, (f64, Vec<f64>)>, reference: &BTreeMap<u64, Vec<f64>>) -> usize {
    fmu_common::compare(rows, reference, &OUTPUTS)
}

#[test]
fn a_pythonfmu_fmu_in_a_synchronous_domain_matches_fmpy_at_every_step() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmusync");
    let (fmu, ddf) = setup(&py, dir.path(), true);
    let csv = dir.path().join("run.csv");
    let host = host(&ns, &ddf, &csv, "3s");
    let (status, _, err) = fmu_run(&ns, &py, &fmu, &ddf, &[]);
    let (host_status, _, host_err) = host.join().unwrap();
    assert!(host_status.success(), "tutti host failed: {host_err}");
    assert!(status.success(), "tutti fmu run failed: {err}");
    assert!(err.contains("the framework stopped"), "{err}");
    let rows = recorded(&csv);
    // The FMU joins at some step; whether the framework already waited for its answer to the
    // first step it read depends on timing (it is a writer only once it has committed), so
    // the comparison is by the FMU's own step count: from its second step on, every step is
    // a row (lock-step), and each must equal fmpy's.
    let counts: Vec<u64> = rows.keys().copied().collect();
    assert!(counts.len() > 50, "only {} steps recorded", counts.len());
    // Every row, repeats kept: a framework step answered with a stale count shows here.
    let every = fmu_common::recorded_counts(&csv, OUTPUTS[3]);
    assert!(every.windows(2).skip(1).all(|w| w[1] == w[0] + 1), "a step is missing or repeated: {every:?}");
    assert!(counts.windows(2).skip(1).all(|w| w[1] == w[0] + 1), "a step is missing or repeated: {counts:?}");
    // The FMU started at the framework's time of its first step: t after n steps is start + n·h.
    let (first, (_, values)) = rows.iter().next().unwrap();
    let start = values[2] - *first as f64 * H;
    for (n, (sim, values)) in &rows {
        assert!(close(values[2], sim + H), "step {n}: the FMU's time {} is not the framework's {sim} + h", values[2]);
    }
    let reference = reference(&py, &fmu, start, *counts.last().unwrap());
    let compared = compare(&rows, &reference);
    assert!(compared + 1 >= counts.len(), "compared {compared} of {} steps", counts.len());
}

#[test]
fn a_pythonfmu_fmu_steps_on_its_own_clock_in_an_asynchronous_domain() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmuasync");
    let (fmu, ddf) = setup(&py, dir.path(), false);
    let csv = dir.path().join("run.csv");
    let host = host(&ns, &ddf, &csv, "4s");
    let (status, _, err) = fmu_run(&ns, &py, &fmu, &ddf, &["--step", "10ms", "--steps", "60"]);
    let (host_status, _, host_err) = host.join().unwrap();
    assert!(host_status.success(), "tutti host failed: {host_err}");
    assert!(status.success(), "tutti fmu run failed: {err}");
    assert!(err.contains("made 60 steps"), "{err}");
    let rows = recorded(&csv);
    assert!(rows.contains_key(&60), "the last step never reached the framework: {:?}", rows.keys());
    // On its own clock the FMU starts at 0 and steps by 10 ms with the latest input (constant
    // here), so each step seen equals fmpy's.
    let reference = reference(&py, &fmu, 0.0, 60);
    assert!(compare(&rows, &reference) >= 10);
}

#[test]
fn a_failing_do_step_ends_the_component_with_the_fmu_log_and_the_framework_steps_on() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmufail");
    let (fmu, ddf) = setup(&py, dir.path(), true);
    let csv = dir.path().join("run.csv");
    let host = host(&ns, &ddf, &csv, "3s");
    // The model refuses (status Error, with a log message) its first step past 1.5 s of the
    // framework's time, whenever it joined.
    let (status, _, err) = fmu_run(&ns, &py, &fmu, &ddf, &["--param", "fail_at=1.5"]);
    let (host_status, _, host_err) = host.join().unwrap();
    assert_eq!(status.code(), Some(1), "tutti fmu run: {err}");
    assert!(err.contains("doStep") && err.contains("refusing to step past fail_at=1.5"), "{err}");
    assert!(host_status.success(), "tutti host failed: {host_err}");
    // The framework went on to its end, with the connection gone.
    let text = std::fs::read_to_string(&csv).unwrap();
    let last = text.lines().last().unwrap();
    let f: Vec<&str> = last.split(',').collect();
    assert_eq!(f[3], "0", "connections at the end: {last}");
    assert!(f[1].parse::<f64>().unwrap() > 2.5, "the framework stopped early: {last}");
}

#[test]
fn a_python_exception_in_do_step_is_reported_with_the_fmu_log_not_a_crash() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmuraise");
    let (fmu, ddf) = setup(&py, dir.path(), true);
    let csv = dir.path().join("run.csv");
    let host = host(&ns, &ddf, &csv, "2s");
    // PythonFMU reports the exception at status Fatal with a NULL log category.
    let (status, _, err) = fmu_run(&ns, &py, &fmu, &ddf, &["--param", "raise_at=1.0"]);
    let (host_status, _, host_err) = host.join().unwrap();
    assert_eq!(status.code(), Some(1), "tutti fmu run: {err}");
    assert!(
        err.contains("doStep") && err.contains("Fatal") && err.contains("RuntimeError('Lag: raise_at=1.0 reached')"),
        "{err}"
    );
    assert!(host_status.success(), "tutti host failed: {host_err}");
}

/// Without `--preload`, a PythonFMU model gets the libpython of the `python3` on PATH (the
/// one whose packages its embedded interpreter finds): the run steps as with `--preload`.
/// With no python3 on PATH, the refusal says what is missing and how to give it.
#[test]
fn a_pythonfmu_model_finds_libpython_from_the_python3_on_path() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmulibpy");
    let (fmu, ddf) = setup(&py, dir.path(), false);
    // PATH is the test's Python's directory only, which has its python3 (a venv's bin, or
    // the system's).
    let bin = py.parent().unwrap();
    assert!(bin.join("python3").exists(), "no python3 beside {}", py.display());
    let csv = dir.path().join("run.csv");
    let host = host(&ns, &ddf, &csv, "4s");
    let args = ["--step", "10ms", "--steps", "30", "-q"];
    let (status, _, err) = fmu_run_with(&ns, &fmu, &ddf, &args, None, Some(bin));
    let (host_status, _, host_err) = host.join().unwrap();
    assert!(host_status.success(), "tutti host failed: {host_err}");
    assert!(status.success(), "tutti fmu run without --preload failed: {err}");
    let rows = recorded(&csv);
    assert!(rows.contains_key(&30), "the last step never reached the framework: {:?}", rows.keys());

    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let (status, _, err) = fmu_run_with(&ns, &fmu, &ddf, &args, None, Some(&empty));
    assert_eq!(status.code(), Some(2), "{err}");
    assert!(err.contains("undefined symbol") && err.contains("could not find it (running python3"), "{err}");
    assert!(err.contains("--preload"), "{err}");
}
