//! The invalid-DDF corpus: every file in `tests/ddf-invalid/` is refused by `tutti check`
//! with exit status 2 and exactly the diagnostics its `.expect` sibling lists.
//!
//! An `.expect` file has one `LINE:COL: error: MESSAGE-SUBSTRING` line per expected
//! diagnostic (`#` starts a comment). Each must match a distinct `FILE:LINE:COL: error: …`
//! line on stderr with that exact position and a message containing the substring, and
//! there must be no other `error:` lines: the validator reports every problem in one run.

use tutti_test_support as common;

use std::fs;
use std::path::{Path, PathBuf};

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ddf-invalid")
}

/// Runs `tutti check ARGS` with a watchdog; returns (exit code, stdout, stderr).
fn tutti(args: &[&Path]) -> (i32, String, String) {
    common::tutti(std::iter::once(Path::new("check")).chain(args.iter().copied()))
}

/// One expected diagnostic.
#[derive(Debug)]
struct Expected {
    line: u32,
    col: u32,
    message: String,
}

fn parse_expect(path: &Path) -> Vec<Expected> {
    let text = fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = || panic!("{}:{}: expected LINE:COL: error: MESSAGE, found {line:?}", path.display(), n + 1);
        let mut parts = line.splitn(3, ':');
        let (Some(l), Some(c), Some(rest)) = (parts.next(), parts.next(), parts.next()) else { bad() };
        let Some(message) = rest.strip_prefix(" error: ") else { bad() };
        let (Ok(line), Ok(col)) = (l.parse(), c.parse()) else { bad() };
        out.push(Expected { line, col, message: message.to_string() });
    }
    out
}

/// Checks stderr of `tutti check FILE` against the expectations; returns the problems.
fn compare(file: &Path, stderr: &str, expected: &[Expected]) -> Vec<String> {
    let prefix = format!("{}:", file.display());
    let errors: Vec<&str> = stderr.lines().filter(|l| l.contains("error:")).collect();
    let mut problems = Vec::new();
    let mut used = vec![false; errors.len()];
    for e in expected {
        let head = format!("{prefix}{}:{}: error: ", e.line, e.col);
        let found = errors
            .iter()
            .enumerate()
            .position(|(i, l)| !used[i] && l.strip_prefix(&head).is_some_and(|m| m.contains(&e.message)));
        match found {
            Some(i) => used[i] = true,
            None => problems.push(format!("missing {}:{}: error: {}", e.line, e.col, e.message)),
        }
    }
    for (i, l) in errors.iter().enumerate() {
        if !used[i] {
            problems.push(format!("unexpected {l}"));
        }
    }
    if errors.len() != expected.len() {
        problems.push(format!("{} error lines, {} expected", errors.len(), expected.len()));
    }
    problems
}

fn corpus() -> Vec<(PathBuf, Vec<Expected>)> {
    let mut cases: Vec<_> = fs::read_dir(corpus_dir())
        .expect("read tests/ddf-invalid")
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "ddf"))
        .collect();
    cases.sort();
    cases
        .into_iter()
        .map(|ddf| {
            let expect = ddf.with_extension("expect");
            assert!(expect.exists(), "{} has no .expect file", ddf.display());
            let expected = parse_expect(&expect);
            assert!(!expected.is_empty(), "{} expects no error", expect.display());
            (ddf, expected)
        })
        .collect()
}

#[test]
fn every_invalid_ddf_is_refused_with_its_diagnostics() {
    let cases = corpus();
    assert!(cases.len() >= 35, "only {} cases in tests/ddf-invalid", cases.len());
    let mut failures = Vec::new();
    for (ddf, expected) in &cases {
        let (code, _, stderr) = tutti(&[ddf]);
        let mut problems = compare(ddf, &stderr, expected);
        if code != 2 {
            problems.insert(0, format!("exit status {code}, expected 2"));
        }
        if !problems.is_empty() {
            failures.push(format!("{}:\n  {}\n  stderr:\n{stderr}", ddf.display(), problems.join("\n  ")));
        }
    }
    assert!(failures.is_empty(), "{} of {} cases failed:\n{}", failures.len(), cases.len(), failures.join("\n"));
}

#[test]
fn every_expect_file_has_a_ddf() {
    for entry in fs::read_dir(corpus_dir()).expect("read tests/ddf-invalid") {
        let path = entry.expect("directory entry").path();
        if path.extension().is_some_and(|x| x == "expect") {
            assert!(path.with_extension("ddf").exists(), "{} has no .ddf file", path.display());
        }
    }
}

