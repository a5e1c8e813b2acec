//! Connections in the framework (`tutti host --connect`, `tutti show --connect`): an output a
//! participant writes reaches an input at the next step, scaled and converted, in a
//! synchronous domain (a C participant answering every step) and from an asynchronous
//! domain into another; refusals name both ends before anything is created.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use tutti_core::ddf::Role;
use tutti_core::shm::{ConnectOptions, Participant, Segment};
use tutti_test_support::{self as common, lazy, wait_until, Proc};

const DDF: &str = "tests/gateway/gw.ddf";
const WATCHDOG: Duration = Duration::from_secs(120);

fn host(ns: &str, connects: &[&str]) -> Proc {
    let mut cmd = common::tutti_command();
    cmd.args(["host", DDF, "--step", "5ms", "--timeout", "2s", "-q"]).env("TUTTI_NAMESPACE", ns);
    for c in connects {
        cmd.args(["--connect", c]);
    }
    Proc::spawn("tutti host", cmd, WATCHDOG)
}

/// Waits until domain `domain` of `ns` exists.
fn wait_domain(ns: &str, domain: &str, host: &Proc) {
    let no_domain = lazy(|| format!("no domain {domain}\n{}", host.dump()));
    wait_until(no_domain, Duration::from_secs(30), || Segment::open(ns, domain).is_ok());
}

/// In a synchronous domain, `y` (what the C participant answers: its step count n) comes
/// back as `x = 2 y + 1` at its next step: the participant reads 2(n - 1) + 1 at step n.
#[test]
fn an_output_reaches_an_input_at_the_next_step_in_a_synchronous_domain() {
    let dir = tempfile::tempdir().unwrap();
    let ns = common::namespace("connsync");
    let _segments = common::RemoveSegments(ns.clone());
    let mut fw = host(&ns, &["gw_sync/subscribe/y -> gw_sync/publish/x * 2 + 1"]);
    wait_domain(&ns, "gw_sync", &fw);
    let stepper = common::compile_c(
        &common::repo_root().join("tests/ctl/stepper.c"),
        &dir.path().join("stepper"),
        &["-std=c99", "-Wall", "-Werror"],
    );
    let mut c = Command::new(stepper);
    c.arg(common::repo_root().join(DDF)).args(["gw_sync", "x", "y", "5"]).env("TUTTI_NAMESPACE", &ns);
    let mut part = Proc::spawn("stepper", c, WATCHDOG);
    assert!(part.wait_line("step 40 ", Duration::from_secs(60)).is_some(), "{}\n{}", part.dump(), fw.dump());
    let seen: Vec<(u64, f64)> = part
        .lines()
        .iter()
        .filter_map(|l| l.strip_prefix("step "))
        .filter_map(|l| l.split_once(" x="))
        .map(|(n, x)| (n.parse().unwrap(), x.parse().unwrap()))
        .collect();
    // From its third step: the step it joined in was under way when it connected, so the
    // framework read that step's answers without waiting for its first one.
    for &(n, x) in seen.iter().filter(|(n, _)| (3..=40).contains(n)) {
        assert_eq!(
            x,
            2.0 * (n - 1) as f64 + 1.0,
            "step {n}: the answer of step {} did not arrive\n{}",
            n - 1,
            part.dump()
        );
    }
    assert_eq!(fw.interrupt(Duration::from_secs(30)), Some(0), "{}", fw.dump());
    part.wait(Duration::from_secs(30));
}

/// From an asynchronous domain to another domain: an int32 output lands in a float64
/// input, the value of the latest commit, at every step after it.
#[test]
fn an_asynchronous_output_reaches_another_domain_converted() {
    let ns = common::namespace("connasync");
    let _segments = common::RemoveSegments(ns.clone());
    let mut fw = host(&ns, &["gw_async/subscribe/n -> gw_states/publish/x - 0.5"]);
    wait_domain(&ns, "gw_async", &fw);
    wait_domain(&ns, "gw_states", &fw);
    let opts = ConnectOptions { namespace: ns.clone(), name: "writer".into(), ..Default::default() };
    let mut p = Participant::connect("gw_async", opts).unwrap();
    let target = Segment::open(&ns, "gw_states").unwrap();
    let x = |seg: &Segment| {
        let mut buf = vec![0u8; seg.info.publish.size as usize];
        seg.read_set(Role::Publish, &mut buf).unwrap();
        f64::from_ne_bytes(buf[0..8].try_into().unwrap())
    };
    for n in [7i32, -3, 12] {
        p.publish_lock().unwrap();
        p.stage("n", &n.to_ne_bytes()).unwrap();
        p.commit().unwrap();
        let never = lazy(|| format!("x = {} never became {n} - 0.5\n{}", x(&target), fw.dump()));
        wait_until(never, Duration::from_secs(30), || x(&target) == f64::from(n) - 0.5);
    }
    drop(p);
    assert_eq!(fw.interrupt(Duration::from_secs(30)), Some(0), "{}", fw.dump());
}

