//! Embeds the interface files under `interfaces/PKG/{msg,srv,action}/NAME.EXT`: writes
//! `$OUT_DIR/interfaces.rs`, a table of `(package, kind, name, text)` whose texts are
//! `include_str!`s, sorted so the table only changes with the files. The crate parses them at
//! first use (`registry`).

use std::fmt::Write as _;
use std::path::Path;
use std::{env, fs, io};

const KINDS: [&str; 3] = ["msg", "srv", "action"];

fn main() -> io::Result<()> {
    let root = Path::new(&env::var("CARGO_MANIFEST_DIR").map_err(io::Error::other)?).join("interfaces");
    println!("cargo:rerun-if-changed={}", root.display());
    let mut files = Vec::new();
    for package in fs::read_dir(&root)? {
        let package = package?;
        if !package.file_type()?.is_dir() {
            continue;
        }
        println!("cargo:rerun-if-changed={}", package.path().display());
        for kind in KINDS {
            let dir = package.path().join(kind);
            if !dir.is_dir() {
                continue;
            }
            println!("cargo:rerun-if-changed={}", dir.display());
            for file in fs::read_dir(&dir)? {
                let path = file?.path();
                if path.extension().is_some_and(|e| e == kind) {
                    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
                    let pkg = package.file_name().to_string_lossy().into_owned();
                    files.push((pkg, kind, stem, path));
                }
            }
        }
    }
    files.sort();
    let mut out = String::from("/// Every embedded interface file: (package, kind, name, text).\n");
    out.push_str("pub(crate) const FILES: &[(&str, &str, &str, &str)] = &[\n");
    for (pkg, kind, name, path) in &files {
        let path = path.to_string_lossy();
        let _ = writeln!(out, "    ({pkg:?}, {kind:?}, {name:?}, include_str!({path:?})),");
    }
    out.push_str("];\n");
    fs::write(Path::new(&env::var("OUT_DIR").map_err(io::Error::other)?).join("interfaces.rs"), out)
}
