//! Two gateways, two namespaces (two "machines"): the home gateway bridges a framework's
//! domains to DDS (or Zenoh); the `--mirror` gateway hosts local copies fed from it. A component on
//! the mirror side reads the PUBLISH set and writes the SUBSCRIBE set of the framework on
//! the home side, asynchronously and in lock-step.
//!
//! The tests over a `Wire` run their gateways in network namespaces of their own, so their
//! DDS domains (119-124) meet no other test's traffic.

use crate::gateway;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use gateway::*;
use tutti_test_support::RemoveSegments;

fn a_component_on_the_mirror_side_drives_an_asynchronous_domain(e: Eng) {
    let (dom, home, away) = (e.dom(109), e.ns("gwtest109a"), e.ns("gwtest109b"));
    mirror_async(&home, &away, || (e.gateway(DDF, dom, &home, &[]), e.gateway(DDF, dom, &away, &["--mirror"])));
}

/// The mirror across two network stacks: each gateway in a network namespace of its own,
/// joined by a veth pair, discovering the other by multicast on the veth (both engines).
fn the_mirror_discovers_across_network_namespaces_by_multicast(e: Eng) {
    let Some(_py) = python() else { return };
    let Some(net) = netns(&format!("mc{}", &e.name[..2])) else { return };
    let (dom, home, away) = (e.dom(115), e.ns("gwtest115a"), e.ns("gwtest115b"));
    mirror_async(&home, &away, || {
        (net.gateway(0, e, DDF, dom, &home, &[], &[]), net.gateway(1, e, DDF, dom, &away, &["--mirror"], &[]))
    });
}

/// As above with multicast switched off (CYCLONEDDS_URI): discovery by `--peer` unicast
/// only, as between two machines without multicast (Cyclone engine; rustdds cannot be given
/// unicast peers).
#[test]
fn the_mirror_discovers_across_network_namespaces_by_unicast_peers() {
    let Some(_py) = python() else { return };
    let Some(net) = netns("uc") else { return };
    let e = Eng::CYCLONE;
    let (dom, home, away) = (e.dom(116), e.ns("gwtest116a"), e.ns("gwtest116b"));
    let no_multicast = "<CycloneDDS><Domain id=\"any\"><General><AllowMulticast>false</AllowMulticast></General></Domain></CycloneDDS>";
    let env = [("CYCLONEDDS_URI", no_multicast)];
    let [a, b] = NetnsPair::ADDRS;
    mirror_async(&home, &away, || {
        (
            net.gateway(0, e, DDF, dom, &home, &["--peer", b], &env),
            net.gateway(1, e, DDF, dom, &away, &["--mirror", "--peer", a], &env),
        )
    });
}

/// The pair of namespaces of a test, or None (skipped with the reason; a failure under
/// CI=true) where this machine does not let a test create them.
fn netns(tag: &str) -> Option<NetnsPair> {
    tutti_test_support::require("network namespaces (root, and `ip` of iproute2)", NetnsPair::create(tag))
}

/// A framework on the home side publishes x = 4.5; a component on the mirror side reads it
/// and answers y = x + 4; the framework must see 8.5. `gateways` starts the home and the
/// mirror gateway once the framework is up.
fn mirror_async(home: &str, away: &str, gateways: impl FnOnce() -> (Proc, Proc)) {
    let host = Host::start(home, "gw_async", Duration::from_millis(10), |_| {
        let mut b = vec![0u8; 40];
        b[0..8].copy_from_slice(&4.5f64.to_ne_bytes());
        b
    });
    let (gw_home, gw_away) = gateways();
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let away_ns = away.to_string();
    let component = thread::spawn(move || {
        let mut p = connect(&away_ns, "gw_async");
        let mut x = 0.0;
        tutti_test_support::poll_for(SECS(60), || {
            p.subscribe_lock().unwrap();
            x = f64_at(p.snapshot(), 0);
            (x == 4.5).then_some(())
        });
        while !s.load(Ordering::Acquire) {
            p.stage("y", &(x + 4.0).to_ne_bytes()).unwrap();
            p.commit().unwrap();
            thread::sleep(Duration::from_millis(20));
        }
        x
    });
    let got = host.wait_for(SECS(75), |_, b| f64_at(b, 0) == 8.5);
    stop.store(true, Ordering::Release);
    let x = component.join().unwrap();
    assert_eq!(x, 4.5, "the mirror side never read the PUBLISH set\n{}\n{}", gw_home.dump(), gw_away.dump());
    assert!(got.is_some(), "the framework never read the mirror side's commit\n{}\n{}", gw_home.dump(), gw_away.dump());
}

fn a_component_on_the_mirror_side_takes_part_in_lock_step(e: Eng) {
    let (dom, home, away) = (e.dom(110), e.ns("gwtest110a"), e.ns("gwtest110b"));
    let (home, away) = (home.as_str(), away.as_str());
    let host = Host::start(home, "gw_sync", Duration::from_millis(5), |k| (k as f64 * 10.0).to_ne_bytes().to_vec());
    let gw_home = e.gateway(DDF, dom, home, &[]);
    let gw_away = e.gateway(DDF, dom, away, &["--mirror", "--timeout", "500ms"]);
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let away_ns = away.to_string();
    let component = thread::spawn(move || {
        let mut p = connect(&away_ns, "gw_sync");
        let mut steps = 0;
        while !s.load(Ordering::Acquire) {
            if p.subscribe_lock().is_err() {
                continue;
            }
            let x = f64_at(p.snapshot(), 0);
            if p.publish_lock().is_ok() {
                p.stage("y", &(x + 1.0).to_ne_bytes()).unwrap();
                p.commit().unwrap();
                steps += 1;
            }
        }
        steps
    });
    // In lock-step, the SUBSCRIBE set read at the end of step k answers step k's PUBLISH set.
    let answered = |k: u64, b: &[u8]| f64_at(b, 0) == k as f64 * 10.0 + 1.0;
    let first = host.wait_for(SECS(75), answered);
    // Lock-step is judged over the 140 steps (0.7 s) after the first answered one.
    if let Some(first) = first {
        host.wait_for(SECS(60), |k, _| k >= first + 140);
    }
    stop.store(true, Ordering::Release);
    let seen = host.seen.lock().unwrap().clone();
    drop(host);
    let steps = component.join().unwrap();
    assert!(first.is_some(), "no step was answered ({steps} commits)\n{}\n{}", gw_home.dump(), gw_away.dump());
    assert_lock_step(&seen, first.unwrap(), answered);
    crate::gateway_reliable::assert_no_step_lost(&gw_home, false);
    crate::gateway_reliable::assert_no_step_lost(&gw_away, false);
}

