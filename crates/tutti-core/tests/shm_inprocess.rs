//! Framework and participants in one process (threads): the semantics of `docs/domains.md`.

use std::time::Duration;

mod common;

use tutti_core::ddf::Model;
use tutti_core::shm::segment::segment_path;
use tutti_core::shm::{ConnKind, ConnectOptions, Framework, FrameworkOptions, Participant, ShmError, WaitMode};
use tutti_test_support::wait_until;

fn model(sync: bool, mpa: bool, states: bool) -> Model {
    common::domain(
        sync,
        mpa,
        states,
        r#"<item name="x"><type>float64</type></item>"#,
        r#"<item name="a"><type>float64</type><default>2.5</default></item><item name="b"><type>int32</type></item>"#,
    )
}

fn ns(tag: &str) -> String {
    format!("t{}-{tag}", std::process::id())
}

fn fopts(tag: &str) -> FrameworkOptions {
    FrameworkOptions { namespace: ns(tag), timeout: Duration::from_secs(20), ..Default::default() }
}

fn copts(tag: &str) -> ConnectOptions {
    ConnectOptions { namespace: ns(tag), name: "test".into(), timeout: Duration::from_secs(20), ..Default::default() }
}

#[test]
fn async_values_flow_both_ways_and_defaults_apply() {
    let mut fw = Framework::create(&model(false, true, false), &fopts("async")).unwrap();
    let host = &mut fw.domains[0];
    host.step(&1.5f64.to_ne_bytes(), 0.0).unwrap();
    // Defaults before any writer.
    assert_eq!(f64::from_ne_bytes(host.subscribe()[0..8].try_into().unwrap()), 2.5);
    let mut p = Participant::connect("d", copts("async")).unwrap();
    assert_eq!(host.connection_count(), 1);
    p.subscribe_lock().unwrap();
    assert_eq!(f64::from_ne_bytes(p.snapshot()[0..8].try_into().unwrap()), 1.5);
    p.publish_lock().unwrap();
    p.stage("b", &7i32.to_ne_bytes()).unwrap();
    p.commit().unwrap();
    host.step(&2.0f64.to_ne_bytes(), 0.1).unwrap();
    let sub = host.subscribe();
    assert_eq!(f64::from_ne_bytes(sub[0..8].try_into().unwrap()), 2.5, "unstaged item keeps its value");
    assert_eq!(i32::from_ne_bytes(sub[8..12].try_into().unwrap()), 7);
    assert!(matches!(p.stage("nope", &[0; 8]), Err(ShmError::UnknownItem { .. })));
    assert!(matches!(p.stage("b", &[0; 8]), Err(ShmError::SizeMismatch { .. })));
    p.disconnect();
    assert_eq!(host.connection_count(), 0);
}

#[test]
fn second_writer_on_exclusive_domain_is_refused_until_the_owner_leaves() {
    let _fw = Framework::create(&model(false, false, false), &fopts("excl")).unwrap();
    let mut a = Participant::connect("d", copts("excl")).unwrap();
    let mut b = Participant::connect("d", copts("excl")).unwrap();
    a.publish_lock().unwrap();
    a.commit().unwrap();
    let err = b.publish_lock().unwrap_err();
    assert!(matches!(err, ShmError::NotOwner { .. }), "{err}");
    a.disconnect();
    b.publish_lock().unwrap();
    b.commit().unwrap();
}

#[test]
fn synchronous_steps_are_read_once_and_answered() {
    let mut fw = Framework::create(&model(true, false, false), &fopts("sync")).unwrap();
    let mut p = Participant::connect("d", copts("sync")).unwrap();
    let t = std::thread::spawn(move || {
        let mut seen = Vec::new();
        for _ in 0..200 {
            let step = p.subscribe_lock().unwrap();
            let x = f64::from_ne_bytes(p.snapshot()[0..8].try_into().unwrap());
            seen.push((step, x));
            p.publish_lock().unwrap();
            p.stage("a", &(x * 10.0).to_ne_bytes()).unwrap();
            p.commit().unwrap();
        }
        seen
    });
    let host = &mut fw.domains[0];
    for k in 1..=200u64 {
        let r = host.step(&(k as f64).to_ne_bytes(), 0.0).unwrap();
        assert_eq!(r.timed_out, 0);
        // The answer of this very step is visible once the step returns (after the first,
        // which may start before the participant's first read).
        if k > 1 {
            assert_eq!(f64::from_ne_bytes(host.subscribe()[0..8].try_into().unwrap()), k as f64 * 10.0);
        }
    }
    let seen = t.join().unwrap();
    for (i, (step, x)) in seen.iter().enumerate() {
        assert_eq!(*step, i as u64 + 1);
        assert_eq!(*x, *step as f64);
    }
}

