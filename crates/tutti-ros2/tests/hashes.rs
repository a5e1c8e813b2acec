//! Every type the registry holds hashes as ROS 2's own generator hashes it, and its files are
//! ROS 2's: rosidl's type-description generator (tests/ros2/rosidl/, run by
//! tests/ros2/interface_hashes.py) hashes the same packages from the ROS 2 Jazzy sources
//! (tests/ros2/jazzy/jazzy-src.tar.xz), implicit types of services and actions included, and
//! every line it prints must be the registry's hash of that type, and every type of the
//! registry among them; tests/ros2/interface_sources.py checks that `interfaces/` holds those
//! packages' files byte for byte.
//!
//! The Python needs `lark` (rosidl's parser; launch-scripts/test.sh installs it into .venv):
//! without it the tests are skipped, and fail under CI=true.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use tutti_ros2::registry;

fn interfaces() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("interfaces")
}

/// The sources' tarballs, comma-separated as the scripts take them: ROS 2 Jazzy's, and
/// geometry2's (tf2_msgs).
fn tarball() -> std::ffi::OsString {
    let dir = tutti_test_support::repo_root().join("tests/ros2/jazzy");
    let mut list = dir.join("jazzy-src.tar.xz").into_os_string();
    list.push(",");
    list.push(dir.join("geometry2-jazzy-src.tar.xz"));
    list
}

/// The folder of each package in the tarball, each after those it uses (`interfaces/SOURCES.txt`).
fn package_dirs() -> Vec<String> {
    let text = std::fs::read_to_string(interfaces().join("SOURCES.txt")).expect("interfaces/SOURCES.txt");
    text.lines()
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .filter_map(|l| l.split_whitespace().nth(3))
        .map(String::from)
        .collect()
}

/// Runs `script` with `args` under the venv's Python to its end: its output.
fn run(py: &Path, script: &str, args: &[&std::ffi::OsStr]) -> String {
    let mut cmd = Command::new(py);
    cmd.arg(tutti_test_support::repo_root().join("tests/ros2").join(script)).args(args);
    let (status, out, err) = tutti_test_support::run_with_timeout(cmd, Duration::from_secs(300));
    assert!(status.success(), "{script} failed:\n{out}\n{err}");
    out
}

#[test]
fn every_type_hashes_as_rosidl_hashes_it() {
    let Some(py) = tutti_test_support::python(&["lark"]) else { return };
    let tar = tarball();
    let dirs = package_dirs();
    let mut args = vec![tar.as_os_str()];
    args.extend(dirs.iter().map(|d| std::ffi::OsStr::new(d.as_str())));
    let out = run(&py, "interface_hashes.py", &args);
    let theirs: BTreeMap<&str, &str> = out.lines().filter_map(|l| l.split_once(' ')).collect();
    let ours: BTreeMap<&str, String> = registry()
        .type_names()
        .into_iter()
        .map(|n| (n, registry().hash(n).map(|h| h.to_string()).unwrap_or_else(|| format!("{n} has no hash"))))
        .collect();
    let mut differ = Vec::new();
    for name in theirs.keys().chain(ours.keys()).collect::<std::collections::BTreeSet<_>>() {
        let (t, o) = (theirs.get(name).copied(), ours.get(name).map(String::as_str));
        if t != o {
            let json = registry().description(name).map(|d| d.canonical_json()).unwrap_or_default();
            differ.push(format!("{name}: rosidl {t:?}, tutti {o:?}\n  {json}"));
        }
    }
    assert!(differ.is_empty(), "{} of {} types differ:\n{}", differ.len(), theirs.len(), differ.join("\n"));
    assert!(theirs.len() > 200, "{out}");
}

#[test]
fn the_interface_files_are_those_of_the_ros2_sources() {
    let Some(py) = tutti_test_support::python(&["tarfile", "lzma"]) else { return };
    let (tar, dir) = (tarball(), interfaces());
    let out = run(&py, "interface_sources.py", &[tar.as_os_str(), dir.as_os_str()]);
    assert!(out.starts_with("same "), "{out}");
}
