//! Checkpoints (docs/run.md, "Checkpoints"): a system of a C RTAPI component with state
//! callbacks, the suite's C FMU and two PythonFMUs (all getting and setting their state), in
//! a loop of connections, saved at step 500 and restored by a new run, reproduces the straight
//! run value by value (bit-identical doubles), and so does a restore into the run still going;
//! a component that keeps no state fails `tutti ctl save`
//! with its name (and is left out, named, when told); a checkpoint of another DDF, or a
//! damaged one, is refused with the reason (exit 2) before anything runs.

use tutti_test_support as common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{fmu, wait_until, Proc, RemoveSegments};

const LIMIT: Duration = Duration::from_secs(240);
const WAIT: Duration = Duration::from_secs(120);

/// A directory with the DDF, the C component `stateful`, the FMUs (with `fmus`: the C
/// Integrator and the PythonFMU Lag, built with state handling) and a launch file per `files`
/// entry. With FMUs, also the libpython they need preloaded; None when Python with pythonfmu
/// is missing (a failure under CI=true).
fn setup(files: &[(&str, String)], fmus: bool) -> Option<(tempfile::TempDir, Option<PathBuf>)> {
    let dir = tempfile::tempdir().unwrap();
    let src = common::repo_root().join("tests/checkpoint");
    for ddf in ["cosim.ddf", "plant.ddf"] {
        std::fs::copy(src.join(ddf), dir.path().join(ddf)).unwrap();
    }
    common::compile_c(&src.join("stateful.c"), &dir.path().join("stateful"), &["-std=c99", "-Wall", "-Werror"]);
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    let mut preload = None;
    if fmus {
        let py = fmu::python()?;
        fmu::build_integrator(dir.path());
        fmu::build_lag_with(&py, dir.path(), fmu::PythonFmuOptions { state: true });
        preload = Some(fmu::libpython(&py));
    }
    Some((dir, preload))
}

/// The FMU components and the loop: plant -> integ -> lag1 -> lag2 -> plant.
const SYSTEM: &str = r#",
    { name: "integ", fmu: "Integrator.fmu", domain: "integ", params: ["k=0.5"] },
    { name: "lag1", fmu: "Lag.fmu", domain: "lag1", params: ["tau=0.05"] },
    { name: "lag2", fmu: "Lag.fmu", domain: "lag2", params: ["tau=0.2", "gain=0.5"] } ],
  connections: ["plant/subscribe/y -> integ/publish/u", "integ/subscribe/y -> lag1/publish/u",
                "lag1/subscribe/y -> lag2/publish/u", "lag2/subscribe/y -> plant/publish/u"] }"#;

/// A launch file: `stateful` (with `extra` arguments) fed back through a connection, or with
/// `system` in the loop of the FMUs ([`SYSTEM`]), stepping as fast as it goes (or `speed`),
/// `steps` steps (0: until stopped), recording `record`, with `more` framework keys and
/// component keys `component`.
fn launch(steps: u64, speed: &str, record: &str, more: &str, component: &str, system: bool) -> String {
    let steps = if steps == 0 { String::new() } else { format!("steps: {steps}, ") };
    // The C component alone has a DDF of its domain alone: no other domain waits for a seed.
    let (ddf, rest) = if system {
        ("cosim.ddf", SYSTEM)
    } else {
        (
            "plant.ddf",
            r#" ],
  connections: ["plant/subscribe/y -> plant/publish/u"] }"#,
        )
    };
    format!(
        r#"{{ ddf: "{ddf}",
  framework: {{ step: "10ms", speed: {speed}, {steps}hold: true, timeout: "10s", record: ["{record}"]{more} }},
  components: [ {{ name: "c", run: ["./stateful", "{ddf}", "plant"{component}], domain: "plant" }}{rest}"#
    )
}

/// `tutti run FILE` in `dir` (with libpython preloaded for the PythonFMUs, when given).
fn start_with(dir: &Path, file: &str, ns: &str, extra: &[&str], preload: Option<&Path>) -> Proc {
    let mut cmd = common::tutti_command();
    cmd.current_dir(dir).arg("run").arg(file).args(["-q", "--grace", "5s"]).args(extra).env("TUTTI_NAMESPACE", ns);
    cmd.env("TMPDIR", dir);
    if let Some(p) = preload {
        cmd.env("TUTTI_FMU_PRELOAD", p);
    }
    Proc::spawn("tutti run", cmd, LIMIT)
}