#[test]
fn live_segment_is_refused_with_its_pid() {
    let _fw = Framework::create(&model(false, true, false), &fopts("busy")).unwrap();
    let err = Framework::create(&model(false, true, false), &fopts("busy")).unwrap_err();
    match err {
        ShmError::DomainBusy { pid, .. } => assert_eq!(pid, std::process::id()),
        e => panic!("unexpected {e}"),
    }
}

#[test]
fn wait_modes_all_work() {
    // Adaptive twice: a spin long enough to catch most hand-offs, and one so short that the
    // waits go on to block.
    let adaptive = [WaitMode::Adaptive(Duration::from_millis(5)), WaitMode::Adaptive(Duration::from_nanos(1))];
    for mode in [WaitMode::Spin, WaitMode::Poll(Duration::from_micros(50)), WaitMode::Block].into_iter().chain(adaptive)
    {
        let tag = format!("mode{mode:?}").replace(|c: char| !c.is_ascii_alphanumeric(), "");
        let mut fw =
            Framework::create(&model(true, true, false), &FrameworkOptions { wait: mode, ..fopts(&tag) }).unwrap();
        let mut p = Participant::connect("d", ConnectOptions { wait: mode, ..copts(&tag) }).unwrap();
        // The participant answers step k (x = k) with a = 10·x and b = k.
        let t = std::thread::spawn(move || {
            let mut seen = Vec::new();
            for _ in 0..50 {
                let step = p.subscribe_lock().unwrap();
                let x = f64::from_ne_bytes(p.snapshot()[0..8].try_into().unwrap());
                // The framework waits for this step's answer (from the second step on: at the
                // first it does not know yet that this connection writes), so its time is
                // still the step's.
                let sim_time = p.sim_time();
                let locked = p.publish_lock().unwrap();
                p.stage("a", &(x * 10.0).to_ne_bytes()).unwrap();
                p.stage("b", &(step as i32).to_ne_bytes()).unwrap();
                p.commit().unwrap();
                seen.push((step, x, locked, sim_time));
            }
            seen
        });
        let host = &mut fw.domains[0];
        for k in 1..=50u64 {
            let r = host.step(&(k as f64).to_ne_bytes(), k as f64 * 0.5).unwrap();
            assert_eq!(r.timed_out, 0, "{mode:?}");
            // The answer of this very step is visible once the step returns (after the
            // first, which may start before the participant's first read).
            if k > 1 {
                let sub = host.subscribe();
                assert_eq!(f64::from_ne_bytes(sub[0..8].try_into().unwrap()), k as f64 * 10.0, "{mode:?}");
                assert_eq!(i32::from_ne_bytes(sub[8..12].try_into().unwrap()), k as i32, "{mode:?}");
            }
        }
        let seen = t.join().unwrap();
        for (i, &(step, x, locked, sim_time)) in seen.iter().enumerate() {
            // Every step read once, in order, with its own value; the commit answers it.
            assert_eq!(step, i as u64 + 1, "{mode:?}");
            assert_eq!(x, step as f64, "{mode:?}");
            assert_eq!(locked, step, "{mode:?}");
            if step > 1 {
                assert_eq!(sim_time, step as f64 * 0.5, "{mode:?}");
            }
        }
    }
}

#[test]
fn segments_belong_to_the_creating_user_only_and_vanish_with_the_framework() {
    use std::os::unix::fs::PermissionsExt;
    let fw = Framework::create(&model(false, true, false), &fopts("mode")).unwrap();
    let path = segment_path(&ns("mode"), "d");
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600, "{} has mode {mode:o}", path.display());
    drop(fw);
    assert!(!path.exists());
}

#[test]
fn a_set_committed_in_place_is_staged_and_later_commits_keep_other_writers_items() {
    let mut fw = Framework::create(&model(false, true, false), &fopts("inplace")).unwrap();
    let host = &mut fw.domains[0];
    host.step(&3.0f64.to_ne_bytes(), 0.0).unwrap();
    let mut a = Participant::connect("d", copts("inplace")).unwrap();
    let mut b = Participant::connect("d", copts("inplace")).unwrap();
    a.subscribe_lock().unwrap();
    a.publish_lock().unwrap();
    a.commit_all_with(|snap, out| {
        let x = f64::from_ne_bytes(snap[0..8].try_into().unwrap());
        out[0..8].copy_from_slice(&(x * 2.0).to_ne_bytes());
        out[8..12].copy_from_slice(&11i32.to_ne_bytes());
    })
    .unwrap();
    assert_eq!(&a.staging()[0..12], [6.0f64.to_ne_bytes().as_slice(), &11i32.to_ne_bytes()].concat());
    let mut item_a = [0u8; 8];
    let mut item_b = [0u8; 4];
    host.read_subscribe_at(0, &mut item_a).unwrap();
    host.read_subscribe_at(8, &mut item_b).unwrap();
    assert_eq!((f64::from_ne_bytes(item_a), i32::from_ne_bytes(item_b)), (6.0, 11));
    // Once more in place, then `b` changes item a, and `a` changes item b only, through its
    // staging buffer: its commit must not put back the a it committed in place.
    a.commit_all_with(|_, out| {
        out[0..8].copy_from_slice(&7.0f64.to_ne_bytes());
        out[8..12].copy_from_slice(&11i32.to_ne_bytes());
    })
    .unwrap();
    b.publish_lock().unwrap();
    b.stage("a", &99.0f64.to_ne_bytes()).unwrap();
    b.commit().unwrap();
    a.staging_mut()[8..12].copy_from_slice(&12i32.to_ne_bytes());
    a.commit().unwrap();
    host.read_subscribe_at(0, &mut item_a).unwrap();
    host.read_subscribe_at(8, &mut item_b).unwrap();
    assert_eq!((f64::from_ne_bytes(item_a), i32::from_ne_bytes(item_b)), (99.0, 12));
    assert_eq!(&a.staging()[0..12], [99.0f64.to_ne_bytes().as_slice(), &12i32.to_ne_bytes()].concat());
    assert_eq!(f64::from_ne_bytes(host.read_subscribe().unwrap()[0..8].try_into().unwrap()), 99.0);
}

