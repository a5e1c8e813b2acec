//! The IDL `tutti idl` writes is accepted by the two DDS code generators in common use:
//! Cyclone DDS `idlc` (Debian package `cyclonedds-tools`) and eProsima `fastddsgen` (Debian
//! package `fastddsgen`), for every shipped DDF and for a DDF that uses every scalar type,
//! arrays, defaults and nested buses. Where the DDS headers are installed (`cyclonedds-dev`,
//! `libfastrtps-dev`), the generated C and C++ is compiled too; without them that step is
//! skipped with a note.
//!
//! A missing tool or header skips the test (or the compile step) with a message, and fails
//! it under `CI=true` (launch-scripts/test.sh installs them all).

use tutti_test_support as common;

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// Longest any one tool may run (fastddsgen starts a JVM).
const TIMEOUT: Duration = Duration::from_secs(120);

/// The shipped DDFs, by file stem.
const SHIPPED: &[&str] = &["multiuav", "paper-figure2", "product-sample"];

/// Every scalar type, arrays with defaults, a bus inside a bus, and an absent (empty) set.
const ALL_TYPES_DDF: &str = r#"<?xml version="1.0"?>
<orchestra>
  <domain name="all_types">
    <synchronous>yes</synchronous>
    <multiplePublishAllowed>no</multiplePublishAllowed>
    <states>no</states>
    <set name="PUBLISH">
      <item name="flag"><type>boolean</type><default>yes</default></item>
      <item name="flags"><type>boolean</type><length>4</length><default>no</default></item>
      <item name="i8"><type>int8</type><default>-128</default></item>
      <item name="i16"><type>int16</type><length>2</length></item>
      <item name="i32"><type>int32</type><default>-7</default></item>
      <item name="i64"><type>int64</type><default>-9223372036854775808</default></item>
      <item name="u8"><type>unsigned int8</type><length>16</length><default>255</default></item>
      <item name="u16"><type>uint16</type></item>
      <item name="u32"><type>uint32</type></item>
      <item name="u64"><type>unsigned int64</type><default>18446744073709551615</default></item>
      <item name="gain"><type>float32</type><length>3</length><default>0.1</default></item>
      <item name="voltageABC"><type>float64</type><length>3</length><default>1e300</default></item>
      <item name="gps">
        <type>bus</type>
        <item name="fix">
          <type>bus</type>
          <item name="Latitude"><type>double</type></item>
          <item name="Longitude"><type>double</type></item>
        </item>
        <item name="satellites"><type>uchar</type></item>
      </item>
    </set>
  </domain>
</orchestra>
"#;

/// The executable `name` on PATH, or `None`.
fn which(name: &str) -> Option<PathBuf> {
    tutti_test_support::which(name)
}

/// The executable `name` on PATH; when it is missing the test is skipped, or fails under
/// CI=true, saying what to install.
/// A step that needs `tool` (a compiler with the DDS headers): `None`, when it is missing,
/// skips the step with a note, except under CI=true, where it fails the test.
fn optional_step(tool: Option<PathBuf>, note: &str) -> Option<PathBuf> {
    if tool.is_none() {
        assert!(!tutti_test_support::ci(), "CI=true: {note}");
        eprintln!("note: {note}");
    }
    tool
}

/// Runs `cmd` in `dir` with a timeout; fails the test, with the tool's output, when it does
/// not exit 0. Returns its stderr (warnings).
fn run(mut cmd: Command, dir: &Path) -> String {
    let shown = format!("{cmd:?}");
    cmd.current_dir(dir);
    let (status, out, err) = common::run_with_timeout(cmd, TIMEOUT);
    assert!(status.success(), "{shown} failed ({status})\n--- stdout\n{out}\n--- stderr\n{err}");
    err
}