fn start(dir: &Path, file: &str, ns: &str, extra: &[&str]) -> Proc {
    start_with(dir, file, ns, extra, None)
}

fn finish(mut run: Proc) {
    assert_eq!(run.wait(WAIT), Some(0), "the run failed\n{}", run.dump());
}

/// `tutti ctl ARGS` in namespace `ns`: (exit status, stdout, stderr).
pub(crate) fn ctl(ns: &str, args: &[&str], dir: &Path) -> (i32, String, String) {
    let mut cmd = common::tutti_command();
    cmd.current_dir(dir).arg("ctl").args(args).env("TUTTI_NAMESPACE", ns);
    let (status, out, err) = common::run_with_timeout(cmd, WAIT);
    (status.code().unwrap_or(-1), out, err)
}

/// One CSV file's rows in order: (step index, every value of the row, as written).
pub(crate) fn csv_rows(csv: &Path) -> Vec<(u64, Vec<String>)> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let sim = head.iter().position(|h| *h == "sim_time").unwrap_or_else(|| panic!("no sim_time in {head:?}"));
    // The values: every column but the step's number, time and connections.
    let values: Vec<usize> =
        (0..head.len()).filter(|&i| head[i].starts_with("publish.") || head[i].starts_with("subscribe.")).collect();
    assert!(values.len() >= 2, "no values in {head:?}");
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let index = (f[sim].parse::<f64>().unwrap() / 0.01).round() as u64;
            (index, values.iter().map(|&i| f[i].to_string()).collect())
        })
        .collect()
}

/// A recording's rows in order, every domain's (`STEM-DOMAIN.csv`, by domain name) side by
/// side: (step index, every value of the step).
fn rows(dir: &Path, stem: &str) -> Vec<(u64, Vec<String>)> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with(&format!("{stem}-"))))
        .filter(|p| p.extension().is_some_and(|x| x == "csv"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 4, "a recording per domain: {files:?}");
    let mut all = csv_rows(&files[0]);
    for f in &files[1..] {
        let more = csv_rows(f);
        assert_eq!(more.len(), all.len(), "{}: as many steps as the others", f.display());
        for (row, (index, values)) in all.iter_mut().zip(more) {
            assert_eq!(row.0, index, "{}: the same steps", f.display());
            row.1.extend(values);
        }
    }
    all
}

/// The straight run: 1,000 steps, as a map from step index to values.
fn straight(dir: &Path, ns: &str, preload: Option<&Path>) -> BTreeMap<u64, Vec<String>> {
    finish(start_with(dir, "straight.json5", ns, &[], preload));
    let all: BTreeMap<u64, Vec<String>> = rows(dir, "straight").into_iter().collect();
    assert_eq!(all.len(), 1000, "the straight run's steps");
    all
}

/// A recording's rows: (step index, every value of the step).
pub(crate) type Row = (u64, Vec<String>);

/// A recording of a run restored into at step index `at` while it went on to `end` and past:
/// (the rows before the restore, the rows from `at` to `end` made again after it).
pub(crate) fn split_at_restore(all: &[Row], at: u64, end: u64) -> (&[Row], Vec<Row>) {
    let back = all.windows(2).position(|w| w[1].0 < w[0].0).expect("the recording goes back at the restore") + 1;
    assert_eq!(all[back].0, at, "the restore went back to step index {at}");
    let after: Vec<Row> = all[back..].iter().filter(|r| r.0 < end).cloned().collect();
    assert_eq!(after.len() as u64, end - at, "steps {at} to {} again", end - 1);
    (&all[..back], after)
}

/// Every row of `part` equals the straight run's row of the same step, value by value.
pub(crate) fn same_as(straight: &BTreeMap<u64, Vec<String>>, part: &[(u64, Vec<String>)], what: &str) {
    assert!(!part.is_empty(), "{what}: no rows");
    for (index, values) in part {
        assert_eq!(straight.get(index), Some(values), "{what}: step index {index} differs from the straight run");
    }
}