/// A mirrored synchronous domain with a lookahead of K steps (`--lookahead`, docs/run.md,
/// "Sites and lookahead"): the answer the mirror side gives to step n is the one the home
/// framework reads at the end of step n + K, exactly, and the first K steps read the initial
/// value. Both gateways on this machine's loopback; the stats endpoint shows the lookahead.
fn a_mirrored_domain_with_a_lookahead_answers_each_step_k_steps_later(e: Eng) {
    let (dom, home, away) = (e.dom(118), e.ns("gwtest118a"), e.ns("gwtest118b"));
    let k = 4;
    let args = ["--lookahead".to_string(), format!("gw_sync={k}"), "--http".into(), "127.0.0.1:0".into()];
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let run = LookaheadRun { home: &home, away: &away, k, steps: 300, timeout: SECS(5) };
    // `tutti status --json` in the middle of the run: the remote writer's link.
    let mut shown = None;
    let (gw_home, _gw_away) = run.check_with(
        || {
            (
                e.gateway(DDF, dom, &home, &args),
                e.gateway(DDF, dom, &away, &["--mirror", "--timeout", "5s", "--lookahead", "4"]),
            )
        },
        |step| {
            if step == 200 {
                let mut cmd = tutti_test_support::tutti_command();
                cmd.args(["status", "--json", "--namespace", &home]);
                shown = Some(tutti_test_support::run_with_timeout(cmd, SECS(60)).1);
            }
        },
    );
    let shown = shown.expect("tutti status ran");
    let v: serde_json::Value = serde_json::from_str(&shown).unwrap_or_else(|e| panic!("{e}: {shown}"));
    let conns = v
        .as_array()
        .into_iter()
        .flatten()
        .filter(|d| d["domain"] == "gw_sync")
        .flat_map(|d| d["connections"].as_array().cloned().unwrap_or_default());
    let link = conns.filter(|c| c["remote"] == true).find_map(|c| c.get("link").cloned());
    let link = link.unwrap_or_else(|| panic!("no remote writer shows its link: {shown}"));
    assert_eq!(link["lookahead"], k, "{link}");
    assert!(link["rtt_us"].as_u64().is_some_and(|r| r > 0), "{link}");
    let v: serde_json::Value = serde_json::from_str(&http_get(&stats_addr(&gw_home), "/stats")).unwrap();
    let sub = v["topics"].as_array().unwrap().iter().find(|t| t["set"] == "gw_sync/subscribe").unwrap().clone();
    assert_eq!(sub["lookahead"], k, "{sub}");
    assert_eq!(v["gateway"]["totals"]["late"], 0, "{v}");
}

/// The same across a link of 20 ms each way between two network namespaces (a
/// `tutti_test_support::Wire`: TAP devices joined by this process after the delay), with
/// K = 10: the home framework runs ahead of the link, and every value is still exactly the
/// one of a run with a 10-step delay.
fn a_lookahead_across_a_slow_link_keeps_every_value_of_a_k_step_delay(e: Eng) {
    let Some(wire) = tutti_test_support::require(
        "network namespaces and TAP devices (root, `ip` of iproute2, /dev/net/tun)",
        tutti_test_support::Wire::create(&format!("la{}", &e.name[..2]), Duration::from_millis(20)),
    ) else {
        return;
    };
    let (dom, home, away) = (e.dom(119), e.ns("gwtest119a"), e.ns("gwtest119b"));
    let names = wire.names().clone();
    let run = LookaheadRun { home: &home, away: &away, k: 10, steps: 200, timeout: SECS(5) };
    let (gw_home, gw_away) = run.check(|| {
        sites(&names, e, dom, (&home, &away), &["--lookahead", "10"], &["--timeout", "5s", "--lookahead", "10"])
    });
    assert_eq!(counter(&gw_home, "late"), 0, "{}\n{}", gw_home.dump(), gw_away.dump());
    assert!(wire.counts().0 > 0, "nothing crossed the wire");
}

/// Through a link that loses 5 % of the frames each way and holds 5 % back by 3 ms (so that
/// later ones overtake them), and is cut for 0.5 s in the middle of the run: the run waits
/// for the link and goes on, and no step is lost, repeated or taken out of order.
fn a_lookahead_through_a_lossy_reordering_link_that_is_cut_loses_no_step(e: Eng) {
    let Some(wire) = wire_for("lf", e) else { return };
    let f = wire.faults();
    let (dom, home, away) = (e.dom(120), e.ns("gwtest120a"), e.ns("gwtest120b"));
    let names = wire.names().clone();
    let run = LookaheadRun { home: &home, away: &away, k: 4, steps: 400, timeout: SECS(10) };
    let mut mend = None;
    let (gw_home, gw_away) = run.check_with(
        || {
            // A lease above the time a lost frame takes to be sent again (rustdds: up to
            // seconds), so that a loss is waited for rather than taken for a dead site.
            sites(
                &names,
                e,
                dom,
                (&home, &away),
                &["--lookahead", "4", "--lease", "5s"],
                &["--timeout", "10s", "--lease", "5s", "--lookahead", "4"],
            )
        },
        |step| match step {
            // Losses and reordering from the first step on (discovery is not what is tested).
            1 => {
                f.loss_ppm.store(50_000, Ordering::Relaxed);
                f.reorder_ppm.store(50_000, Ordering::Relaxed);
                f.reorder_us.store(3_000, Ordering::Relaxed);
            }
            // Cut for 0.5 s: the framework, at most 4 steps ahead, waits for the link.
            150 => mend = Some(cut_for(&f, Duration::from_millis(500))),
            _ => {}
        },
    );
    mend.expect("the link was cut").join().unwrap();
    let (copied, dropped) = wire.counts();
    assert!(dropped > 0 && copied > 0, "the wire lost nothing ({copied} copied)");
    assert_eq!(counter(&gw_home, "late"), 0, "{}\n{}", gw_home.dump(), gw_away.dump());
    assert_eq!(counter(&gw_home, "lapsed"), 0, "{}\n{}", gw_home.dump(), gw_away.dump());
}

