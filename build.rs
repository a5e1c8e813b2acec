//! What `tutti --version` prints beside the version: the commit the binary was built from and
//! the gateway engines compiled in (docs/install.md, "Versions and crates").
//!
//! The commit is `TUTTI_COMMIT` when set (a build from a source archive, which has no Git
//! history), else `git rev-parse --short=12 HEAD`, else `unknown`. Uncommitted changes are not
//! marked: build scripts rerun when HEAD moves, not on every edit.

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    println!("cargo:rerun-if-env-changed=TUTTI_COMMIT");
    // A new commit or checkout changes HEAD or the ref it names (loose or packed).
    // Only files that exist: cargo reruns a script whose watched file is missing every time.
    // refs/heads as a directory: a branch packed, then moved, gets a new loose file there.
    let mut watched = vec!["HEAD".to_string(), "packed-refs".to_string(), "refs/heads".to_string()];
    watched.extend(git(&["symbolic-ref", "-q", "HEAD"]));
    for path in watched {
        if let Some(p) = git(&["rev-parse", "--git-path", &path]).filter(|p| std::path::Path::new(p).exists()) {
            println!("cargo:rerun-if-changed={p}");
        }
    }
    let commit = std::env::var("TUTTI_COMMIT")
        .ok()
        .filter(|c| !c.is_empty())
        .or_else(|| git(&["rev-parse", "--short=12", "HEAD"]))
        .unwrap_or_else(|| "unknown".into());
    let mut engines = vec!["cyclone"];
    if std::env::var_os("CARGO_FEATURE_RUSTDDS").is_some() {
        engines.push("rustdds");
    }
    if std::env::var_os("CARGO_FEATURE_ZENOH").is_some() {
        engines.push("zenoh");
    }
    println!("cargo:rustc-env=TUTTI_BUILD_COMMIT={commit}");
    println!("cargo:rustc-env=TUTTI_BUILD_ENGINES={}", engines.join(", "));
}
