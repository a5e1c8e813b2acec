//! Two gateways, two namespaces (two "machines"): the home gateway bridges a framework's
//! domains to DDS (or Zenoh); the `--mirror` gateway hosts local copies fed from it. A component on
//! the mirror side reads the PUBLISH set and writes the SUBSCRIBE set of the framework on
//! the home side, asynchronously and in lock-step.

use crate::gateway;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use gateway::*;

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
    let run = LookaheadRun { home: &home, away: &away, k, steps: 300 };
    let (gw_home, _gw_away) =
        run.check(|| (e.gateway(DDF, dom, &home, &args), e.gateway(DDF, dom, &away, &["--mirror", "--timeout", "5s"])));
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
    let [a, b] = tutti_test_support::Wire::ADDRS;
    let names = wire.names().clone();
    let run = LookaheadRun { home: &home, away: &away, k: 10, steps: 200 };
    let (gw_home, gw_away) = run.check(|| {
        (
            netns_gateway((&names[0], a), e, DDF, dom, &home, &["--lookahead", "10"], &[]),
            netns_gateway((&names[1], b), e, DDF, dom, &away, &["--mirror", "--timeout", "5s"], &[]),
        )
    });
    assert_eq!(counter(&gw_home, "late"), 0, "{}\n{}", gw_home.dump(), gw_away.dump());
    assert!(wire.counts().0 > 0, "nothing crossed the wire");
}

/// Through a link that loses 5 % of the frames each way and holds 5 % back by 3 ms (so that
/// later ones overtake them), and is cut for 0.5 s in the middle of the run: the run waits
/// for the link and goes on, and no step is lost, repeated or taken out of order.
fn a_lookahead_through_a_lossy_reordering_link_that_is_cut_loses_no_step(e: Eng) {
    let Some(wire) = tutti_test_support::require(
        "network namespaces and TAP devices (root, `ip` of iproute2, /dev/net/tun)",
        tutti_test_support::Wire::create(&format!("lf{}", &e.name[..2]), Duration::from_millis(5)),
    ) else {
        return;
    };
    let f = wire.faults();
    f.loss_ppm.store(50_000, Ordering::Relaxed);
    f.reorder_ppm.store(50_000, Ordering::Relaxed);
    f.reorder_us.store(3_000, Ordering::Relaxed);
    let (dom, home, away) = (e.dom(120), e.ns("gwtest120a"), e.ns("gwtest120b"));
    let [a, b] = tutti_test_support::Wire::ADDRS;
    let names = wire.names().clone();
    let run = LookaheadRun { home: &home, away: &away, k: 4, steps: 400 };
    let mut mend = None;
    let (gw_home, gw_away) = run.check_with(
        || {
            (
                netns_gateway((&names[0], a), e, DDF, dom, &home, &["--lookahead", "4"], &[]),
                netns_gateway((&names[1], b), e, DDF, dom, &away, &["--mirror", "--timeout", "5s"], &[]),
            )
        },
        |step| {
            if step == 150 {
                // Cut for 0.5 s: the framework, at most 4 steps ahead, waits for the link
                // meanwhile (in its step, so another thread joins the wire again).
                f.cut.store(true, Ordering::Relaxed);
                let f = f.clone();
                mend = Some(thread::spawn(move || {
                    thread::sleep(Duration::from_millis(500));
                    f.cut.store(false, Ordering::Relaxed);
                }));
            }
        },
    );
    mend.expect("the link was cut").join().unwrap();
    let (copied, dropped) = wire.counts();
    assert!(dropped > 0 && copied > 0, "the wire lost nothing ({copied} copied)");
    assert_eq!(counter(&gw_home, "late"), 0, "{}\n{}", gw_home.dump(), gw_away.dump());
    assert_eq!(counter(&gw_home, "lapsed"), 0, "{}\n{}", gw_home.dump(), gw_away.dump());
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
}

impl LookaheadRun<'_> {
    /// Runs it with the gateways `gateways` starts (home, mirror) once the home framework is
    /// up; returns them, for what the caller checks next.
    fn check(&self, gateways: impl FnOnce() -> (Proc, Proc)) -> (Proc, Proc) {
        self.check_with(gateways, |_| {})
    }

    /// [`LookaheadRun::check`], calling `before(n)` before each step n (a fault to make).
    fn check_with(&self, gateways: impl FnOnce() -> (Proc, Proc), mut before: impl FnMut(u64)) -> (Proc, Proc) {
        let (k, steps) = (self.k, self.steps);
        let model = tutti_core::ddf::load(tutti_test_support::repo_root().join(DDF)).unwrap();
        let opts = tutti_core::shm::FrameworkOptions {
            namespace: self.home.to_string(),
            timeout: Duration::from_secs(5),
            ..Default::default()
        };
        let mut fw = tutti_core::shm::Framework::create(&model, &opts).expect("framework");
        let (gw_home, gw_away) = gateways();
        let dump = || format!("{}\n{}", gw_home.dump(), gw_away.dump());
        // The mirror side's component: y = x + 1 at every step.
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let away_ns = self.away.to_string();
        let component = thread::spawn(move || {
            let mut p = connect(&away_ns, "gw_sync");
            // A writer from the start, so that the mirror's first step waits for its answer
            // too (a connection is otherwise a writer from its first lock).
            p.publish_gate().unwrap();
            while !s.load(Ordering::Acquire) {
                if p.subscribe_lock().is_err() {
                    continue;
                }
                let x = f64_at(p.snapshot(), 0);
                if p.publish_lock().is_ok() {
                    p.stage("y", &(x + 1.0).to_ne_bytes()).unwrap();
                    p.commit().unwrap();
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
        let mut read = Vec::new();
        let mut y = 0.0;
        for step in 1..=steps {
            before(step);
            let x = step as f64 + 0.5 * y;
            let r =
                d.step(&x.to_ne_bytes(), step as f64 * 0.01).unwrap_or_else(|e| panic!("step {step}: {e}\n{}", dump()));
            assert_eq!(r.step, step);
            y = f64_at(d.subscribe(), 0);
            read.push((x, y));
        }
        stop.store(true, Ordering::Release);
        drop(fw);
        component.join().unwrap();
        // The same loop with a K-step delay on the connection.
        let (mut xs, mut y) = (Vec::new(), 0.0);
        for (i, &(x_got, y_got)) in read.iter().enumerate() {
            let step = i as u64 + 1;
            let x = step as f64 + 0.5 * y;
            xs.push(x);
            y = if step > k { xs[(step - k - 1) as usize] + 1.0 } else { 0.0 };
            assert_eq!((x_got, y_got), (x, y), "step {step} differs from a run with a {k}-step delay\n{}", dump());
        }
        (gw_home, gw_away)
    }
}

per_engine!(
    the_mirror_discovers_across_network_namespaces_by_multicast,
    a_lookahead_across_a_slow_link_keeps_every_value_of_a_k_step_delay,
    a_lookahead_through_a_lossy_reordering_link_that_is_cut_loses_no_step,
);

// The gateway on the other side is the peer: these run on Zenoh too, both gateways meeting at
// a router (docs/gateway.md, "Zenoh").
per_any_engine!(
    a_component_on_the_mirror_side_drives_an_asynchronous_domain,
    a_component_on_the_mirror_side_takes_part_in_lock_step,
    a_mirrored_domain_with_a_lookahead_answers_each_step_k_steps_later,
);
