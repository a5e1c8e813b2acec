//! Real C (and C++) programs compiled against include/RTAPI.h and the built library, run
//! against a live framework (stepping in a thread of this test process).

mod common;

use std::process::Command;
use std::time::Duration;

use common::*;
use tutti_core::shm::FrameworkOptions;

const LIMIT: Duration = Duration::from_secs(120);

fn fopts(ns: &str) -> FrameworkOptions {
    FrameworkOptions { namespace: ns.to_string(), timeout: Duration::from_secs(20), ..Default::default() }
}

fn f64_at(bytes: &[u8], off: usize) -> f64 {
    f64::from_ne_bytes(bytes[off..off + 8].try_into().expect("8 bytes"))
}

/// The values `uav_reader` printed, in order.
fn printed_values(stdout: &str) -> Vec<f64> {
    stdout.lines().filter_map(|l| l.split_whitespace().nth(1)?.split('=').nth(1)?.parse().ok()).collect()
}

/// Runs uav_reader (built as `program`) for `steps` steps, optionally under a wrapper such
/// as valgrind, and checks the exchange step by step.
fn run_uav_reader(test: &str, program: &std::path::Path, wrapper: &[&str], steps: usize) {
    let ns = namespace(test);
    let host = Host::start(&load("ddf/multiuav.ddf"), fopts(&ns), Duration::from_millis(1));
    let ddf = root().join("ddf/multiuav.ddf");
    let mut cmd = Command::new(wrapper.first().copied().unwrap_or(program.to_str().expect("path")));
    if !wrapper.is_empty() {
        cmd.args(&wrapper[1..]).arg(program);
    }
    cmd.env("TUTTI_NAMESPACE", &ns).arg(&ddf).args(["multiuav_uav2", "Z", "Elevation", &steps.to_string(), "2"]);
    let out = run(&mut cmd, LIMIT);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "uav_reader failed ({}):\n{stdout}\n{stderr}", out.status);
    let values = printed_values(&stdout);
    assert_eq!(values.len(), steps, "{stdout}");
    // Lock-step: every step read once, none skipped. From the second value on: until its
    // first commit a connection is not a writer, the framework may move on meanwhile, and the
    // core's publish_lock then counts the newer step as read (see docs/rtapi.md, "Joining a
    // synchronous domain").
    for w in values[1..].windows(2) {
        assert_eq!(w[1], w[0] + 1.0, "steps skipped or repeated: {values:?}");
    }
    assert!(stdout.lines().all(|l| l.ends_with("status=1")), "{stdout}");
    let last = values.last().map_or(0, |v| *v as u64);
    let seen = host.seen_through(&[("multiuav_uav2", last)], Duration::from_secs(30));
    drop(host);
    // The framework's view: the answer to step k (Elevation, SUBSCRIBE offset 16) is 2k.
    // The first step read is skipped: a connection counts as a writer from its first
    // RTPublishLock, so the framework does not wait for that first answer (docs/rtapi.md).
    for v in &values[1..] {
        let step = *v as u64;
        let s =
            seen.iter().find(|s| s.domain == "multiuav_uav2" && s.step == step).expect("step seen by the framework");
        assert_eq!(f64_at(&s.subscribe, 16), 2.0 * v, "step {step}");
    }
}

#[test]
fn product_pattern_client_exchanges_every_step_with_a_live_framework() {
    let dir = tempfile::tempdir().expect("temp dir");
    let program = compile(&root().join("examples/c/uav_reader.c"), dir.path());
    run_uav_reader("uavreader", &program, &[], 200);
}

#[test]
fn product_pattern_client_is_clean_under_valgrind() {
    // Skipped without valgrind, except under CI=true, where that is a failure.
    let Some(_) = tutti_test_support::require_tool("valgrind", "valgrind") else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let program = compile(&root().join("examples/c/uav_reader.c"), dir.path());
    run_uav_reader("valgrind", &program, &["valgrind", "--error-exitcode=99", "--leak-check=no", "-q"], 20);
}

#[test]
fn static_library_links_and_runs() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("uav_reader_static");
    let lib = lib_dir().join("librtapi.a");
    let mut cmd = Command::new("gcc");
    cmd.args(["-std=c99", "-Wall", "-Werror"]).arg(format!("-I{}", root().join("include").display()));
    cmd.arg(root().join("examples/c/uav_reader.c")).arg(&lib).args(["-lpthread", "-ldl", "-lm", "-o"]).arg(&out);
    let o = run(&mut cmd, LIMIT);
    assert!(o.status.success(), "static link failed:\n{}", String::from_utf8_lossy(&o.stderr));
    run_uav_reader("static", &out, &[], 20);
}

