//! The generated interfaces committed under `idl/` are what `tutti idl` writes today for the
//! shipped DDFs: regenerate each into a temporary directory and compare, file for file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The shipped DDFs whose interface is committed, by file stem.
const SHIPPED: &[&str] = &["multiuav", "paper-figure2", "product-sample"];

/// Every file under `dir`, by path relative to `dir`, with its contents.
fn tree(dir: &Path) -> BTreeMap<PathBuf, String> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, String>) {
        let entries = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()));
        for entry in entries {
            let path = entry.unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display())).path();
            if path.is_dir() {
                walk(root, &path, out);
            } else {
                let text =
                    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
                out.insert(path.strip_prefix(root).unwrap_or(&path).to_path_buf(), text);
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

#[test]
fn committed_idl_matches_the_generator() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for stem in SHIPPED {
        let ddf = root.join("ddf").join(format!("{stem}.ddf"));
        let tmp = tempfile::tempdir().expect("temporary directory");
        let out = tutti_test_support::tutti_command()
            .arg("idl")
            .arg(&ddf)
            .arg("--out")
            .arg(tmp.path())
            .output()
            .expect("run tutti idl");
        assert!(
            out.status.success(),
            "tutti idl {} failed: {}\n{}",
            ddf.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        let package = tutti_core::mapping::package_name(&ddf);
        let fresh = tree(&tmp.path().join(&package));
        assert!(!fresh.is_empty(), "tutti idl {} wrote nothing under {package}/", ddf.display());
        let committed_dir = root.join("idl").join(&package);
        let committed = tree(&committed_dir);
        let hint =
            format!("idl/{package} is out of date: run `cargo run -q -- idl ddf/{stem}.ddf --out idl` and commit it");
        for (path, text) in &fresh {
            match committed.get(path) {
                None => panic!("{hint}: {} is missing", path.display()),
                Some(old) => assert!(old == text, "{hint}: {} differs", path.display()),
            }
        }
        for path in committed.keys() {
            assert!(fresh.contains_key(path), "{hint}: {} is no longer generated", path.display());
        }
    }
}
