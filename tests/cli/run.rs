//! `tutti run FILE`: a launch file refused with its line and column; two C components in
//! lock-step, one SIGKILLed and restarted by its policy while the other keeps every step;
//! Ctrl-C tearing everything down (no process, segment or temporary file left); `steps: N`
//! ending the run; a component that fails making the exit status 1; a run (and a `tutti
//! host`) whose control socket file was removed still ending on SIGTERM or with its duration.

use tutti_test_support as common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use common::{lazy, wait_until, Proc, RemoveSegments};

const LIMIT: Duration = Duration::from_secs(120);
const WAIT: Duration = Duration::from_secs(60);

/// A directory with the test DDF, the C component `answer` and the launch file `text`.
fn setup(text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(common::repo_root().join("tests/run/lockstep.ddf"), dir.path().join("lockstep.ddf")).unwrap();
    common::compile_c(
        &common::repo_root().join("tests/replay/answer.c"),
        &dir.path().join("answer"),
        &["-std=c99", "-Wall", "-Werror"],
    );
    let file = dir.path().join("run.json5");
    std::fs::write(&file, text).unwrap();
    (dir, file)
}

/// `answer` for item ITEM of domain `lock`, answering its own step count (factor 0), for
/// as long as it is left running.
fn answer(item: &str) -> String {
    format!(r#"["./answer", "lockstep.ddf", "lock", "x", "{item}", "1000000000", "0", "0"]"#)
}

/// `tutti run FILE` in namespace `ns`, with its temporary files in `tmp`.
fn start(file: &Path, ns: &str, tmp: &Path) -> Proc {
    let mut cmd = common::tutti_command();
    cmd.arg("run").arg(file).env("TUTTI_NAMESPACE", ns).env("TMPDIR", tmp);
    Proc::spawn("tutti run", cmd, LIMIT)
}

/// The pid in a line `run: NAME: connected (pid N)` (or `started`).
fn pid_in(line: &str) -> u32 {
    let n = line.rsplit("pid ").next().unwrap().trim_end_matches(')');
    n.parse().unwrap_or_else(|_| panic!("no pid in {line:?}"))
}

fn alive(pid: u32) -> bool {
    Path::new(&format!("/proc/{pid}")).exists()
}

/// The domain's step now.
fn step_of(ns: &str) -> u64 {
    tutti_core::shm::Segment::open(ns, "lock").map(|s| s.status().step).unwrap_or(0)
}

/// Waits until the connection of `pid` in `lock` has read at least `reads` steps.
fn wait_reads(ns: &str, pid: u32, reads: u64, run: &Proc) {
    let seen = || {
        tutti_core::shm::Segment::open(ns, "lock")
            .ok()
            .and_then(|s| s.status().connections.into_iter().find(|c| c.pid == pid))
            .map_or(0, |c| c.reads)
    };
    let not_yet = lazy(|| format!("pid {pid} read {} steps, not {reads}\n{}", seen(), run.dump()));
    wait_until(not_yet, WAIT, || seen() >= reads);
}

/// The CSV recording's rows: step -> (a, b).
fn rows(csv: &Path) -> BTreeMap<u64, (f64, f64)> {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name} in {head:?}"));
    let (a, b) = (col("subscribe.a"), col("subscribe.b"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].parse().unwrap(), (f[a].parse().unwrap(), f[b].parse().unwrap()))
        })
        .collect()
}

/// A launch file of two `answer` components in lock-step, `a` and `b` (with `b_keys` added
/// to `b`'s), held until both have connected, recorded to `run.csv`.
fn pair(b_keys: &str) -> String {
    format!(
        r#"{{
  ddf: "lockstep.ddf",
  framework: {{ step: "2ms", timeout: "5s", hold: true, record: ["run.csv"] }},
  components: [
    {{ name: "a", run: {a}, domain: "lock" }},
    {{ name: "b", run: {b}, domain: "lock"{b_keys} }},
  ],
}}"#,
        a = answer("a"),
        b = answer("b")
    )
}

