//! An FMU (Lag.fmu, exported by pythonfmu from tests/fmu/python/Lag.py) and a C component
//! (RTAPI) in one domain, both directions, synchronous and asynchronous; and `kill -9` of
//! `tutti fmu run` while it steps: the framework steps on, the connection count drops, and
//! a new `tutti fmu run` reconnects.
//!
//! The framework is this test, through the core API, so that it sees every step: external
//! participants read PUBLISH and write SUBSCRIBE, so the framework routes between them, as
//! an Orchestra framework does: each step it publishes the C component's command as the
//! FMU's input `u` and the FMU's output `y` as the C component's input `lag_y`.

use tutti_test_support as common;
use tutti_test_support::fmu as fmu_common;

use std::path::Path;
use std::process::Command;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use fmu_common::{build_lag, libpython, python};
use tutti_core::ddf::{Model, Role};
use tutti_core::shm::{Framework, FrameworkOptions};
use tutti_test_support::{Proc, Spawn, Worker};

const PERIOD: Duration = Duration::from_millis(10);

/// One step as the framework saw it.
#[derive(Debug, Clone, Copy)]
struct Step {
    /// The simulated time the framework published.
    sim: f64,
    /// The FMU's output `t`: its time after the step.
    t: f64,
    connections: u32,
    /// SUBSCRIBE `y` (the FMU's output), `c_cmd`, `c_seen` (what the C component read).
    y: f64,
    c_seen: f64,
    count: i32,
}

fn ddf_text(synchronous: bool) -> String {
    format!(
        r#"<orchestra><domain name="fmu_c">
  <synchronous>{}</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
  <set name="PUBLISH">
    <item name="u"><type>float64</type></item>
    <item name="lag_y"><type>float64</type></item>
  </set>
  <set name="SUBSCRIBE">
    <item name="y"><type>float64</type></item>
    <item name="count"><type>int32</type></item>
    <item name="t"><type>float64</type></item>
    <item name="c_cmd"><type>float64</type></item>
    <item name="c_seen"><type>float64</type></item>
  </set>
</domain></orchestra>"#,
        if synchronous { "yes" } else { "no" }
    )
}

/// A framework stepping every PERIOD of wall time and `sim_step` of simulated time, in a
/// thread, routing c_cmd -> u and y -> lag_y.
struct Host {
    steps: Arc<Mutex<Vec<Step>>>,
    _stepping: Worker,
}

impl Host {
    fn start(model: &Model, ns: &str, sim_step: f64) -> Host {
        let opts = FrameworkOptions { namespace: ns.into(), timeout: Duration::from_secs(2), ..Default::default() };
        let mut fw = Framework::create(model, &opts).expect("framework");
        let steps = Arc::new(Mutex::new(Vec::new()));
        let steps2 = steps.clone();
        let stepping = Worker::spawn(move |stop2| {
            let host = &mut fw.domains[0];
            let info = host.info().clone();
            let leaf =
                |role: Role, path: &str| info.set(role).leaves.iter().find(|l| l.path == path).expect("item").range();
            let (u, lag_y) = (leaf(Role::Publish, "u"), leaf(Role::Publish, "lag_y"));
            let t_out = leaf(Role::Subscribe, "t");
            let (y, count, c_cmd, c_seen) = (
                leaf(Role::Subscribe, "y"),
                leaf(Role::Subscribe, "count"),
                leaf(Role::Subscribe, "c_cmd"),
                leaf(Role::Subscribe, "c_seen"),
            );
            let mut publish = vec![0u8; info.publish.size as usize];
            let start = Instant::now();
            let mut k = 0u32;
            while !stop2.load(Ordering::Acquire) {
                host.set_period(PERIOD);
                let sim = f64::from(k) * sim_step;
                host.publish_step(&publish, sim).expect("publish");
                host.complete_step().expect("step");
                let sub = host.subscribe();
                let f = |r: std::ops::Range<usize>| f64::from_ne_bytes(sub[r].try_into().unwrap());
                let step = Step {
                    sim,
                    t: f(t_out.clone()),
                    connections: host.connection_count(),
                    y: f(y.clone()),
                    c_seen: f(c_seen.clone()),
                    count: i32::from_ne_bytes(sub[count.clone()].try_into().unwrap()),
                };
                // Route: the C component's command is the FMU's input, the FMU's output the
                // C component's input.
                let cmd = sub[c_cmd.clone()].to_vec();
                let yb = sub[y.clone()].to_vec();
                publish[u.clone()].copy_from_slice(&cmd);
                publish[lag_y.clone()].copy_from_slice(&yb);
                steps2.lock().unwrap().push(step);
                k += 1;
                let next = start + PERIOD * k;
                if let Some(wait) = next.checked_duration_since(Instant::now()) {
                    thread::sleep(wait);
                }
            }
        });
        Host { steps, _stepping: stepping }
    }

    fn steps(&self) -> Vec<Step> {
        self.steps.lock().unwrap().clone()
    }