#[test]
fn a_run_saved_at_step_500_and_restored_goes_on_as_the_straight_run() {
    let ns = common::namespace("ckpsplit");
    let _segments = RemoveSegments(ns.clone());
    let every = r#", checkpoint: { every: 500, dir: "ck", keep: 1 }"#;
    let Some((dir, preload)) = setup(
        &[
            ("straight.json5", launch(1000, "0", "straight.csv", "", "", true)),
            ("first.json5", launch(500, "0", "first.csv", every, "", true)),
            ("second.json5", launch(1000, "0", "second.csv", "", "", true)),
        ],
        true,
    ) else {
        return;
    };
    let (dir, preload) = (dir.path(), preload.as_deref());
    let reference = straight(dir, &ns, preload);

    finish(start_with(dir, "first.json5", &ns, &[], preload));
    let c = tutti_host::checkpoint::Checkpoint::read(&dir.join("ck/step-000000500.tutti-checkpoint")).unwrap();
    let mut saved: Vec<&str> = c.components.iter().map(|s| s.name.as_str()).collect();
    saved.sort_unstable();
    assert_eq!(saved, ["c", "integ", "lag1", "lag2"], "every component's state is in the checkpoint");
    let ckpt = dir.join("ck/step-000000500.tutti-checkpoint");
    assert!(ckpt.exists(), "no checkpoint at step 500");
    let first = rows(dir, "first");
    assert_eq!(first.len(), 500);
    same_as(&reference, &first, "the first half");

    finish(start_with(dir, "second.json5", &ns, &["--restore", ckpt.to_str().unwrap()], preload));
    let second = rows(dir, "second");
    assert_eq!(
        second.iter().map(|r| r.0).collect::<Vec<_>>(),
        (500..1000).collect::<Vec<_>>(),
        "the second half's steps"
    );
    same_as(&reference, &second, "the run restored from step 500");
}

#[test]
fn a_restore_into_the_running_run_goes_back_to_step_500_and_on_as_the_straight_run() {
    let ns = common::namespace("ckpinto");
    let _segments = RemoveSegments(ns.clone());
    // Paced (5 times real time): the test pauses it after its checkpoint at 500. Late steps
    // are made, not skipped: the component is stepped at every step, as in the straight run.
    let every = r#", catch_up: true, checkpoint: { every: 500, dir: "ck" }"#;
    let Some((dir, preload)) = setup(
        &[
            ("straight.json5", launch(1000, "0", "straight.csv", "", "", true)),
            ("long.json5", launch(0, "5", "long.csv", every, "", true)),
        ],
        true,
    ) else {
        return;
    };
    let (dir, preload) = (dir.path(), preload.as_deref());
    let reference = straight(dir, &ns, preload);

    let run = start_with(dir, "long.json5", &ns, &[], preload);
    let ckpt = dir.join("ck/step-000000500.tutti-checkpoint");
    wait_until(format_args!("the checkpoint at step 500\n{}", run.dump()), WAIT, || ckpt.exists());
    let (code, out, err) = ctl(&ns, &["pause"], dir);
    assert_eq!(code, 0, "{out}{err}");
    let (code, out, err) = ctl(&ns, &["restore", "ck/step-000000500.tutti-checkpoint"], dir);
    assert_eq!(code, 0, "restore: {out}{err}\n{}", run.dump());
    assert!(out.contains("paused"), "a restore leaves a paused run paused: {out}");
    let (code, out, err) = ctl(&ns, &["resume"], dir);
    assert_eq!(code, 0, "{out}{err}");
    // Steps count from the checkpoint's again: the next periodic one is at step 1000.
    let at_1000 = dir.join("ck/step-000001000.tutti-checkpoint");
    wait_until("the checkpoint at step 1000", WAIT, || at_1000.exists());
    let (code, out, err) = ctl(&ns, &["stop"], dir);
    assert_eq!(code, 0, "{out}{err}");
    finish(run);

    let all = rows(dir, "long");
    let (before, after) = split_at_restore(&all, 500, 1000);
    same_as(&reference, before, "before the restore");
    same_as(&reference, &after, "after the restore");
}

