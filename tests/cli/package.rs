//! The packages of `launch-scripts/package.sh` as a user meets them (docs/install.md): the
//! wheel installed offline into a fresh venv, the Debian package installed with `dpkg -i` and
//! removed with `dpkg -r`; and the version that `tutti --version`, the CHANGELOG and the
//! manifests must agree on.

use tutti_test_support as common;

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::install::{python_component, reads_from_the_host_with, run, start_host_with};

const VERSION: &str = env!("CARGO_PKG_VERSION");

/// The directory `package.sh --build-dir` takes: the test build's `tutti` with librtapi
/// (shared and static) beside it, built when missing.
fn build_dir() -> PathBuf {
    let exe = common::tutti_exe();
    let dir = exe.parent().expect("the profile directory").to_path_buf();
    if !(dir.join("librtapi.so").is_file() && dir.join("librtapi.a").is_file()) {
        let mut cargo = Command::new(common::cargo());
        cargo.args(["build", "-q", "-p", "tutti-rtapi"]).current_dir(common::repo_root());
        if dir.file_name().is_some_and(|n| n == "release") {
            cargo.arg("--release");
        }
        run(cargo, "cargo build -p tutti-rtapi");
    }
    dir
}

/// `package.sh KIND` into `out`; returns the package it made (the one file there).
fn package(kind: &str, out: &Path) -> PathBuf {
    let mut cmd = Command::new("bash");
    cmd.arg(common::repo_root().join("launch-scripts/package.sh"))
        .arg(kind)
        .arg("--build-dir")
        .arg(build_dir())
        .arg("--out")
        .arg(out);
    run(cmd, &format!("package.sh {kind}"));
    let made: Vec<PathBuf> =
        std::fs::read_dir(out).expect("the output directory").flatten().map(|e| e.path()).collect();
    assert_eq!(made.len(), 1, "package.sh {kind} made {made:?}");
    made.into_iter().next().unwrap()
}

/// A command with none of the variables that would find the library or the header outside
/// the package under test.
fn bare(program: impl AsRef<std::ffi::OsStr>) -> Command {
    let mut c = Command::new(program);
    for v in ["LD_LIBRARY_PATH", "PKG_CONFIG_PATH", "TUTTI_RTAPI_LIB", "PYTHONPATH", "CMAKE_PREFIX_PATH"] {
        c.env_remove(v);
    }
    c
}

/// `tutti --version` of `exe`: the workspace's version, the commit and the engines.
fn says_the_version(exe: &Path) -> String {
    let mut cmd = bare(exe);
    cmd.arg("--version");
    let out = run(cmd, "tutti --version");
    assert!(out.starts_with(&format!("tutti {VERSION} (commit ")), "{out}");
    assert!(out.contains("engines: cyclone"), "{out}");
    out
}

#[test]
fn the_wheel_installs_offline_and_runs_tutti_a_python_component_and_ctl_from_a_fresh_venv() {
    let Some(_) = common::python(&["wheel", "auditwheel"]) else { return };
    let Some(_) = common::require_tool("python3", "python3-venv") else { return };
    let dir = tempfile::tempdir().unwrap();
    let wheel = package("wheel", &dir.path().join("dist"));
    let name = wheel.file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.starts_with(&format!("tutti-{VERSION}-py3-none-manylinux_")), "{name}");
    // PyPA's judge of the tag, not the file name alone.
    let mut show = Command::new(common::repo_root().join(".venv/bin/auditwheel"));
    show.arg("show").arg(&wheel);
    let shown = run(show, "auditwheel show").split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(shown.contains("is consistent with the following platform tag: \"manylinux_"), "{shown}");

    let venv = dir.path().join("venv");
    let mut mk = Command::new("python3");
    mk.arg("-m").arg("venv").arg(&venv);
    run(mk, "python3 -m venv");
    let mut pip = bare(venv.join("bin/pip"));
    pip.args(["install", "-q", "--disable-pip-version-check", "--no-index"]).arg(&wheel).current_dir(dir.path());
    run(pip, "pip install --no-index tutti-*.whl");

    let tutti = venv.join("bin/tutti");
    let version = says_the_version(&tutti);
    let mut check = bare(&tutti);
    check.arg("check").arg(common::repo_root().join("ddf/multiuav.ddf")).current_dir(dir.path());
    let checked = run(check, "tutti check");
    assert!(checked.contains(": ok ("), "{checked}");

    let ns = common::namespace("wheel");
    let mut host = bare(&tutti);
    host.current_dir(dir.path());
    let _host = start_host_with(host, &ns);
    let out = run(python_component(&venv, dir.path(), &ns), "the wheel's Python component");
    assert!(out.contains("z 1.5"), "{out}");
    let site = venv.join("lib");
    let loaded = out.split_whitespace().last().unwrap_or_default();
    assert!(
        Path::new(loaded).starts_with(&site) && loaded.ends_with("/tutti/lib/librtapi.so.0"),
        "tutti_rtapi loaded {loaded}, not the wheel's library under {}",
        site.display()
    );
    let mut ctl = bare(&tutti);
    ctl.args(["ctl", "state", "--json"]).env("TUTTI_NAMESPACE", &ns).current_dir(dir.path());
    let state: serde_json::Value = serde_json::from_str(run(ctl, "tutti ctl state").trim()).expect("JSON");
    assert_eq!(state["state"], "playing", "{state} ({version})");
    assert!(state["step"].as_u64().is_some_and(|s| s > 0), "{state}");
}

/// `dpkg -r tutti` when dropped, if it is still installed: a failed test leaves no package.
struct Installed;

