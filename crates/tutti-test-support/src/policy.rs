//! One policy for what a test needs from the machine (a tool, a Python module, root for
//! network namespaces): present, the test runs; missing, the test is skipped with a message
//! saying what to install, except under `CI=true`, where that fails the test.
//! `launch-scripts/test.sh` installs everything the tests need.

use std::path::PathBuf;
use std::process::{Command, Stdio};

/// Whether this run is CI (`CI=true`), where nothing a test needs may be missing.
pub fn ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// `found`, or, when it is an error (saying why `what` is not there), `None` with a message
/// that the test is skipped; under `CI=true` the test fails instead.
pub fn require<T, E: std::fmt::Display>(what: &str, found: Result<T, E>) -> Option<T> {
    match found {
        Ok(v) => Some(v),
        Err(why) => {
            assert!(!ci(), "CI=true: {what} is required: {why} (launch-scripts/test.sh installs it)");
            eprintln!("test skipped: {what} is missing: {why} (launch-scripts/test.sh installs it)");
            None
        }
    }
}

/// The executable `name` on PATH, or `None`.
pub fn which(name: &str) -> Option<PathBuf> {
    if name.contains('/') {
        return Some(PathBuf::from(name)).filter(|p| p.is_file());
    }
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|dir| dir.join(name)).find(|p| p.is_file())
}

/// The program `name` (found on PATH), as [`require`] has it; `package` is the Debian
/// package that brings it.
pub fn require_tool(name: &str, package: &str) -> Option<PathBuf> {
    require(&format!("`{name}`"), which(name).ok_or_else(|| format!("not on PATH (apt-get install {package})")))
}

/// The repository's `.venv` Python when it imports every one of `modules`, as [`require`]
/// has it.
pub fn python(modules: &[&str]) -> Option<PathBuf> {
    let py = crate::repo_root().join(".venv/bin/python");
    let imports = format!("import {}", modules.join(", "));
    let ok = Command::new(&py)
        .args(["-c", &imports])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let why = || format!("{} cannot `{imports}`", py.display());
    require(&format!("the venv's Python with {}", modules.join(" and ")), if ok { Ok(py) } else { Err(why()) })
}