/// A cut of 5 s, with both gateways' `--lease` (how long a silent writer is waited for, and
/// the DDS participants' lease) and the home framework's step timeout above it: the run
/// waits for the link and goes on when it returns, no step lost, repeated or reordered.
fn a_lookahead_waits_out_a_five_second_cut_within_its_lease(e: Eng) {
    let Some(wire) = wire_for("l5", e) else { return };
    let (dom, home, away) = (e.dom(121), e.ns("gwtest121a"), e.ns("gwtest121b"));
    let names = wire.names().clone();
    let f = wire.faults();
    let run = LookaheadRun { home: &home, away: &away, k: 4, steps: 200, timeout: SECS(20) };
    let mut mend = None;
    let (gw_home, gw_away) = run.check_with(
        || {
            sites(
                &names,
                e,
                dom,
                (&home, &away),
                &["--lookahead", "4", "--lease", "10s"],
                &["--timeout", "20s", "--lease", "10s", "--lookahead", "4"],
            )
        },
        |step| {
            if step == 100 {
                mend = Some(cut_for(&f, Duration::from_secs(5)));
            }
        },
    );
    mend.expect("the link was cut").join().unwrap();
    assert_eq!(counter(&gw_home, "lapsed"), 0, "{}\n{}", gw_home.dump(), gw_away.dump());
    assert!(gw_home.wait_line("waits for the link", SECS(1)).is_some(), "the wait was not logged\n{}", gw_home.dump());
}

/// A cut longer than the home framework's step timeout (3 s against 2 s; the leases are
/// longer): the step times out, and the framework's report names the domain and the other
/// site's writer (its participant and the lookahead); when the link returns the run goes on
/// and its steps again read what a K-step delay gives.
fn a_cut_longer_than_the_step_timeout_is_reported_and_the_run_goes_on(e: Eng) {
    let Some(wire) = wire_for("lt", e) else { return };
    let (dom, home, away) = (e.dom(122), e.ns("gwtest122a"), e.ns("gwtest122b"));
    let [a, b] = tutti_test_support::Wire::ADDRS;
    let names = wire.names().clone();
    let f = wire.faults();
    let (k, steps) = (4, 300);
    let run = LookaheadRun { home: &home, away: &away, k, steps, timeout: SECS(2) };
    let mut mend = None;
    let mirror: Away = Arc::default();
    let r = run.run_with(
        || {
            let away_args = ["--mirror", "--timeout", "20s", "--lease", "10s", "--lookahead", "4"];
            *mirror.lock().unwrap() = Some(netns_gateway((&names[1], b), e, DDF, dom, &away, &away_args, &[]));
            netns_gateway((&names[0], a), e, DDF, dom, &home, &["--lookahead", "4", "--lease", "10s"], &[])
        },
        &mirror,
        |step| {
            if step == 100 {
                mend = Some(cut_for(&f, Duration::from_secs(3)));
            }
        },
    );
    mend.expect("the link was cut").join().unwrap();
    let (first, waited_for) = r.timed_out.first().cloned().unwrap_or_else(|| panic!("no step timed out\n{}", r.dump()));
    assert!((100..=110).contains(&first), "step {first} timed out, not one during the cut\n{}", r.dump());
    assert!(waited_for.iter().any(|c| c.contains("lookahead 4")), "{waited_for:?}");
    for step in 1..first {
        assert!(r.delayed(k, step), "step {step} before the cut\n{}", r.dump());
    }
    for step in steps - 50..=steps {
        assert!(r.delayed(k, step), "step {step}: the run did not go on with a {k}-step delay\n{}", r.dump());
    }
}