    /// Waits (at most 60 s) until `cond` holds for the steps so far.
    fn wait_for(&self, what: &str, cond: impl Fn(&[Step]) -> bool) {
        let timed_out = common::lazy(|| format!("timed out waiting for {what}; last steps: {:?}", self.steps().last()));
        common::wait_until(timed_out, Duration::from_secs(60), || cond(&self.steps()));
    }
}

/// `tutti fmu run`, killed (if still running) when dropped, even when the test fails.
struct Guard(Proc);

impl Guard {
    /// Waits for the child to exit (at most `limit`), returning its stderr.
    fn wait(mut self, limit: Duration) -> (std::process::ExitStatus, String) {
        let status = self.0.wait_status(limit);
        let status = status.unwrap_or_else(|| panic!("{} did not finish within {limit:?}", self.0.name));
        (status, self.0.stderr())
    }
}

fn spawn_fmu(ns: &str, py: &Path, fmu: &Path, ddf: &Path, extra: &[&str]) -> Guard {
    let mut child = common::tutti_command();
    child
        .args(["fmu", "run"])
        .arg(fmu)
        .arg("--ddf")
        .arg(ddf)
        .args(["--domain", "fmu_c", "--connect-timeout", "20s", "-q", "--preload"])
        .arg(libpython(py))
        .args(["--param", "tau=0.25"])
        .args(extra)
        .env("TUTTI_NAMESPACE", ns)
        .env("TMPDIR", fmu.parent().unwrap());
    let opts = Spawn { watchdog: Duration::from_secs(600), grace: Duration::ZERO, ..Spawn::default() };
    Guard(Proc::spawn_with("tutti fmu run", child, opts))
}

const C_COMPONENT: &str = r#"
/* Reads the FMU's output (lag_y, routed by the framework), commands the FMU (c_cmd = 1.5)
 * and reports what it read (c_seen). Synchronous: one answer per step; asynchronous: every
 * 10 ms. Prints the largest lag_y it read. */
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>
#include "RTAPI.h"

#define CHECK(call) do { RTAPIReturn_t rc = (call); if (rc != RTAPI_SUCCESS) { \
    fprintf(stderr, "%s: %s\n", #call, RTGetErrorMessage(rc)); return 1; } } while (0)

int main(int argc, char **argv)
{
    long steps = atol(argv[1]);
    int async = argc > 2;
    unsigned int key;
    double best = 0.0, cmd = 1.5;
    CHECK(RTNewConnectionKey(&key));
    CHECK(RTSetConnectionKey(key));
    CHECK(RTConnect("fmu_c", 20));
    for (long i = 0; i < steps; i++) {
        double lag_y;
        CHECK(RTSubscribeLock());
        CHECK(RTSubscribe("lag_y", &lag_y, sizeof lag_y));
        CHECK(RTSubscribeUnlock());
        if (lag_y > best)
            best = lag_y;
        CHECK(RTPublishLock());
        CHECK(RTPublish("c_cmd", &cmd, sizeof cmd));
        CHECK(RTPublish("c_seen", &lag_y, sizeof lag_y));
        CHECK(RTPublishUnlock());
        if (async)
            usleep(10000);
    }
    CHECK(RTDisconnect());
    printf("max_lag_y=%.17g\n", best);
    return 0;
}
"#;

fn exchange(synchronous: bool) {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace(if synchronous { "fmucs" } else { "fmuca" });
    let fmu = build_lag(&py, dir.path());
    let ddf = dir.path().join("fmu_c.ddf");
    std::fs::write(&ddf, ddf_text(synchronous)).unwrap();
    let model = tutti_core::ddf::load(&ddf).unwrap();
    let src = dir.path().join("component.c");
    std::fs::write(&src, C_COMPONENT).unwrap();
    let exe = common::compile_c(&src, &dir.path().join("component"), &[]);

    let host = Host::start(&model, &ns, PERIOD.as_secs_f64());
    let mut step_arg = vec![];
    if !synchronous {
        step_arg = vec!["--step", "10ms"];
    }
    let fmu_child = spawn_fmu(&ns, &py, &fmu, &ddf, &step_arg);
    let mut c = Command::new(&exe);
    c.arg("300").env("TUTTI_NAMESPACE", &ns);
    if !synchronous {
        c.arg("async");
    }
    let (status, out, err) = common::run_with_timeout(c, Duration::from_secs(120));
    assert!(status.success(), "C component failed: {out}{err}");
    let steps = host.steps();
    drop(host);
    let (fmu_status, fmu_err) = fmu_child.wait(Duration::from_secs(30));
    assert!(fmu_status.success(), "tutti fmu run failed: {fmu_err}");
    // The FMU read the C component's command: its output moved towards gain·1.5 = 3.
    let y_max = steps.iter().map(|s| s.y).fold(0.0, f64::max);
    assert!(y_max > 1.0, "the FMU never followed the C command: max y {y_max}");
    // The C component read the FMU's output, and said so through the domain.
    let best: f64 = out.trim().strip_prefix("max_lag_y=").expect("C output").parse().unwrap();
    assert!(best > 1.0, "the C component never saw the FMU's output: {out}");
    let seen_max = steps.iter().map(|s| s.c_seen).fold(0.0, f64::max);
    assert!(seen_max > 1.0, "the framework never saw the C component's copy of y");
    assert!(steps.iter().any(|s| s.connections == 2), "never both connected");
}

#[test]
fn an_fmu_and_a_c_component_exchange_data_both_ways_in_a_synchronous_domain() {
    exchange(true);
}

#[test]
fn an_fmu_and_a_c_component_exchange_data_both_ways_in_an_asynchronous_domain() {
    exchange(false);
}

#[test]
fn kill_9_of_tutti_fmu_run_leaves_the_framework_stepping_and_a_new_run_reconnects() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmukill");
    let fmu = build_lag(&py, dir.path());
    let ddf = dir.path().join("fmu_c.ddf");
    std::fs::write(&ddf, ddf_text(true)).unwrap();
    let model = tutti_core::ddf::load(&ddf).unwrap();
    let host = Host::start(&model, &ns, PERIOD.as_secs_f64());
    let mut first = spawn_fmu(&ns, &py, &fmu, &ddf, &[]);
    host.wait_for("the FMU to step", |s| s.last().is_some_and(|l| l.connections == 1 && l.count > 30));
    // SIGKILL, wherever it is in its step.
    first.0.kill9();
    let at_kill = host.steps().len();
    host.wait_for("the connection to be removed", |s| s.last().is_some_and(|l| l.connections == 0));
    // The framework steps on without it.
    host.wait_for("steps after the kill", |s| s.len() > at_kill + 50);
    let second = spawn_fmu(&ns, &py, &fmu, &ddf, &[]);
    // A fresh instance: its step count starts again from 1 and grows.
    let restarted = host.steps().len();
    host.wait_for("the new run to step", |s| {
        s[restarted..].iter().any(|x| x.connections == 1 && x.count >= 1 && x.count < 20)
            && s.last().is_some_and(|l| l.connections == 1 && l.count > 30)
    });
    drop(host);
    let (status, err) = second.wait(Duration::from_secs(30));
    assert!(status.success(), "the second tutti fmu run failed: {err}");
}

