//! SSP archives (`tutti ssp inspect|ddf`, `tutti run SYSTEM.ssp`): systems of FMUs exported
//! by pythonfmu (tests/fmu/python/Lag.py, tests/ssp/Gain.py, a gain with direct
//! feedthrough) and of the suite's own C FMU (tests/fmu/c2/Gain.c), run by tutti with a CSV record and by libcosim (tests/ssp/reference.py), and
//! compared value by value at every communication step; refusals point at the element.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use tutti_test_support::fmu::{build_c_gain, build_lag, libpython, write_zip};
use tutti_test_support::{self as common, run_with_timeout};

const STEP: f64 = 0.01;
/// Both run the same FMU code with the same numbers; only the order of floating-point
/// operations in a unit conversion may differ.
const TOLERANCE: f64 = 1e-12;

/// The venv's Python with pythonfmu and libcosimpy (skipped when missing, a failure under CI).
fn python() -> Option<PathBuf> {
    common::python(&["pythonfmu", "libcosimpy"])
}

/// Builds Lag.fmu, Gain.fmu (pythonfmu) and CGain.fmu (C) into `dir`.
fn build_fmus(py: &Path, dir: &Path) -> Vec<PathBuf> {
    let lag = build_lag(py, dir);
    let mut cmd = Command::new(py);
    cmd.args(["-m", "pythonfmu", "build", "-f"])
        .arg(common::repo_root().join("tests/ssp/Gain.py"))
        .arg("-d")
        .arg(dir)
        .current_dir(dir);
    let (status, out, err) = run_with_timeout(cmd, Duration::from_secs(120));
    assert!(status.success(), "pythonfmu build failed:\n{out}\n{err}");
    vec![lag, dir.join("Gain.fmu"), build_c_gain(dir)]
}

/// Zips `ssd` (text) with the FMUs and `extra` files into `dir/NAME.ssp`.
fn archive(dir: &Path, name: &str, ssd: &str, fmus: &[PathBuf], extra: &[(&str, &[u8])]) -> PathBuf {
    let files: Vec<(String, Vec<u8>)> = fmus
        .iter()
        .map(|f| (format!("resources/{}", f.file_name().unwrap().to_string_lossy()), std::fs::read(f).unwrap()))
        .collect();
    let mut entries: Vec<(&str, &[u8])> = vec![("SystemStructure.ssd", ssd.as_bytes())];
    entries.extend(files.iter().map(|(n, b)| (n.as_str(), b.as_slice())));
    entries.extend_from_slice(extra);
    let path = dir.join(format!("{name}.ssp"));
    write_zip(&path, &entries);
    path
}

fn fixture(name: &str) -> String {
    std::fs::read_to_string(common::repo_root().join("tests/ssp").join(name)).unwrap()
}

/// `tutti run SYSTEM.ssp --record DIR/run.csv`, with libpython preloaded for the PythonFMU
/// models; returns the output directory's CSV files by domain.
fn run_tutti(py: &Path, ssp: &Path, dir: &Path, tag: &str) -> BTreeMap<String, String> {
    run_tutti_with(py, ssp, dir, tag, &[])
}

/// [`run_tutti`] with more flags.
fn run_tutti_with(py: &Path, ssp: &Path, dir: &Path, tag: &str, flags: &[&str]) -> BTreeMap<String, String> {
    let ns = common::namespace(tag);
    let _segments = common::RemoveSegments(ns.clone());
    let out = dir.join(format!("{tag}-out"));
    let csv = dir.join(format!("{tag}.csv"));
    // The run's temporary directory: the FMU components unpack their archives there.
    let tmp = dir.join(format!("{tag}-tmp"));
    std::fs::create_dir_all(&tmp).unwrap();
    let mut cmd = common::tutti_command();
    cmd.arg("run")
        .arg(ssp)
        .arg("--out")
        .arg(&out)
        .arg("--record")
        .arg(&csv)
        .args(["--step", "10ms", "-q"])
        .args(flags)
        .env("TUTTI_NAMESPACE", &ns)
        .env("TUTTI_FMU_PRELOAD", libpython(py))
        .env("TMPDIR", &tmp);
    let (status, stdout, stderr) = run_with_timeout(cmd, Duration::from_secs(120));
    assert!(status.success(), "tutti run {}:\n{stdout}\n{stderr}", ssp.display());
    assert!(common::segments_of(&ns).is_empty(), "the run left segments");
    // Each component ended at the teardown's SIGTERM and removed its unpacked FMU.
    let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "the run left temporary files: {left:?}\n{stderr}");
    let mut files = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if let Some(domain) = name.strip_prefix(&format!("{tag}-")).and_then(|n| n.strip_suffix(".csv")) {
            files.insert(domain.to_string(), std::fs::read_to_string(&p).unwrap());
        }
    }
    files
}