#[test]
fn a_framework_can_await_a_step_and_read_one_item_of_the_answer() {
    let mut fw = Framework::create(&model(true, true, false), &fopts("await")).unwrap();
    let mut p = Participant::connect("d", copts("await")).unwrap();
    let t = std::thread::spawn(move || {
        for _ in 0..100 {
            p.subscribe_lock().unwrap();
            p.publish_lock().unwrap();
            p.commit_all_with(|snap, out| {
                let x = f64::from_ne_bytes(snap[0..8].try_into().unwrap());
                out[0..8].copy_from_slice(&(x + 0.5).to_ne_bytes());
                out[8..12].copy_from_slice(&(x as i32).to_ne_bytes());
            })
            .unwrap();
        }
    });
    let host = &mut fw.domains[0];
    let mut item_b = [0u8; 4];
    for k in 1..=100u64 {
        host.publish_step(&(k as f64).to_ne_bytes(), 0.0).unwrap();
        assert_eq!(host.await_step().unwrap().timed_out, 0);
        // The first step may complete before the participant's first read.
        if k > 1 {
            host.read_subscribe_at(8, &mut item_b).unwrap();
            assert_eq!(i32::from_ne_bytes(item_b), k as i32);
        }
    }
    t.join().unwrap();
    let err = host.read_subscribe_at(12, &mut [0u8; 8]).unwrap_err();
    assert!(matches!(err, ShmError::OutOfRange { offset: 12, end: 20, size: 16, .. }), "{err}");
}

#[test]
fn answering_in_place_reads_each_step_once_and_commits_what_it_computes() {
    let mut fw = Framework::create(&model(true, true, false), &fopts("answer")).unwrap();
    let mut p = Participant::connect("d", copts("answer")).unwrap();
    let t = std::thread::spawn(move || {
        let mut steps = Vec::new();
        for _ in 0..100 {
            let step = p
                .answer_with(|publish, out| {
                    let x = f64::from_ne_bytes(publish[0..8].try_into().unwrap());
                    out[0..8].copy_from_slice(&(-x).to_ne_bytes());
                    out[8..12].copy_from_slice(&(x as i32 * 3).to_ne_bytes());
                })
                .unwrap();
            steps.push(step);
        }
        // Staging follows what was committed in place.
        let staged = i32::from_ne_bytes(p.staging()[8..12].try_into().unwrap());
        (steps, staged)
    });
    let host = &mut fw.domains[0];
    for k in 1..=100u64 {
        let r = host.step(&(k as f64).to_ne_bytes(), 0.0).unwrap();
        assert_eq!(r.timed_out, 0);
        if k > 1 {
            let sub = host.subscribe();
            assert_eq!(f64::from_ne_bytes(sub[0..8].try_into().unwrap()), -(k as f64));
            assert_eq!(i32::from_ne_bytes(sub[8..12].try_into().unwrap()), k as i32 * 3);
        }
    }
    let (steps, staged) = t.join().unwrap();
    let first = steps[0];
    assert_eq!(steps, (first..first + 100).collect::<Vec<_>>(), "each step answered once, in order");
    assert_eq!(staged, 300);
}