#[test]
fn two_connections_to_two_domains_in_one_process() {
    let ns = namespace("twodomains");
    let dir = tempfile::tempdir().expect("temp dir");
    let program = compile(&root().join("examples/c/two_domains.c"), dir.path());
    let host = Host::start(&load("ddf/multiuav.ddf"), fopts(&ns), Duration::from_millis(1));
    let mut cmd = Command::new(&program);
    cmd.env("TUTTI_NAMESPACE", &ns).args(["multiuav_uav1", "multiuav_uav3", "X", "Latitude", "40"]);
    let out = run(&mut cmd, LIMIT);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "two_domains failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        stdout.contains("multiuav_uav1 connections=1") && stdout.contains("multiuav_uav3 connections=1"),
        "{stdout}"
    );
    let steps: Vec<(f64, f64)> = stdout
        .lines()
        .filter(|l| l.starts_with("step "))
        .filter_map(|l| {
            let mut it = l.split_whitespace().skip(2).filter_map(|kv| kv.split('=').nth(1)?.parse().ok());
            Some((it.next()?, it.next()?))
        })
        .collect();
    assert_eq!(steps.len(), 40, "{stdout}");
    for w in steps[1..].windows(2) {
        assert_eq!(w[1].0, w[0].0 + 1.0, "{stdout}");
        assert_eq!(w[1].1, w[0].1 + 1.0, "{stdout}");
    }
    let last = steps.last().copied().unwrap_or_default();
    let until = [("multiuav_uav1", last.0 as u64), ("multiuav_uav3", last.1 as u64)];
    let seen = host.seen_through(&until, Duration::from_secs(30));
    drop(host);
    // Each domain got back the value it published that step (Latitude, SUBSCRIBE offset 0).
    // (From the second step on: see run_uav_reader.)
    for (domain, idx) in [("multiuav_uav1", 0), ("multiuav_uav3", 1)] {
        for s in &steps[1..] {
            let v = if idx == 0 { s.0 } else { s.1 };
            let seen = seen.iter().find(|x| x.domain == domain && x.step == v as u64).expect("step seen");
            assert_eq!(f64_at(&seen.subscribe, 0), v, "{domain} step {v}");
        }
    }
}

#[test]
fn header_compiles_as_c_and_inside_extern_c_in_cpp() {
    let dir = tempfile::tempdir().expect("temp dir");
    let c = dir.path().join("hdr_c.c");
    std::fs::write(
        &c,
        "#include \"RTAPI.h\"\n#include \"RTAPI.h\"\n#include <stdio.h>\n\
         int main(void) { RTAPIReturn_t rc = RTAPI_SUCCESS; unsigned int n; \
         rc = RTGetConnectionCount(NULL, &n); \
         printf(\"%d %s|%s\\n\", rc, RTGetErrorMessage(rc), RTGetErrorMessage(RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED)); \
         return rc == RTAPI_ERROR_NULL_POINTER ? 0 : 1; }\n",
    )
    .expect("writing");
    let cpp = dir.path().join("hdr_cpp.cpp");
    std::fs::write(
        &cpp,
        "extern \"C\" {\n#include \"RTAPI.h\"\n}\n#include <cstdio>\n\
         int main() { bool skip = true; RTAPIReturn_t rc = RTSetSkipWaitToGoAtConnection(skip); \
         std::printf(\"%d %s\\n\", rc, RTGetErrorMessage(RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED)); \
         return rc == RTAPI_SUCCESS ? 0 : 1; }\n",
    )
    .expect("writing");
    for src in [c, cpp] {
        let program = compile(&src, dir.path());
        let out = run(&mut Command::new(&program), LIMIT);
        assert!(out.status.success(), "{}: {}", src.display(), String::from_utf8_lossy(&out.stdout));
        assert!(String::from_utf8_lossy(&out.stdout).contains("framework has stopped"));
    }
}