/// The pids of [`pair`]'s `a` and `b` once both have connected and `b` has read 50 steps,
/// and the index of the run's next line.
fn started_pair(ns: &str, run: &Proc) -> (u32, u32, usize) {
    let mut at = 0;
    let a = pid_in(&run.next_line(&mut at, "run: a: connected", WAIT).unwrap_or_else(|| panic!("{}", run.dump())));
    let b = pid_in(&run.next_line(&mut at, "run: b: connected", WAIT).unwrap_or_else(|| panic!("{}", run.dump())));
    assert!(run.next_line(&mut at, "every component has connected", WAIT).is_some(), "{}", run.dump());
    wait_reads(ns, b, 50, run);
    (a, b, at)
}

/// From the recording `csv`, up to step `last`: checks that `a` answered every step (its
/// count goes up by one a step) and returns `b`'s answers.
fn b_answers_while_a_kept_every_step(csv: &Path, last: u64) -> Vec<f64> {
    let rows: Vec<(u64, (f64, f64))> = rows(csv).into_iter().filter(|(s, _)| *s <= last).collect();
    let a_steps: Vec<f64> = rows.iter().map(|(_, (a, _))| *a).skip_while(|a| *a < 1.0).collect();
    assert!(a_steps.len() > 100, "{} steps of a", a_steps.len());
    for w in a_steps.windows(2) {
        assert_eq!(w[1] - w[0], 1.0, "a missed or repeated a step: {w:?}");
    }
    rows.iter().map(|(_, (_, b))| *b).collect()
}

#[test]
fn launch_file_mistakes_are_refused_with_file_line_and_column_before_anything_starts() {
    let ns = common::namespace("runbad");
    let _clean = RemoveSegments(ns.clone());
    let cases = [
        ("{ ddf: \"lockstep.ddf\",\n  components: [ { name: \"a\", run: [\"true\"], cwdd: \".\" } ] }", ":2:45: unknown field `cwdd`"),
        ("{ ddf: \"lockstep.ddf\", framework: {\n  step: 5 } }", ":2:9: invalid type: integer `5`"),
        ("{ ddf: \"lockstep.ddf\", framework: {\n  timeout: \"later\" } }", ":2:12: timeout: 'later' is not a duration"),
        ("{ ddf: \"lockstep.ddf\", components: [\n  { name: \"a\", run: [\"./nothing\"] } ] }", ":2:21: component 'a': run: './nothing' is not an executable file"),
        ("{ ddf: \"lockstep.ddf\", components: [\n  { name: \"a\", run: [\"true\"], domain: \"plant\" } ] }", ":2:39: component 'a': domain 'plant' is not in"),
        ("{ ddf: \"lockstep.ddf\", components: [\n  { name: \"a\", run: [\"true\"] },\n  { name: \"a\", run: [\"true\"] } ] }", ":3:11: name 'a' is given to two components"),
        ("{ ddf: \"lockstep.ddf\", framework: {\n  duration: \"1s\", steps: 10 } }", ":1:35: framework: give `duration` or `steps`, not both"),
    ];
    for (text, want) in cases {
        let (dir, file) = setup(text);
        let (code, _, err) = common::tutti(["run".as_ref(), file.as_os_str()]);
        assert_eq!(code, 2, "{text}\n{err}");
        let want = format!("{}{want}", file.display());
        assert!(err.contains(&want), "{text}\nwanted {want}\ngot {err}");
        assert!(!dir.path().join("logs").exists(), "nothing started: no log directory");
        assert!(common::segments_of(&ns).is_empty());
    }
}