#[test]
fn a_panic_while_committing_in_place_leaves_the_set_and_the_writer_lock_as_they_were() {
    let mut fw = Framework::create(&model(false, true, false), &fopts("panic")).unwrap();
    let host = &mut fw.domains[0];
    host.step(&1.0f64.to_ne_bytes(), 0.0).unwrap();
    let mut a = Participant::connect("d", copts("panic")).unwrap();
    let short = ConnectOptions { timeout: Duration::from_secs(1), ..copts("panic") };
    let mut b = Participant::connect("d", short).unwrap();
    a.subscribe_lock().unwrap();
    a.publish_lock().unwrap();
    a.stage("a", &5.0f64.to_ne_bytes()).unwrap();
    a.commit().unwrap();
    let quiet = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        a.commit_all_with(|_, out| {
            out.fill(0xff);
            panic!("the model failed half-way");
        })
    }));
    std::panic::set_hook(quiet);
    assert!(caught.is_err());
    // The half-written value was never made current, and the next writer is not kept waiting.
    assert_eq!(f64::from_ne_bytes(host.read_subscribe().unwrap()[0..8].try_into().unwrap()), 5.0);
    b.publish_lock().unwrap();
    b.stage("b", &9i32.to_ne_bytes()).unwrap();
    b.commit().unwrap();
    let sub = host.read_subscribe().unwrap();
    assert_eq!(f64::from_ne_bytes(sub[0..8].try_into().unwrap()), 5.0);
    assert_eq!(i32::from_ne_bytes(sub[8..12].try_into().unwrap()), 9);
}

/// A step that times out says whom it waited for (the host prints it), and DDS writers and
/// observers are counted apart from participants.
#[test]
fn a_timed_out_step_names_the_connection_it_waited_for_and_kinds_are_counted_apart() {
    let opts = FrameworkOptions { timeout: Duration::from_millis(200), ..fopts("owed") };
    let mut fw = Framework::create(&model(true, true, false), &opts).unwrap();
    let host = &mut fw.domains[0];
    let mut slow = Participant::connect("d", ConnectOptions { name: "slow-writer".into(), ..copts("owed") }).unwrap();
    let remote = Participant::connect(
        "d",
        ConnectOptions { name: "dds-writer ab".into(), kind: ConnKind::Remote, ..copts("owed") },
    )
    .unwrap();
    let mut watcher = tutti_core::shm::observer::Observer::with_presence("d".into(), "tutti_gateway");
    assert!(matches!(watcher.look(&ns("owed")), tutti_core::shm::observer::Look::Fresh));
    watcher.set_dds_readers(3);
    let s = host.status();
    assert_eq!((s.connection_count, s.dds_writers, s.dds_readers), (1, 1, 3), "{:?}", s.connections);
    assert!(s.connections.iter().any(|c| c.observer && c.name == "tutti_gateway" && c.dds_readers == 3));

    // The writer answers step 1, then not step 2.
    host.publish_step(&1.0f64.to_ne_bytes(), 0.0).unwrap();
    slow.subscribe_lock().unwrap();
    slow.publish_lock().unwrap();
    slow.commit().unwrap();
    assert_eq!(host.complete_step().unwrap().timed_out, 0);
    let r = host.step(&2.0f64.to_ne_bytes(), 0.1).unwrap();
    assert_eq!(r.timed_out, 1);
    assert_eq!(host.timed_out_on(), [format!("'slow-writer' (pid {})", std::process::id())]);
    drop((remote, watcher));
    let s = host.status();
    assert_eq!((s.connection_count, s.dds_writers, s.dds_readers), (1, 0, 0), "{:?}", s.connections);
}

/// A participant held in wait-to-go is not waited for by the steps the framework makes
/// meanwhile (it could not answer them), and takes part in lock-step from its release on.
#[test]
fn a_participant_held_in_wait_to_go_is_not_waited_for_until_released() {
    let opts = FrameworkOptions { timeout: Duration::from_millis(300), ..fopts("held") };
    let mut fw = Framework::create(&model(true, true, false), &opts).unwrap();
    let host = &mut fw.domains[0];
    host.set_hold(true);
    let connecting =
        std::thread::spawn(|| Participant::connect("d", ConnectOptions { name: "held".into(), ..copts("held") }));
    wait_until("the held participant never connected", Duration::from_secs(60), || {
        !host.status().connections.is_empty()
    });
    for k in 1..=3 {
        let r = host.step(&(k as f64).to_ne_bytes(), 0.0).unwrap();
        assert_eq!(r.timed_out, 0, "step {k} waited for a participant it holds");
    }
    host.set_hold(false);
    let mut p = connecting.join().unwrap().unwrap();
    // From the release on, the framework waits for it: it reads step 4, then step 5 waits.
    host.publish_step(&4.0f64.to_ne_bytes(), 0.0).unwrap();
    assert_eq!(p.subscribe_lock().unwrap(), 4);
    assert_eq!(host.complete_step().unwrap().timed_out, 0);
    assert_eq!(host.step(&5.0f64.to_ne_bytes(), 0.0).unwrap().timed_out, 1, "it takes part once released");
}