/// The C example against the real `tutti host` binary (as a user runs them), with the host
/// recording what it read: the C component's answers reach the framework.
#[test]
fn c_example_runs_against_a_live_tutti_host() {
    let tutti = tutti();
    let ns = namespace("livehost");
    let dir = tempfile::tempdir().expect("temp dir");
    let program = compile(&root().join("examples/c/uav_reader.c"), dir.path());
    let csv = dir.path().join("rec.csv");
    let mut host = Command::new(&tutti);
    host.current_dir(root())
        .env("TUTTI_NAMESPACE", &ns)
        .args(["host", "ddf/multiuav.ddf", "--step", "2ms", "--quiet", "--set", "multiuav_uav2/Z=3.25", "--record"])
        .arg(&csv);
    let mut host = spawn(host);
    // The C program gives the framework 5 s to appear; a loaded machine can take longer to
    // start the host, so the program starts once the domain is there (60 s watchdog).
    let domains = || shm_path(&ns, "multiuav_uav2").exists();
    tutti_test_support::wait_until(
        "tutti host did not create its domains within 60 s",
        Duration::from_secs(60),
        domains,
    );
    let ddf = root().join("ddf/multiuav.ddf");
    let mut cmd = Command::new(&program);
    cmd.env("TUTTI_NAMESPACE", &ns).arg(&ddf).args(["multiuav_uav2", "Z", "Elevation", "50", "2"]);
    let out = run(&mut cmd, LIMIT);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "uav_reader failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let values = printed_values(&stdout);
    assert_eq!(values, vec![3.25; 50], "{stdout}");
    // Stop the host (SIGINT: it flushes the recording and removes its segments).
    host.signal("INT");
    host.wait_status(LIMIT).expect("tutti host did not stop on SIGINT");
    let rec = std::fs::read_to_string(dir.path().join("rec-multiuav_uav2.csv")).expect("recording");
    let header: Vec<&str> = rec.lines().next().expect("header").split(',').collect();
    let col = header.iter().position(|c| *c == "subscribe.Elevation").expect("Elevation column");
    assert!(
        rec.lines().skip(1).any(|l| l.split(',').nth(col) == Some("6.5")),
        "the framework never read the C component's answer 2 x 3.25"
    );
    assert!(!shm_path(&ns, "multiuav_uav2").exists());
}

/// A client that reads a synchronous domain in one thread and writes it in another (as
/// VILLASnode does), with and without a mutex of its own around every call: it keeps up with
/// the framework, reads every step once, and never makes a step wait for its timeout.
#[test]
fn a_two_thread_client_keeps_lock_step_with_and_without_its_own_mutex() {
    let dir = tempfile::tempdir().expect("temp dir");
    let program = compile(&root().join("crates/tutti-rtapi/tests/c/two_threads.c"), dir.path());
    for mode in ["own-mutex", "no-mutex"] {
        let ns = namespace(&format!("threads-{mode}"));
        let host = Host::start(&load("ddf/multiuav.ddf"), fopts(&ns), Duration::from_millis(1));
        let mut cmd = Command::new(&program);
        cmd.env("TUTTI_NAMESPACE", &ns).args(["multiuav_uav2", "Z", "Elevation", "300", mode]);
        let out = run(&mut cmd, LIMIT);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{mode}: {stdout}{}", String::from_utf8_lossy(&out.stderr));
        let values: Vec<f64> = stdout.lines().filter_map(|l| l.strip_prefix("read ")?.parse().ok()).collect();
        assert_eq!(values.len(), 300, "{mode}: {stdout}");
        for w in values.windows(2) {
            assert_eq!(w[1], w[0] + 1.0, "{mode}: steps skipped or read twice: {values:?}");
        }
        let writes: u64 =
            stdout.lines().find_map(|l| l.strip_prefix("writes ")?.parse().ok()).expect("the writes line");
        // The writer answers the latest value read; a writer held up for steps at a time
        // answers far fewer than it reads.
        // (With its own mutex held through RTSubscribeLock, the client itself starves its
        // writer on a loaded machine: only the library's part is checked, without it.)
        if mode == "no-mutex" {
            assert!(writes * 2 >= values.len() as u64, "{mode}: {writes} answers to {} reads", values.len());
        } else {
            assert!(writes > 0, "{mode}: no answer");
        }
        let status = tutti_core::shm::segment::Segment::open(&ns, "multiuav_uav2").expect("segment").status();
        drop(host);
        // A stall would make the framework wait for its 20 s timeout at least once.
        assert_eq!(status.step_timeouts, 0, "{mode}: the framework waited for the client's answer until its timeout");
    }
}