/// Every file under `dir` whose name ends with `ext`, sorted.
fn files_with(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("cannot list {}: {e}", d.display())) {
            let path = entry.expect("directory entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension() == Some(OsStr::new(ext)) {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// One DDF's generated interface in a temporary directory.
struct Case {
    name: String,
    /// Holds the generated files (and anything the tools write) until dropped.
    dir: tempfile::TempDir,
}

impl Case {
    /// The directory `tutti idl` wrote into (and the IDL include directory).
    fn out(&self) -> PathBuf {
        self.dir.path().join("out")
    }

    fn idl_files(&self) -> Vec<PathBuf> {
        let files = files_with(&self.out(), "idl");
        assert!(!files.is_empty(), "{}: tutti idl wrote no .idl file", self.name);
        files
    }
}

/// Generates the interface of every shipped DDF and of [`ALL_TYPES_DDF`].
fn cases() -> Vec<Case> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut ddfs: Vec<(String, PathBuf, Option<&str>)> =
        SHIPPED.iter().map(|s| (format!("ddf/{s}.ddf"), root.join("ddf").join(format!("{s}.ddf")), None)).collect();
    ddfs.push(("all-types.ddf".into(), PathBuf::from("all-types.ddf"), Some(ALL_TYPES_DDF)));
    ddfs.into_iter()
        .map(|(name, path, text)| {
            let dir = tempfile::tempdir().expect("temporary directory");
            let path = match text {
                Some(text) => {
                    let p = dir.path().join(path);
                    std::fs::write(&p, text).expect("write the DDF");
                    p
                }
                None => path,
            };
            let mut cmd = common::tutti_command();
            cmd.arg("idl").arg(&path).arg("--out").arg(dir.path().join("out"));
            run(cmd, dir.path());
            Case { name, dir }
        })
        .collect()
}

/// Whether a system include directory holds `header`.
fn has_header(header: &str) -> bool {
    ["/usr/include", "/usr/local/include"].iter().any(|d| Path::new(d).join(header).is_file())
}

#[test]
fn idlc_accepts_every_generated_idl() {
    let Some(idlc) = tutti_test_support::require_tool("idlc", "cyclonedds-tools") else { return };
    let compile = optional_step(
        which("gcc").filter(|_| has_header("dds/dds.h")),
        "gcc or the Cyclone DDS headers (Debian package cyclonedds-dev) missing: not compiling the generated C",
    );
    for case in cases() {
        let out = case.out();
        let c_dir = case.dir.path().join("c");
        std::fs::create_dir_all(&c_dir).expect("create the C output directory");
        for idl in case.idl_files() {
            // -b/-o mirror the IDL tree, so that the generated `#include "PKG/msg/BUS.h"` resolve.
            let mut cmd = Command::new(&idlc);
            cmd.arg("-Wno-implicit-extensibility").arg("-I").arg(&out).arg("-b").arg(&out).arg("-o").arg(&c_dir);
            cmd.arg(&idl);
            let warnings = run(cmd, case.dir.path());
            for line in warnings.lines() {
                // idlc's C generator ignores @default values; that is the only warning expected.
                assert!(
                    line.contains("Explicit defaults are not supported yet in the C generator"),
                    "{}: unexpected idlc warning on {}: {line}",
                    case.name,
                    idl.display()
                );
            }
            let rel = idl.strip_prefix(&out).expect("under the output directory");
            for ext in ["c", "h"] {
                let generated = c_dir.join(rel).with_extension(ext);
                assert!(generated.is_file(), "{}: idlc did not write {}", case.name, generated.display());
            }
        }
        if let Some(gcc) = &compile {
            for c in files_with(&c_dir, "c") {
                let mut cmd = Command::new(gcc);
                cmd.args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-c", "-I"]).arg(&c_dir).arg(&c);
                cmd.arg("-o").arg(c.with_extension("o"));
                run(cmd, case.dir.path());
            }
        }
    }
}

#[test]
fn fastddsgen_accepts_every_generated_idl() {
    let Some(fastddsgen) = tutti_test_support::require_tool("fastddsgen", "fastddsgen") else { return };
    let compile = optional_step(
        which("g++").filter(|_| has_header("fastcdr/Cdr.h") && has_header("fastdds/dds/topic/TopicDataType.hpp")),
        "g++ or the Fast DDS headers (Debian package libfastrtps-dev) missing: not compiling the generated C++",
    );
    for case in cases() {
        let out = case.out();
        let cxx_dir = case.dir.path().join("cxx");
        std::fs::create_dir_all(&cxx_dir).expect("create the C++ output directory");
        let idl_files = case.idl_files();
        // One run for all files: the JVM starts once. Paths relative to the working
        // directory, as a user types them: with an absolute -I, fastddsgen 2.3 writes every
        // file flat into -d but `#include`s nested types as "PKG/msg/BUS.h".
        let relative = |p: &Path| p.strip_prefix(case.dir.path()).expect("under the case directory").to_path_buf();
        let mut cmd = Command::new(&fastddsgen);
        cmd.arg("-d").arg(relative(&cxx_dir)).arg("-I").arg(relative(&out)).arg("-replace");
        // Its preprocessed copies of the IDL go to the case's directory, not to /tmp.
        cmd.arg("-t").arg(".");
        cmd.args(idl_files.iter().map(|p| relative(p)));
        run(cmd, case.dir.path());
        let mut sources = Vec::new();
        for idl in &idl_files {
            let stem = idl.file_stem().expect("file name").to_string_lossy().into_owned();
            for name in [
                format!("{stem}.h"),
                format!("{stem}.cxx"),
                format!("{stem}PubSubTypes.h"),
                format!("{stem}PubSubTypes.cxx"),
            ] {
                let generated = cxx_dir.join(&name);
                assert!(generated.is_file(), "{}: fastddsgen did not write {name} for {}", case.name, idl.display());
                if name.ends_with(".cxx") {
                    sources.push(name);
                }
            }
        }
        if let Some(gxx) = &compile {
            // One translation unit for all sources: compiling them one by one takes a second each.
            let unity = cxx_dir.join("unity.cpp");
            let text: String = sources.iter().map(|s| format!("#include \"{s}\"\n")).collect();
            std::fs::write(&unity, text).expect("write the unity source");
            let mut cmd = Command::new(gxx);
            cmd.args(["-std=c++11", "-c", "-I"]).arg(&cxx_dir).arg(&unity);
            cmd.arg("-o").arg(cxx_dir.join("unity.o"));
            run(cmd, case.dir.path());
        }
    }
}