/// A framework creates its segment, then sizes it: a participant that opens it in between
/// finds it empty. That is a domain being created (wait for it), not a corrupt one: a
/// component started beside its framework once failed there under load.
#[test]
fn a_segment_created_but_not_yet_sized_is_waited_for_not_refused() {
    let tag = "creating";
    let path = segment_path(&ns(tag), "d");
    std::fs::File::create(&path).unwrap();
    // Removed when the test ends, also when it fails (the framework replaces it first).
    let _remove = tempfile::TempPath::try_from_path(&path).unwrap();
    let err = tutti_core::shm::segment::Segment::open(&ns(tag), "d").unwrap_err();
    assert!(matches!(err, ShmError::NotReady { .. }), "{err}");
    let quick = ConnectOptions { connect_timeout: Duration::from_millis(100), ..copts(tag) };
    let err = Participant::connect("d", quick).unwrap_err();
    assert!(matches!(err, ShmError::NotReady { .. }), "{err}");
    // A participant already waiting connects once the framework has finished, and then
    // waits for its go: the segment is published holding it.
    let patient = ConnectOptions { connect_timeout: Duration::from_secs(60), ..copts(tag) };
    let waiting = std::thread::spawn(move || Participant::connect("d", patient));
    let fw = Framework::create(&model(true, false, false), &FrameworkOptions { hold: true, ..fopts(tag) }).unwrap();
    wait_until("the waiting participant never connected", Duration::from_secs(60), || {
        fw.domains[0].connection_count() != 0
    });
    assert!(!waiting.is_finished(), "a participant passed a hold set from the start");
    fw.domains[0].set_hold(false);
    let p = waiting.join().unwrap().unwrap();
    assert_eq!(fw.domains[0].connection_count(), 1);
    p.disconnect();
}

/// Domain "d" of [`model`], event-driven (docs/timing.md).
fn event_model() -> Model {
    tutti_core::ddf::parse_str(
        r#"<orchestra><domain name="d"><synchronous>event</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed>
        <set name="PUBLISH"><item name="x"><type>float64</type></item></set>
        <set name="SUBSCRIBE"><item name="a"><type>float64</type></item></set>
        </domain></orchestra>"#,
        "event.ddf",
    )
    .unwrap()
}

/// A DDS writer through the gateway, in an event-driven domain, is due only where the
/// PUBLISH set changed, and its commit answers the step: the framework waits for it there and
/// nowhere else.
#[test]
fn a_wake_on_change_writer_is_waited_for_at_the_steps_whose_input_changed_only() {
    let model = event_model();
    assert!(model.domains[0].flags.event && model.domains[0].flags.synchronous);
    let opts = FrameworkOptions { timeout: Duration::from_millis(200), ..fopts("wake") };
    let mut fw = Framework::create(&model, &opts).unwrap();
    let host = &mut fw.domains[0];
    host.set_sim_step(0.001);
    let mut w = Participant::connect("d", ConnectOptions { kind: ConnKind::Remote, ..copts("wake") }).unwrap();
    w.wake_on_change_writer();
    // Step 1 (a change: the first) is answered by the writer's commit.
    host.publish_step(&1.0f64.to_ne_bytes(), 0.0).unwrap();
    assert_eq!(w.publish_lock().unwrap(), 1);
    w.stage("a", &10.0f64.to_ne_bytes()).unwrap();
    w.commit().unwrap();
    assert_eq!(host.complete_step().unwrap().timed_out, 0);
    assert_eq!(f64::from_ne_bytes(host.subscribe()[0..8].try_into().unwrap()), 10.0);
    // Steps 2 and 3 keep x: nobody is due, nothing is waited for.
    for k in 2..=3u32 {
        assert_eq!(host.step(&1.0f64.to_ne_bytes(), 0.001 * f64::from(k)).unwrap().timed_out, 0, "step {k}");
    }
    // Step 4 changes x: the writer is due, and it does not answer.
    let r = host.step(&2.0f64.to_ne_bytes(), 0.004).unwrap();
    assert_eq!(r.timed_out, 1, "the writer was not waited for where its input changed");
}

/// A wake-on-change writer whose first lock commits nothing (the gateway drops a DDS sample
/// that answers a step the framework has left) is still due only where the PUBLISH set
/// changed: the lock alone must not make it a lock-step writer that owes every step.
#[test]
fn a_wake_on_change_writers_lock_without_a_commit_leaves_it_due_at_changes_only() {
    let opts = FrameworkOptions { timeout: Duration::from_millis(200), ..fopts("wakelate") };
    let mut fw = Framework::create(&event_model(), &opts).unwrap();
    let host = &mut fw.domains[0];
    host.set_sim_step(0.001);
    let mut w = Participant::connect("d", ConnectOptions { kind: ConnKind::Remote, ..copts("wakelate") }).unwrap();
    w.wake_on_change_writer();
    assert_eq!(host.step(&1.0f64.to_ne_bytes(), 0.0).unwrap().timed_out, 0, "not a writer yet");
    // Step 2 keeps x; the writer's sample answered step 1: the lock, no commit.
    host.publish_step(&1.0f64.to_ne_bytes(), 0.001).unwrap();
    assert_eq!(w.publish_lock().unwrap(), 2);
    assert_eq!(host.complete_step().unwrap().timed_out, 0, "waited for at a step whose input kept");
    assert_eq!(host.step(&1.0f64.to_ne_bytes(), 0.002).unwrap().timed_out, 0, "step 3");
    // Step 4 changes x: due there, and its commit answers it.
    host.publish_step(&2.0f64.to_ne_bytes(), 0.003).unwrap();
    assert_eq!(w.publish_lock().unwrap(), 4);
    w.stage("a", &3.0f64.to_ne_bytes()).unwrap();
    w.commit().unwrap();
    assert_eq!(host.complete_step().unwrap().timed_out, 0);
    assert_eq!(f64::from_ne_bytes(host.subscribe()[0..8].try_into().unwrap()), 3.0);
    // Step 5 changes x again and nothing answers it: it was waited for.
    assert_eq!(host.step(&3.0f64.to_ne_bytes(), 0.004).unwrap().timed_out, 1, "not waited for at a change");
}