/// A writer thread beside a reader thread that loops on RTSubscribeLock, neither with a
/// mutex of its own, over 10,000 steps of 1 ms (a 10 s run): the writer writes every 20
/// steps the reader reads, and every write reaches the framework. Its RTPublishLock never
/// waits for the reader's wait for the next step: across all its calls, the reader reads
/// fewer steps than there were calls (a lock that waited for the reader's step would see one
/// pass every time; the library used to hold its state through that wait).
#[test]
fn a_writer_thread_beside_a_looping_reader_keeps_its_rate() {
    const STEPS: u64 = 10_000;
    let dir = tempfile::tempdir().expect("temp dir");
    let program = compile(&root().join("crates/tutti-rtapi/tests/c/two_threads.c"), dir.path());
    let ns = namespace("threads-paced");
    let host = Host::start(&load("ddf/multiuav.ddf"), fopts(&ns), Duration::from_millis(1));
    let mut cmd = Command::new(&program);
    cmd.env("TUTTI_NAMESPACE", &ns).args(["multiuav_uav2", "Z", "Elevation", &STEPS.to_string(), "paced"]);
    let out = run(&mut cmd, LIMIT);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
    let field = |name: &str| -> u64 {
        stdout
            .lines()
            .find_map(|l| l.strip_prefix(name)?.trim().parse().ok())
            .unwrap_or_else(|| panic!("{name}: {stdout}"))
    };
    let (writes, lock_steps) = (field("writes "), field("lock_steps "));
    eprintln!(
        "paced writer: {writes} writes, {lock_steps} steps read during its locks, max {}",
        field("max_lock_steps ")
    );
    // A write every 20 steps read, counted from the end of the last write: a writer that
    // loses no step in its locks makes STEPS / 20 of them; one that waits a step in every lock
    // makes at most STEPS / 21.
    assert!(writes * 21 > STEPS, "the writer fell behind: {writes} writes in {STEPS} steps\n{stdout}");
    assert!(lock_steps < writes, "RTPublishLock waited for the reader's steps: {lock_steps} in {writes} calls");
    // Every write reached the framework: it saw each value 1..=writes in the SUBSCRIBE set.
    let seen = host.seen_through(&[("multiuav_uav2", STEPS)], Duration::from_secs(30));
    // Elevation is at SUBSCRIBE offset 16.
    let values: std::collections::BTreeSet<u64> =
        seen.iter().filter(|s| s.domain == "multiuav_uav2").map(|s| f64_at(&s.subscribe, 16) as u64).collect();
    let missing: Vec<u64> = (1..=writes).filter(|v| !values.contains(v)).collect();
    assert!(missing.is_empty(), "writes the framework never saw: {missing:?}");
    let status = tutti_core::shm::segment::Segment::open(&ns, "multiuav_uav2").expect("segment").status();
    drop(host);
    assert_eq!(status.step_timeouts, 0, "the framework waited for the client until its timeout");
}

/// Every RTAPI call VILLASnode's Orchestra node makes, with the argument types it declares,
/// compiled as C++ with -Wconversion (and the C examples with it too), run against `tutti
/// host` in the three connection forms of the product's DDFs: a synchronous local domain, an
/// asynchronous remote one (with RTSetupRefMemRemoteConnection) and a synchronous dolphin one.
/// The host's recording shows each answer (y = 2 x).
#[test]
fn a_client_making_villasnodes_calls_runs_in_every_connection_form() {
    let tutti = tutti();
    let dir = tempfile::tempdir().expect("temp dir");
    let strict = ["-Wconversion"];
    let program = compile_with(&root().join("crates/tutti-rtapi/tests/c/villas_calls.cpp"), dir.path(), &strict);
    for example in ["uav_reader.c", "uav_altitude_log.c", "two_domains.c"] {
        let out = dir.path().join("strict");
        std::fs::create_dir_all(&out).expect("dir");
        compile_with(&root().join("examples/c").join(example), &out, &strict);
    }
    let ns = namespace("villas");
    let ddf = root().join("tests/ddf/connection-forms.ddf");
    let csv = dir.path().join("rec.csv");
    let mut host = Command::new(&tutti);
    host.current_dir(root()).env("TUTTI_NAMESPACE", &ns).arg("host").arg(&ddf).args(["--step", "2ms", "--quiet"]);
    for set in ["local_link/x=1.25", "remote_link/x=2.5", "dolphin_link/x=3.75"] {
        host.args(["--set", set]);
    }
    host.arg("--record").arg(&csv);
    let mut host = spawn(host);
    for (domain, x, remote) in [("local_link", 1.25, false), ("remote_link", 2.5, true), ("dolphin_link", 3.75, false)]
    {
        let mut cmd = Command::new(&program);
        cmd.env("TUTTI_NAMESPACE", &ns).arg(&ddf).args([domain, "20"]);
        if remote {
            cmd.args(["rfm2g", "0"]);
        }
        let out = run(&mut cmd, LIMIT);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{domain}: {stdout}{}", String::from_utf8_lossy(&out.stderr));
        assert_eq!(stdout.lines().filter(|l| *l == format!("x={x} status=1")).count(), 20, "{domain}: {stdout}");
    }
    host.signal("INT");
    host.wait_status(LIMIT).expect("tutti host did not stop on SIGINT");
    for (domain, y) in [("local_link", "2.5"), ("remote_link", "5"), ("dolphin_link", "7.5")] {
        let rec = std::fs::read_to_string(dir.path().join(format!("rec-{domain}.csv"))).expect("recording");
        let header: Vec<&str> = rec.lines().next().expect("header").split(',').collect();
        let col = header.iter().position(|c| *c == "subscribe.y").expect("y column");
        assert!(
            rec.lines().skip(1).any(|l| l.split(',').nth(col) == Some(y)),
            "{domain}: the answer {y} never reached the host"
        );
    }
    for d in ["local_link", "remote_link", "dolphin_link"] {
        assert!(!shm_path(&ns, d).exists());
    }
}
