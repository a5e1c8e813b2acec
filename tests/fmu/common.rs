//! Support for the FMU tests: FMUs built from the sources in tests/fmu/ into a test's temp
//! dir, the venv's Python with pythonfmu and fmpy, and small FMU archives made here.
#![allow(dead_code)]

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use super::common::run_with_timeout;

pub fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Whether a missing tool must fail the test (CI) rather than skip it.
fn required() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// The venv's Python with pythonfmu and fmpy, or None (skipped) outside CI when missing.
pub fn python() -> Option<PathBuf> {
    let py = repo().join(".venv/bin/python");
    let ok = Command::new(&py).args(["-c", "import pythonfmu, fmpy"]).status().is_ok_and(|s| s.success());
    if ok {
        return Some(py);
    }
    let hint = "run `.venv/bin/pip install pythonfmu fmpy` (launch-scripts/test.sh does)";
    assert!(!required(), "CI=true: {hint}");
    eprintln!("pythonfmu or fmpy is missing: test skipped ({hint})");
    None
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

/// Builds tests/fmu/python/Lag.py into `dir/Lag.fmu` with pythonfmu (FMI 2.0 co-simulation).
pub fn build_lag(py: &Path, dir: &Path) -> PathBuf {
    let mut cmd = Command::new(py);
    cmd.args(["-m", "pythonfmu", "build", "-f"])
        .arg(repo().join("tests/fmu/python/Lag.py"))
        .arg("-d")
        .arg(dir)
        .current_dir(dir);
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