/// The other site killed (`kill -9` of its gateway, the framework of its copy of the domain)
/// and started again: the home side waits for the lease, then releases the silent writer
/// (a warning names the domain and the step) and goes on with the values as they are; when
/// the other site is back, it joins at a step boundary (logged), and from a step on every
/// step again reads what a K-step delay gives.
fn a_killed_site_that_starts_again_rejoins_at_a_step_boundary(e: Eng) {
    let Some(wire) = wire_for("lk", e) else { return };
    let (dom, home, away) = (e.dom(123), e.ns("gwtest123a"), e.ns("gwtest123b"));
    let [a, b] = tutti_test_support::Wire::ADDRS;
    let names = wire.names().clone();
    let (k, steps) = (4, 1500);
    let run = LookaheadRun { home: &home, away: &away, k, steps, timeout: SECS(10) };
    let mirror: Away = Arc::default();
    let start_mirror = {
        let (netns, away) = (names[1].clone(), away.clone());
        move || {
            netns_gateway((&netns, b), e, DDF, dom, &away, &["--mirror", "--timeout", "10s", "--lookahead", "4"], &[])
        }
    };
    let first = start_mirror.clone();
    let mut restart = None;
    let r = run.run_with(
        || {
            *mirror.lock().unwrap() = Some(first());
            netns_gateway((&names[0], a), e, DDF, dom, &home, &["--lookahead", "4"], &[])
        },
        &mirror,
        |step| {
            // Paced, so that the run outlasts the other site's absence.
            thread::sleep(Duration::from_millis(4));
            if step == 100 {
                let (slot, start) = (mirror.clone(), start_mirror.clone());
                restart = Some(thread::spawn(move || {
                    slot.lock().unwrap().as_mut().expect("the mirror").kill9();
                    thread::sleep(Duration::from_secs(2));
                    let again = start();
                    *slot.lock().unwrap() = Some(again);
                }));
            }
        },
    );
    restart.expect("the site was killed").join().unwrap();
    assert!(r.timed_out.is_empty(), "steps timed out: {:?}\n{}", r.timed_out, r.dump());
    for step in 1..100 {
        assert!(r.delayed(k, step), "step {step}, before the kill\n{}", r.dump());
    }
    let last_off = (1..=steps)
        .rev()
        .find(|&n| !r.delayed(k, n))
        .unwrap_or_else(|| panic!("no step missed an answer\n{}", r.dump()));
    assert!(
        last_off < steps - 200,
        "the other site did not rejoin for good (step {last_off} read no answer)\n{}",
        r.dump()
    );
    assert!(r.gw_home.wait_line("its share of the step is released", SECS(1)).is_some(), "{}", r.dump());
    // The step the home gateway said the rejoined site's answers are read from is the one
    // from which every step reads a K-step delay again.
    let joins: Vec<String> = r.gw_home.lines().into_iter().filter(|l| l.contains(" joins at step ")).collect();
    assert!(joins.len() >= 2, "the rejoin was not logged\n{}", r.dump());
    let from: u64 = joins[joins.len() - 1]
        .split("read from step ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next()?.parse().ok())
        .unwrap_or_else(|| panic!("{joins:?}"));
    assert_eq!(last_off + 1, from, "{joins:?}\n{}", r.dump());
}

/// A mirror that joins a running home starts at the home's current step (docs/run.md, "Sites
/// and lookahead"), across a link of 20 ms each way: the home runs on alone while the other
/// site's component takes 3 s over its first step; the other site then steps the home's
/// latest step instead of working one by one through the thousands the home made meanwhile,
/// and from there on every home step is answered in lock-step, each seen once on that site.
fn a_mirror_that_joins_a_running_home_starts_at_its_current_step(e: Eng) {
    let Some(wire) = wire_for("lj", e) else { return };
    wire.set_delay(Duration::from_millis(20));
    let (dom, home, away) = (e.dom(124), e.ns("gwtest124a"), e.ns("gwtest124b"));
    let names = wire.names().clone();
    let model = tutti_core::ddf::load(tutti_test_support::repo_root().join(DDF)).unwrap();
    let opts = tutti_core::shm::FrameworkOptions { namespace: home.clone(), timeout: SECS(10), ..Default::default() };
    let mut fw = tutti_core::shm::Framework::create(&model, &opts).expect("framework");
    let (gw_home, gw_away) = sites(&names, e, dom, (&home, &away), &["--every-step"], &["--timeout", "10s"]);
    let dump = || format!("{}\n{}", gw_home.dump(), gw_away.dump());
    // The other site's component: y = x + 1, its first step 3 s long (a model loading); it
    // tells each x it is given.
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, seen) = std::sync::mpsc::channel::<f64>();
    let component = {
        let (s, away) = (stop.clone(), away.clone());
        thread::spawn(move || {
            let mut p = connect(&away, "gw_sync");
            // A writer from the start: the mirror's steps wait for its answer.
            p.publish_gate().expect("publish gate");
            let mut first = true;
            while !s.load(Ordering::Acquire) {
                match p.subscribe_lock() {
                    Ok(_) => {}
                    Err(tutti_core::shm::ShmError::Timeout { .. }) => continue,
                    Err(_) => break,
                }
                let x = f64_at(p.snapshot(), 0);
                if std::mem::take(&mut first) {
                    thread::sleep(SECS(3));
                }
                let _ = tx.send(x);
                if p.publish_lock().is_ok() {
                    p.stage("y", &(x + 1.0).to_ne_bytes()).unwrap();
                    if p.commit().is_err() {
                        break;
                    }
                }
            }
        })
    };
    let ready = tutti_test_support::poll_for(SECS(60), || {
        let away_ok = tutti_core::shm::segment::Segment::open(&away, "gw_sync").is_ok_and(|seg| {
            seg.status().connections.iter().any(|c| c.name == "test-component" && c.sync_reader && c.writer)
        });
        let home_ok = status(&home, "gw_sync").connections.iter().any(|c| c.observer && c.dds_readers >= 1);
        (away_ok && home_ok).then_some(())
    });
    assert!(ready.is_some(), "the two sides never met\n{}", dump());
    // The home steps alone (about a step per ms) until the other site answers, then in
    // lock-step: y read at the end of step n is x_n + 1. Until 100 steps in a row are so.
    let d = fw.domains.iter_mut().find(|d| d.info().name == "gw_sync").unwrap();
    let (mut n, mut in_a_row) = (0u64, 0u64);
    let watchdog = std::time::Instant::now() + SECS(120);
    while in_a_row < 100 {
        assert!(std::time::Instant::now() < watchdog, "step {n}: no lock-step after 120 s\n{}", dump());
        n += 1;
        thread::sleep(Duration::from_millis(1));
        let r =
            d.step(&(n as f64).to_ne_bytes(), n as f64 * 0.01).unwrap_or_else(|e| panic!("step {n}: {e}\n{}", dump()));
        assert_eq!(r.timed_out, 0, "step {n} timed out waiting for {:?}\n{}", d.timed_out_on(), dump());
        in_a_row = if f64_at(d.subscribe(), 0) == n as f64 + 1.0 { in_a_row + 1 } else { 0 };
    }
    let lock_step = n - 99;
    stop.store(true, Ordering::Release);
    drop(fw);
    component.join().unwrap();
    let seen: Vec<f64> = seen.try_iter().collect();
    let first = seen[0];
    // What the home made without the other site, and what of it that site stepped anyway.
    let alone = lock_step as f64 - first;
    let stepped_late = seen.iter().filter(|&&x| x > first && x < lock_step as f64).count();
    assert!(alone >= 500.0, "the home made only {alone} steps alone: no backlog to skip\n{}", dump());
    assert!(
        (stepped_late as f64) * 4.0 < alone,
        "the other site stepped {stepped_late} of the {alone} steps the home made without it (first {first}, lock-step from {lock_step})\n{}",
        dump()
    );
    let tail: Vec<f64> = seen.iter().copied().filter(|&x| x >= lock_step as f64).collect();
    let want: Vec<f64> = (lock_step..=n).map(|k| k as f64).collect();
    assert_eq!(tail, want, "the steps in lock-step, as the other site saw them\n{}", dump());
    assert!(gw_away.wait_line("the mirror starts at step", SECS(1)).is_some(), "{}", dump());
}

