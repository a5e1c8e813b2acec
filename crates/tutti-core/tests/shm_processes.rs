//! Multi-process tests of the shared-memory domains: torn reads, lock-step, exclusivity,
//! seeding, kill -9 at random points, stale and corrupted segments.
//!
//! Child processes are this very test binary, re-run with `TUTTI_TEST_CHILD` set: the test
//! `child_main` then plays the role it names and every other test is filtered out. Every
//! child is killed when its guard drops, and every wait has a deadline.

mod common;

use std::process::Command;
use std::time::{Duration, Instant};

use tutti_core::ddf::Model;
use tutti_core::shm::segment::segment_path;
use tutti_core::shm::{ConnectOptions, Framework, FrameworkOptions, Participant, ShmError, WaitMode};
use tutti_test_support::{wait_for, wait_until, Proc, Spawn};

const WORDS: usize = 128; // 1 KiB PUBLISH set: 127 copies of a value and a checksum

/// The checksummed PUBLISH set (and the echo's SUBSCRIBE set).
fn words_item() -> String {
    format!(r#"<item name="w"><type>unsigned int64</type><length>{WORDS}</length></item>"#)
}

fn model(sync: bool, mpa: bool, states: bool) -> Model {
    let subscribe = r#"<item name="a"><type>float64</type><default>-1</default></item><item name="b"><type>int64</type><default>-1</default></item>"#;
    common::domain(sync, mpa, states, &words_item(), subscribe)
}

/// A domain whose SUBSCRIBE set has the PUBLISH set's layout, for a participant that echoes.
fn echo_model() -> Model {
    common::domain(false, true, false, &words_item(), &words_item())
}

fn payload(v: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(WORDS * 8);
    for _ in 0..WORDS - 1 {
        out.extend_from_slice(&v.to_ne_bytes());
    }
    out.extend_from_slice(&v.wrapping_mul(WORDS as u64 - 1).wrapping_add(0x5eed).to_ne_bytes());
    out
}

/// The value a payload carries, or `None` if it is torn. The set's defaults (all zeros,
/// before the framework's first write) are a whole value too: 0.
fn check(bytes: &[u8]) -> Option<u64> {
    let w: Vec<u64> = bytes.chunks_exact(8).map(|c| u64::from_ne_bytes(c.try_into().unwrap())).collect();
    if w.iter().all(|&x| x == 0) {
        return Some(0);
    }
    let v = w[0];
    (w[..WORDS - 1].iter().all(|&x| x == v) && w[WORDS - 1] == v.wrapping_mul(WORDS as u64 - 1).wrapping_add(0x5eed))
        .then_some(v)
}

fn ns(tag: &str) -> String {
    tutti_test_support::namespace(&format!("tp-{tag}-"))
}

fn fopts(tag: &str, timeout: Duration) -> FrameworkOptions {
    FrameworkOptions { namespace: ns(tag), timeout, ..Default::default() }
}

fn copts(namespace: &str) -> ConnectOptions {
    ConnectOptions {
        namespace: namespace.to_string(),
        name: "child".into(),
        timeout: Duration::from_secs(30),
        connect_timeout: Duration::from_secs(30),
        ..Default::default()
    }
}

/// A child process (this test binary in a role), killed when dropped.
struct Guard {
    proc: Proc,
    /// How many of its output lines were looked at for results.
    read: usize,
}

impl Guard {
    fn spawn(role: &str, namespace: &str) -> Guard {
        let mut cmd = Command::new(std::env::current_exe().unwrap());
        cmd.args(["--exact", "child_main", "--nocapture", "--test-threads=1"])
            .env("TUTTI_TEST_CHILD", role)
            .env("TUTTI_NAMESPACE", namespace)
            .current_dir(env!("CARGO_MANIFEST_DIR"));
        // stderr stays the test's; no clean stop on drop (the roles run until killed).
        let opts =
            Spawn { watchdog: Duration::from_secs(600), stderr: false, grace: Duration::ZERO, ..Spawn::default() };
        Guard { proc: Proc::spawn_with(role, cmd, opts), read: 0 }
    }

    /// Waits for the child's next `RESULT …` line (with a deadline) and returns it.
    fn result(&mut self, deadline: Duration) -> String {
        self.next_result(deadline).expect("child gave no result in time")
    }

    /// The child's next `RESULT …` line if it has printed one (zero `wait`: at once).
    fn next_result(&mut self, wait: Duration) -> Option<String> {
        let line = self.proc.next_line(&mut self.read, "RESULT ", wait)?;
        line.split_once("RESULT ").map(|(_, r)| r.to_string())
    }

    fn id(&self) -> u32 {
        self.proc.id()
    }

    fn kill9(&mut self) {
        self.proc.kill9();
    }
}

fn xorshift(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

/// Tells the parent a result (flushed at once: the child may go on running).
fn say(result: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    // Own line: the harness may have left "test child_main ... " unterminated.
    let _ = writeln!(out, "\nRESULT {result}");
    let _ = out.flush();
}

/// The child side: plays the role named by `TUTTI_TEST_CHILD`.
#[test]
fn child_main() {
    let Ok(role) = std::env::var("TUTTI_TEST_CHILD") else { return };
    let namespace = std::env::var("TUTTI_NAMESPACE").unwrap();
    let mut parts = role.split(':');
    match parts.next().unwrap() {
        "snapshots" => snapshots(&namespace, parts.next().unwrap().parse().unwrap()),
        "echo_all" => echo_all(&namespace, parts.next() == Some("snapshot")),
        "sync_reader" => sync_reader(&namespace, parts.next().unwrap().parse().unwrap()),
        "writer_loop" => writer_loop(&namespace),
        "seed" => seed(&namespace),
        "stepper" => stepper(namespace, parts.next() == Some("sync")),
        "framework" => framework(namespace),
        other => panic!("unknown role {other}"),
    }
}

/// Role `snapshots:N`: takes `n` snapshots of the PUBLISH set from the writer's first write
/// on and says how many were torn and how many distinct values it saw.
fn snapshots(namespace: &str, n: u64) {
    let mut p = Participant::connect("d", copts(namespace)).unwrap();
    // Count from the writer's first write on, so that every read races a writer.
    loop {
        p.subscribe_lock().unwrap();
        if check(p.snapshot()).is_some_and(|v| v > 0) {
            break;
        }
        std::thread::yield_now();
    }
    let (mut torn, mut distinct, mut last) = (0u64, 0u64, u64::MAX);
    for _ in 0..n {
        p.subscribe_lock().unwrap();
        match check(p.snapshot()) {
            None => {
                if torn == 0 {
                    let w: Vec<u64> =
                        p.snapshot().chunks_exact(8).map(|c| u64::from_ne_bytes(c.try_into().unwrap())).collect();
                    eprintln!("first torn snapshot (generation {}): {:?}", p.last_step(), w);
                }
                torn += 1
            }
            Some(v) if v != last => {
                distinct += 1;
                last = v;
            }
            Some(_) => {}
        }
    }
    say(&format!("torn={torn} distinct={distinct}"));
}

/// Role `echo_all:MODE`: answers every PUBLISH value with the same bytes, written in place:
/// from a snapshot (`commit_all_with`, `from_snapshot`), or read in place too (`answer_with`);
/// until the framework stops.
fn echo_all(namespace: &str, from_snapshot: bool) {
    let mut p = Participant::connect("d", copts(namespace)).unwrap();
    loop {
        let r = if from_snapshot {
            p.subscribe_lock().and_then(|_| p.commit_all_with(|snapshot, out| out.copy_from_slice(snapshot)))
        } else {
            p.answer_with(|publish, out| out.copy_from_slice(publish)).map(drop)
        };
        match r {
            Ok(()) => {}
            Err(ShmError::FrameworkStopped { .. }) => return,
            Err(e) => panic!("{e}"),
        }
    }
}

/// Role `sync_reader:N`: reads `n` steps in lock-step and says the first and last step and
/// how many were torn or out of sequence.
fn sync_reader(namespace: &str, n: u64) {
    let mut p = Participant::connect("d", copts(namespace)).unwrap();
    let (mut first, mut prev, mut bad) = (0u64, 0u64, 0u64);
    for i in 0..n {
        let step = p.subscribe_lock().unwrap();
        if check(p.snapshot()) != Some(step) {
            bad += 1;
        }
        if i == 0 {
            first = step;
        } else if step != prev + 1 {
            bad += 1;
        }
        prev = step;
    }
    say(&format!("first={first} last={prev} bad={bad}"));
}

/// Role `writer_loop`: reads each step and answers it with a = b = step, until killed (or
/// until the framework stops).
fn writer_loop(namespace: &str) {
    let mut p = Participant::connect("d", copts(namespace)).unwrap();
    loop {
        let step = match p.subscribe_lock() {
            Ok(s) => s,
            Err(ShmError::FrameworkStopped { .. }) => return,
            Err(e) => panic!("{e}"),
        };
        p.publish_lock().unwrap();
        p.stage("a", &(step as f64).to_ne_bytes()).unwrap();
        p.stage("b", &(step as i64).to_ne_bytes()).unwrap();
        p.commit().unwrap();
    }
}

/// Role `seed`: seeds a = 42 once the framework's first step waits for it, says so, and
/// stays connected for 30 s.
fn seed(namespace: &str) {
    let mut p = Participant::connect("d", copts(namespace)).unwrap();
    // Seed a little later than the framework's first step starts to wait for it: the
    // test calls that step right after starting this process, so it waits long before
    // this process has connected; the 300 ms only make sure of it.
    std::thread::sleep(Duration::from_millis(300));
    p.publish_lock().unwrap();
    p.stage("a", &42f64.to_ne_bytes()).unwrap();
    p.commit().unwrap();
    say("seeded");
    std::thread::sleep(Duration::from_secs(30));
}

/// Role `stepper:sync|async`: a framework stepping its domain until killed: PUBLISH carries
/// the checksummed payload of each step; synchronous (lock-step with its participants) or not.
fn stepper(namespace: String, sync: bool) {
    let opts = FrameworkOptions { namespace, timeout: Duration::from_millis(500), ..Default::default() };
    let mut fw = Framework::create(&model(sync, true, false), &opts).unwrap();
    say("created");
    let host = &mut fw.domains[0];
    loop {
        let k = host.current_step() + 1;
        host.step(&payload(k), k as f64).unwrap();
        if !sync {
            std::thread::sleep(Duration::from_micros(100));
        }
    }
}

/// Role `framework`: a framework that creates its domain, says so and lives for 60 s.
fn framework(namespace: String) {
    let _fw =
        Framework::create(&model(false, true, false), &FrameworkOptions { namespace, ..Default::default() }).unwrap();
    say("created");
    std::thread::sleep(Duration::from_secs(60));
}

#[test]
fn a_million_snapshots_under_a_concurrent_writer_are_never_torn() {
    let mut fw = Framework::create(&model(false, true, false), &fopts("torn", Duration::from_secs(5))).unwrap();
    let mut child = Guard::spawn("snapshots:1000000", &ns("torn"));
    let host = &mut fw.domains[0];
    // Written out, not `wait_for`: the framework steps as fast as it can between its looks
    // at the reader's result, so that every snapshot may meet a write (a pause between looks
    // would leave the reader nothing to tear).
    let deadline = Instant::now() + Duration::from_secs(120);
    let mut v = 0u64;
    let result = loop {
        v += 1;
        host.step(&payload(v), 0.0).unwrap();
        if v % 64 == 0 {
            if let Some(r) = child.next_result(Duration::ZERO) {
                break r;
            }
            assert!(Instant::now() < deadline, "reader did not finish");
        }
    };
    assert!(result.starts_with("torn=0 "), "{result}");
    let distinct: u64 = result.rsplit('=').next().unwrap().parse().unwrap();
    assert!(distinct > 1, "the writer must have changed the value under the reader: {result}");
}

#[test]
fn sets_committed_in_place_are_never_seen_torn_whole_or_in_part() {
    echo_under_a_racing_framework("snapshot");
}

#[test]
fn sets_read_and_answered_in_place_are_never_torn() {
    echo_under_a_racing_framework("in_place");
}

/// The framework publishes checksummed sets back to back while a participant echoes each
/// one as its whole SUBSCRIBE set; every answer the framework reads must be whole.
fn echo_under_a_racing_framework(mode: &str) {
    let tag = format!("echo{mode}").replace('_', "");
    let mut fw = Framework::create(&echo_model(), &fopts(&tag, Duration::from_secs(5))).unwrap();
    let _child = Guard::spawn(&format!("echo_all:{mode}"), &ns(&tag));
    let host = &mut fw.domains[0];
    // Not a wait but a watchdog over a fixed amount of work, done back to back (see below).
    let deadline = Instant::now() + Duration::from_secs(120);
    let (mut whole, mut changes, mut last, mut v) = (0u64, 0u64, 0u64, 0u64);
    let mut tail = [0u8; 16];
    // The framework publishes back to back while the participant answers in place, so that
    // the framework's reads race the participant's writes.
    while whole < 100_000 {
        v += 1;
        host.publish_step(&payload(v), 0.0).unwrap();
        let got = check(host.read_subscribe().unwrap());
        assert!(got.is_some(), "torn SUBSCRIBE set after {whole} reads");
        // The echo's answers change under the framework's reads: count the changes.
        if let Some(x) = got.filter(|&x| x > 0 && x != last) {
            changes += 1;
            last = x;
        }
        whole += 1;
        // The last two words (a value and the checksum) read on their own.
        host.read_subscribe_at((WORDS - 2) * 8, &mut tail).unwrap();
        let (a, sum) =
            (u64::from_ne_bytes(tail[..8].try_into().unwrap()), u64::from_ne_bytes(tail[8..].try_into().unwrap()));
        assert!(
            a == 0 && sum == 0 || sum == a.wrapping_mul(WORDS as u64 - 1).wrapping_add(0x5eed),
            "torn part: {a} {sum}"
        );
        assert!(whole % 1024 != 0 || Instant::now() < deadline, "too slow");
    }
    // Reads that never met a write would prove nothing about torn reads.
    assert!(changes >= 2, "the participant's answers never changed under the reads ({changes} changes)");
    // A range outside the set is an error that names it, not a short read.
    let err = host.read_subscribe_at(WORDS * 8 - 4, &mut tail).unwrap_err();
    assert!(matches!(err, ShmError::OutOfRange { .. }), "{err}");
    assert!(err.to_string().contains("outside the SUBSCRIBE set"), "{err}");
}

#[test]
fn every_sync_reader_reads_each_of_100000_steps_exactly_once() {
    const STEPS: u64 = 100_000;
    let mut fw = Framework::create(&model(true, true, false), &fopts("steps", Duration::from_secs(30))).unwrap();
    let mut readers: Vec<Guard> = (0..2).map(|_| Guard::spawn(&format!("sync_reader:{STEPS}"), &ns("steps"))).collect();
    // Start stepping once both readers are connected, so that they see step 1.
    let host = &mut fw.domains[0];
    wait_until("readers did not connect", Duration::from_secs(30), || host.connection_count() >= 2);
    for k in 1..=STEPS {
        let r = host.step(&payload(k), k as f64).unwrap();
        assert_eq!(r.timed_out, 0, "step {k} timed out");
    }
    for r in &mut readers {
        let result = r.result(Duration::from_secs(60));
        assert_eq!(result, format!("first=1 last={STEPS} bad=0"));
    }
}

#[test]
fn second_writer_on_exclusive_domain_gets_the_error_and_death_releases_ownership() {
    let mut fw = Framework::create(&model(true, false, false), &fopts("excl", Duration::from_secs(5))).unwrap();
    let mut child = Guard::spawn("writer_loop", &ns("excl"));
    let host = &mut fw.domains[0];
    // Step until the child has committed (it owns the SUBSCRIBE set from its first commit).
    wait_until("child never committed", Duration::from_secs(30), || {
        if f64::from_ne_bytes(host.subscribe()[0..8].try_into().unwrap()) >= 1.0 {
            return true;
        }
        host.step(&payload(host.current_step() + 1), 0.0).unwrap();
        false
    });
    let mut me =
        Participant::connect("d", ConnectOptions { timeout: Duration::from_secs(5), ..copts(&ns("excl")) }).unwrap();
    match me.publish_lock() {
        Err(ShmError::NotOwner { owner_pid, .. }) => assert_eq!(owner_pid, child.id()),
        other => panic!("expected NotOwner, got {other:?}"),
    }
    child.kill9();
    // The framework notices the death while stepping; then the set is free. In a synchronous
    // domain publish_lock waits for a step, so the framework steps meanwhile.
    let t = std::thread::spawn(move || {
        me.publish_lock()?;
        me.stage("b", &7i64.to_ne_bytes())?;
        me.commit().map(|()| me)
    });
    wait_until("the new writer never got the set", Duration::from_secs(30), || {
        if t.is_finished() {
            return true;
        }
        host.step(&payload(host.current_step() + 1), 0.0).unwrap();
        false
    });
    let me = t.join().unwrap().unwrap();
    assert_eq!(host.connection_count(), 1);
    drop(me);
}

#[test]
fn seeded_domain_waits_for_the_seed_before_its_first_step() {
    let mut fw = Framework::create(&model(true, true, true), &fopts("seed", Duration::from_secs(60))).unwrap();
    let mut child = Guard::spawn("seed", &ns("seed"));
    let host = &mut fw.domains[0];
    let r = host.step(&payload(1), 0.0).unwrap();
    assert_eq!(r.step, 1);
    assert!(host.seeded(), "the first step returned without the seed");
    assert_eq!(f64::from_ne_bytes(host.subscribe()[0..8].try_into().unwrap()), 42.0);
    assert_eq!(child.result(Duration::from_secs(30)), "seeded");
}

#[test]
fn killing_a_participant_at_random_points_never_stalls_the_framework() {
    let timeout = Duration::from_secs(3);
    let mut fw = Framework::create(&model(true, false, false), &fopts("kill", timeout)).unwrap();
    let host = &mut fw.domains[0];
    let mut rng = 0x9e37_79b9_7f4a_7c15u64 ^ u64::from(std::process::id());
    for run in 0..100 {
        let mut child = Guard::spawn("writer_loop", &ns("kill"));
        // Written out: one deadline for the whole run's three phases, in which the framework
        // steps between its looks as fast as the child answers (the kill must fall anywhere
        // in a step, which pauses between the looks would make rare).
        let deadline = Instant::now() + Duration::from_secs(30);
        while host.connection_count() == 0 {
            assert!(Instant::now() < deadline, "run {run}: child did not connect");
            host.step(&payload(host.current_step() + 1), 0.0).unwrap();
            std::thread::sleep(Duration::from_micros(200));
        }
        // Kill at a random moment while the framework steps as fast as the child answers.
        let delay = Duration::from_micros(xorshift(&mut rng) % 20_000);
        let pid = child.id();
        let killer = std::thread::spawn(move || {
            std::thread::sleep(delay);
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
        });
        let mut after_death = 0;
        while after_death < 5 {
            assert!(Instant::now() < deadline, "run {run}: framework stalled");
            let r = host.step(&payload(host.current_step() + 1), 0.0).unwrap();
            // The SUBSCRIBE set is never torn: a and b are always written together.
            let a = f64::from_ne_bytes(host.subscribe()[0..8].try_into().unwrap());
            let b = i64::from_ne_bytes(host.subscribe()[8..16].try_into().unwrap());
            assert_eq!(a as i64, b, "run {run}: torn SUBSCRIBE set at step {}", r.step);
            if killer.is_finished() && host.connection_count() == 0 {
                after_death += 1;
            }
        }
        killer.join().unwrap();
        child.kill9();
        // The domain is reusable: a new participant owns and writes the exclusive set (it
        // waits for a step, so the framework steps meanwhile).
        let mut p = Participant::connect("d", ConnectOptions { timeout, ..copts(&ns("kill")) }).unwrap();
        assert_eq!(host.connection_count(), 1);
        let t = std::thread::spawn(move || {
            p.publish_lock()?;
            p.stage("a", &(-1f64).to_ne_bytes())?;
            p.stage("b", &(-1i64).to_ne_bytes())?;
            p.commit()?;
            p.disconnect();
            Ok::<(), ShmError>(())
        });
        while !t.is_finished() {
            assert!(Instant::now() < deadline, "run {run}: new participant never wrote");
            host.step(&payload(host.current_step() + 1), 0.0).unwrap();
        }
        t.join().unwrap().unwrap_or_else(|e| panic!("run {run}: {e}"));
        host.step(&payload(host.current_step() + 1), 0.0).unwrap();
        assert_eq!(host.connection_count(), 0, "run {run}");
    }
}

#[test]
fn a_stale_segment_of_a_dead_framework_is_reclaimed() {
    let mut child = Guard::spawn("framework", &ns("stale"));
    assert_eq!(child.result(Duration::from_secs(30)), "created");
    // While it lives, the domain is refused with its pid.
    match Framework::create(&model(false, true, false), &fopts("stale", Duration::from_secs(1))) {
        Err(ShmError::DomainBusy { pid, .. }) => assert_eq!(pid, child.id()),
        other => panic!("expected DomainBusy, got {other:?}"),
    }
    child.kill9();
    let fw = Framework::create(&model(false, true, false), &fopts("stale", Duration::from_secs(1))).unwrap();
    drop(fw);
    assert!(!segment_path(&ns("stale"), "d").exists());
}

#[test]
fn a_framework_killed_outright_is_reported_to_its_participants() {
    let mut child = Guard::spawn("framework", &ns("fwdeath"));
    assert_eq!(child.result(Duration::from_secs(30)), "created");
    let opts = ConnectOptions { timeout: Duration::from_secs(5), ..copts(&ns("fwdeath")) };
    let mut p = Participant::connect("d", opts).unwrap();
    p.subscribe_lock().unwrap();
    child.kill9();
    let err = wait_for("the dead framework was never noticed", Duration::from_secs(30), || {
        p.subscribe_lock().and_then(|_| p.publish_lock()).and_then(|_| p.commit()).err()
    });
    assert!(matches!(err, ShmError::FrameworkStopped { .. }), "{err}");
    drop(p);
    // The dead framework's segment is reclaimed by the next one.
    drop(Framework::create(&model(false, true, false), &fopts("fwdeath", Duration::from_secs(1))).unwrap());
}

/// The framework is killed (SIGKILL) at a random moment while a participant exchanges with
/// it as fast as it can, so that the kill falls in every call: the wait for a step, the
/// snapshot, the lock, staging and the commit. Each time, the participant's next calls end
/// in `FrameworkStopped` (never a hang, a panic or another error), every snapshot it took
/// was whole, and after a new framework starts on the same domain the participant connects
/// again and exchanges whole sets with it.
fn killing_the_framework_at_random_points(sync: bool) {
    let tag = if sync { "fwkill-s" } else { "fwkill-a" };
    let namespace = ns(tag);
    let mut rng = 0x2545_f491_4f6c_dd1du64 ^ u64::from(std::process::id());
    let opts = || ConnectOptions { timeout: Duration::from_secs(5), ..copts(&namespace) };
    let role = if sync { "stepper:sync" } else { "stepper:async" };
    let mut child = Guard::spawn(role, &namespace);
    assert_eq!(child.result(Duration::from_secs(30)), "created");
    let mut p = Participant::connect("d", opts()).unwrap();
    for round in 0..25 {
        // Written out: the participant exchanges with the framework as fast as it can until
        // the kill (see above), with no pause between its tries.
        let deadline = Instant::now() + Duration::from_secs(30);
        let delay = Duration::from_micros(xorshift(&mut rng) % 30_000);
        let pid = child.id();
        let killer = std::thread::spawn(move || {
            std::thread::sleep(delay);
            let _ = Command::new("kill").args(["-9", &pid.to_string()]).status();
        });
        let err = loop {
            assert!(Instant::now() < deadline, "round {round}: the participant never saw the framework die");
            let r = p.subscribe_lock().and_then(|step| {
                let v = check(p.snapshot());
                assert!(v.is_some(), "round {round}: a torn snapshot at step {step}");
                p.publish_lock()?;
                p.stage("a", &(step as f64).to_ne_bytes())?;
                p.stage("b", &(step as i64).to_ne_bytes())?;
                p.commit()
            });
            match r {
                Ok(()) => {}
                Err(e) => break e,
            }
        };
        assert!(matches!(err, ShmError::FrameworkStopped { .. }), "round {round}: {err}");
        // Every later call says the same, at once.
        assert!(matches!(p.subscribe_lock(), Err(ShmError::FrameworkStopped { .. })), "round {round}");
        killer.join().unwrap();
        child.kill9();
        // A new framework on the same domain serves the participant once it connects again.
        child = Guard::spawn(role, &namespace);
        assert_eq!(child.result(Duration::from_secs(30)), "created", "round {round}");
        p = Participant::connect("d", opts()).unwrap_or_else(|e| panic!("round {round}: reconnecting: {e}"));
        for _ in 0..3 {
            let step = p.subscribe_lock().unwrap_or_else(|e| panic!("round {round}: after the restart: {e}"));
            assert!(check(p.snapshot()).is_some(), "round {round}: a torn snapshot after the restart");
            p.publish_lock().unwrap();
            p.stage("a", &(step as f64).to_ne_bytes()).unwrap();
            p.stage("b", &(step as i64).to_ne_bytes()).unwrap();
            p.commit().unwrap();
        }
    }
    drop(p);
    child.kill9();
    let _ = std::fs::remove_file(segment_path(&namespace, "d"));
}

#[test]
fn killing_the_framework_of_a_synchronous_domain_at_random_points_gives_clean_errors() {
    killing_the_framework_at_random_points(true);
}

#[test]
fn killing_the_framework_of_an_asynchronous_domain_at_random_points_gives_clean_errors() {
    killing_the_framework_at_random_points(false);
}

#[test]
fn a_segment_with_garbage_in_its_header_is_refused_cleanly() {
    use std::io::{Seek, SeekFrom, Write};
    let mut rng = 0x1234_5678_9abc_def1u64 ^ u64::from(std::process::id());
    let path = segment_path(&ns("garbage"), "d");
    for round in 0..200 {
        let mut fw =
            Framework::create(&model(round % 2 == 0, true, false), &fopts("garbage", Duration::from_millis(50)))
                .unwrap();
        let mut f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
        // Garbage over a random stretch of the header, connection table or directory; the
        // first rounds overwrite the whole header.
        let (off, len) = if round < 3 {
            (if round == 0 { 0u64 } else { 8 }, 1016usize)
        } else {
            (xorshift(&mut rng) % 1200, 1 + (xorshift(&mut rng) % 64) as usize)
        };
        let junk: Vec<u8> = (0..len).map(|_| xorshift(&mut rng) as u8).collect();
        f.seek(SeekFrom::Start(off)).unwrap();
        f.write_all(&junk).unwrap();
        drop(f);
        // Connecting and using the domain must give a result or an error, never a crash.
        let opts = ConnectOptions {
            connect_timeout: Duration::from_millis(20),
            timeout: Duration::from_millis(20),
            wait: WaitMode::Poll(Duration::from_micros(100)),
            ..copts(&ns("garbage"))
        };
        match Participant::connect("d", opts) {
            Ok(mut p) => {
                let _ = p.subscribe_lock();
                let _ = p.publish_lock();
                let _ = p.commit();
            }
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains("domain 'd'") || msg.contains("/dev/shm"), "error names the domain: {msg}");
            }
        }
        if round < 3 {
            assert!(matches!(
                Participant::connect("d", copts(&ns("garbage"))),
                Err(ShmError::Corrupt { .. } | ShmError::VersionMismatch { .. } | ShmError::NotTuttiSegment { .. })
            ));
        }
        let _ = fw.domains[0].step(&payload(1), 0.0);
        drop(fw);
    }
    assert!(!std::path::Path::new(&path).exists());
}
