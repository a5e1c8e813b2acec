//! `tutti ctl`, the run's control plane: pause, step, reset, resume and stop a running
//! `tutti host` from the command line, from Python (`tutti_ctl`) and from the Rust library,
//! with a C participant and a DDS reader watching every step.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::thread;
use std::time::Duration;

use tutti_host::control::{ControlClient, RunState};
use tutti_test_support::{self as common, lazy, wait_until, Proc};

use super::gateway::{json_lines, python, Eng, PEER};

const DDF: &str = "tests/gateway/gw.ddf";
const SYNC_PUB: &str = r#"[["step","uint64"],["sim_time","float64"],["x","float64"]]"#;
const WATCHDOG: Duration = Duration::from_secs(180);

/// The test's C participant, compiled against the workspace's librtapi.
fn stepper(dir: &Path) -> PathBuf {
    common::compile_c(
        &common::repo_root().join("tests/ctl/stepper.c"),
        &dir.join("stepper"),
        &["-std=c99", "-Wall", "-Werror"],
    )
}

/// `tutti ARGS` in namespace `ns`: (exit code, stdout, stderr).
fn tutti(ns: &str, args: &[&str]) -> (i32, String, String) {
    let mut cmd = common::tutti_command();
    cmd.args(args).env("TUTTI_NAMESPACE", ns);
    let (status, out, err) = common::run_with_timeout(cmd, Duration::from_secs(60));
    (status.code().unwrap_or(-1), out, err)
}

/// `tutti ctl ARGS --json` in namespace `ns`: the run's state after the command.
fn ctl(ns: &str, args: &[&str]) -> serde_json::Value {
    let (code, out, err) = tutti(ns, &[&["ctl"], args, &["--json"]].concat());
    assert_eq!(code, 0, "tutti ctl {args:?}: {err}");
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("tutti ctl {args:?}: {e}: {out}"))
}

/// The steps the C participant has printed so far.
fn steps_seen(p: &Proc) -> usize {
    p.lines().iter().filter(|l| l.starts_with("step ")).count()
}

/// Waits until `p` has printed `n` steps; fails with what it printed.
fn wait_steps(p: &Proc, n: usize, also: &Proc) {
    let seen = lazy(|| format!("{} of {n} steps seen\n{}\n{}", steps_seen(p), p.dump(), also.dump()));
    wait_until(seen, Duration::from_secs(60), || steps_seen(p) >= n);
}

/// How many steps the connection of process `pid` in `gw_sync` has read.
fn reads_of(ns: &str, pid: u32) -> usize {
    let status = tutti_core::shm::Segment::open(ns, "gw_sync").map(|s| s.status()).expect("gw_sync is there");
    status.connections.iter().find(|c| c.pid == pid).map_or(0, |c| c.reads as usize)
}

/// The step numbers the DDS reader has received.
fn dds_steps(reader: &Proc) -> Vec<u64> {
    json_lines(reader, "step").iter().filter_map(|v| v["step"].as_u64()).collect()
}