/// The worked example of two sites (examples/sites/README.md; docs/run.md, "Sites and
/// lookahead"), as a user runs it on one machine: each site a `tutti run` of its own launch
/// file (its own framework, namespace and components: the cart at home; the operator, the
/// controller and the mirror of `link` on the other site), joined over DDS on loopback by
/// `link` with a lookahead of 10 steps. The home run ends well, its cart settles at the target
/// the other site's operator set, and every step's force is the controller's answer to the
/// cart's state 10 steps before, exactly.
#[test]
fn the_two_site_example_brings_the_home_cart_to_the_target_set_on_the_other_site() {
    let Some(ex) = SitesExample::new("47") else { return };
    let site = &ex.site;
    let run = |name: &str, launch: &str, ns: &str| ex.run(name, launch, ns, &[]);
    let mut away = run("the other site", "away.json5", &tutti_test_support::namespace("sites_b"));
    let mut home = run("the home site", "home.json5", &tutti_test_support::namespace("sites_a"));
    let code = home.wait(SECS(120));
    assert_eq!(code, Some(0), "the home run did not end well\n{}\n{}", home.dump(), away.dump());
    let stopped = away.interrupt(SECS(30));
    let dump = || format!("{}\n{}", home.dump(), away.dump());
    assert_eq!(stopped, Some(0), "the other site did not stop well\n{}", dump());
    let csv = std::fs::read_to_string(site.join("home-link.csv")).unwrap_or_else(|e| panic!("{e}\n{}", dump()));
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col =
        |name: &str| header.iter().position(|h| h.trim() == name).unwrap_or_else(|| panic!("no {name}: {header:?}"));
    let (step, pos, vel, force) =
        (col("step"), col("publish.position"), col("publish.velocity"), col("subscribe.force"));
    let rows: Vec<(u64, f64, f64, f64)> = lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            let f = |i: usize| v[i].trim().parse::<f64>().unwrap();
            (v[step].trim().parse().unwrap(), f(pos), f(vel), f(force))
        })
        .collect();
    assert_eq!(rows.len(), 1500, "a row per step\n{}", dump());
    let (k, (kp, kd)) = (10, (4.0, 3.0));
    for (i, &(n, _, _, f)) in rows.iter().enumerate() {
        assert_eq!(n, i as u64 + 1);
        if i < k {
            assert_eq!(f, 0.0, "step {n}: no answer can have come yet");
            continue;
        }
        // The answer to step n - 10, for one of the targets the operator sets (none yet: 0).
        let (_, p, v, _) = rows[i - k];
        assert!(
            [0.0, 1.0, 0.5].iter().any(|g| f == kp * (g - p) - kd * v),
            "step {n} read force {f}: not the answer to step {} (position {p}, velocity {v})\n{}",
            n - 10,
            dump()
        );
    }
    let (_, p, v, _) = rows[rows.len() - 1];
    assert!((p - 0.5).abs() < 0.02 && v.abs() < 0.05, "the cart ended at {p} m, {v} m/s, not at 0.5 m\n{}", dump());
}

/// The two-site example (examples/sites) in a temporary folder, as a user runs it.
struct SitesExample {
    _dir: tempfile::TempDir,
    /// `examples/sites` in it (its relative paths hold: `python` beside `examples`).
    site: std::path::PathBuf,
    /// PATH with this build's `tutti` and the tests' Python first.
    path: String,
    lib: std::path::PathBuf,
    ros_domain_id: String,
}

impl SitesExample {
    /// None where Python is missing (a failure under CI=true).
    fn new(ros_domain_id: &str) -> Option<SitesExample> {
        let py = tutti_test_support::python(&["ctypes"])?;
        let repo = tutti_test_support::repo_root();
        let dir = tempfile::tempdir().unwrap();
        // The example where it is in the repository, so its relative paths hold; its
        // recording goes to the temporary folder.
        let site = dir.path().join("examples/sites");
        std::fs::create_dir_all(&site).unwrap();
        for f in std::fs::read_dir(repo.join("examples/sites")).unwrap() {
            let f = f.unwrap().path();
            std::fs::copy(&f, site.join(f.file_name().unwrap())).unwrap();
        }
        std::os::unix::fs::symlink(repo.join("python"), dir.path().join("python")).unwrap();
        let path = format!(
            "{}:{}:{}",
            tutti_test_support::tutti_exe().parent().unwrap().display(),
            py.parent().unwrap().display(),
            std::env::var("PATH").unwrap_or_default()
        );
        let lib = tutti_test_support::rtapi_lib_dir().join("librtapi.so");
        Some(SitesExample { _dir: dir, site, path, lib, ros_domain_id: ros_domain_id.into() })
    }

    /// `tutti run LAUNCH EXTRA...` in namespace `ns`.
    fn run(&self, name: &str, launch: &str, ns: &str, extra: &[&str]) -> Proc {
        let mut cmd = tutti_test_support::tutti_command();
        cmd.args(["run", &self.site.join(launch).display().to_string()])
            .args(extra)
            .env("TUTTI_NAMESPACE", ns)
            .env("ROS_DOMAIN_ID", &self.ros_domain_id)
            .env("ROS_LOCALHOST_ONLY", "1")
            .env("TUTTI_RTAPI_LIB", &self.lib)
            .env("PATH", &self.path);
        Proc::spawn(name, cmd, SECS(240))
    }
}

