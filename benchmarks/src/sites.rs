//! `tutti-bench sites`: lock-step between two sites joined by a slow link, with a declared
//! lookahead (docs/run.md, "Sites and lookahead").
//!
//! Two network namespaces joined by a `tutti_test_support::Wire` (a TAP device in each, and
//! threads of this process that copy every frame after `--delay`, each way) stand for two
//! sites. The home site's framework is this process (a synchronous domain stepped as fast as
//! the other site answers, `speed: 0`), with `tutti gateway --lookahead K` in the first
//! namespace; the other site is `tutti gateway --mirror` in the second, and a component of
//! this process that answers every step (y = x + 1). For each K the run makes `--steps`
//! steps and prints the steps per second after the first K (which wait for nothing) next to
//! K / RTT (the issue asks for 80 % of it) and (K + 1) / RTT, the most the link allows: step
//! n + 1 is published once step n has the answer to step n - K, which left K + 1 steps
//! before. The home framework
//! is a closed loop (what it publishes is computed from what it read), and every step's
//! values are compared with the same loop computed with a K-step delay on the connection:
//! the run fails on one that differs.
//!
//! Needs root (network namespaces, TAP devices) and `ip`.

use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context as _};
use serde_json::json;
use tutti_core::parse::parse_duration;
use tutti_core::shm::segment::Segment;
use tutti_core::shm::{ConnectOptions, Framework, FrameworkOptions, Participant};
use tutti_gateway::EngineKind;
use tutti_host::{ChildProcess, SIGINT};
use tutti_test_support::Wire;

use crate::CliResult;