/// A period that is not a whole multiple of the framework's step, or a time that is not a
/// number, is refused with the domain named; in a lock-step domain the calls change nothing.
#[test]
fn periods_and_times_that_cannot_be_steps_are_refused() {
    let _fw = Framework::create(&event_model(), &fopts("period")).unwrap();
    _fw.domains[0].set_sim_step(0.001);
    let mut p = Participant::connect("d", copts("period")).unwrap();
    p.set_period(0.01).unwrap();
    for bad in [0.0015, -1.0, f64::NAN] {
        let e = p.set_period(bad).unwrap_err();
        assert!(matches!(e, ShmError::InvalidTiming { .. }) && e.to_string().contains("domain 'd'"), "{e}");
    }
    assert!(matches!(p.request_time(f64::INFINITY), Err(ShmError::InvalidTiming { .. })));
    p.request_time(0.5).unwrap();
}

/// An every-10th-step participant and one asking for times, driven by a framework that
/// leaves out the steps nobody is due at (`idle_steps`: the next step made is at the time of
/// the next due one): each reads exactly its due steps, and the framework makes no other.
#[test]
fn the_framework_skips_exactly_the_steps_nobody_is_due_at() {
    let mut fw = Framework::create(&event_model(), &fopts("skip")).unwrap();
    fw.domains[0].set_sim_step(0.001);
    let spawn = |period: Option<f64>, request: Option<f64>| {
        let mut p = Participant::connect("d", copts("skip")).unwrap();
        std::thread::spawn(move || {
            if let Some(s) = period {
                p.set_period(s).unwrap();
            }
            let mut seen = Vec::new();
            loop {
                if let Some(dt) = request {
                    p.request_time(p.simulation_time() + dt).unwrap();
                }
                match p.subscribe_lock() {
                    Ok(_) => seen.push((p.simulation_time() * 1000.0).round() as u64),
                    Err(ShmError::FrameworkStopped { .. }) => return seen,
                    Err(e) => panic!("{e}"),
                }
            }
        })
    };
    let a = spawn(Some(0.010), None);
    let b = spawn(None, Some(0.007));
    let host = &mut fw.domains[0];
    let publish = 0.0f64.to_ne_bytes();
    let mut made = Vec::new();
    let mut n = 0u64;
    while n < 100 {
        n += host.idle_steps(&publish, n).unwrap_or(0);
        assert_eq!(host.step(&publish, n as f64 * 0.001).unwrap().timed_out, 0);
        made.push(n);
        n += 1;
    }
    drop(fw);
    let (a, b) = (a.join().unwrap(), b.join().unwrap());
    assert!(a.iter().all(|n| n % 10 == 0) && a.len() >= 10, "{a:?}");
    assert!(b.windows(2).all(|w| w[1] - w[0] == 7), "{b:?}");
    let due: std::collections::BTreeSet<u64> = a.iter().chain(&b).copied().collect();
    assert_eq!(
        made.iter().copied().collect::<std::collections::BTreeSet<u64>>(),
        due,
        "steps made besides the due ones"
    );
}