/// A synchronous domain with a C participant and a DDS reader of its PUBLISH set (the
/// gateway a lock-step reader, so that every step reaches DDS): a pause ten times the
/// participant's lock timeout costs no timeout, `step 7` (from Python) is seven steps for
/// both, reset (from the library) sets the step count and simulated time to zero, resume
/// and stop (from the command line) end the run with nothing left.
#[test]
fn a_paused_run_steps_exactly_as_asked_and_no_participant_times_out() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = common::namespace("ctlsync");
    let _segments = common::RemoveSegments(ns.clone());
    let dom = Eng::CYCLONE.dom(130);
    let mut host = common::tutti_command();
    host.args(["host", DDF, "--step", "5ms", "--timeout", "300ms", "-q"]).env("TUTTI_NAMESPACE", &ns);
    let mut host = Proc::spawn("tutti host", host, WATCHDOG);
    let mut c = Command::new(stepper(dir.path()));
    c.arg(common::repo_root().join(DDF)).args(["gw_sync", "x", "y", "1"]).env("TUTTI_NAMESPACE", &ns);
    let mut part = Proc::spawn("stepper", c, WATCHDOG);
    let gw = Eng::CYCLONE.gateway(DDF, dom, &ns, &["--every-step"]);
    let args = ["--topic", "rt/gw_sync/publish", "--type", "gw_msgs::msg::dds_::GwSyncPublish_"];
    let mut cmd = Command::new(&py);
    cmd.arg(PEER).args(["sub", "--domain", &dom.to_string()]).args(args);
    cmd.args(["--fields", SYNC_PUB, "--count", "1000000", "--timeout", "170"]);
    let reader = Proc::spawn("dds reader", cmd, WATCHDOG);
    wait_steps(&part, 20, &host);
    let no_step = lazy(|| format!("the DDS reader got no step\n{}\n{}", reader.dump(), gw.dump()));
    wait_until(no_step, Duration::from_secs(90), || dds_steps(&reader).len() >= 5);

    // Pause, for ten times the participant's lock timeout (1 s) and far more than the
    // framework's step timeout: no step, no timeout.
    let paused = ctl(&ns, &["pause"]);
    assert_eq!(paused["state"], "paused", "{paused}");
    let at = paused["step"].as_u64().unwrap();
    // Every step the participant read before the pause (its connection counts them before
    // the framework may go on) is printed by now or soon: wait for the lines to catch up.
    wait_steps(&part, reads_of(&ns, part.id()), &host);
    let seen = steps_seen(&part);
    // A window, not a wait: what is checked is that nothing happens. The participant's lock
    // waits time out after 1 s and are armed again while paused, so 10.5 s is ten such
    // timeouts the pause must cost nothing (and 35 of the framework's 300 ms step timeout);
    // a step made while paused would be printed within one 5 ms period.
    thread::sleep(Duration::from_millis(10_500));
    assert_eq!(steps_seen(&part), seen, "a step was made while paused\n{}", part.dump());
    assert!(part.exited().is_none(), "the participant ended while paused\n{}", part.dump());
    assert_eq!(ctl(&ns, &["state"])["step"].as_u64(), Some(at), "the step count moved while paused");
    let before = *dds_steps(&reader).last().unwrap();

    // `step 7`, from Python: seven steps for the C participant and for the DDS reader.
    let script = "import json, sys, tutti_ctl\nprint(json.dumps(tutti_ctl.connect(sys.argv[1]).step(7)))";
    let mut cmd = Command::new(&py);
    cmd.args(["-c", script, &ns]).env("PYTHONPATH", common::repo_root().join("python"));
    let (status, out, err) = common::run_with_timeout(cmd, Duration::from_secs(60));
    assert!(status.success(), "{out}{err}");
    let stepped: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!((stepped["state"].as_str(), stepped["step"].as_u64()), (Some("paused"), Some(at + 7)), "{stepped}");
    wait_steps(&part, seen + 7, &host);
    let got_7 = lazy(|| format!("the DDS reader did not get the 7 steps\n{}", reader.dump()));
    wait_until(got_7, Duration::from_secs(30), || dds_steps(&reader).last() >= Some(&(before + 7)));
    // A window for an eighth step to show, which the run must not make: it would follow the
    // seventh within one 5 ms period and be printed before it is answered; 300 ms is sixty
    // periods.
    thread::sleep(Duration::from_millis(300));
    assert_eq!(steps_seen(&part), seen + 7, "the participant saw other than 7 steps\n{}", part.dump());
    let after: Vec<u64> = dds_steps(&reader).into_iter().filter(|&s| s > before).collect();
    assert_eq!(after, (before + 1..=before + 7).collect::<Vec<_>>(), "the DDS reader's steps");

    // Reset, from the library: step count and simulated time back to zero, still paused.
    let mut client = ControlClient::connect(&ns, Duration::from_secs(30)).unwrap();
    let reset = client.reset().unwrap();
    assert_eq!((reset.state, reset.step, reset.sim_time), (RunState::Paused, 0, 0.0));
    let one = client.step(1).unwrap();
    assert_eq!((one.step, one.sim_time), (1, 0.0), "the first step after a reset is at t=0");

    // Resume and stop, from the command line.
    let seen = steps_seen(&part);
    assert_eq!(ctl(&ns, &["resume"])["state"], "playing");
    wait_steps(&part, seen + 10, &host);
    let s = tutti_core::shm::Segment::open(&ns, "gw_sync").unwrap().status();
    assert_eq!(s.step_timeouts, 0, "a step timed out: {s:?}");
    let stopped = ctl(&ns, &["stop"]);
    assert_eq!(stopped["namespace"], ns.as_str());
    assert_eq!(host.wait(Duration::from_secs(30)), Some(0), "{}", host.dump());
    assert_eq!(part.wait(Duration::from_secs(30)), Some(0), "the participant: {}", part.dump());
    assert!(!part.lines().iter().any(|l| l.contains("timed out")), "{}", part.dump());
    assert!(common::segments_of(&ns).is_empty(), "segments left: {:?}", common::segments_of(&ns));
    assert!(!tutti_host::control::socket_path(&ns).exists(), "the control socket was left");
}