/// Refusals name both ends, exit with status 2 and create nothing; `tutti show --connect`
/// lists what will be copied, in order.
#[test]
fn connections_that_cannot_be_made_are_refused_naming_both_ends() {
    let ns = common::namespace("connbad");
    let _segments = common::RemoveSegments(ns.clone());
    let run = |args: &[&str]| {
        let mut cmd = common::tutti_command();
        cmd.args(args).env("TUTTI_NAMESPACE", &ns);
        let (status, out, err) = common::run_with_timeout(cmd, Duration::from_secs(60));
        (status.code(), out, err)
    };
    let cases = [
        (
            "gw_sync/subscribe/nope -> gw_sync/publish/x",
            "gw_sync/subscribe/nope -> gw_sync/publish/x: no item 'nope' in the SUBSCRIBE set of domain 'gw_sync'",
        ),
        (
            "gw_async/subscribe/y -> gw_async/publish/v",
            "length mismatch: gw_async/subscribe/y has 1 element(s), gw_async/publish/v has 3",
        ),
        (
            "gw_async/subscribe/y -> gw_async/publish/flag",
            "type mismatch: gw_async/subscribe/y is float64, gw_async/publish/flag is boolean",
        ),
        ("gw_async/publish/x -> gw_sync/publish/x", "gw_async/publish/x must be an output"),
        ("gw_async/y -> gw_sync/publish/x", "is not DOMAIN/ROLE/ITEM"),
    ];
    for (connection, want) in cases {
        let (code, _, err) = run(&["host", DDF, "--connect", connection, "--duration", "10s"]);
        assert_eq!(code, Some(2), "{connection}: {err}");
        assert!(err.contains(want), "{connection}: {err}");
        assert!(common::segments_of(&ns).is_empty(), "a refused run created segments");
    }
    let two = [
        "--connect",
        "gw_async/subscribe/y -> gw_sync/publish/x",
        "--connect",
        "gw_states/subscribe/y -> gw_sync/publish/x",
    ];
    let (code, _, err) = run(&[&["host", DDF, "--duration", "10s"], &two[..]].concat());
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("gw_sync/publish/x already has a source: gw_async/subscribe/y -> gw_sync/publish/x"), "{err}");
    let (code, _, err) =
        run(&["host", DDF, "--set", "gw_sync/x=1", "--connect", "gw_async/subscribe/y -> gw_sync/publish/x"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("also given a value by set 'gw_sync/x=1'"), "{err}");

    let (code, out, err) = run(&[&["show", DDF], &two[..1], &two[1..2]].concat());
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("1. gw_async/subscribe/y -> gw_sync/publish/x   (float64 -> float64, 1 element(s))"), "{out}");
    assert!(out.contains("a value reaches its input at the next step"), "{out}");
    let _ = Path::new(DDF);
}

/// `@sim_time -> DOMAIN/publish/ITEM`: every recorded step published its own simulated
/// time in the item (not the step before's), in a synchronous and an asynchronous domain.
#[test]
fn the_simulated_time_reaches_an_input_in_the_step_it_is_published_in() {
    let dir = tempfile::tempdir().unwrap();
    let ns = common::namespace("connclock");
    let _segments = common::RemoveSegments(ns.clone());
    let csv = dir.path().join("run.csv");
    let mut cmd = common::tutti_command();
    cmd.args(["host", DDF, "--step", "5ms", "--duration", "500ms", "-q"])
        .args(["--connect", "@sim_time -> gw_sync/publish/x", "--connect", "@sim_time -> gw_async/publish/x * 1000"])
        .arg("--record")
        .arg(&csv)
        .env("TUTTI_NAMESPACE", &ns);
    let mut fw = Proc::spawn("tutti host", cmd, WATCHDOG);
    assert_eq!(fw.wait(Duration::from_secs(60)), Some(0), "{}", fw.dump());
    for (domain, gain) in [("gw_sync", 1.0), ("gw_async", 1000.0)] {
        let text = std::fs::read_to_string(dir.path().join(format!("run-{domain}.csv"))).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col =
            |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name}: {header:?}"));
        let (t, x) = (col("sim_time"), col("publish.x"));
        let rows: Vec<(f64, f64)> = lines
            .map(|l| l.split(',').collect::<Vec<_>>())
            .map(|f| (f[t].parse().unwrap(), f[x].parse().unwrap()))
            .collect();
        assert!(rows.len() > 10, "{domain}: {} steps recorded\n{}", rows.len(), fw.dump());
        assert!(rows.iter().any(|r| r.0 > 0.0), "{domain}: the time never moved");
        for (sim, value) in rows {
            assert!((value - sim * gain).abs() < 1e-6 * gain, "{domain}: the step at {sim} s published {value}");
        }
    }
}