#[test]
fn a_component_without_a_state_is_named_and_a_checkpoint_of_another_ddf_is_refused() {
    let ns = common::namespace("ckpstateless");
    let _segments = RemoveSegments(ns.clone());
    let (dir, _) = setup(&[("nostate.json5", launch(0, "5", "n.csv", "", r#", "nostate""#, false))], false).unwrap();
    let dir = dir.path();
    let run = start(dir, "nostate.json5", &ns, &[]);
    wait_until("the run playing", WAIT, || ctl(&ns, &["state"], dir).1.contains("playing"));
    let (code, _, err) = ctl(&ns, &["save", "x.tutti-checkpoint"], dir);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("'c' (domain 'plant')") && err.contains("keep no state"), "{err}");
    assert!(!dir.join("x.tutti-checkpoint").exists());
    // Nor has the run a checkpoint of its step 0 to reset to, and it says why.
    let (code, _, err) = ctl(&ns, &["reset", "state"], dir);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no checkpoint of its step 0") && err.contains("'c' (domain 'plant')"), "{err}");
    let (code, out, err) = ctl(&ns, &["save", "skip.tutti-checkpoint", "--skip-stateless"], dir);
    assert_eq!(code, 0, "{out}{err}");
    let c = tutti_host::checkpoint::Checkpoint::read(&dir.join("skip.tutti-checkpoint")).unwrap();
    assert!(c.components.is_empty());
    assert_eq!(
        c.skipped.iter().map(|s| (s.name.as_str(), s.why.as_str())).collect::<Vec<_>>(),
        [("c", "keeps no state")]
    );

    // Another DDF: the same domain with another item.
    let other = dir.join("other.ddf");
    let text = std::fs::read_to_string(dir.join("plant.ddf")).unwrap().replace(r#"name="y""#, r#"name="z""#);
    std::fs::write(&other, text).unwrap();
    let model = tutti_core::ddf::load(&other).unwrap();
    let mut foreign = c.clone();
    foreign.domains[0].layout_hash = model.domains[0].layout_hash;
    foreign.write(&dir.join("foreign.tutti-checkpoint")).unwrap();
    let (code, _, err) = ctl(&ns, &["restore", "foreign.tutti-checkpoint"], dir);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("another DDF") && err.contains("layout hash"), "{err}");
    // Truncated: refused, and the run goes on.
    let bytes = std::fs::read(dir.join("skip.tutti-checkpoint")).unwrap();
    std::fs::write(dir.join("cut.tutti-checkpoint"), &bytes[..bytes.len() / 2]).unwrap();
    let (code, _, err) = ctl(&ns, &["restore", "cut.tutti-checkpoint"], dir);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("not a tutti checkpoint") || err.contains("damaged"), "{err}");
    let (code, out, err) = ctl(&ns, &["stop"], dir);
    assert_eq!(code, 0, "{out}{err}");
    finish(run);

    // `tutti run --restore` refuses it before anything starts.
    let mut cmd = common::tutti_command();
    cmd.current_dir(dir)
        .args(["run", "nostate.json5", "--restore", "foreign.tutti-checkpoint"])
        .env("TUTTI_NAMESPACE", &ns);
    let (status, _, err) = common::run_with_timeout(cmd, WAIT);
    assert_eq!(status.code(), Some(2), "{err}");
    assert!(err.contains("another DDF"), "{err}");
    assert!(!dir.join("n.csv.part").exists() && !Path::new(&format!("/dev/shm/tutti.{ns}.plant")).exists());
}

#[test]
fn a_component_declared_stateless_is_left_out_by_name() {
    let ns = common::namespace("ckpdeclared");
    let _segments = RemoveSegments(ns.clone());
    let text = launch(20, "0", "d.csv", r#", checkpoint: { every: 10, dir: "ck" }"#, r#", "nostate""#, false)
        .replace(r#"domain: "plant" }"#, r#"domain: "plant", stateless: true }"#);
    let (dir, _) = setup(&[("declared.json5", text)], false).unwrap();
    let dir = dir.path();
    finish(start(dir, "declared.json5", &ns, &[]));
    let saved: Vec<PathBuf> = ["ck/step-000000010.tutti-checkpoint", "ck/step-000000020.tutti-checkpoint"]
        .iter()
        .map(|p| dir.join(p))
        .collect();
    for p in &saved {
        let c = tutti_host::checkpoint::Checkpoint::read(p).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            c.skipped.iter().map(|s| (s.name.as_str(), s.why.as_str())).collect::<Vec<_>>(),
            [("c", "stateless")]
        );
    }
}