#[test]
fn ctrl_c_ends_tutti_fmu_run_cleanly_and_the_framework_steps_on() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmuint");
    let fmu = build_lag(&py, dir.path());
    let ddf = dir.path().join("fmu_c.ddf");
    std::fs::write(&ddf, ddf_text(true)).unwrap();
    // An explicit mapping from a file, comments and blank lines included.
    let map = dir.path().join("lag.map");
    std::fs::write(&map, "# FMU variable = item\n\ny = y\ncount=count\n").unwrap();
    let model = tutti_core::ddf::load(&ddf).unwrap();
    let host = Host::start(&model, &ns, PERIOD.as_secs_f64());
    let child = spawn_fmu(&ns, &py, &fmu, &ddf, &["--map-file", map.to_str().unwrap()]);
    host.wait_for("the FMU to step", |s| s.last().is_some_and(|l| l.connections == 1 && l.count > 20));
    let (status, _, _) = common::run_with_timeout(
        {
            let mut kill = Command::new("kill");
            kill.args(["-INT", &child.0.id().to_string()]);
            kill
        },
        Duration::from_secs(10),
    );
    assert!(status.success());
    let (status, err) = child.wait(Duration::from_secs(30));
    assert!(status.success(), "tutti fmu run after SIGINT: {status:?} {err}");
    // Disconnected, not swept: the count drops at once, and the framework steps on.
    let after = host.steps().len();
    host.wait_for("the connection to go", |s| s.last().is_some_and(|l| l.connections == 0));
    host.wait_for("steps after the disconnection", |s| s.len() > after + 20);
}

#[test]
fn a_framework_faster_than_real_time_sets_the_step_by_its_simulated_time() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ns = tutti_test_support::namespace("fmufast");
    let fmu = build_lag(&py, dir.path());
    let ddf = dir.path().join("fmu_c.ddf");
    std::fs::write(&ddf, ddf_text(true)).unwrap();
    let model = tutti_core::ddf::load(&ddf).unwrap();
    // 50 ms of simulated time per 10 ms step of wall time (as `tutti-demo uav --speed 5`).
    let host = Host::start(&model, &ns, 0.05);
    let child = spawn_fmu(&ns, &py, &fmu, &ddf, &[]);
    host.wait_for("the FMU to step", |s| s.last().is_some_and(|l| l.count > 30));
    let steps = host.steps();
    drop(host);
    let _ = child.wait(Duration::from_secs(30));
    // From the FMU's third step on, its time after each step is the framework's + 50 ms.
    let answered: Vec<&Step> = steps.iter().filter(|s| s.count > 2).collect();
    assert!(answered.len() > 20);
    for s in answered {
        assert!(fmu_common::close(s.t, s.sim + 0.05), "the FMU is at {} after the step at {}", s.t, s.sim);
    }
}
