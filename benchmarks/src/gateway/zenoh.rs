//! Zenoh without tutti: the router the Zenoh engine's runs meet at, and Zenoh's own
//! ping-pong (the loop of `z_ping` and `z_pong` of Zenoh's examples, with the `zenoh` crate
//! the engine uses), on the placement's cores.
//!
//! Every session here is configured as the engine's: a peer that connects to the router and
//! listens on loopback, no multicast scouting (rmw_zenoh's defaults, docs/gateway.md,
//! "Zenoh"), so that the ping-pong and the gateway's round trip take the same path.

use std::process::Stdio;
use std::time::{Duration, Instant};

use anyhow::{bail, Context as _};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use super::figures::Rtt;
use super::processes::{pin_self, start, Cpus};
use super::{Args, Bench, PATIENCE};
use crate::CliResult;

const PING: &str = "tutti_bench/ping";
const PONG: &str = "tutti_bench/pong";
/// The payload: the gateway's sample of the benchmark's set (the 4-byte CDR header, step,
/// simulated time and 8 doubles).
const SIZE: usize = 4 + 8 + 8 + 8 * super::ITEMS;

/// A Zenoh session in `mode` on loopback, multicast scouting off, connected to `connect`.
fn open(mode: &str, connect: Option<&str>) -> anyhow::Result<zenoh::Session> {
    let mut c = zenoh::Config::default();
    let mut set =
        |key: &str, value: String| c.insert_json5(key, &value).map_err(|e| anyhow::anyhow!("Zenoh setting {key}: {e}"));
    set("mode", format!(r#""{mode}""#))?;
    set("listen/endpoints", r#"["tcp/127.0.0.1:0"]"#.into())?;
    set("scouting/multicast/enabled", "false".into())?;
    if let Some(endpoint) = connect {
        set("connect/endpoints", format!(r#"["{endpoint}"]"#))?;
    }
    zenoh::open(c).wait().map_err(|e| anyhow::anyhow!("opening a Zenoh {mode}: {e}"))
}

/// A session as the engine's, connected to the router at `endpoint`.
fn session(endpoint: &str) -> anyhow::Result<zenoh::Session> {
    open("peer", Some(endpoint))
}

/// The router of the run (as `rmw_zenohd`), in this process, and its endpoint.
pub(super) fn router() -> anyhow::Result<(zenoh::Session, String)> {
    let r = open("router", None)?;
    let locators = r.info().locators().wait();
    let endpoint = locators.iter().map(|l| l.to_string()).find(|l| l.starts_with("tcp/127.0.0.1:"));
    let endpoint = endpoint.context("the Zenoh router has no loopback TCP endpoint")?;
    Ok((r, endpoint))
}

/// A publisher on `key` as z_ping's and z_pong's: express, blocking when congested.
fn publisher(s: &zenoh::Session, key: &'static str) -> anyhow::Result<zenoh::pubsub::Publisher<'static>> {
    let p = s.declare_publisher(key).congestion_control(CongestionControl::Block).express(true).wait();
    p.map_err(|e| anyhow::anyhow!("the publisher on {key}: {e}"))
}

/// `--zenoh-pong`: answers every ping with its payload, as `z_pong` does, until stopped.
pub(super) fn pong(args: &Args) -> CliResult {
    let endpoint = args.zenoh_connect.as_deref().context("--zenoh-pong needs --zenoh-connect")?;
    let s = session(endpoint)?;
    let publisher = publisher(&s, PONG)?;
    let _sub = s
        .declare_subscriber(PING)
        .callback(move |sample| {
            let _ = publisher.put(sample.payload().clone()).wait();
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("the ping subscriber: {e}"))?;
    let stop = tutti_exit::stop_flag()?;
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok(())
}

impl Bench<'_> {
    /// Zenoh's own ping-pong: this process pings on the gateway's CPU (where the gateway's
    /// engine runs), the pong runs on the peer's, `--samples` round trips back to back after
    /// those that find the path.
    pub(super) fn zenoh_ping_pong(&mut self, cpus: Cpus) -> anyhow::Result<Rtt> {
        let endpoint = self.zenoh_router.clone().context("no Zenoh router (the zenoh engine is not in --engines)")?;
        let slot = self.slot();
        let mut cmd = std::process::Command::new(&self.bench_exe);
        cmd.args(["gateway", "--zenoh-pong", "--zenoh-connect", &endpoint])
            .env("TUTTI_NAMESPACE", &slot.ns)
            .stdin(Stdio::null());
        let mut pong = start("Zenoh's pong", cmd, cpus.peer)?;
        pin_self(cpus.gw);
        let r = ping(&endpoint, self.args.samples);
        pin_self(cpus.fw);
        if let Some(status) = pong.poll() {
            bail!("Zenoh's pong exited ({status})");
        }
        r
    }
}

/// `z_ping`'s loop: put, then wait for the pong; round trips that take over a second are
/// lost.
fn ping(endpoint: &str, samples: u32) -> anyhow::Result<Rtt> {
    let s = session(endpoint)?;
    let sub = s.declare_subscriber(PONG).wait().map_err(|e| anyhow::anyhow!("the pong subscriber: {e}"))?;
    let publisher = publisher(&s, PING)?;
    let data: Vec<u8> = (0..SIZE).map(|i| (i % 10) as u8).collect();
    let put = || publisher.put(data.clone()).wait().map_err(|e| anyhow::anyhow!("a ping: {e}"));
    // Until the path works (the pong's session found, its subscriber declared), then a
    // second's warm-up, as z_ping's default.
    let end = Instant::now() + PATIENCE;
    loop {
        put()?;
        if sub.recv_timeout(Duration::from_millis(100)).ok().flatten().is_some() {
            break;
        }
        if Instant::now() > end {
            bail!("no pong within {} s", PATIENCE.as_secs());
        }
    }
    let warm = Instant::now();
    while warm.elapsed() < Duration::from_secs(1) {
        put()?;
        let _ = sub.recv_timeout(Duration::from_secs(1));
    }
    let (mut times, mut lost) = (Vec::with_capacity(samples as usize), 0);
    for _ in 0..samples {
        let t = Instant::now();
        put()?;
        match sub.recv_timeout(Duration::from_secs(1)) {
            Ok(Some(_)) => times.push(t.elapsed().as_secs_f64() * 1e6),
            _ => lost += 1,
        }
    }
    Rtt::of(times, lost)
}
