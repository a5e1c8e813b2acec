//! Event-driven synchronisation (`<synchronous>event</synchronous>`, docs/timing.md), with
//! C participants through the RTAPI and a framework paced at 1 kHz: one due at every step, one every 10 ms
//! (`RTSetPeriod`), one woken on change (`RTSetWakeOnChange`) and one asking for given times
//! (`RTRequestTime`). Each is woken exactly at its due steps and reads there what the same
//! program reads in a lock-step run of the same components; a participant killed while due
//! frees its step; with nobody due, a run not paced by the wall clock jumps to the next due
//! step, and its recording shows the jump.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Duration;

use tutti_test_support::{self as common, Proc, RemoveSegments};

const LIMIT: Duration = Duration::from_secs(180);
const STEPS: u64 = 1000;

/// A directory with both DDFs and the C participant.
fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for f in ["event.ddf", "lockstep.ddf"] {
        std::fs::copy(common::repo_root().join("tests/event").join(f), dir.path().join(f)).unwrap();
    }
    common::compile_c(
        &common::repo_root().join("tests/event/participant.c"),
        &dir.path().join("participant"),
        &["-std=c99", "-D_POSIX_C_SOURCE=200809L", "-Wall", "-Werror"],
    );
    dir
}

/// Runs launch file `name` of `dir` (framework and `components`, each `(name, mode)`) to
/// its end; returns the run and its exit status. `extra`: more framework keys; `clock`: the
/// simulated time into `t`, an item that changes at every step and that nobody reads.
fn run(
    dir: &Path,
    name: &str,
    ddf: &str,
    components: &[(&str, &str)],
    extra: &str,
    clock: bool,
) -> (Proc, Option<i32>) {
    let clock = if clock { r#", "@sim_time -> ev/publish/t""# } else { "" };
    let ns = common::namespace(&format!("ev{name}"));
    let _clean = RemoveSegments(ns.clone());
    let list: Vec<String> = components
        .iter()
        .map(|(n, args)| {
            let args: Vec<String> = args.split(' ').map(|a| format!("\"{a}\"")).collect();
            format!(r#"{{ name: "{n}", run: ["./participant", {}], domain: "ev" }}"#, args.join(", "))
        })
        .collect();
    let text = format!(
        r#"{{
  ddf: "{ddf}",
  framework: {{ step: "1ms", steps: {STEPS}, timeout: "5s", hold: true{extra} }},
  connections: ["ev/subscribe/src -> ev/publish/x"{clock}],
  components: [ {} ],
}}"#,
        list.join(",\n    ")
    );
    let file = dir.join(format!("{name}.json5"));
    std::fs::write(&file, text).unwrap();
    let mut cmd = common::tutti_command();
    cmd.arg("run").arg(&file).arg("--logs").arg(dir.join(format!("logs-{name}"))).env("TUTTI_NAMESPACE", &ns);
    let mut p = Proc::spawn("tutti run", cmd, LIMIT);
    let code = p.wait(LIMIT);
    assert!(common::segments_of(&ns).is_empty(), "{:?}", common::segments_of(&ns));
    (p, code)
}

/// What a participant printed: step index -> x read there.
fn wakes(dir: &Path, run: &str, component: &str) -> BTreeMap<u64, f64> {
    let log: PathBuf = dir.join(format!("logs-{run}/{component}.log"));
    let text = std::fs::read_to_string(&log).unwrap_or_else(|e| panic!("{}: {e}", log.display()));
    let mut seen = BTreeMap::new();
    for line in text.lines().filter_map(|l| l.strip_prefix("wake ")) {
        let (n, x) = line.split_once(' ').unwrap();
        let n: u64 = n.parse().unwrap();
        assert!(seen.insert(n, x.parse().unwrap()).is_none(), "{component} woken twice at step {n}\n{text}");
    }
    seen
}

/// The steps `RTRequestTime(t + 37 ms, + 10.5 ms, + 3 ms, …)` is due at, up to `last`.
fn requested_steps(last: u64) -> BTreeSet<u64> {
    let mut due = BTreeSet::new();
    let (mut n, mut i) = (0, 0);
    while n <= last {
        due.insert(n);
        n += [37, 11, 3][i % 3];
        i += 1;
    }
    due
}