/// Lock-step across a slow link, per lookahead.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  sudo tutti-bench sites\n  sudo tutti-bench sites --delay 5ms --lookahead 0,4,16 --json"
)]
pub struct Args {
    /// The link's delay, each way.
    #[arg(long, default_value = "20ms", value_parser = parse_duration)]
    delay: Duration,
    /// The lookaheads to run, in steps (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "0,1,10,40")]
    lookahead: Vec<u64>,
    /// Steps of each run with a lookahead above 0 (a run with none makes a tenth of them:
    /// each costs a round trip).
    #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(20..))]
    steps: u64,
    /// The engines: on DDS the two gateways find each other by multicast on the wire; on
    /// Zenoh each connects to its site's router (eclipse-zenoh's, `tests/gateway/zenoh_router.py`
    /// run by the repository's `.venv` Python), and the second router to the first.
    #[arg(long, value_delimiter = ',', default_value = "cyclone")]
    engines: Vec<EngineKind>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

/// The share of K / RTT a run must reach.
const TARGET: f64 = 0.8;

const DDF: &str = r#"<?xml version="1.0"?>
<orchestra>
<domain name="site_link">
  <synchronous>yes</synchronous>
  <multiplePublishAllowed>no</multiplePublishAllowed>
  <states>no</states>
  <block name="site_link/Publish"><item name="x"><type>double</type></item></block>
  <block name="site_link/Subscribe"><item name="y"><type>double</type></item></block>
</domain>
</orchestra>
"#;

/// One run's figures.
#[derive(Debug)]
struct Run {
    engine: EngineKind,
    k: u64,
    steps: u64,
    steps_per_s: f64,
    /// (K + 1) / RTT: step n waits for the answer to step n - K, sent when step n - K was
    /// published, which was K + 1 steps before step n + 1 is.
    allowed: f64,
}

pub fn run(a: Args) -> CliResult {
    let dir = std::env::temp_dir().join(format!("tutti-bench-sites-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let ddf = dir.join("sites.ddf");
    std::fs::write(&ddf, DDF).context("writing the benchmark's DDF")?;
    let result = runs(&a, &ddf);
    let _ = std::fs::remove_dir_all(&dir);
    let runs = result?;
    let rtt = 2.0 * a.delay.as_secs_f64();
    if a.json {
        let list: Vec<_> = runs
            .iter()
            .map(|r| {
                json!({
                    "engine": r.engine.name(), "lookahead": r.k, "steps": r.steps,
                    "steps_per_s": r.steps_per_s, "k_over_rtt": r.k as f64 / rtt,
                    "k_plus_1_over_rtt": r.allowed, "share_of_k_plus_1_over_rtt": r.steps_per_s / r.allowed,
                    "met": r.k == 0 || r.steps_per_s >= TARGET * r.k as f64 / rtt,
                    "ms_per_step": 1e3 / r.steps_per_s,
                    "values_equal_k_step_delay": true,
                })
            })
            .collect();
        println!(
            "{}",
            json!({ "delay_each_way_ms": a.delay.as_secs_f64() * 1e3, "target_share": TARGET, "runs": list })
        );
        return Ok(());
    }
    println!(
        "\nLock-step across a link of {:.1} ms each way (RTT {:.1} ms), steps/s after the first K:",
        a.delay.as_secs_f64() * 1e3,
        rtt * 1e3
    );
    println!(
        "{:<8} {:>5} {:>7} {:>10} {:>9} {:>12} {:>8} {:>9}  values",
        "engine", "K", "steps", "steps/s", "K/RTT", "(K+1)/RTT", "share", "per step"
    );
    for r in &runs {
        let target = TARGET * r.k as f64 / rtt;
        let met = match r.k {
            0 => "",
            _ if r.steps_per_s >= target => "  (met: at least 80 % of K/RTT)",
            _ => "  (MISSED: below 80 % of K/RTT)",
        };
        println!(
            "{:<8} {:>5} {:>7} {:>10.1} {:>9.1} {:>12.1} {:>7.0}% {:>7.2}ms  each equal to a {}-step delay{met}",
            r.engine.name(),
            r.k,
            r.steps,
            r.steps_per_s,
            r.k as f64 / rtt,
            r.allowed,
            100.0 * r.steps_per_s / r.allowed,
            1e3 / r.steps_per_s,
            r.k
        );
    }
    Ok(())
}

fn runs(a: &Args, ddf: &Path) -> anyhow::Result<Vec<Run>> {
    let mut out = Vec::new();
    for &engine in &a.engines {
        let wire = Wire::create(&format!("bs{}", &engine.name()[..2]), a.delay)
            .map_err(|e| anyhow!("cannot make the two sites' namespaces (run as root): {e}"))?;
        let _routers = if engine == EngineKind::Zenoh { Some(routers(&wire)?) } else { None };
        for (i, &k) in a.lookahead.iter().enumerate() {
            let steps = if k == 0 { (a.steps / 10).max(20) } else { a.steps };
            eprintln!("{}: K = {k}, {steps} steps ...", engine.name());
            let r = one(&wire, ddf, engine, k, steps, i)?;
            eprintln!("{}: K = {k}: {:.1} steps/s", engine.name(), r.steps_per_s);
            out.push(Run { allowed: (k as f64 + 1.0) / (2.0 * a.delay.as_secs_f64()), ..r });
        }
    }
    Ok(out)
}

/// One run: the two gateways on the two sides of `wire`, the framework and the component of
/// this process.
fn one(wire: &Wire, ddf: &Path, engine: EngineKind, k: u64, steps: u64, i: usize) -> anyhow::Result<Run> {
    let tag = format!("{}{}{i}", std::process::id(), &engine.name()[..2]);
    let (home, away) = (format!("bsites{tag}a"), format!("bsites{tag}b"));
    let dom = 120 + (std::process::id() % 50) as u16 + i as u16;
    let model = tutti_core::ddf::load(ddf)?;
    let opts = FrameworkOptions { namespace: home.clone(), timeout: Duration::from_secs(10), ..Default::default() };
    let mut fw = Framework::create(&model, &opts).context("creating the home framework")?;
    let names = wire.names();
    let la = k.to_string();
    let mut home_args = vec!["--lookahead", &la];
    if k == 0 {
        // Lock-step still needs every step sent (with a lookahead the gateway does it).
        home_args = vec!["--every-step"];
    }
    // The mirror keeps the steps of the lookahead (docs/run.md, "Sites and lookahead").
    let mut away_args = vec!["--mirror", "--timeout", "10s", "--lookahead", &la];
    let routers = [0, 1].map(router_endpoint);
    if engine == EngineKind::Zenoh {
        home_args.extend(["--zenoh-connect", &routers[0]]);
        away_args.extend(["--zenoh-connect", &routers[1]]);
    }
    let _gw_home = gateway(&names[0], Wire::ADDRS[0], engine, ddf, dom, &home, &home_args)?;
    let _gw_away = gateway(&names[1], Wire::ADDRS[1], engine, ddf, dom, &away, &away_args)?;
    let stop = Arc::new(AtomicBool::new(false));
    let s = stop.clone();
    let away_ns = away.clone();
    let component = thread::spawn(move || -> anyhow::Result<()> {
        let opts = ConnectOptions {
            namespace: away_ns,
            name: "bench-component".into(),
            connect_timeout: Duration::from_secs(30),
            timeout: Duration::from_secs(2),
            skip_wait_to_go: true,
            ..Default::default()
        };
        let mut p = Participant::connect("site_link", opts)?;
        p.publish_gate()?;
        while !s.load(Ordering::Acquire) {
            if p.subscribe_lock().is_err() {
                continue;
            }
            let x = f64::from_ne_bytes(p.snapshot()[..8].try_into()?);
            if p.publish_lock().is_ok() {
                p.stage("y", &(x + 1.0).to_ne_bytes())?;
                p.commit()?;
            }
        }
        Ok(())
    });
    let result = (|| {
        wait_ready(&home, &away, k > 0)?;
        let d = fw.domains.iter_mut().next().ok_or_else(|| anyhow!("no domain"))?;
        let mut read = Vec::with_capacity(steps as usize);
        let mut times = Vec::with_capacity(steps as usize);
        let mut y = 0.0;
        // In lock-step the home gateway answers for the mirror from its first answer on: until
        // then the framework steps slowly (warm-up steps, neither timed nor checked).
        let mut from = None;
        let mut step = 0u64;
        while times.len() < steps as usize {
            step += 1;
            let x = step as f64 + 1e-3 * y;
            d.step(&x.to_ne_bytes(), step as f64 * 1e-3).with_context(|| format!("step {step}"))?;
            y = f64::from_ne_bytes(d.subscribe()[..8].try_into()?);
            read.push((x, y));
            if from.is_none() && (k > 0 || y != 0.0) {
                from = Some(read.len() - 1);
            }
            match from {
                Some(_) => times.push(Instant::now()),
                None if step > 2000 => bail!("lock-step: no answer in {step} steps"),
                None => thread::sleep(Duration::from_millis(10)),
            }
        }
        let from = from.unwrap_or(0);
        check_delay(&read, k, from)?;
        let first = (k as usize).min(times.len() - 2);
        let span = times[times.len() - 1].duration_since(times[first]).as_secs_f64();
        let steps_per_s = (times.len() - 1 - first) as f64 / span;
        Ok(Run { engine, k, steps, steps_per_s, allowed: 0.0 })
    })();
    stop.store(true, Ordering::Release);
    drop(fw);
    let _ = component.join();
    result
}

/// `tutti gateway` of engine `e` inside namespace `netns`, on its address `addr`.
fn gateway(
    netns: &str,
    addr: &str,
    e: EngineKind,
    ddf: &Path,
    dom: u16,
    ns: &str,
    extra: &[&str],
) -> anyhow::Result<ChildProcess> {
    let mut cmd = Command::new("ip");
    cmd.args(["netns", "exec", netns]).arg(crate::tutti_exe()?);
    cmd.arg("gateway").arg(ddf).args([
        "--interface",
        addr,
        "--ros-domain-id",
        &dom.to_string(),
        "--dds",
        e.name(),
        "-q",
    ]);
    cmd.args(extra).env("TUTTI_NAMESPACE", ns).env("RUST_LOG", "warn").stdin(Stdio::null());
    Ok(ChildProcess::spawn(&format!("the gateway in {netns}"), cmd, None)?
        .stop_on_drop(Some(SIGINT), Duration::from_secs(5)))
}

/// The endpoint of site `i`'s Zenoh router.
fn router_endpoint(i: usize) -> String {
    format!("tcp/{}:7447", Wire::ADDRS[i])
}

/// The two sites' Zenoh routers (eclipse-zenoh's, run by the repository's `.venv` Python):
/// the second connects to the first.
fn routers(wire: &Wire) -> anyhow::Result<[ChildProcess; 2]> {
    let root = tutti_test_support::repo_root();
    let py = root.join(".venv/bin/python");
    anyhow::ensure!(py.is_file(), "{} is missing: the Zenoh runs need the test command's venv", py.display());
    let start = |i: usize, connect: Option<String>| -> anyhow::Result<ChildProcess> {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", &wire.names()[i]]).arg(&py).arg(root.join("tests/gateway/zenoh_router.py"));
        cmd.args(["--listen", &router_endpoint(i)]).args(connect.iter().flat_map(|c| ["--connect", c.as_str()]));
        cmd.stdin(Stdio::null()).stdout(Stdio::null());
        Ok(ChildProcess::spawn(&format!("the Zenoh router of site {i}"), cmd, None)?
            .stop_on_drop(Some(SIGINT), Duration::from_secs(3)))
    };
    let first = start(0, None)?;
    let second = start(1, Some(router_endpoint(0)))?;
    // The gateways connect to them, retrying until they listen.
    Ok([first, second])
}

/// Waits until the component waits for the mirror's first step as a writer, the home gateway
/// has the mirror's PUBLISH reader and (with a lookahead) answers for the mirror's writer.
fn wait_ready(home: &str, away: &str, lookahead: bool) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let away_ok = Segment::open(away, "site_link").is_ok_and(|seg| {
            seg.status().connections.iter().any(|c| c.name == "bench-component" && c.sync_reader && c.writer)
        });
        let home_ok = Segment::open(home, "site_link").is_ok_and(|seg| {
            let conns = seg.status().connections;
            (!lookahead || conns.iter().any(|c| c.remote && c.writer))
                && conns.iter().any(|c| c.observer && c.dds_readers >= 1)
        });
        if away_ok && home_ok {
            return Ok(());
        }
        if Instant::now() > deadline {
            bail!("the two sites did not join within 60 s (mirror side ready: {away_ok}, home side: {home_ok})");
        }
        thread::sleep(Duration::from_millis(50));
    }
}

/// Fails unless every step's (x, y) from index `from` on is the one of the same loop with a
/// `k`-step delay: x of step n computed from the y read at step n - 1, and y of step n the
/// answer to step n - k (none before step k + 1).
fn check_delay(read: &[(f64, f64)], k: u64, from: usize) -> anyhow::Result<()> {
    let k = k as usize;
    for (i, &(x_got, y_got)) in read.iter().enumerate().skip(from) {
        let before = if i == 0 { 0.0 } else { read[i - 1].1 };
        let x = (i + 1) as f64 + 1e-3 * before;
        let y = if i >= k { read[i - k].0 + 1.0 } else { 0.0 };
        if (x_got, y_got) != (x, y) {
            bail!("step {}: read ({x_got}, {y_got}), a run with a {k}-step delay reads ({x}, {y})", i + 1);
        }
    }
    Ok(())
}
