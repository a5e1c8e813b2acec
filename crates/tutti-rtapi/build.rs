//! librtapi.so gets a SONAME, `librtapi.so.0` (the major version of its ABI), so that a
//! program linked against it names that file, and a future incompatible library can sit
//! beside it. Cargo writes the library as `librtapi.so`; the name the SONAME gives is a
//! symbolic link next to it, made here in the directories cargo puts the library in (the
//! profile directory and its `deps/`), so that programs linked against the build tree find it
//! at run time. `launch-scripts/install.sh` installs the same names.

use std::path::{Path, PathBuf};

const SONAME: &str = "librtapi.so.0";

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("linux") {
        return;
    }
    println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,{SONAME}");
    // OUT_DIR is <target>/<profile>/build/<pkg>-<hash>/out.
    let Some(out_dir) = std::env::var_os("OUT_DIR").map(PathBuf::from) else { return };
    let Some(profile) = out_dir.ancestors().nth(3) else { return };
    for dir in [profile.to_path_buf(), profile.join("deps")] {
        link(&dir);
    }
}

/// `dir/librtapi.so.0 -> librtapi.so` (dangling until cargo writes the library).
fn link(dir: &Path) {
    let path = dir.join(SONAME);
    if std::fs::read_link(&path).is_ok() || std::fs::create_dir_all(dir).is_err() {
        return;
    }
    #[cfg(unix)]
    if let Err(e) = std::os::unix::fs::symlink("librtapi.so", &path) {
        println!("cargo:warning=could not link {}: {e}", path.display());
    }
}
