//! The supervisor as a control plane drives it: a C component restarted, stopped and started
//! again mid-run while the other keeps stepping, then the whole run torn down by its
//! interrupt with nothing left.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

use tutti_launch::{ComponentState, RunOptions, SupervisorError};
use tutti_test_support as common;

const WAIT: Duration = Duration::from_secs(60);

/// Reads of the connection of `pid` in domain `lock`.
fn reads(ns: &str, pid: u32) -> u64 {
    tutti_core::shm::Segment::open(ns, "lock")
        .ok()
        .and_then(|s| s.status().connections.into_iter().find(|c| c.pid == pid))
        .map_or(0, |c| c.reads)
}

fn wait_until(what: &str, ok: impl FnMut() -> bool) {
    common::wait_until(format_args!("waiting for {what}"), WAIT, ok);
}

#[test]
fn a_component_is_restarted_stopped_and_started_mid_run_while_the_other_keeps_stepping() {
    let ns = common::namespace("launchsup");
    let _clean = common::RemoveSegments(ns.clone());
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(common::repo_root().join("tests/run/lockstep.ddf"), dir.path().join("lockstep.ddf")).unwrap();
    common::compile_c(
        &common::repo_root().join("tests/replay/answer.c"),
        &dir.path().join("answer"),
        &["-std=c99", "-Wall", "-Werror"],
    );
    let answer = |item: &str| format!(r#"["./answer", "lockstep.ddf", "lock", "x", "{item}", "1000000000", "0", "0"]"#);
    let text = format!(
        r#"{{ ddf: "lockstep.ddf", framework: {{ step: "2ms", timeout: "5s", hold: true }},
  components: [ {{ name: "a", run: {}, domain: "lock" }}, {{ name: "b", run: {}, domain: "lock" }} ] }}"#,
        answer("a"),
        answer("b")
    );
    let file = dir.path().join("run.json5");
    std::fs::write(&file, text).unwrap();
    let launch = tutti_launch::load(&file).unwrap();

    let interrupt = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let opts = RunOptions {
        log_dir: dir.path().join("logs"),
        tutti_exe: PathBuf::from("tutti"),
        namespace: Some(ns.clone()),
        grace: Duration::from_secs(3),
        realtime: None,
        restore: None,
    };
    let stop = interrupt.clone();
    let run = std::thread::spawn(move || {
        tutti_launch::run(&launch, opts, stop, Arc::new(|_| {}), move |s| tx.send(s.clone()).unwrap())
    });
    // Whatever happens below, the run is interrupted (torn down) when the test ends.
    struct Interrupt(Arc<AtomicBool>);
    impl Drop for Interrupt {
        fn drop(&mut self) {
            self.0.store(true, Ordering::SeqCst);
        }
    }
    let _interrupt = Interrupt(interrupt.clone());
    let sup = rx.recv_timeout(WAIT).expect("the run hands over its supervisor");
    sup.wait_started().unwrap();
    let pid = |name: &str| sup.status().into_iter().find(|c| c.name == name).and_then(|c| c.pid).unwrap();
    let (a, b) = (pid("a"), pid("b"));
    wait_until("b to step", || reads(&ns, b) >= 20);

    let b2 = sup.restart("b").unwrap();
    assert_ne!(b, b2);
    let a_before = reads(&ns, a);
    wait_until("the new b to step", || reads(&ns, b2) >= 20);
    assert!(reads(&ns, a) > a_before, "a kept stepping");
    let st = sup.status();
    assert_eq!((st[1].state, st[1].restarts), (ComponentState::Connected, 0), "a restart asked for is not counted");

    sup.stop_component("b").unwrap();
    assert_eq!(sup.status()[1].state, ComponentState::Stopped);
    assert!(!std::path::Path::new(&format!("/proc/{b2}")).exists());
    let a_before = reads(&ns, a);
    wait_until("a to step without b", || reads(&ns, a) >= a_before + 20);
    let b3 = sup.start_component("b").unwrap();
    assert!(matches!(sup.start_component("b"), Err(SupervisorError::AlreadyRunning { .. })));
    assert!(matches!(sup.restart("nobody"), Err(SupervisorError::NoComponent { .. })));
    wait_until("the started b to step", || reads(&ns, b3) >= 20);

    interrupt.store(true, Ordering::SeqCst);
    let outcome = run.join().unwrap().unwrap();
    assert!(outcome.all_well(), "{outcome:?}");
    assert!(outcome.components.iter().all(|c| c.state == ComponentState::Stopped), "{outcome:?}");
    for p in [a, b, b2, b3] {
        assert!(!std::path::Path::new(&format!("/proc/{p}")).exists(), "pid {p} is left");
    }
    assert!(common::segments_of(&ns).is_empty());
    assert!(matches!(sup.restart("b"), Err(SupervisorError::Stopping)), "a supervisor shut down refuses");
}