#[test]
fn each_value_is_read_with_the_step_it_belongs_to() {
    use tutti_core::ddf::Role;
    use tutti_core::shm::segment::Segment;
    let mut fw = Framework::create(&model(true, false, false), &fopts("stamp")).unwrap();
    let mut p = Participant::connect("d", copts("stamp")).unwrap();
    const STEPS: u64 = 300;
    let answers = std::thread::spawn(move || {
        for _ in 0..STEPS {
            let step = p.subscribe_lock().unwrap();
            p.publish_lock().unwrap();
            p.stage("a", &(step as f64 * 10.0).to_ne_bytes()).unwrap();
            p.commit().unwrap();
        }
    });
    // A reader that labels what it reads, as the gateway does, while the framework steps:
    // the framework's latest step may be ahead of the answer it reads, never the label.
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let reader = {
        let (done, ns) = (done.clone(), ns("stamp"));
        std::thread::spawn(move || {
            let seg = Segment::open(&ns, "d").unwrap();
            let (mut pbuf, mut sbuf) = (vec![0u8; 8], vec![0u8; 16]);
            let mut reads = 0u64;
            while !done.load(std::sync::atomic::Ordering::Acquire) {
                if let Some((_, s)) = seg.try_read_set_stamped(Role::Publish, &mut pbuf, 100) {
                    let x = f64::from_ne_bytes(pbuf[..8].try_into().unwrap());
                    assert_eq!((x, s.sim_time), (s.step as f64, s.step as f64 * 0.25), "PUBLISH {s:?}");
                }
                if let Some((_, s)) = seg.try_read_set_stamped(Role::Subscribe, &mut sbuf, 100) {
                    let a = f64::from_ne_bytes(sbuf[..8].try_into().unwrap());
                    if s.step > 0 {
                        assert_eq!((a, s.sim_time), (s.step as f64 * 10.0, s.step as f64 * 0.25), "SUBSCRIBE {s:?}");
                        reads += 1;
                    }
                }
            }
            reads
        })
    };
    let host = &mut fw.domains[0];
    for k in 1..=STEPS {
        host.step(&(k as f64).to_ne_bytes(), k as f64 * 0.25).unwrap();
    }
    answers.join().unwrap();
    done.store(true, std::sync::atomic::Ordering::Release);
    assert!(reader.join().unwrap() > 0, "the reader never saw an answer");
    // After the last answer, the framework publishes once more: the answer keeps its step.
    host.step(&0.0f64.to_ne_bytes(), 1e9).unwrap_or_else(|e| panic!("{e}"));
    let seg = Segment::open(&ns("stamp"), "d").unwrap();
    let (mut buf, step) = (vec![0u8; 16], seg.step());
    let (_, s) = seg.try_read_set_stamped(Role::Subscribe, &mut buf, 100).unwrap();
    assert_eq!((step, s.step, s.sim_time), (STEPS + 1, STEPS, STEPS as f64 * 0.25));
}

/// No state file of domain `d` of test `tag` is left in /dev/shm.
fn assert_no_state_files(tag: &str) {
    let files: Vec<_> = std::fs::read_dir("/dev/shm")
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(&format!("{}.d.state", ns(tag))))
        .collect();
    assert!(files.is_empty(), "state files left: {files:?}");
}

/// A participant's state as a checkpoint sees it: a running sum, shared with the test.
struct Sum(std::sync::Arc<std::sync::Mutex<f64>>);

impl tutti_core::shm::StateHandler for Sum {
    fn save(&mut self) -> Result<Vec<u8>, tutti_core::shm::StateError> {
        Ok(self.0.lock().unwrap().to_ne_bytes().to_vec())
    }
    fn restore(&mut self, state: &[u8]) -> Result<(), tutti_core::shm::StateError> {
        let bytes: [u8; 8] = state.try_into().map_err(|_| format!("{} bytes, not 8", state.len()))?;
        *self.0.lock().unwrap() = f64::from_ne_bytes(bytes);
        Ok(())
    }
}

#[test]
fn a_state_is_saved_and_restored_at_a_step_boundary_through_the_segment() {
    use tutti_core::shm::{SharedState, StateAnswer, StateRequest};
    let tag = "state";
    let mut fw = Framework::create(&model(true, true, false), &fopts(tag)).unwrap();
    let sum = std::sync::Arc::new(std::sync::Mutex::new(0.0));
    let handler = SharedState::new(Box::new(Sum(sum.clone())));
    let mut p = Participant::connect("d", ConnectOptions { state: Some(handler), ..copts(tag) }).unwrap();
    let shared = sum.clone();
    let t = std::thread::spawn(move || {
        // Each step adds its input to the sum and answers it; the state requests are answered
        // in the waits between.
        while p.subscribe_lock().is_ok() {
            let x = f64::from_ne_bytes(p.snapshot()[0..8].try_into().unwrap());
            let now = {
                let mut s = shared.lock().unwrap();
                *s += x;
                *s
            };
            if p.publish_lock().is_err() {
                break;
            }
            p.stage("a", &now.to_ne_bytes()).unwrap();
            if p.commit().is_err() {
                break;
            }
        }
    });
    for k in 1..=3u64 {
        fw.domains[0].step(&(k as f64).to_ne_bytes(), 0.0).unwrap();
    }
    // A connection without a state, here for the look only: the next step would wait for it.
    let plain = Participant::connect("d", ConnectOptions { name: "plain".into(), ..copts(tag) }).unwrap();
    let conns = fw.domains[0].state_connections();
    drop(plain);
    assert_eq!(conns.len(), 2, "{conns:?}");
    let keeper = conns.iter().find(|c| c.name == "test").expect("the participant with a state");
    assert!(keeper.keeps_state && !conns.iter().find(|c| c.name == "plain").unwrap().keeps_state);
    let asked = [vec![(keeper, &[][..])]];
    let saved = fw.exchange_states(StateRequest::Save, &asked, Duration::from_secs(20)).unwrap();
    assert_eq!(saved[0], vec![StateAnswer::Saved(6.0f64.to_ne_bytes().to_vec())]);
    fw.domains[0].step(&10.0f64.to_ne_bytes(), 0.0).unwrap();
    assert_eq!(*sum.lock().unwrap(), 16.0);
    let back = 6.0f64.to_ne_bytes();
    let asked = [vec![(keeper, &back[..])]];
    let restored = fw.exchange_states(StateRequest::Restore, &asked, Duration::from_secs(20)).unwrap();
    assert_eq!(restored[0], vec![StateAnswer::Restored]);
    assert_eq!(*sum.lock().unwrap(), 6.0);
    // Bytes the handler refuses: its words come back.
    let asked = [vec![(keeper, &b"xyz"[..])]];
    let refused = fw.exchange_states(StateRequest::Restore, &asked, Duration::from_secs(20)).unwrap();
    assert_eq!(refused[0], vec![StateAnswer::Failed("3 bytes, not 8".into())]);
    fw.domains[0].step(&1.0f64.to_ne_bytes(), 0.0).unwrap();
    assert_eq!(f64::from_ne_bytes(fw.domains[0].subscribe()[0..8].try_into().unwrap()), 7.0);
    assert_no_state_files(tag);
    drop(fw);
    t.join().unwrap();
}