/// tutti's value of `COMPONENT.VARIABLE` at every step (its domain is the component's name;
/// an input is the PUBLISH item of the step, an output the step's answer).
fn tutti_trace(files: &BTreeMap<String, String>, var: &str, input: bool) -> Vec<f64> {
    let (domain, item) = var.split_once('.').unwrap();
    let text = files.get(domain).unwrap_or_else(|| panic!("no CSV of domain {domain}: {:?}", files.keys()));
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let name = format!("{}.{item}", if input { "publish" } else { "subscribe" });
    let col = head.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}: {head:?}"));
    lines
        .map(|l| match l.split(',').nth(col).unwrap() {
            "yes" => 1.0,
            "no" => 0.0,
            v => v.parse().unwrap(),
        })
        .collect()
}

/// libcosim's value of each of `vars` after each of `steps` steps (tests/ssp/reference.py).
fn libcosim(py: &Path, ssp: &Path, steps: usize, vars: &[&str]) -> Vec<Vec<f64>> {
    let mut cmd = Command::new(py);
    cmd.arg(common::repo_root().join("tests/ssp/reference.py"))
        .arg(ssp)
        .arg(STEP.to_string())
        .arg(steps.to_string())
        .args(vars);
    let (status, out, err) = run_with_timeout(cmd, Duration::from_secs(120));
    assert!(status.success(), "libcosim failed: {err}");
    let rows: Vec<Vec<f64>> = out
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('['))
        .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), steps, "libcosim printed {} rows:\n{out}\n{err}", rows.len());
    rows
}

fn close(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= TOLERANCE * a.abs().max(b.abs()).max(1.0)
}

/// Asserts that tutti's trace of each variable (`name`, input?) equals libcosim's at every
/// communication step: tutti's row of step k (t = k·h) holds the inputs that step used and
/// the outputs it ended with, which libcosim shows after the step ending at (k + 1)·h.
fn compare(files: &BTreeMap<String, String>, reference: &[Vec<f64>], vars: &[(&str, bool)], what: &str) {
    for (i, (var, input)) in vars.iter().enumerate() {
        let got = tutti_trace(files, var, *input);
        assert_eq!(got.len(), reference.len(), "{what}: {var}: tutti recorded {} steps", got.len());
        for (k, (g, row)) in got.iter().zip(reference).enumerate() {
            assert!(close(*g, row[i]), "{what}: step {k}: {var} = {g} under tutti, {} under libcosim", row[i]);
        }
    }
}

fn differs(files: &BTreeMap<String, String>, reference: &[Vec<f64>], var: &str, col: usize) -> bool {
    tutti_trace(files, var, false).iter().zip(reference).any(|(g, r)| !close(*g, r[col]))
}

