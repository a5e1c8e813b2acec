//! Support for the FMU tests: FMUs built from the sources in tests/fmu/ into a test's temp
//! dir, the venv's Python with pythonfmu and fmpy, and small FMU archives made here.

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};
use std::thread;
use std::time::Duration;

use crate::{repo_root as repo, run_with_timeout};

/// The venv's Python with pythonfmu and fmpy ([`crate::python`]: skipped when missing, a
/// failure under CI=true).
pub fn python() -> Option<PathBuf> {
    crate::python(&["pythonfmu", "fmpy"])
}

/// The shared libpython of `py`, which a PythonFMU model needs its host to load.
pub fn libpython(py: &Path) -> PathBuf {
    let out = Command::new(py)
        .args([
            "-c",
            "import sysconfig, os; print(os.path.join(sysconfig.get_config_var('LIBDIR'), sysconfig.get_config_var('LDLIBRARY')))",
        ])
        .output()
        .expect("python runs");
    PathBuf::from(String::from_utf8_lossy(&out.stdout).trim())
}

/// How a PythonFMU model is built ([`build_lag_with`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PythonFmuOptions {
    /// The FMU gets, sets and serializes its state (`pythonfmu build --handle-state
    /// --serialize-state`: `canGetAndSetFMUstate` and `canSerializeFMUstate`), so that it
    /// keeps its state in a checkpoint. Its state is its registered variables (as JSON).
    pub state: bool,
}

/// Builds tests/fmu/python/Lag.py into `dir/Lag.fmu` with pythonfmu (FMI 2.0 co-simulation),
/// without state handling: a component that keeps no state.
pub fn build_lag(py: &Path, dir: &Path) -> PathBuf {
    build_lag_with(py, dir, PythonFmuOptions::default())
}

/// Builds tests/fmu/python/Lag.py into `dir/Lag.fmu` with pythonfmu and `opts`.
pub fn build_lag_with(py: &Path, dir: &Path, opts: PythonFmuOptions) -> PathBuf {
    let mut cmd = Command::new(py);
    cmd.args(["-m", "pythonfmu", "build", "-f"])
        .arg(repo().join("tests/fmu/python/Lag.py"))
        .arg("-d")
        .arg(dir)
        .current_dir(dir);
    if opts.state {
        cmd.args(["--handle-state", "--serialize-state"]);
    }
    let (status, out, err) = run_with_timeout(cmd, Duration::from_secs(120));
    assert!(status.success(), "pythonfmu build failed:\n{out}\n{err}");
    let fmu = dir.join("Lag.fmu");
    assert!(fmu.exists(), "pythonfmu made no Lag.fmu:\n{out}\n{err}");
    fmu
}

/// Writes a zip at `path` with `entries` (name, bytes).
pub fn write_zip(path: &Path, entries: &[(&str, &[u8])]) {
    let file = std::fs::File::create(path).unwrap();
    let mut zip = zip::ZipWriter::new(file);
    let opts = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, bytes) in entries {
        zip.start_file(*name, opts).unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap();
}

/// A small FMI 2.0 co-simulation model description: input `u`, output `y` (Real).
pub fn model_description(model_identifier: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Stub" guid="{{stub}}">
  <CoSimulation modelIdentifier="{model_identifier}"/>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="0" causality="input"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="1" causality="output"><Real/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="2"/></Outputs></ModelStructure>
</fmiModelDescription>
"#
    )
}

/// Compiles C `source` into a shared library at `out` with gcc.
pub fn compile_so(source: &str, out: &Path) {
    let c = out.with_extension("c");
    std::fs::write(&c, source).unwrap();
    let mut cmd = Command::new("gcc");
    cmd.args(["-shared", "-fPIC", "-o"]).arg(out).arg(&c);
    let (status, _, err) = run_with_timeout(cmd, Duration::from_secs(60));
    assert!(status.success(), "gcc failed: {err}");
}

