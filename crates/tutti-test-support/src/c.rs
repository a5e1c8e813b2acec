//! C programs built against `include/RTAPI.h` and this build's librtapi.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::Duration;

/// The folder of this build's librtapi.so and librtapi.a: `deps/`, where `cargo test` builds
/// them (`cargo build` copies them up to `target/<profile>`, where an older copy may be), else
/// `target/<profile>`. Built when missing (a test run before the workspace was built).
pub fn rtapi_lib_dir() -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let profile = crate::profile_dir();
        let find = || [profile.join("deps"), profile.clone()].into_iter().find(|d| d.join("librtapi.so").is_file());
        if let Some(d) = find() {
            return d;
        }
        let mut cmd = Command::new(crate::cargo());
        cmd.args(["build", "-q", "-p", "tutti-rtapi"]).current_dir(crate::repo_root());
        if profile.file_name().is_some_and(|n| n == "release") {
            cmd.arg("--release");
        }
        assert!(cmd.status().expect("running cargo").success(), "building librtapi");
        find().unwrap_or_else(|| panic!("librtapi.so missing under {} after building it", profile.display()))
    })
    .clone()
}

/// Compiles the C program `source` against include/RTAPI.h and this build's librtapi (run
/// path set, so it runs from there) into `out`, with the compiler flags `flags`; fails the
/// test with the compiler's output when it does not compile.
pub fn compile_c(source: &Path, out: &Path, flags: &[&str]) -> PathBuf {
    let lib = rtapi_lib_dir();
    let include = crate::repo_root().join("include");
    let mut cc = Command::new("gcc");
    cc.args(flags)
        .arg(format!("-I{}", include.display()))
        .arg(source)
        .arg("-o")
        .arg(out)
        .arg(format!("-L{}", lib.display()))
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .arg("-lrtapi");
    let (status, _, err) = crate::run_with_timeout(cc, Duration::from_secs(120));
    assert!(status.success(), "compiling {}: {err}", source.display());
    out.to_path_buf()
}