/// A handler that answers a save only once the test lets it: the framework gives up first.
struct Late {
    entered: std::sync::mpsc::Sender<()>,
    go: std::sync::mpsc::Receiver<()>,
}

impl tutti_core::shm::StateHandler for Late {
    fn save(&mut self) -> Result<Vec<u8>, tutti_core::shm::StateError> {
        self.entered.send(()).unwrap();
        self.go.recv().unwrap();
        Ok(b"late".to_vec())
    }
    fn restore(&mut self, _: &[u8]) -> Result<(), tutti_core::shm::StateError> {
        Ok(())
    }
}

/// An answer that comes after the framework gave up on its request leaves no file behind,
/// and the request is not answered again.
#[test]
fn an_answer_after_the_framework_gave_up_leaves_no_file() {
    use tutti_core::shm::{SharedState, StateAnswer, StateRequest};
    let tag = "statelate";
    let fw = Framework::create(&model(false, true, false), &fopts(tag)).unwrap();
    let (entered_tx, entered) = std::sync::mpsc::channel();
    let (go, go_rx) = std::sync::mpsc::channel();
    let handler = SharedState::new(Box::new(Late { entered: entered_tx, go: go_rx }));
    let p = Participant::connect("d", ConnectOptions { state: Some(handler), ..copts(tag) }).unwrap();
    let conns = fw.domains[0].state_connections();
    assert!(conns[0].keeps_state, "the state is the connection's from its first moment: {conns:?}");
    let served = std::thread::spawn(move || {
        wait_until("the participant to answer", Duration::from_secs(60), || p.serve_state());
        p
    });
    let asked = [vec![(&conns[0], &[][..])]];
    std::thread::scope(|s| {
        let asking = s.spawn(|| fw.exchange_states(StateRequest::Save, &asked, Duration::from_millis(100)).unwrap());
        // The handler is in its save; the framework gives up on it meanwhile.
        entered.recv_timeout(Duration::from_secs(60)).expect("the handler was asked");
        assert_eq!(asking.join().unwrap()[0], vec![StateAnswer::NoAnswer]);
    });
    go.send(()).unwrap();
    let p = served.join().unwrap();
    assert_no_state_files(tag);
    assert!(!p.serve_state(), "a request given up on is not answered again");
}

/// A participant that connects while the framework holds wait-to-go answers a state request
/// made before its first step (the checkpoint of step 0) from inside its connect.
#[test]
fn a_held_participant_answers_the_checkpoint_of_step_0() {
    use tutti_core::shm::{SharedState, StateAnswer, StateRequest};
    let tag = "stateheld";
    let fw = Framework::create(&model(true, true, false), &FrameworkOptions { hold: true, ..fopts(tag) }).unwrap();
    let sum = std::sync::Arc::new(std::sync::Mutex::new(4.5));
    let handler = SharedState::new(Box::new(Sum(sum.clone())));
    let t =
        std::thread::spawn(move || Participant::connect("d", ConnectOptions { state: Some(handler), ..copts(tag) }));
    wait_until("the participant to connect", Duration::from_secs(60), || fw.domains[0].connection_count() == 1);
    let conns = fw.domains[0].state_connections();
    let asked = [vec![(&conns[0], &[][..])]];
    let saved = fw.exchange_states(StateRequest::Save, &asked, Duration::from_secs(20)).unwrap();
    assert_eq!(saved[0], vec![StateAnswer::Saved(4.5f64.to_ne_bytes().to_vec())]);
    assert!(!t.is_finished(), "the participant still waits for the framework's go");
    fw.domains[0].set_hold(false);
    t.join().unwrap().expect("connects once released");
}