/// A chain of three (a lag, a gain with direct feedthrough, a lag), Real, Integer and
/// Boolean connections, a linear transformation, component-level values from an SSV file
/// and inline, and a system-level value: equal to libcosim at every step. libcosim does not
/// apply the system-level value (c.tau = 0.1), so the reference is the same archive with the
/// value bound at component level, and libcosim's run of the original differs.
#[test]
fn a_chain_with_feedthrough_matches_libcosim_at_every_step() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fmus = build_fmus(&py, dir.path());
    let ssv = fixture("a.ssv");
    let set = |v: &str| {
        format!(
            "<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version=\"1.0\" name=\"p\"><ssv:Parameters><ssv:Parameter name=\"{v}\"><ssv:Real value=\"0.1\"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"
        )
    };
    let system_level = fixture("chain.ssd").replace("<!--SYSTEM-->", &set("c.tau"));
    let component_level = fixture("chain.ssd").replace("<!--COMPONENT-C-->", &set("tau"));
    let extra: [(&str, &[u8]); 1] = [("resources/a.ssv", ssv.as_bytes())];
    let ssp = archive(dir.path(), "chain", &system_level, &fmus, &extra);
    let reference_ssp = archive(dir.path(), "chain-component", &component_level, &fmus, &extra);

    let (code, out, err) = common::tutti(["ssp", "inspect", ssp.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    for want in [
        "b  resources/Gain.fmu",
        "a.y -> b.u",
        "b.y -> c.u  (× 0.5 + 1)",
        "a.tau = 0.2  (Real, component level",
        "c.tau = 0.1  (Real, system level",
    ] {
        assert!(out.contains(want), "inspect lacks '{want}':\n{out}");
    }

    let files = run_tutti(&py, &ssp, dir.path(), "chain");
    let vars = [
        ("a.y", false),
        ("a.count", false),
        ("b.u", true),
        ("b.n_in", true),
        ("b.b_in", true),
        ("b.y", false),
        ("b.n_out", false),
        ("b.b_out", false),
        ("c.u", true),
        ("c.y", false),
    ];
    let names: Vec<&str> = vars.iter().map(|(v, _)| *v).collect();
    let steps = 40; // stopTime 0.4 s at 10 ms
    let reference = libcosim(&py, &reference_ssp, steps, &names);
    compare(&files, &reference, &vars, "chain");
    // The chain reaches c: b's feedthrough in the same step, the transformation on c.u.
    let cu = tutti_trace(&files, "c.u", true);
    assert_eq!(cu[0], 1.0, "c.u at step 0 is 0.5 · b.y(0) + 1");
    assert!(cu.iter().any(|v| *v > 1.5), "c.u never moved: {cu:?}");

    let ignored = libcosim(&py, &ssp, steps, &names);
    assert!(
        differs(&files, &ignored, "c.y", 9),
        "libcosim applied the system-level value too: the documented difference is gone"
    );
}

/// Asserts that tutti's run of a chain a -> b (y = 3·u) -> c (0.5·y + 1) under `--ordering
/// feedthrough` is libcosim's run of the same system with b folded into the connection
/// (`folded`: a.y, c.u, c.y): b passes a's output of the step on within the step.
fn assert_feedthrough_is_folded(files: &BTreeMap<String, String>, folded: &[Vec<f64>], what: &str) {
    let (ay, by, bu) =
        (tutti_trace(files, "a.y", false), tutti_trace(files, "b.y", false), tutti_trace(files, "b.u", true));
    let (cu, cy) = (tutti_trace(files, "c.u", true), tutti_trace(files, "c.y", false));
    assert_eq!(cy.len(), folded.len(), "{what}: tutti recorded {} steps", cy.len());
    assert!(ay.iter().any(|v| *v > 0.1), "{what}: a.y never moved: {ay:?}");
    for k in 0..folded.len() {
        // Within the step: b's input is a's output of this step, and its output follows.
        assert!(
            close(bu[k], ay[k]) && close(by[k], 3.0 * ay[k]),
            "{what}: step {k}: a.y {} b.u {} b.y {}",
            ay[k],
            bu[k],
            by[k]
        );
        assert!(
            close(ay[k], folded[k][0]),
            "{what}: step {k}: a.y = {} under tutti, {} under libcosim",
            ay[k],
            folded[k][0]
        );
        assert!(
            close(cy[k], folded[k][2]),
            "{what}: step {k}: c.y = {} under tutti, {} under libcosim",
            cy[k],
            folded[k][2]
        );
        // A re-evaluated domain's row holds the inputs it was evaluated with last: those of
        // the next step, which libcosim shows after the next step.
        if k + 1 < folded.len() {
            assert!(
                close(cu[k], folded[k + 1][1]),
                "{what}: step {k}: c.u = {} under tutti, {} under libcosim",
                cu[k],
                folded[k + 1][1]
            );
        }
    }
}

/// The chain under `--ordering feedthrough` (OMSimulator's ordering): b, a gain with direct
/// feedthrough, is evaluated again within the step, so b.y is 3 × a.y of the same step and
/// c gets it one step sooner than in the default ordering. That is libcosim's run of the same
/// system with b folded into the connection (a.y × 1.5 + 1 into c.u): equal at every step.
#[test]
fn the_feedthrough_ordering_passes_a_gain_on_within_the_step_as_if_folded() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fmus = build_fmus(&py, dir.path());
    let ssv = fixture("a.ssv");
    let extra: [(&str, &[u8]); 1] = [("resources/a.ssv", ssv.as_bytes())];
    let ssp = archive(dir.path(), "chain", &fixture("chain.ssd"), &fmus, &extra);
    let folded = archive(dir.path(), "folded", &fixture("chain-folded.ssd"), &fmus, &extra);
    let files = run_tutti_with(&py, &ssp, dir.path(), "feedthrough", &["--ordering", "feedthrough"]);
    let steps = 40;
    assert_feedthrough_is_folded(&files, &libcosim(&py, &folded, steps, &["a.y", "c.u", "c.y"]), "pythonfmu gain");
    // And the default ordering is not that: c is one step behind.
    let delayed = run_tutti(&py, &ssp, dir.path(), "delayed");
    let (cy, cy_delayed) = (tutti_trace(&files, "c.y", false), tutti_trace(&delayed, "c.y", false));
    assert!(cy_delayed.iter().zip(&cy).any(|(d, f)| !close(*d, *f)), "the orderings gave the same c.y");

    // A feedback loop with one feedthrough component (the controller) is exact too: the
    // plant's next input is the controller's answer to the plant's output of this step.
    let loop_ssp = archive(dir.path(), "feedback", &fixture("feedback.ssd"), &fmus, &[]);
    let loop_folded = archive(dir.path(), "feedback-folded", &fixture("feedback-folded.ssd"), &fmus, &[]);
    let files = run_tutti_with(&py, &loop_ssp, dir.path(), "loop", &["--ordering", "feedthrough"]);
    let reference = libcosim(&py, &loop_folded, steps, &["plant.y"]);
    let (plant_y, ctrl_y) = (tutti_trace(&files, "plant.y", false), tutti_trace(&files, "ctrl.y", false));
    assert_eq!(plant_y.len(), steps, "tutti recorded {} steps", plant_y.len());
    for k in 0..steps {
        assert!(
            close(plant_y[k], reference[k][0]),
            "loop step {k}: plant.y = {} under tutti, {} under libcosim",
            plant_y[k],
            reference[k][0]
        );
        assert!(
            close(ctrl_y[k], -0.8 * plant_y[k] + 2.0),
            "loop step {k}: ctrl.y {} for plant.y {}",
            ctrl_y[k],
            plant_y[k]
        );
    }
}