impl Drop for Installed {
    fn drop(&mut self) {
        if installed() {
            let _ = Command::new("dpkg").args(["--purge", "tutti"]).status();
        }
    }
}

fn installed() -> bool {
    Command::new("dpkg-query")
        .args(["-W", "-f=${Status}", "tutti"])
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("install ok installed"))
}

#[test]
fn the_debian_package_installs_builds_the_c_reader_with_pkg_config_and_is_removed_without_a_trace() {
    let (Some(_), Some(_), Some(_), Some(_)) = (
        common::require_tool("dpkg-deb", "dpkg"),
        common::require_tool("pkg-config", "pkgconf"),
        common::require_tool("gcc", "gcc"),
        common::require_tool("dpkg-query", "dpkg"),
    ) else {
        return;
    };
    let root = Command::new("id").arg("-u").output().map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
    let root = root.map_err(|e| e.to_string()).and_then(|r| if r { Ok(()) } else { Err("not root".to_string()) });
    let Some(()) = common::require("root, for dpkg -i", root) else { return };
    assert!(!installed(), "a package named tutti is installed on this machine already: this test would replace it");
    let dir = tempfile::tempdir().unwrap();
    let deb = package("deb", &dir.path().join("dist"));
    let mut contents = Command::new("dpkg-deb");
    contents.arg("--contents").arg(&deb);
    let contents = run(contents, "dpkg-deb --contents");
    for f in [
        "./usr/bin/tutti",
        &format!("./usr/lib/librtapi.so.{VERSION}"),
        "./usr/lib/librtapi.so.0 -> ",
        "./usr/lib/librtapi.so -> ",
        "./usr/lib/libOpalOrchestra.so",
        "./usr/include/RTAPI.h",
        "./usr/lib/pkgconfig/rtapi.pc",
        "./usr/lib/cmake/tutti/tuttiConfig.cmake",
        "./usr/share/doc/tutti/CHANGELOG.md",
    ] {
        assert!(contents.contains(f), "the package has no {f}:\n{contents}");
    }

    let _guard = Installed;
    let mut install = Command::new("dpkg");
    install.arg("-i").arg(&deb);
    run(install, "dpkg -i");
    let mut list = Command::new("dpkg");
    list.args(["-L", "tutti"]);
    let files: Vec<PathBuf> = run(list, "dpkg -L tutti").lines().map(PathBuf::from).collect();
    says_the_version(Path::new("/usr/bin/tutti"));

    // The reader built as a C project would: pkg-config finds the package's rtapi.pc on the
    // system's own path, and the program finds the library with no RPATH.
    let mut flags = bare("pkg-config");
    flags.args(["--cflags", "--libs", "rtapi"]);
    let flags = run(flags, "pkg-config --cflags --libs rtapi");
    let exe = dir.path().join("reader");
    let mut gcc = bare("gcc");
    gcc.args(["-std=c99", "-Wall", "-Wextra", "-Werror"])
        .arg(common::repo_root().join("examples/c/uav_reader.c"))
        .args(flags.split_whitespace())
        .arg("-o")
        .arg(&exe);
    run(gcc, "gcc with the package's pkg-config flags");
    {
        let ns = common::namespace("deb");
        let _host = start_host_with(bare("/usr/bin/tutti"), &ns);
        reads_from_the_host_with(bare(&exe), &ns, "the reader built against the package");
    }

    let mut remove = Command::new("dpkg");
    remove.args(["-r", "tutti"]);
    run(remove, "dpkg -r tutti");
    assert!(!installed(), "tutti is still installed after dpkg -r");
    // Every file and link of the package, and the directories only it had.
    let own_dirs = [PathBuf::from("/usr/lib/cmake/tutti"), PathBuf::from("/usr/share/doc/tutti")];
    let left: Vec<&PathBuf> = files
        .iter()
        .filter(|f| f.symlink_metadata().is_ok_and(|m| !m.is_dir()))
        .chain(own_dirs.iter().filter(|d| d.exists()))
        .collect();
    assert!(left.is_empty(), "dpkg -r left these behind: {left:?}");
}

#[test]
fn the_version_is_the_workspaces_and_the_changelogs_newest_and_tutti_version_names_commit_and_engines() {
    let out = says_the_version(&common::tutti_exe());
    let mut engines = vec!["cyclone"];
    if cfg!(feature = "rustdds") {
        engines.push("rustdds");
    }
    if cfg!(feature = "zenoh") {
        engines.push("zenoh");
    }
    assert!(out.trim_end().ends_with(&format!("; engines: {})", engines.join(", "))), "{out}");
    if let Ok(head) = Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .current_dir(common::repo_root())
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    {
        if !head.is_empty() && std::env::var_os("TUTTI_COMMIT").is_none() {
            assert!(out.contains(&format!("(commit {head};")), "built from {head}: {out}");
        }
    }
    let root = common::repo_root();
    let changelog = std::fs::read_to_string(root.join("CHANGELOG.md")).expect("CHANGELOG.md");
    let newest = changelog.lines().find(|l| l.starts_with("## ")).expect("a version in CHANGELOG.md");
    assert!(
        newest.starts_with(&format!("## {VERSION} (")),
        "CHANGELOG.md's newest entry is '{newest}', tutti {VERSION}"
    );
    let pyproject = std::fs::read_to_string(root.join("python/pyproject.toml")).expect("python/pyproject.toml");
    assert!(
        pyproject.contains(&format!("\nversion = \"{VERSION}\"\n")),
        "python/pyproject.toml is not version {VERSION}"
    );
}