/// How two sets of steps differ, briefly: the first steps only one of them has.
fn differ(seen: &BTreeSet<u64>, want: &BTreeSet<u64>) -> String {
    let extra: Vec<u64> = seen.difference(want).take(10).copied().collect();
    let missing: Vec<u64> = want.difference(seen).take(10).copied().collect();
    format!(
        "{} steps, {} wanted; woken but not due at {extra:?}…, due but not woken at {missing:?}…",
        seen.len(),
        want.len()
    )
}

/// Paced at 1 kHz: a step every millisecond of wall time, late ones made back to back (so
/// that the machine's load never skips a step's time).
const KILOHERTZ: &str = ", speed: 1, catch_up: true";
/// As fast as the participants go.
const FAST: &str = ", speed: 0";

const ALL: [(&str, &str); 4] = [("every", "every"), ("period", "period"), ("wake", "wake"), ("request", "request")];

#[test]
fn each_participant_runs_exactly_at_its_due_steps_and_reads_what_lock_step_gives_there() {
    let dir = setup();
    let (lock, code) = run(dir.path(), "lock", "lockstep.ddf", &ALL, KILOHERTZ, true);
    assert_eq!(code, Some(0), "{}", lock.dump());
    let (event, code) = run(dir.path(), "event", "event.ddf", &ALL, KILOHERTZ, true);
    assert_eq!(code, Some(0), "{}", event.dump());
    assert!(!event.dump().contains("timed out"), "a participant stalled a step\n{}", event.dump());

    // The reference: in lock-step every program is woken at every step, with the same x.
    let reference = wakes(dir.path(), "lock", "every");
    let last = STEPS - 1;
    assert_eq!(reference.keys().copied().collect::<Vec<_>>(), (0..=last).collect::<Vec<_>>());
    for (component, _) in ALL {
        assert_eq!(wakes(dir.path(), "lock", component), reference, "{component} in lock-step");
    }
    // x changes at irregular steps: what wakes the change-driven participant, which reads x
    // only (t changes at every step).
    let changed: BTreeSet<u64> =
        reference.iter().filter(|(n, x)| **n == 0 || reference.get(&(*n - 1)) != Some(*x)).map(|(n, _)| *n).collect();
    assert!(changed.len() > 30 && changed.len() < 100, "{changed:?}");
    let due: [(&str, BTreeSet<u64>); 4] = [
        ("every", (0..=last).collect()),
        ("period", (0..=last).filter(|n| n % 10 == 0).collect()),
        ("wake", changed),
        ("request", requested_steps(last)),
    ];
    for (component, steps) in due {
        let seen = wakes(dir.path(), "event", component);
        let at: BTreeSet<u64> = seen.keys().copied().collect();
        assert!(at == steps, "{component} was woken at other steps than it is due at: {}", differ(&at, &steps));
        for (n, x) in &seen {
            assert_eq!(Some(x), reference.get(n), "{component} read another x at step {n} than in lock-step");
        }
    }
}

#[test]
fn a_participant_killed_while_due_frees_its_step_and_the_others_go_on() {
    let dir = setup();
    let parts = [("every", "every"), ("period", "period 500"), ("request", "request")];
    let (event, code) = run(dir.path(), "kill", "event.ddf", &parts, FAST, false);
    assert_eq!(code, Some(1), "the killed component did not end well\n{}", event.dump());
    assert!(event.dump().contains("signal 9"), "{}", event.dump());
    assert!(!event.dump().contains("timed out"), "the step was not freed before the timeout\n{}", event.dump());
    let period = wakes(dir.path(), "kill", "period");
    assert_eq!(period.keys().last(), Some(&500), "it died at its due step 500");
    let every = wakes(dir.path(), "kill", "every");
    assert_eq!(every.len() as u64, STEPS, "the every-step participant kept every step");
    let request: BTreeSet<u64> = wakes(dir.path(), "kill", "request").keys().copied().collect();
    assert!(request == requested_steps(STEPS - 1), "request: {}", differ(&request, &requested_steps(STEPS - 1)));
}