#[test]
fn a_killed_component_is_restarted_by_its_policy_and_steps_again_while_the_other_keeps_lock_step() {
    let ns = common::namespace("runkill");
    let _clean = RemoveSegments(ns.clone());
    let (dir, file) = setup(&pair(r#", restart: "on-failure", max_restarts: 1"#));
    let tmp = tempfile::tempdir().unwrap();
    let mut run = start(&file, &ns, tmp.path());
    let (a, b, mut at) = started_pair(&ns, &run);
    common::run_with_timeout(
        {
            let mut k = std::process::Command::new("kill");
            k.args(["-KILL", &b.to_string()]);
            k
        },
        WAIT,
    );
    let ended = run.next_line(&mut at, "run: b: pid", WAIT).unwrap_or_else(|| panic!("{}", run.dump()));
    assert!(ended.contains("signal 9"), "{ended}");
    assert!(run.next_line(&mut at, "run: b: restarting (1 of at most 1)", WAIT).is_some(), "{}", run.dump());
    let b2 = pid_in(&run.next_line(&mut at, "run: b: connected", WAIT).unwrap_or_else(|| panic!("{}", run.dump())));
    assert_ne!(b, b2);
    wait_reads(&ns, b2, 50, &run);
    let last = step_of(&ns);
    assert_eq!(run.interrupt(WAIT), Some(0), "a restarted component that was then stopped ended well\n{}", run.dump());
    for pid in [a, b, b2] {
        assert!(!alive(pid), "pid {pid} is left\n{}", run.dump());
    }
    assert!(common::segments_of(&ns).is_empty(), "{:?}", common::segments_of(&ns));

    // Every step up to the interrupt: `a` answered each (its count goes up by one a step);
    // `b`'s count fell back once, at its restart, and went up by one a step after it.
    let b_steps = b_answers_while_a_kept_every_step(&dir.path().join("run.csv"), last);
    let falls = b_steps.windows(2).filter(|w| w[1] < w[0]).count();
    assert_eq!(falls, 1, "b started again once");
    let fall = b_steps.windows(2).position(|w| w[1] < w[0]).unwrap();
    let after: Vec<f64> = b_steps[fall + 1..].iter().copied().skip_while(|b| *b < 1.0).collect();
    assert!(after.len() >= 40, "b stepped {} times after its restart", after.len());
    for w in after.windows(2) {
        assert_eq!(w[1] - w[0], 1.0, "the restarted b missed or repeated a step: {w:?}");
    }
    let log = std::fs::read_to_string(dir.path().join("logs/b.log")).unwrap();
    assert!(log.contains("--- started again ---"), "{log}");
}

#[test]
fn ctrl_c_tears_everything_down_in_reverse_order_leaving_no_process_segment_or_temporary_file() {
    let ns = common::namespace("runint");
    let _clean = RemoveSegments(ns.clone());
    let (dir, file) = setup(&format!(
        r#"{{
  ddf: "lockstep.ddf",
  framework: {{ step: "5ms", timeout: "5s" }},
  components: [
    {{ name: "a", run: {a}, domain: "lock", env: {{ GREETING: "hello" }} }},
    {{ name: "talker", run: ["sh", "-c", "echo $GREETING from talker; exec sleep 1000"], env: {{ GREETING: "hi" }} }},
  ],
}}"#,
        a = answer("a")
    ));
    let tmp = tempfile::tempdir().unwrap();
    let mut run = start(&file, &ns, tmp.path());
    let mut at = 0;
    let a = pid_in(&run.next_line(&mut at, "run: a: connected", WAIT).unwrap_or_else(|| panic!("{}", run.dump())));
    let talker =
        pid_in(&run.next_line(&mut at, "run: talker: connected", WAIT).unwrap_or_else(|| panic!("{}", run.dump())));
    assert!(run.wait_line("[talker] hi from talker", WAIT).is_some(), "{}", run.dump());
    assert!(segments_of_exist(&ns));
    assert_eq!(run.interrupt(WAIT), Some(0), "{}", run.dump());
    let lines = run.lines();
    let stop_of = |name: &str| lines.iter().position(|l| l.contains(&format!("run: {name}: stopping"))).unwrap();
    assert!(stop_of("talker") < stop_of("a"), "the last component is stopped first\n{}", run.dump());
    for pid in [a, talker] {
        assert!(!alive(pid), "pid {pid} is left\n{}", run.dump());
    }
    assert!(common::segments_of(&ns).is_empty(), "{:?}", common::segments_of(&ns));
    let left: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().flatten().map(|e| e.path()).collect();
    assert!(left.is_empty(), "temporary files left: {left:?}");
    let log = std::fs::read_to_string(dir.path().join("logs/talker.log")).unwrap();
    assert_eq!(log, "hi from talker\n");
}

