//! Runs the Python module's tests (python/tests, stdlib unittest) against this build's
//! librtapi.so and the rtapi_test_host example (cargo test builds examples).

mod common;

use std::process::Command;
use std::time::Duration;

use common::*;

#[test]
fn python_module_tests_pass() {
    let Some(_) = tutti_test_support::require_tool("python3", "python3") else { return };
    let lib = lib_dir();
    let host = profile_dir().join("examples/rtapi_test_host");
    assert!(
        host.exists(),
        "{} missing: cargo test builds it (or cargo build -p tutti-rtapi --examples)",
        host.display()
    );
    let mut cmd = Command::new("python3");
    cmd.args(["-m", "unittest", "discover", "-s", "python/tests", "-v"])
        .current_dir(root())
        .env("TUTTI_RTAPI_LIB", lib.join("librtapi.so"))
        .env("TUTTI_TEST_HOST", &host)
        .env("PYTHONDONTWRITEBYTECODE", "1");
    let out = run(&mut cmd, Duration::from_secs(300));
    assert!(
        out.status.success(),
        "python tests failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