#[test]
fn with_nobody_due_a_run_not_paced_by_the_clock_jumps_to_the_next_due_step() {
    let dir = setup();
    let parts = [("period", "period"), ("request", "request")];
    let (event, code) = run(dir.path(), "jump", "event.ddf", &parts, r#", speed: 0, record: ["jump.csv"]"#, false);
    assert_eq!(code, Some(0), "{}", event.dump());
    // The due steps, and the run's last step (its end is made, whoever is due).
    let due: BTreeSet<u64> =
        (0..STEPS).filter(|n| n % 10 == 0).chain(requested_steps(STEPS - 1)).chain([STEPS - 1]).collect();
    for (component, want) in
        [("period", (0..STEPS).filter(|n| n % 10 == 0).collect()), ("request", requested_steps(STEPS - 1))]
    {
        let at: BTreeSet<u64> = wakes(dir.path(), "jump", component).keys().copied().collect();
        assert!(at == want, "{component}: {}", differ(&at, &want));
    }
    // The recording has a row for each step made: exactly the due ones, at their times.
    let csv = std::fs::read_to_string(dir.path().join("jump.csv")).unwrap();
    let mut lines = csv.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let t = head.iter().position(|h| *h == "sim_time").unwrap_or_else(|| panic!("{head:?}"));
    let made: BTreeSet<u64> =
        lines.map(|l| (l.split(',').nth(t).unwrap().parse::<f64>().unwrap() * 1000.0).round() as u64).collect();
    assert!(made == due, "the steps made are not the due ones: {}", differ(&made, &due));
    assert!(made.len() < STEPS as usize / 5, "{} of {STEPS} steps made", made.len());
}

/// The example (examples/event/tank.json5 with examples/c/event_tank.c), run as its comment
/// says: the supervisor every 100 ms, the alarm exactly at the steps after the supervisor
/// changed the valve (the level, which it does not read, changes at every step), the logger
/// every 250 ms; every component ends well.
#[test]
fn the_event_driven_example_runs_each_component_when_it_needs_to() {
    let dir = tempfile::tempdir().unwrap();
    let (event, c) = (dir.path().join("event"), dir.path().join("c"));
    std::fs::create_dir_all(&event).unwrap();
    std::fs::create_dir_all(&c).unwrap();
    for f in ["tank.ddf", "tank.json5"] {
        std::fs::copy(common::repo_root().join("examples/event").join(f), event.join(f)).unwrap();
    }
    common::compile_c(
        &common::repo_root().join("examples/c/event_tank.c"),
        &c.join("event_tank"),
        &["-std=c99", "-Wall", "-Wextra", "-Werror"],
    );
    let ns = common::namespace("evtank");
    let _clean = RemoveSegments(ns.clone());
    let mut cmd = common::tutti_command();
    cmd.arg("run").arg(event.join("tank.json5")).env("TUTTI_NAMESPACE", &ns);
    let mut run = Proc::spawn("tutti run", cmd, LIMIT);
    assert_eq!(run.wait(LIMIT), Some(0), "{}", run.dump());
    let times = |who: &str| -> Vec<(u64, String)> {
        let log = std::fs::read_to_string(event.join(format!("logs/{who}.log"))).unwrap();
        log.lines()
            .map(|l| {
                let t = l.split_whitespace().nth(1).and_then(|w| w.strip_prefix("t=")).unwrap();
                ((t.parse::<f64>().unwrap() * 1000.0).round() as u64, l.to_string())
            })
            .collect()
    };
    let supervisor = times("supervisor");
    assert!(supervisor.len() == 50 && supervisor.iter().all(|(n, _)| n % 100 == 0), "{supervisor:?}");
    let logger: Vec<u64> = times("logger").iter().map(|(n, _)| *n).collect();
    assert_eq!(logger, (0..20).map(|i| i * 250).collect::<Vec<_>>());
    // The valve the supervisor set reaches the alarm at the next step, and only then.
    let mut changes = vec![0];
    let mut valve = 0.0;
    for (n, line) in &supervisor {
        let v: f64 = line.rsplit("valve=").next().unwrap().parse().unwrap();
        if v != valve {
            changes.push(n + 1);
            valve = v;
        }
    }
    let alarm: Vec<u64> = times("alarm").iter().map(|(n, _)| *n).collect();
    assert!(changes.len() >= 4, "the valve changed {} times", changes.len() - 1);
    assert_eq!(alarm, changes, "the alarm woke at other steps than where the valve changed");
}