fn segments_of_exist(ns: &str) -> bool {
    !common::segments_of(ns).is_empty()
}

#[test]
fn steps_end_the_run_after_that_many_steps_and_a_failed_component_makes_the_status_1() {
    let ns = common::namespace("runsteps");
    let _clean = RemoveSegments(ns.clone());
    let text = |extra: &str| {
        format!(
            r#"{{
  ddf: "lockstep.ddf",
  framework: {{ step: "1ms", timeout: "5s", hold: true, steps: 40, record: ["run.csv"] }},
  components: [ {{ name: "a", run: {a}, domain: "lock" }}, {extra} ],
}}"#,
            a = answer("a")
        )
    };
    let (dir, file) = setup(&text(""));
    let tmp = tempfile::tempdir().unwrap();
    let mut run = start(&file, &ns, tmp.path());
    assert_eq!(run.wait(WAIT), Some(0), "{}", run.dump());
    let steps: Vec<u64> = rows(&dir.path().join("run.csv")).into_keys().collect();
    assert_eq!(steps, (1..=40).collect::<Vec<u64>>());
    assert!(common::segments_of(&ns).is_empty());

    let (_dir, file) = setup(&text(r#"{ name: "fails", run: ["sh", "-c", "echo giving up; exit 3"] }"#));
    let mut run = start(&file, &ns, tmp.path());
    assert_eq!(run.wait(WAIT), Some(1), "{}", run.dump());
    assert!(run.stderr().contains("not every component ended well: fails"), "{}", run.dump());
    assert!(run.stdout().contains("[fails] giving up"), "{}", run.dump());
    assert!(common::segments_of(&ns).is_empty());
}

/// `tutti ctl` of a launched run: `state` lists its components, `restart b` replaces the C
/// component `b` mid-run (a new process that connects and steps again) while `a` keeps
/// every step, `stop b` and `start b` too; `tutti ctl stop` ends the run and its
/// components with nothing left.
#[test]
fn tutti_ctl_restarts_a_c_component_mid_run_and_stops_the_run() {
    let ns = common::namespace("runctl");
    let _clean = RemoveSegments(ns.clone());
    let (dir, file) = setup(&pair(""));
    let tmp = tempfile::tempdir().unwrap();
    let mut run = start(&file, &ns, tmp.path());
    let (a, b, _) = started_pair(&ns, &run);
    let ctl = |args: &[&str]| {
        let mut cmd = common::tutti_command();
        cmd.arg("ctl").args(args).arg("--json").env("TUTTI_NAMESPACE", &ns);
        let (status, out, err) = common::run_with_timeout(cmd, WAIT);
        assert!(status.success(), "tutti ctl {args:?}: {err}\n{}", run.dump());
        serde_json::from_str::<serde_json::Value>(out.trim()).unwrap()
    };
    let state = ctl(&["state"]);
    let names: Vec<&str> =
        state["components"].as_array().unwrap().iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["a", "b"], "{state}");
    assert_eq!(state["components"][1]["pid"], b, "{state}");

    let restarted = ctl(&["restart", "b"]);
    let b2 = restarted["components"][1]["pid"].as_u64().unwrap() as u32;
    assert!(b2 != b && !alive(b), "b was replaced by a new process: {restarted}");
    assert_eq!(restarted["components"][1]["state"], "connected", "{restarted}");
    wait_reads(&ns, b2, 50, &run);
    assert_eq!(ctl(&["stop", "b"])["components"][1]["state"], "stopped");
    let b3 = ctl(&["start", "b"])["components"][1]["pid"].as_u64().unwrap() as u32;
    wait_reads(&ns, b3, 20, &run);
    let last = step_of(&ns);

    ctl(&["stop"]);
    assert_eq!(run.wait(WAIT), Some(0), "{}", run.dump());
    for pid in [a, b2, b3] {
        assert!(!alive(pid), "pid {pid} is left\n{}", run.dump());
    }
    assert!(common::segments_of(&ns).is_empty(), "{:?}", common::segments_of(&ns));
    assert!(!tutti_host::control::socket_path(&ns).exists(), "the control socket was left");

    // `a` answered every step while `b` was replaced, stopped and started again.
    let b_steps = b_answers_while_a_kept_every_step(&dir.path().join("run.csv"), last);
    assert_eq!(b_steps.windows(2).filter(|w| w[1] < w[0]).count(), 2, "b started over twice");
}

