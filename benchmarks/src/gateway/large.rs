//! The gateway on the large DDF: its start-up, the discovery of its topics and its memory.

use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::time::{Duration, Instant};

use anyhow::{bail, Context as _};
use tutti_core::shm::{Framework, FrameworkOptions};
use tutti_gateway::EngineKind;
use tutti_host::{ChildProcess, SIGINT};

use super::figures::Large;
use super::{Bench, Slot};
use crate::load_ddf;

impl Bench<'_> {
    /// The gateway on the large DDF, as its figure says: a framework hosts every domain of
    /// it, the gateway bridges them all, and a DDS peer (a Cyclone participant of this
    /// process) discovers every topic the gateway bridges. Returns the time until the gateway
    /// is up, the time until the peer has seen every topic, the topics bridged and the RSS.
    pub(super) fn large(&self, e: EngineKind, slot: &Slot) -> anyhow::Result<Large> {
        let model = load_ddf(&self.args.large).map_err(|f| f.error)?;
        let opts = FrameworkOptions { namespace: slot.ns.clone(), ..Default::default() };
        let _framework = Framework::create(&model, &opts).context("hosting the large DDF's domains")?;
        let peer_cfg = tutti_gateway::engine::EngineConfig {
            domain_id: slot.dom,
            interfaces: vec![std::net::Ipv4Addr::LOCALHOST.into()],
            peers: Vec::new(),
            node_name: "bench_peer".into(),
            node_namespace: "/".into(),
            participant_lease: None,
            zenoh_connect: self.zenoh_router.iter().cloned().collect(),
            zenoh_listen: Vec::new(),
            security: None,
        };
        // The peer speaks what the gateway speaks: Zenoh to the Zenoh engine, else DDS.
        let peer_engine = if e == EngineKind::Zenoh { e } else { EngineKind::Cyclone };
        let peer = tutti_gateway::engine::open(peer_engine, &peer_cfg).context("the peer")?;
        let t = Instant::now();
        let ddf = self.args.large.to_string_lossy();
        let mut cmd = self.tutti(e, slot, &["gateway", &ddf, "--interface", "127.0.0.1", "--status-every", "1h"]);
        cmd.stderr(Stdio::piped());
        let mut kid = ChildProcess::spawn("the gateway on the large DDF", cmd, None)?
            .stop_on_drop(Some(SIGINT), Duration::from_secs(3));
        let stderr = kid.child.stderr.take();
        let mut up = None;
        if let Some(s) = stderr {
            let mut lines = BufReader::new(s).lines().map_while(Result::ok);
            for line in lines.by_ref() {
                if let Some(rest) = line.split("tutti gateway: up: ").nth(1) {
                    up = Some((t.elapsed(), rest.to_string()));
                    break;
                }
            }
            // Keep the pipe drained: a gateway blocked on stderr would stall.
            std::thread::spawn(move || for _ in lines {});
        }
        let (up, line) = up.context("the gateway on the large DDF did not start")?;
        // "B of D domains bridged, T topics, ..."
        let number = |after: &str| -> Option<usize> {
            let words: Vec<&str> = line.split([' ', ',']).filter(|w| !w.is_empty()).collect();
            let i = words.iter().position(|w| *w == after)?;
            words.get(i.checked_sub(1)?)?.parse().ok()
        };
        let bridged = line.split(' ').next().and_then(|w| w.parse::<usize>().ok()).unwrap_or(0);
        let topics = number("topics").context("the gateway's up line names no topic count")?;
        if bridged != model.domains.len() {
            bail!("the gateway bridged {bridged} of {} domains: {line}", model.domains.len());
        }
        // Every topic the gateway bridges, as a DDS peer discovers it.
        let deadline = Instant::now() + Duration::from_secs(300);
        let discovered = loop {
            let remote = peer.remote();
            let seen: std::collections::BTreeSet<&String> =
                remote.writers.keys().chain(remote.readers.keys()).filter(|t| t.starts_with("rt/")).collect();
            if seen.len() >= topics {
                break t.elapsed();
            }
            if Instant::now() > deadline {
                bail!("the DDS peer discovered {} of the gateway's {topics} topics in 300 s", seen.len());
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let rss = rss_kib(kid.pid()).context("the gateway's RSS")?;
        Ok(Large { up, discovered, topics, rss_kib: rss })
    }
}

fn rss_kib(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    s.lines().find_map(|l| l.strip_prefix("VmRSS:")).and_then(|v| v.split_whitespace().next()?.parse().ok())
}