#[test]
fn all_files_in_one_run_report_every_error() {
    let cases = corpus();
    let files: Vec<&Path> = cases.iter().map(|(p, _)| p.as_path()).collect();
    let (code, stdout, stderr) = tutti(&files);
    assert_eq!(code, 2);
    assert!(stdout.is_empty(), "{stdout}");
    let total: usize = cases.iter().map(|(_, e)| e.len()).sum();
    assert_eq!(stderr.lines().filter(|l| l.contains("error:")).count(), total, "{stderr}");
    assert!(stderr.contains(&format!("{} of {} files invalid", cases.len(), cases.len())), "{stderr}");
}

#[test]
fn a_valid_file_among_invalid_ones_still_fails_the_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let good = dir.path().join("good.ddf");
    let bad = dir.path().join("bad.ddf");
    fs::write(&good, r#"<orchestra><domain name="d"/></orchestra>"#).unwrap();
    fs::write(&bad, "<orchestra>\n  <domain name=\"d\"><states>maybe</states></domain>\n</orchestra>\n").unwrap();
    let (code, stdout, stderr) = tutti(&[&good, &bad]);
    assert_eq!(code, 2);
    assert!(stdout.contains("good.ddf: ok (1 domain, 0 items)"), "{stdout}");
    let problems =
        compare(&bad, &stderr, &[Expected { line: 2, col: 28, message: "<states> must be yes or no".into() }]);
    assert!(problems.is_empty(), "{problems:?}\n{stderr}");
}

#[test]
fn generated_binary_and_control_bytes_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Pseudo-random bytes (fixed seed), not valid UTF-8.
    let mut x: u32 = 0x2545_f491;
    let noise: Vec<u8> = (0..4096)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x >> 24) as u8 | 0x80
        })
        .collect();
    let noise_path = dir.path().join("noise.ddf");
    fs::write(&noise_path, &noise).unwrap();
    let (code, _, stderr) = tutti(&[&noise_path]);
    assert_eq!(code, 2);
    let problems = compare(&noise_path, &stderr, &[Expected { line: 1, col: 1, message: "not UTF-8".into() }]);
    assert!(problems.is_empty(), "{problems:?}\n{stderr}");

    // Valid UTF-8 but with a NUL on line 2.
    let nul_path = dir.path().join("nul.ddf");
    fs::write(&nul_path, b"<orchestra>\n  \0<domain name=\"d\"/>\n</orchestra>\n").unwrap();
    let (code, _, stderr) = tutti(&[&nul_path]);
    assert_eq!(code, 2);
    let problems = compare(&nul_path, &stderr, &[Expected { line: 2, col: 3, message: "NUL bytes".into() }]);
    assert!(problems.is_empty(), "{problems:?}\n{stderr}");
}

#[test]
fn a_file_over_64_mib_is_refused_before_reading() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("huge.ddf");
    let file = fs::File::create(&path).expect("create");
    // Sparse: takes no disk space, and is refused from its size alone.
    file.set_len((64 << 20) + 1).expect("set_len");
    drop(file);
    let (code, _, stderr) = tutti(&[&path]);
    assert_eq!(code, 2);
    let expected =
        [Expected { line: 1, col: 1, message: "the file is 67108865 bytes; a DDF may be at most 64 MiB".into() }];
    let problems = compare(&path, &stderr, &expected);
    assert!(problems.is_empty(), "{problems:?}\n{stderr}");

    // Exactly 64 MiB is not refused for its size (it is all NUL bytes, so it fails later).
    let path = dir.path().join("limit.ddf");
    fs::File::create(&path).and_then(|f| f.set_len(64 << 20)).expect("create");
    let (code, _, stderr) = tutti(&[&path]);
    assert_eq!(code, 2);
    let problems = compare(&path, &stderr, &[Expected { line: 1, col: 1, message: "NUL bytes".into() }]);
    assert!(problems.is_empty(), "{problems:?}\n{stderr}");
}

#[test]
fn a_missing_file_is_an_error_too() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("absent.ddf");
    let (code, _, stderr) = tutti(&[&path]);
    assert_eq!(code, 2);
    assert!(stderr.contains("error: cannot read the file"), "{stderr}");
}