/// `autostart: false` declares a component that the run does not start (nor wait for);
/// `tutti ctl start` starts it and `tutti ctl signal` reaches its process, while a signal to
/// a component with no process, or of an unknown name, is refused with its reason. With
/// `speed: 4`, step k is made at simulated time k × `step`.
#[test]
fn tutti_ctl_signals_a_component_and_starts_one_declared_without_autostart() {
    let ns = common::namespace("runsig");
    let _clean = RemoveSegments(ns.clone());
    let trap = r#"["sh", "-c", "trap 'echo got USR1' USR1; trap 'echo got USR2' USR2; while :; do sleep 0.05; done"]"#;
    let (dir, file) = setup(&format!(
        r#"{{
  ddf: "lockstep.ddf",
  framework: {{ step: "8ms", speed: 4, timeout: "5s", hold: true }},
  components: [
    {{ name: "a", run: {a}, domain: "lock" }},
    {{ name: "late", run: {trap}, autostart: false }},
  ],
}}"#,
        a = answer("a"),
    ));
    let tmp = tempfile::tempdir().unwrap();
    let mut run = start(&file, &ns, tmp.path());
    let mut at = 0;
    assert!(run.next_line(&mut at, "every component has connected", WAIT).is_some(), "{}", run.dump());
    let ctl = |args: &[&str]| {
        let mut cmd = common::tutti_command();
        cmd.arg("ctl").args(args).arg("--json").env("TUTTI_NAMESPACE", &ns);
        common::run_with_timeout(cmd, WAIT)
    };
    let ok = |args: &[&str]| {
        let (status, out, err) = ctl(args);
        assert!(status.success(), "tutti ctl {args:?}: {err}\n{}", run.dump());
        serde_json::from_str::<serde_json::Value>(out.trim()).unwrap()
    };
    let state = ok(&["state"]);
    assert_eq!(state["components"][1]["state"], "not started", "{state}");
    assert!(state["components"][1]["pid"].is_null(), "{state}");
    let (status, _, err) = ctl(&["signal", "late", "USR1"]);
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains("component 'late' is not running (not started)"), "{err}");
    let (status, _, err) = ctl(&["signal", "a", "USR7"]);
    assert_eq!(status.code(), Some(2), "{err}");
    assert!(err.contains("unknown signal 'USR7'"), "{err}");

    let started = ok(&["start", "late"]);
    assert_eq!(started["components"][1]["state"], "connected", "{started}");
    ok(&["signal", "late", "USR1"]);
    assert!(run.next_line(&mut at, "[late] got USR1", WAIT).is_some(), "{}", run.dump());
    ok(&["signal", "late", "sigusr2"]);
    assert!(run.next_line(&mut at, "[late] got USR2", WAIT).is_some(), "{}", run.dump());
    // Simulated time is 8 ms a step, whatever the wall-clock period (2 ms).
    let s = ok(&["state"]);
    let (step, sim) = (s["step"].as_f64().unwrap(), s["sim_time"].as_f64().unwrap());
    let k = (sim / 0.008).round();
    assert!(step > 1.0 && (sim - k * 0.008).abs() < 1e-9 && (k - (step - 1.0)).abs() <= 1.0, "{s}");

    ok(&["stop"]);
    assert_eq!(run.wait(WAIT), Some(0), "{}", run.dump());
    let log = std::fs::read_to_string(dir.path().join("logs/late.log")).unwrap();
    assert!(log.contains("got USR1") && log.contains("got USR2"), "{log}");
}