/// A run of the two-site example saved and restored (docs/run.md, "Checkpoints"): the home
/// site's checkpoint holds the answers on their way over the link (the lookahead's queue), so
/// that a new run restored from it at step 300, and the run itself restored into while it
/// goes on, read every value the straight run read, step by step (the other site's controller
/// steers towards a fixed target, so the home's values are a function of the home's alone).
/// The home waits for the link before its first step (`wait_for`).
fn a_run_across_sites_is_saved_and_restored_with_the_answers_on_their_way(e: Eng) {
    let dom = e.dom_beside(227).to_string();
    let Some(ex) = SitesExample::new(&dom) else { return };
    let (ns_a, ns_b) = (tutti_test_support::namespace(&e.ns("ckla")), tutti_test_support::namespace(&e.ns("cklb")));
    let _segments = (RemoveSegments(ns_a.clone()), RemoveSegments(ns_b.clone()));
    let engine = if e.name == Eng::ZENOH.name {
        format!(r#"engine: "zenoh", zenoh_connect: ["{}"], "#, gateway::zenoh_router().endpoint())
    } else {
        format!(r#"engine: "{}", "#, e.name)
    };
    let write = |name: &str, text: String| std::fs::write(ex.site.join(name), text).unwrap();
    write("ck-mirror.json5", format!(r#"{{ {engine}allow: ["link/.*"], lookahead: {{ link: 10 }}, timeout: "10s" }}"#));
    write(
        "ck-away.json5",
        r#"{ ddf: "away.ddf", framework: { step: "10ms" },
  components: [
    { name: "mirror", run: ["tutti", "gateway", "home.ddf", "--mirror", "--config", "ck-mirror.json5"] },
    { name: "controller", run: ["python3", "components.py", "controller", "1"], env: { PYTHONPATH: "../../python" } } ] }"#
            .into(),
    );
    let home = |name: &str, steps: u64, speed: u32, more: &str| {
        let steps = if steps == 0 { String::new() } else { format!("steps: {steps}, ") };
        write(
            name,
            format!(
                r#"{{ ddf: "home.ddf",
  framework: {{ step: "10ms", {steps}speed: {speed}, catch_up: true, timeout: "10s", wait_for: {{ link: 1 }}, record: ["{}.csv"]{more} }},
  connections: ["cart/subscribe/position -> link/publish/position", "cart/subscribe/velocity -> link/publish/velocity",
                "link/subscribe/force -> cart/publish/force"],
  components: [ {{ name: "cart", run: ["python3", "components.py", "cart"], domain: "cart", env: {{ PYTHONPATH: "../../python" }} }} ],
  gateway: {{ {engine}allow: ["link/.*"], lookahead: {{ link: 10 }} }} }}"#,
                name.trim_end_matches(".json5")
            ),
        )
    };
    home("warm.json5", 30, 0, "");
    home("straight.json5", 600, 0, "");
    home("first.json5", 300, 0, r#", checkpoint: { every: 300, dir: "ck" }"#);
    home("second.json5", 600, 0, "");
    // Paced (5 times real time), so that the test can pause it after its checkpoint at 300.
    home("long.json5", 0, 5, r#", checkpoint: { every: 300, dir: "ckl" }"#);
    let mut away = ex.run("the other site", "ck-away.json5", &ns_b, &[]);
    let finish = |mut p: Proc, away: &Proc| {
        assert_eq!(p.wait(SECS(180)), Some(0), "the home run failed\n{}\n{}", p.dump(), away.dump());
    };
    let link = |stem: &str| crate::checkpoint::csv_rows(&ex.site.join(format!("{stem}-link.csv")));

    // The other site's controller becomes a writer of `link` with its first answer (until
    // then the mirror's steps do not wait for it, and answer with the initial force): a short
    // run first, so that every run after it meets the other site as it is from then on.
    finish(ex.run("a first short run", "warm.json5", &ns_a, &[]), &away);
    finish(ex.run("the straight run", "straight.json5", &ns_a, &[]), &away);
    let straight: std::collections::BTreeMap<u64, Vec<String>> = link("straight").into_iter().collect();
    assert_eq!(straight.len(), 600, "the straight run's steps");
    // The link answered: the force is the controller's, not the initial 0, after step 10.
    assert!(straight.values().skip(20).all(|v| v[2] != "0"), "{straight:?}");

    finish(ex.run("the first half", "first.json5", &ns_a, &[]), &away);
    let ckpt = ex.site.join("ck/step-000000300.tutti-checkpoint");
    let c = tutti_host::checkpoint::Checkpoint::read(&ckpt).unwrap_or_else(|e| panic!("{e}\n{}", away.dump()));
    let queue = c.components.iter().find(|s| s.remote).expect("the link's queue is in the checkpoint");
    assert_eq!(queue.domain, "link");
    crate::checkpoint::same_as(&straight, &link("first"), "the first half");

    let second = ex.run("the run restored", "second.json5", &ns_a, &["--restore", ckpt.to_str().unwrap()]);
    finish(second, &away);
    let rows = link("second");
    assert_eq!(rows.iter().map(|r| r.0).collect::<Vec<_>>(), (300..600).collect::<Vec<_>>(), "the second half's steps");
    crate::checkpoint::same_as(&straight, &rows, "the run restored from step 300");

    let run = ex.run("the long run", "long.json5", &ns_a, &[]);
    let at_300 = ex.site.join("ckl/step-000000300.tutti-checkpoint");
    tutti_test_support::wait_until(format_args!("the checkpoint at step 300\n{}", run.dump()), SECS(120), || {
        at_300.exists()
    });
    let ctl = |args: &[&str]| {
        let (code, out, err) = crate::checkpoint::ctl(&ns_a, args, &ex.site);
        assert_eq!(code, 0, "tutti ctl {args:?}: {out}{err}\n{}\n{}", run.dump(), away.dump());
    };
    ctl(&["pause"]);
    ctl(&["restore", at_300.to_str().unwrap()]);
    ctl(&["resume"]);
    let at_600 = ex.site.join("ckl/step-000000600.tutti-checkpoint");
    tutti_test_support::wait_until(format_args!("the checkpoint at step 600\n{}", run.dump()), SECS(120), || {
        at_600.exists()
    });
    ctl(&["stop"]);
    finish(run, &away);
    let all = link("long");
    let (before, after) = crate::checkpoint::split_at_restore(&all, 300, 600);
    crate::checkpoint::same_as(&straight, before, "before the restore");
    crate::checkpoint::same_as(&straight, &after, "after the restore");
    assert_eq!(away.interrupt(SECS(30)), Some(0), "the other site did not stop well\n{}", away.dump());
}

/// On Zenoh, across the wire through two routers, one per site (eclipse-zenoh's,
/// `tests/gateway/zenoh_router.py`): each gateway connects to its own site's router, and the
/// second router to the first, as rmw_zenoh graphs on two networks meet. K = 10 keeps every
/// value of a 10-step delay.
#[test]
fn a_lookahead_across_two_zenoh_routers_keeps_every_value_of_a_k_step_delay() {
    let e = Eng::ZENOH;
    let Some(py) = tutti_test_support::python(&["zenoh"]) else { return };
    let Some(wire) = wire_for("lz", e) else { return };
    let names = wire.names().clone();
    let [a, b] = tutti_test_support::Wire::ADDRS;
    let (ra, rb) = (format!("tcp/{a}:7447"), format!("tcp/{b}:7447"));
    let router = |i: usize, listen: &str, connect: &[&str]| {
        let mut cmd = std::process::Command::new("ip");
        cmd.args(["netns", "exec", &names[i]]).arg(&py);
        cmd.arg(tutti_test_support::repo_root().join("tests/gateway/zenoh_router.py")).args(["--listen", listen]);
        for c in connect {
            cmd.args(["--connect", c]);
        }
        let p = Proc::spawn(&format!("the Zenoh router of site {i}"), cmd, SECS(180));
        assert!(p.wait_line("up", SECS(30)).is_some(), "the router did not start\n{}", p.dump());
        p
    };
    let _routers = [router(0, &ra, &[]), router(1, &rb, &[&ra])];
    let (dom, home, away) = (e.dom(119), e.ns("gwtest119a"), e.ns("gwtest119b"));
    let run = LookaheadRun { home: &home, away: &away, k: 10, steps: 200, timeout: SECS(5) };
    let (gw_home, gw_away) = run.check(|| {
        sites(
            &names,
            e,
            dom,
            (&home, &away),
            &["--lookahead", "10", "--zenoh-connect", &ra],
            &["--timeout", "5s", "--lookahead", "10", "--zenoh-connect", &rb],
        )
    });
    assert_eq!(counter(&gw_home, "late"), 0, "{}\n{}", gw_home.dump(), gw_away.dump());
    assert!(wire.counts().0 > 0, "nothing crossed the wire");
}

/// The wire of a test (5 ms each way), or None (skipped with the reason; a failure under
/// CI=true) where this machine does not let a test make it.
fn wire_for(tag: &str, e: Eng) -> Option<tutti_test_support::Wire> {
    tutti_test_support::require(
        "network namespaces and TAP devices (root, `ip` of iproute2, /dev/net/tun)",
        tutti_test_support::Wire::create(&format!("{tag}{}", &e.name[..2]), Duration::from_millis(5)),
    )
}

/// The two sites' gateways across the wire whose namespaces are `names`: the home gateway
/// (namespace `home`) with `home_args` in the first, and `--mirror` (namespace `away`) with
/// `away_args` in the second.
fn sites(
    names: &[String; 2],
    e: Eng,
    dom: u16,
    (home, away): (&str, &str),
    home_args: &[&str],
    away_args: &[&str],
) -> (Proc, Proc) {
    let [a, b] = tutti_test_support::Wire::ADDRS;
    let away_args = [&["--mirror"], away_args].concat();
    (
        netns_gateway((&names[0], a), e, DDF, dom, home, home_args, &[]),
        netns_gateway((&names[1], b), e, DDF, dom, away, &away_args, &[]),
    )
}

/// Cuts the wire whose faults are `f` now, and joins it again after `d` from another thread
/// (the framework waits for the link in its step meanwhile).
fn cut_for(f: &Arc<tutti_test_support::Faults>, d: Duration) -> thread::JoinHandle<()> {
    f.cut.store(true, Ordering::Relaxed);
    let f = f.clone();
    thread::spawn(move || {
        thread::sleep(d);
        f.cut.store(false, Ordering::Relaxed);
    })
}

/// One run of a mirrored domain with a lookahead: the home framework (this test's) is a
/// closed loop, what it publishes computed from what it read, so one answer taken a step
/// early or late changes every value after it; each step is compared with the same loop
/// computed here with a K-step delay on the connection.
struct LookaheadRun<'a> {
    home: &'a str,
    away: &'a str,
    k: u64,
    steps: u64,
    /// The home framework's step timeout.
    timeout: Duration,
}

/// What a [`LookaheadRun`] read: (x, y) of each step, and the steps that timed out with the
/// connections they waited for.
struct LookaheadRead {
    gw_home: Proc,
    gw_away: Away,
    read: Vec<(f64, f64)>,
    timed_out: Vec<(u64, Vec<String>)>,
}

/// The mirror's gateway: in a slot that a test may empty (kill it) and fill again (start
/// another) while the run goes on.
type Away = Arc<std::sync::Mutex<Option<Proc>>>;

fn dump_away(away: &Away) -> String {
    away.lock().unwrap().as_ref().map_or_else(|| "(no mirror gateway now)".into(), Proc::dump)
}

impl LookaheadRead {
    fn dump(&self) -> String {
        format!("{}\n{}", self.gw_home.dump(), dump_away(&self.gw_away))
    }

    /// Whether step `step` (1, 2, ...) read what a run with a K-step delay reads there, given
    /// what the steps before it read.
    fn delayed(&self, k: u64, step: u64) -> bool {
        let i = (step - 1) as usize;
        let before = if i == 0 { 0.0 } else { self.read[i - 1].1 };
        let y = if step > k { self.read[i - k as usize].0 + 1.0 } else { 0.0 };
        self.read[i] == (step as f64 + 0.5 * before, y)
    }
}

impl LookaheadRun<'_> {
    /// Runs it with the gateways `gateways` starts (home, mirror) once the home framework is
    /// up, and checks every step against a K-step delay; returns the gateways, for what the
    /// caller checks next.
    fn check(&self, gateways: impl FnOnce() -> (Proc, Proc)) -> (Proc, Proc) {
        self.check_with(gateways, |_| {})
    }

    /// [`LookaheadRun::check`], calling `before(n)` before each step n (a fault to make).
    fn check_with(&self, gateways: impl FnOnce() -> (Proc, Proc), before: impl FnMut(u64)) -> (Proc, Proc) {
        let away: Away = Arc::default();
        let slot = away.clone();
        let r = self.run_with(
            || {
                let (home, mirror) = gateways();
                *slot.lock().unwrap() = Some(mirror);
                home
            },
            &away,
            before,
        );
        assert!(r.timed_out.is_empty(), "steps timed out: {:?}\n{}", r.timed_out, r.dump());
        for step in 1..=self.steps {
            assert!(
                r.delayed(self.k, step),
                "step {step} read {:?}: not what a run with a {}-step delay reads\n{}",
                r.read[step as usize - 1],
                self.k,
                r.dump()
            );
        }
        let mirror = r.gw_away.lock().unwrap().take().expect("the mirror's gateway");
        (r.gw_home, mirror)
    }

    /// The run itself, `before(n)` called before each step n: the home framework (the test's)
    /// publishes x = n + y/2, y read at the step before; the mirror side's component answers
    /// y = x + 1.
    /// `gateways` starts the home gateway (returned) and puts the mirror's in `away`.
    fn run_with(&self, gateways: impl FnOnce() -> Proc, away: &Away, mut before: impl FnMut(u64)) -> LookaheadRead {
        let model = tutti_core::ddf::load(tutti_test_support::repo_root().join(DDF)).unwrap();
        let opts = tutti_core::shm::FrameworkOptions {
            namespace: self.home.to_string(),
            timeout: self.timeout,
            ..Default::default()
        };
        let mut fw = tutti_core::shm::Framework::create(&model, &opts).expect("framework");
        let gw_home = gateways();
        let dump = || format!("{}\n{}", gw_home.dump(), dump_away(away));
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let away_ns = self.away.to_string();
        let component = thread::spawn(move || {
            // Connected again whenever its domain goes (a mirror killed and started again).
            while !s.load(Ordering::Acquire) {
                let mut p = connect(&away_ns, "gw_sync");
                // A writer from the start, so that the mirror's first step waits for its answer
                // too (a connection is otherwise a writer from its first lock).
                if p.publish_gate().is_err() {
                    continue;
                }
                while !s.load(Ordering::Acquire) {
                    match p.subscribe_lock() {
                        Ok(_) => {}
                        Err(tutti_core::shm::ShmError::Timeout { .. }) => continue,
                        Err(_) => break,
                    }
                    let x = f64_at(p.snapshot(), 0);
                    if p.publish_lock().is_ok() {
                        p.stage("y", &(x + 1.0).to_ne_bytes()).unwrap();
                        if p.commit().is_err() {
                            break;
                        }
                    }
                }
            }
        });
        // Ready when the mirror side's component waits for its first step, the home gateway
        // answers for the mirror's writer, and it has the mirror's PUBLISH reader.
        let ready = tutti_test_support::poll_for(SECS(60), || {
            let away_ok = tutti_core::shm::segment::Segment::open(self.away, "gw_sync").is_ok_and(|seg| {
                seg.status().connections.iter().any(|c| c.name == "test-component" && c.sync_reader && c.writer)
            });
            let conns = status(self.home, "gw_sync").connections;
            let home_ok =
                conns.iter().any(|c| c.remote && c.writer) && conns.iter().any(|c| c.observer && c.dds_readers >= 1);
            (away_ok && home_ok).then_some(())
        });
        assert!(ready.is_some(), "the two sides never joined\n{}", dump());
        let d = fw.domains.iter_mut().find(|d| d.info().name == "gw_sync").unwrap();
        let (mut read, mut timed_out) = (Vec::new(), Vec::new());
        let mut y = 0.0;
        for step in 1..=self.steps {
            before(step);
            let x = step as f64 + 0.5 * y;
            let r =
                d.step(&x.to_ne_bytes(), step as f64 * 0.01).unwrap_or_else(|e| panic!("step {step}: {e}\n{}", dump()));
            assert_eq!(r.step, step);
            if r.timed_out > 0 {
                timed_out.push((step, d.timed_out_on().to_vec()));
            }
            y = f64_at(d.subscribe(), 0);
            read.push((x, y));
        }
        stop.store(true, Ordering::Release);
        drop(fw);
        component.join().unwrap();
        LookaheadRead { gw_home, gw_away: away.clone(), read, timed_out }
    }
}

per_engine!(
    the_mirror_discovers_across_network_namespaces_by_multicast,
    a_lookahead_across_a_slow_link_keeps_every_value_of_a_k_step_delay,
    a_lookahead_through_a_lossy_reordering_link_that_is_cut_loses_no_step,
    a_lookahead_waits_out_a_five_second_cut_within_its_lease,
    a_cut_longer_than_the_step_timeout_is_reported_and_the_run_goes_on,
    a_killed_site_that_starts_again_rejoins_at_a_step_boundary,
    a_mirror_that_joins_a_running_home_starts_at_its_current_step,
);

// The gateway on the other side is the peer: these run on Zenoh too, both gateways meeting at
// a router (docs/gateway.md, "Zenoh").
per_any_engine!(
    a_run_across_sites_is_saved_and_restored_with_the_answers_on_their_way,
    a_component_on_the_mirror_side_drives_an_asynchronous_domain,
    a_component_on_the_mirror_side_takes_part_in_lock_step,
    a_mirrored_domain_with_a_lookahead_answers_each_step_k_steps_later,
);