/// Starts `tutti host DDF` (10 ms steps) for `duration` with PUBLISH value `set`
/// (DOMAIN/ITEM=VALUE), recording to `csv`; joined by the caller.
pub fn host(
    ns: &str,
    ddf: &Path,
    csv: &Path,
    duration: &str,
    set: &str,
) -> thread::JoinHandle<(ExitStatus, String, String)> {
    let mut cmd = crate::tutti_command();
    cmd.args(["host"])
        .arg(ddf)
        // --catch-up: every step is one period of simulated time even when the machine is
        // loaded (a skipped period would make one doStep longer than fmpy's). --hold: the FMU
        // connects once the host has published its inputs (an asynchronous FMU connected
        // before that would step once on the defaults).
        .args(["--step", "10ms", "--catch-up", "--hold", "300ms", "--duration", duration])
        .args(["--timeout", "2s", "--set", set, "-q", "--record"])
        .arg(csv)
        .env("TUTTI_NAMESPACE", ns);
    thread::spawn(move || run_with_timeout(cmd, Duration::from_secs(120)))
}

/// The FMU's step count (output `count`) of every row of a `tutti host --record` CSV that
/// the FMU answered, in order, repeats kept: in a synchronous domain each framework step is a
/// row, so a step answered twice (a stale answer) or missed shows here.
pub fn recorded_counts(csv: &Path, count: &str) -> Vec<u64> {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = head.iter().position(|h| *h == format!("subscribe.{count}")).expect("the count column");
    lines.map(|l| l.split(',').nth(col).unwrap().parse::<f64>().unwrap() as u64).filter(|&n| n > 0).collect()
}

/// The rows of a `tutti host --record` CSV that the FMU answered, by its step count (output
/// `outputs[count]`): (sim_time, outputs, booleans as 0/1).
pub fn recorded(csv: &Path, outputs: &[&str], count: usize) -> BTreeMap<u64, (f64, Vec<f64>)> {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let cols: Vec<usize> = outputs.iter().map(|o| col(&format!("subscribe.{o}"))).collect();
    let sim = col("sim_time");
    let mut rows = BTreeMap::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let values: Vec<f64> = cols
            .iter()
            .map(|&i| match f[i] {
                "yes" => 1.0,
                "no" => 0.0,
                v => v.parse().unwrap(),
            })
            .collect();
        let n = values[count] as u64;
        if n > 0 {
            // A step seen twice (asynchronous: the framework was faster) keeps its first row.
            rows.entry(n).or_insert((f[sim].parse().unwrap(), values));
        }
    }
    rows
}

/// fmpy's trajectory of `fmu` (tests/fmu/reference.py) from `start` for `steps` steps of
/// `h`, with a constant `input` and `params` (JSON): step number -> outputs.
#[allow(clippy::too_many_arguments)]
pub fn reference(
    py: &Path,
    fmu: &Path,
    start: f64,
    steps: u64,
    h: f64,
    input: (&str, f64),
    params: &str,
    outputs: &[&str],
) -> BTreeMap<u64, Vec<f64>> {
    let mut cmd = Command::new(py);
    cmd.arg(repo().join("tests/fmu/reference.py"))
        .arg(fmu)
        .args([start.to_string(), steps.to_string(), h.to_string(), input.0.to_string(), input.1.to_string()])
        .arg(params)
        .arg(outputs.join(","));
    let (status, out, err) = run_with_timeout(cmd, Duration::from_secs(120));
    assert!(status.success(), "fmpy failed: {err}");
    out.lines()
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            (f[0] as u64, f[1..].to_vec())
        })
        .collect()
}

/// Equal within 1e-9 relative.
pub fn close(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
}