/// The chain with b the test suite's own C FMU (tests/fmu/c2/Gain.c, FMI 2.0, its output
/// computed from its input when read): equal to libcosim at every step in the default
/// ordering, and to libcosim's folded chain under `--ordering feedthrough`.
#[test]
fn a_chain_through_a_c_fmu_matches_libcosim_in_both_orderings() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fmus = build_fmus(&py, dir.path());
    let ssv = fixture("a.ssv");
    let extra: [(&str, &[u8]); 1] = [("resources/a.ssv", ssv.as_bytes())];
    let ssp = archive(dir.path(), "chain-c", &fixture("chain-c.ssd"), &fmus, &extra);
    let folded = archive(dir.path(), "folded", &fixture("chain-folded.ssd"), &fmus, &extra);
    let steps = 40;
    let files = run_tutti(&py, &ssp, dir.path(), "c-delayed");
    let vars = [("a.y", false), ("b.u", true), ("b.y", false), ("b.n", false), ("c.u", true), ("c.y", false)];
    let names: Vec<&str> = vars.iter().map(|(v, _)| *v).collect();
    compare(&files, &libcosim(&py, &ssp, steps, &names), &vars, "C chain");
    let files = run_tutti_with(&py, &ssp, dir.path(), "c-feedthrough", &["--ordering", "feedthrough"]);
    assert_feedthrough_is_folded(&files, &libcosim(&py, &folded, steps, &["a.y", "c.u", "c.y"]), "C gain");
    // The repeated step made no doStep: the C gain counted one per communication step.
    let n = tutti_trace(&files, "b.n", false);
    assert_eq!(n.last().copied(), Some(steps as f64), "b.n: {n:?}");
}

/// A feedback loop through a gain with direct feedthrough: each output reaches the other
/// component at the next step, as in libcosim.
#[test]
fn a_feedback_loop_matches_libcosim_at_every_step() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fmus = build_fmus(&py, dir.path());
    let ssp = archive(dir.path(), "feedback", &fixture("feedback.ssd"), &fmus, &[]);
    let files = run_tutti(&py, &ssp, dir.path(), "feedback");
    let vars = [("plant.u", true), ("plant.y", false), ("ctrl.u", true), ("ctrl.y", false)];
    let names: Vec<&str> = vars.iter().map(|(v, _)| *v).collect();
    let reference = libcosim(&py, &ssp, 40, &names);
    compare(&files, &reference, &vars, "feedback");
}

/// SSP 2.0 (Float64 connectors) with a unit conversion from km to m: equal to libcosim's run
/// of the same system in SSP 1.0 with the conversion written as a linear transformation.
#[test]
fn an_ssp2_system_with_a_unit_conversion_matches_libcosim() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fmus = build_fmus(&py, dir.path());
    let ssp = archive(dir.path(), "units2", &fixture("units2.ssd"), &fmus, &[]);
    let reference_ssp = archive(dir.path(), "units1", &fixture("units1.ssd"), &fmus, &[]);
    let files = run_tutti(&py, &ssp, dir.path(), "units");
    let vars = [("a.y", false), ("b.u", true), ("b.y", false)];
    let names: Vec<&str> = vars.iter().map(|(v, _)| *v).collect();
    let reference = libcosim(&py, &reference_ssp, 30, &names);
    compare(&files, &reference, &vars, "units");
    let bu = tutti_trace(&files, "b.u", true);
    let ay = tutti_trace(&files, "a.y", false);
    assert!(close(bu[5], ay[4] * 1000.0), "b.u = 1000 × a.y of the step before: {} {}", bu[5], ay[4]);
}