/// An asynchronous run pauses (its PUBLISH set stops changing) and refuses `step` with the
/// reason; the socket is the owner's alone; with no run, `tutti ctl` says so.
#[test]
fn an_asynchronous_run_pauses_and_refuses_to_step() {
    let ns = common::namespace("ctlasync");
    let _segments = common::RemoveSegments(ns.clone());
    let (code, _, err) = tutti(&ns, &["ctl", "state"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains(&format!("no run in namespace '{ns}'")), "{err}");

    // The asynchronous domain of the gateway tests' DDF, alone.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::repo_root().join(DDF)).unwrap();
    let (start, end) =
        (text.find("<domain name=\"gw_async\">").unwrap(), text.find("<domain name=\"gw_sync\">").unwrap());
    let ddf = dir.path().join("async.ddf");
    std::fs::write(&ddf, format!("<orchestra>\n{}</orchestra>\n", &text[start..end])).unwrap();
    let mut host = common::tutti_command();
    host.arg("host").arg(&ddf).args(["--step", "5ms", "-q"]).env("TUTTI_NAMESPACE", &ns);
    let mut host = Proc::spawn("tutti host", host, WATCHDOG);
    let socket = tutti_host::control::socket_path(&ns);
    wait_until(lazy(|| format!("no control socket\n{}", host.dump())), Duration::from_secs(30), || socket.exists());
    use std::os::unix::fs::PermissionsExt;
    assert_eq!(std::fs::metadata(&socket).unwrap().permissions().mode() & 0o777, 0o600);

    // Run as root (as the test command is), the test can be another user too.
    let uid = std::os::unix::fs::MetadataExt::uid(&std::fs::metadata("/proc/self").unwrap());
    let root = if uid == 0 { Ok(()) } else { Err(format!("running as uid {uid}")) };
    let Some(py) = python() else { return };
    if tutti_test_support::require("root (to act as another user)", root).is_some() {
        another_user_is_refused(&ns, &socket, &py);
        another_users_socket_is_not_told_anything(&py);
    }

    // Every call from Python, on this run.
    let script = "import json, sys, tutti_ctl\n\
        run = tutti_ctl.connect(sys.argv[1])\n\
        out = [run.state()['state'], run.pause()['state']]\n\
        try:\n    run.step(2)\nexcept tutti_ctl.ControlError as e:\n    out.append(str(e))\n\
        out += [run.reset()['step'], run.resume()['state']]\n\
        try:\n    run.restart('x')\nexcept tutti_ctl.ControlError as e:\n    out.append(str(e))\n\
        print(json.dumps(out))";
    let mut cmd = Command::new(&py);
    cmd.args(["-c", script, &ns]).env("PYTHONPATH", common::repo_root().join("python"));
    let (status, out, err) = common::run_with_timeout(cmd, Duration::from_secs(60));
    assert!(status.success(), "{out}{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(
        (&v[0], &v[1], &v[3], &v[4]),
        (&"playing".into(), &"paused".into(), &0.into(), &"playing".into()),
        "{v}"
    );
    assert!(v[2].as_str().unwrap().contains("asynchronous"), "{v}");
    assert!(v[5].as_str().unwrap().contains("no components"), "{v}");

    assert_eq!(ctl(&ns, &["pause"])["state"], "paused");
    assert_eq!(ctl(&ns, &["reset"])["step"], 0);
    let steps = |d: &str| tutti_core::shm::Segment::open(&ns, d).unwrap().status().steps;
    let before = steps("gw_async");
    // A window for a step the paused run must not make: the domain steps every 5 ms when it
    // runs, so 200 ms is forty steps it did not make.
    thread::sleep(Duration::from_millis(200));
    assert_eq!(steps("gw_async"), before, "the framework published while paused");
    let (code, _, err) = tutti(&ns, &["ctl", "step", "3"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("every domain of this run is asynchronous (gw_async)"), "{err}");
    assert_eq!(ctl(&ns, &["state"])["state"], "paused", "a refused step leaves the run paused");
    let (code, _, err) = tutti(&ns, &["ctl", "bogus"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("unknown command 'bogus'"), "{err}");
    assert_eq!(ctl(&ns, &["resume"])["state"], "playing");
    assert_eq!(ctl(&ns, &["stop"])["namespace"], ns.as_str());
    assert_eq!(host.wait(Duration::from_secs(30)), Some(0), "{}", host.dump());
    assert!(!socket.exists());
}

/// `program ARGS` as user `nobody` (uid 65534).
fn nobody(program: &Path, args: &[&str]) -> Command {
    let mut cmd = Command::new("setpriv");
    cmd.args(["--reuid=65534", "--regid=65534", "--clear-groups"]).arg(program).args(args);
    cmd.env("PYTHONPATH", common::repo_root().join("python"));
    cmd
}

/// `program ARGS` as user `nobody`, to its end: its exit code and output.
fn as_nobody(program: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let (status, out, err) = common::run_with_timeout(nobody(program, args), Duration::from_secs(60));
    (status.code(), out, err)
}

/// Another user cannot use the run's control plane: the socket is the owner's (mode 0600),
/// and were it opened to all, the run closes another user's connection unanswered (and
/// `tutti ctl` would not talk to a run that is not its user's).
fn another_user_is_refused(ns: &str, socket: &Path, py: &Path) {
    let ctl = ["ctl", "state", "--namespace", ns, "--timeout", "10s"];
    let (code, out, err) = as_nobody(&common::tutti_exe(), &ctl);
    assert_eq!(code, Some(1), "another user reached the run: {out}{err}");
    assert!(err.contains("ermission denied"), "{err}");
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(socket, std::fs::Permissions::from_mode(0o666)).unwrap();
    let (code, out, err) = as_nobody(&common::tutti_exe(), &ctl);
    // A raw client that sends a request anyway (closed with the request unread, the
    // connection may be reset rather than ended).
    let raw = "import socket, sys\n\
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)\n\
        s.settimeout(10)\n\
        s.connect(sys.argv[1])\n\
        try:\n    s.sendall(b'{\"op\": \"state\"}\\n')\nexcept OSError:\n    pass\n\
        try:\n    data = s.recv(4096)\nexcept ConnectionResetError:\n    data = b''\n\
        print('answered' if data else 'closed')";
    let socket_str = socket.to_str().unwrap();
    let (raw_code, raw_out, raw_err) = as_nobody(py, &["-c", raw, socket_str]);
    std::fs::set_permissions(socket, std::fs::Permissions::from_mode(0o600)).unwrap();
    assert_eq!(code, Some(1), "another user was answered: {out}{err}");
    assert!(err.contains("served by another user (uid 0)"), "{err}");
    assert_eq!((raw_code, raw_out.trim()), (Some(0), "closed"), "the run answered another user: {raw_err}");
}

/// A control socket of the namespace that another user serves is not this user's run:
/// `tutti ctl` and the Python module refuse it, saying whose it is, and send it nothing.
fn another_users_socket_is_not_told_anything(py: &Path) {
    let ns = format!("ctlforeign{}", std::process::id());
    // Removed however the test ends.
    let socket = tempfile::TempPath::try_from_path(tutti_host::control::socket_path(&ns)).unwrap();
    // The stranger's server prints what it was sent, and answers nothing.
    let server = "import os, socket, sys\n\
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)\n\
        s.bind(sys.argv[1])\n\
        os.chmod(sys.argv[1], 0o666)\n\
        s.listen(4)\n\
        print('listening', flush=True)\n\
        while True:\n    c, _ = s.accept()\n    c.settimeout(2)\n    \
        try:\n        print('got', repr(c.recv(4096)), flush=True)\n    except OSError:\n        pass\n    c.close()";
    let stranger =
        Proc::spawn("another user's server", nobody(py, &["-c", server, socket.to_str().unwrap()]), WATCHDOG);
    assert!(stranger.wait_line("listening", Duration::from_secs(30)).is_some(), "{}", stranger.dump());
    let (code, out, err) = tutti(&ns, &["ctl", "pause"]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(
        err.contains(&format!(
            "control socket {} of namespace '{ns}' is served by another user (uid 65534)",
            socket.display()
        )),
        "{err}"
    );
    let script = "import sys, tutti_ctl\n\
        try:\n    tutti_ctl.connect(sys.argv[1]).pause()\nexcept tutti_ctl.ControlError as e:\n    print(e)";
    let mut cmd = Command::new(py);
    cmd.args(["-c", script, &ns]).env("PYTHONPATH", common::repo_root().join("python"));
    let (status, out, err) = common::run_with_timeout(cmd, Duration::from_secs(60));
    assert!(status.success(), "{out}{err}");
    assert!(out.contains("is served by another user (uid 65534)"), "{out}{err}");
    // The server takes its connections one by one, in order: once it has printed what a
    // last connection of the test's own sent, it has printed all that came before.
    let mut last = std::os::unix::net::UnixStream::connect(&socket).expect("connecting to the stranger's server");
    std::io::Write::write_all(&mut last, b"the end").unwrap();
    drop(last);
    let the_end = "got b'the end'";
    let never = lazy(|| format!("the stranger's server never read the last connection\n{}", stranger.dump()));
    wait_until(never, Duration::from_secs(30), || stranger.lines().iter().any(|l| l == the_end));
    assert!(
        stranger.lines().iter().all(|l| l == "listening" || l == "got b''" || l == the_end),
        "a request reached the stranger: {}",
        stranger.dump()
    );
}