/// Asserts that every recorded step equals fmpy's; returns how many were compared.
pub fn compare(rows: &BTreeMap<u64, (f64, Vec<f64>)>, reference: &BTreeMap<u64, Vec<f64>>, outputs: &[&str]) -> usize {
    let mut compared = 0;
    for (n, (_, got)) in rows {
        let Some(want) = reference.get(n) else { continue };
        for ((name, g), w) in outputs.iter().zip(got).zip(want) {
            assert!(close(*g, *w), "step {n}: {name} = {g} through tutti, {w} with fmpy");
        }
        compared += 1;
    }
    compared
}

/// The FMI 3.0 headers of the `fmi-sys` crate (found with `cargo metadata`).
///
/// `--filter-platform` with the host's triple keeps cargo to the packages this machine's
/// build has downloaded: without it, `--offline` needs every package of Cargo.lock, those
/// of other platforms too, which a Linux build never fetches.
pub fn fmi3_headers() -> PathBuf {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let version = Command::new(rustc).arg("-vV").output().expect("rustc -vV");
    let version = String::from_utf8_lossy(&version.stdout);
    let host = version.lines().find_map(|l| l.strip_prefix("host: ")).expect("rustc -vV names the host triple");
    let out = Command::new(crate::cargo())
        .args(["metadata", "--format-version", "1", "--offline", "--filter-platform", host.trim()])
        .current_dir(repo())
        .output()
        .expect("cargo metadata");
    assert!(out.status.success(), "cargo metadata: {}", String::from_utf8_lossy(&out.stderr));
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let sys = meta["packages"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "fmi-sys")
        .expect("fmi-sys in the dependency graph");
    let manifest = PathBuf::from(sys["manifest_path"].as_str().unwrap());
    manifest.parent().unwrap().join("fmi-standard3/headers")
}

/// Builds tests/fmu/c/Integrator.c (FMI 3.0, C) into `dir/Integrator.fmu`; it keeps its state
/// (`canGetAndSetFMUState`, `canSerializeFMUState`).
pub fn build_integrator(dir: &Path) -> PathBuf {
    build_c_fmu(dir, "tests/fmu/c", &["Integrator.c", "stubs.c"], &fmi3_headers(), "Integrator")
}

/// Builds tests/fmu/c2/Gain.c (FMI 2.0, C, direct feedthrough) into `dir/CGain.fmu`.
pub fn build_c_gain(dir: &Path) -> PathBuf {
    let headers = fmi3_headers().parent().unwrap().parent().unwrap().join("fmi-standard2/headers");
    build_c_fmu(dir, "tests/fmu/c2", &["Gain.c"], &headers, "CGain")
}

/// Compiles `sources` of the repository's `src_dir` against `headers` into an FMU
/// `dir/ID.fmu` with that directory's modelDescription.xml (its modelIdentifier `id`).
fn build_c_fmu(dir: &Path, src_dir: &str, sources: &[&str], headers: &Path, id: &str) -> PathBuf {
    let src = repo().join(src_dir);
    let so = dir.join(format!("{id}.so"));
    let mut cmd = Command::new("gcc");
    cmd.args(["-Wall", "-Wextra", "-Werror", "-shared", "-fPIC"]).arg(format!("-I{}", headers.display()));
    for s in sources {
        cmd.arg(src.join(s));
    }
    cmd.arg("-o").arg(&so);
    let (status, _, err) = run_with_timeout(cmd, Duration::from_secs(60));
    assert!(status.success(), "gcc failed: {err}");
    let fmu = dir.join(format!("{id}.fmu"));
    let md = std::fs::read(src.join("modelDescription.xml")).unwrap();
    let lib = std::fs::read(&so).unwrap();
    // FMI 2.0 and 3.0 name the platform folder differently.
    let platform = if String::from_utf8_lossy(&md).contains("fmiVersion=\"3.0\"") { "x86_64-linux" } else { "linux64" };
    let entry = format!("binaries/{platform}/{id}.so");
    write_zip(&fmu, &[("modelDescription.xml", &md), (&entry, &lib)]);
    fmu
}