/// Waits for the control socket of namespace `ns`, then removes it, as a clean-up of
/// `/dev/shm` may do while the run goes on.
fn remove_control_socket(ns: &str, run: &Proc) {
    let socket = tutti_host::control::socket_path(ns);
    wait_until(lazy(|| format!("no control socket\n{}", run.dump())), WAIT, || socket.exists());
    std::fs::remove_file(&socket).unwrap();
}

/// `tutti host` of the test DDF in `dir`, in namespace `ns`, with `args` added.
fn host(dir: &Path, ns: &str, args: &[&str]) -> Proc {
    let mut cmd = common::tutti_command();
    cmd.arg("host").arg(dir.join("lockstep.ddf")).args(["--step", "5ms", "-q"]).args(args);
    cmd.env("TUTTI_NAMESPACE", ns);
    Proc::spawn("tutti host", cmd, LIMIT)
}

/// A launched run whose control socket file was removed (a clean-up of `/dev/shm`) still
/// ends on SIGTERM, with status 0 and no segment left.
#[test]
fn a_launched_run_whose_control_socket_was_removed_ends_on_sigterm() {
    let ns = common::namespace("runnosock");
    let _clean = RemoveSegments(ns.clone());
    let text = r#"{ ddf: "lockstep.ddf", framework: { step: "5ms", timeout: "5s" },
  components: [ { name: "a", run: ANSWER, domain: "lock" } ] }"#;
    let (_dir, file) = setup(&text.replace("ANSWER", &answer("a")));
    let tmp = tempfile::tempdir().unwrap();
    let mut run = start(&file, &ns, tmp.path());
    assert!(run.wait_line("every component has connected", WAIT).is_some(), "{}", run.dump());
    remove_control_socket(&ns, &run);
    run.signal("TERM");
    assert_eq!(run.wait(WAIT), Some(0), "tutti run did not end on SIGTERM\n{}", run.dump());
    assert!(common::segments_of(&ns).is_empty(), "{:?}", common::segments_of(&ns));
}

/// `tutti host` whose control socket file was removed still ends on SIGTERM.
#[test]
fn a_host_whose_control_socket_was_removed_ends_on_sigterm() {
    let ns = common::namespace("hostnosock");
    let _clean = RemoveSegments(ns.clone());
    let (dir, _) = setup("{}");
    let mut host = host(dir.path(), &ns, &[]);
    remove_control_socket(&ns, &host);
    host.signal("TERM");
    assert_eq!(host.wait(WAIT), Some(0), "tutti host did not end on SIGTERM\n{}", host.dump());
    assert!(common::segments_of(&ns).is_empty(), "{:?}", common::segments_of(&ns));
}

/// `tutti host --duration` whose control socket file was removed still ends when its time
/// is up. Held until a writer connects, its time starts only after the socket is gone.
#[test]
fn a_host_whose_control_socket_was_removed_ends_with_its_duration() {
    let ns = common::namespace("durnosock");
    let _clean = RemoveSegments(ns.clone());
    let (dir, _) = setup("{}");
    let mut host = host(dir.path(), &ns, &["--wait-for", "lock=1", "--duration", "300ms"]);
    remove_control_socket(&ns, &host);
    let mut writer = std::process::Command::new(dir.path().join("answer"));
    writer.args(["lockstep.ddf", "lock", "x", "a", "1000000000", "0", "0"]).current_dir(dir.path());
    writer.env("TUTTI_NAMESPACE", &ns);
    let _writer = Proc::spawn("answer", writer, LIMIT);
    assert_eq!(host.wait(WAIT), Some(0), "tutti host did not end with its duration\n{}", host.dump());
    assert!(common::segments_of(&ns).is_empty(), "{:?}", common::segments_of(&ns));
}