/// What tutti does not run is refused with the file, line and column of the element, and
/// `tutti ssp ddf` writes the DDF and one launch file that `tutti run --check` accepts.
#[test]
fn refusals_point_at_the_element_and_ddf_writes_one_launch_file() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let fmus = build_fmus(&py, dir.path());
    let ssv = fixture("a.ssv");
    let extra: [(&str, &[u8]); 1] = [("resources/a.ssv", ssv.as_bytes())];
    let chain = fixture("chain.ssd");
    let pos = |text: &str, needle: &str| -> String {
        let (i, line) = text.lines().enumerate().find(|(_, l)| l.contains(needle)).unwrap();
        format!("SystemStructure.ssd:{}:{}:", i + 1, line.find('<').unwrap() + 1)
    };
    let cases = [
        (
            "nested",
            chain.replace("    </ssd:Elements>", "      <ssd:System name=\"inner\"/>\n    </ssd:Elements>"),
            "<ssd:System name=\"inner\"/>",
            "a nested system (<ssd:System> inside <ssd:Elements>) is not supported",
        ),
        (
            "unknown",
            chain.replace("endConnector=\"n_in\"", "endConnector=\"nope\""),
            "endConnector=\"nope\"",
            "unknown connector 'b.nope': component 'b' declares u, n_in, b_in, y",
        ),
        (
            "mismatch",
            chain.replace("startConnector=\"positive\"", "startConnector=\"y\""),
            "startConnector=\"y\" endElement=\"b\" endConnector=\"b_in\"",
            "type mismatch: a.y is Real, b.b_in is Boolean",
        ),
        (
            "mapping",
            chain.replace(
                "<ssd:ParameterBinding source=\"resources/a.ssv\"/>",
                "<ssd:ParameterBinding source=\"resources/a.ssv\">\n<ssd:ParameterMapping source=\"m.ssm\"/></ssd:ParameterBinding>",
            ),
            "<ssd:ParameterMapping",
            "a parameter mapping (<ssd:ParameterMapping>, SSM) is not supported",
        ),
    ];
    for (name, text, needle, want) in cases {
        let ssp = archive(dir.path(), name, &text, &fmus, &extra);
        for args in [vec!["ssp", "inspect"], vec!["run"]] {
            let mut cmd = common::tutti_command();
            cmd.args(&args).arg(&ssp).env("TUTTI_NAMESPACE", common::namespace("sspbad"));
            let (status, _, err) = run_with_timeout(cmd, Duration::from_secs(60));
            assert_eq!(status.code(), Some(2), "{name}: {args:?}: {err}");
            assert!(err.contains(&pos(&text, needle)), "{name}: {args:?}: no {}: {err}", pos(&text, needle));
            assert!(err.contains(want), "{name}: {args:?}: {err}");
        }
    }

    let ssp = archive(dir.path(), "chain", &chain, &fmus, &extra);
    let out = dir.path().join("made");
    let (code, stdout, err) = common::tutti([
        "ssp",
        "ddf",
        ssp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--steps",
        "7",
        "--ordering",
        "feedthrough",
    ]);
    assert_eq!(code, 0, "{err}");
    let launches: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json5"))
        .collect();
    assert_eq!(launches.len(), 1, "exactly one launch file: {launches:?}");
    assert_eq!(stdout.trim(), launches[0].display().to_string());
    let launch = std::fs::read_to_string(&launches[0]).unwrap();
    for want in [
        "\"steps\": 7",
        "\"ordering\": \"feedthrough\"",
        "\"b/subscribe/y -> c/publish/u * 0.5 + 1\"",
        "\"a/u=1.5\"",
        "\"tau=0.2\"",
        "\"k=3\"",
        "\"fmu\": \"resources/Gain.fmu\"",
    ] {
        assert!(launch.contains(want), "the launch file lacks {want}:\n{launch}");
    }
    assert!(out.join("resources/Lag.fmu").is_file() && out.join("chain.ddf").is_file());
    let (code, _, err) = common::tutti(["run", launches[0].to_str().unwrap(), "--check"]);
    assert_eq!(code, 0, "{err}");
}
