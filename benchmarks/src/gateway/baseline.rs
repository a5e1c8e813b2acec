//! DDS without tutti, on the placement's cores: Cyclone's ddsperf and a Fast DDS ping-pong.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{bail, Context as _};
use tutti_core::shm::os;

use super::figures::{noted, Fig, Peers, Rtt};
use super::processes::{start, Cpus};
use super::Bench;
use crate::nearest_rank;

const LOOPBACK: &str = "<CycloneDDS xmlns=\"https://cdds.io/config\"><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><Peers><Peer address=\"127.0.0.1\"/></Peers><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex></Discovery></Domain></CycloneDDS>";
/// The Fast DDS ping-pong, built with g++ on first use.
const FASTDDS_SRC: &str = include_str!("fastdds_pingpong.cpp");

impl Bench<'_> {
    /// ddsperf (back to back and paced), Fast DDS and Zenoh's ping-pong on the placement's
    /// cores.
    pub(super) fn peers(&mut self, cpus: Cpus, fastdds: &Fig<PathBuf>) -> Peers {
        let at = |what: &str| format!("{}: {what}", cpus.key);
        let ddsperf = noted(self.ddsperf(cpus, None, false), &at("ddsperf"));
        let ddsperf_paced = noted(self.ddsperf(cpus, Some("1kHz"), false), &at("ddsperf 1kHz"));
        let ddsperf_waitset = noted(self.ddsperf(cpus, None, true), &at("ddsperf ping waitset"));
        let fastdds = match fastdds {
            Ok(bin) => noted(self.fastdds(bin, cpus), &at("fastdds")),
            Err(why) => Err(why.clone()),
        };
        let zenoh = match self.zenoh_router {
            Some(_) => noted(self.zenoh_ping_pong(cpus), &at("Zenoh ping-pong")),
            None => Err("the zenoh engine is not in --engines".to_string()),
        };
        Peers { ddsperf, ddsperf_paced, ddsperf_waitset, fastdds, zenoh }
    }

    /// ddsperf ping-pong, back to back (`rate` None: a ping as soon as the pong is in) or at
    /// a rate ("1kHz"), with samples of the gateway's size (`size 80`: the 16 header bytes and
    /// the 8 doubles); it prints half the round trip. `waitset`: the ping waits for each pong
    /// on a thread of its own (ddsperf's `ping waitset`) rather than writing the next ping from
    /// the pong's data-available listener, on the receive thread (its default).
    pub(super) fn ddsperf(&mut self, cpus: Cpus, rate: Option<&str>, waitset: bool) -> anyhow::Result<Rtt> {
        let dom = self.slot().dom.to_string();
        let mut pong = Command::new("ddsperf");
        pong.args(["-i", &dom, "-D8", "pong"]).env("CYCLONEDDS_URI", LOOPBACK).stdout(Stdio::null());
        let mut ping = Command::new("ddsperf");
        ping.args(["-i", &dom, "-D5", "-Qminmatch:1", "-Qinitwait:5", "ping"])
            .args(rate)
            .args(waitset.then_some("waitset"))
            .args(["size", "80"])
            .env("CYCLONEDDS_URI", LOOPBACK);
        if let Some(ks) = &self.secured {
            // Authentication takes a handshake per pair of participants: more time to match.
            pong.args(["-D", "15"]);
            ping.args(["-Qinitwait:10"]);
            super::security::secured_ddsperf(&mut pong, LOOPBACK, ks)?;
            super::security::secured_ddsperf(&mut ping, LOOPBACK, ks)?;
        }
        let out = ping_pong("ddsperf", pong, ping, cpus).context("apt-get install -y cyclonedds-tools")?;
        let mut p50s = Vec::new();
        let mut p99s = Vec::new();
        for line in out.lines().filter(|l| l.contains(" 50% ")) {
            let num = |key: &str| -> Option<f64> { line.split(key).nth(1)?.split("us").next()?.trim().parse().ok() };
            if let (Some(a), Some(b)) = (num(" 50% "), num(" 99% ")) {
                p50s.push(2.0 * a);
                p99s.push(2.0 * b);
            }
        }
        if p50s.is_empty() {
            bail!("no ddsperf output (apt-get install -y cyclonedds-tools)");
        }
        p50s.sort_by(f64::total_cmp);
        p99s.sort_by(f64::total_cmp);
        // The median of its per-second lines.
        Ok(Rtt { p50: nearest_rank(&p50s, 0.5), p99: nearest_rank(&p99s, 0.5), lost: 0 })
    }

    /// The Fast DDS ping-pong program, built on first use and kept next to `tutti`
    /// (`bench-cache/`, keyed by its source), else in the scratch directory.
    pub(super) fn fastdds_program(&self) -> anyhow::Result<PathBuf> {
        let mut h = DefaultHasher::new();
        FASTDDS_SRC.hash(&mut h);
        let name = format!("fastdds_pingpong-{:016x}", h.finish());
        let cache = self
            .exe
            .parent()
            .map(|d| d.join("bench-cache"))
            .filter(|d| std::fs::create_dir_all(d).is_ok())
            .unwrap_or_else(|| self.dir.clone());
        let bin = cache.join(&name);
        if bin.exists() {
            return Ok(bin);
        }
        let src = self.dir.join("fastdds_pingpong.cpp");
        std::fs::write(&src, FASTDDS_SRC).context("writing the Fast DDS ping-pong")?;
        let tmp = cache.join(format!("{name}.{}", std::process::id()));
        let out = Command::new("g++")
            .args(["-std=c++11", "-O2", "-o"])
            .arg(&tmp)
            .arg(&src)
            .args(["-lfastrtps", "-lfastcdr"])
            .output();
        match out {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!("g++ not found: apt-get install -y g++"),
            Err(e) => return Err(e).context("running g++"),
            Ok(o) if !o.status.success() => {
                let err = String::from_utf8_lossy(&o.stderr);
                let first = err.lines().find(|l| l.contains("error")).unwrap_or("g++ failed");
                bail!("building against libfastrtps failed (apt-get install -y libfastrtps-dev): {first}");
            }
            Ok(_) => {}
        }
        std::fs::rename(&tmp, &bin).context("caching the Fast DDS ping-pong")?;
        Ok(bin)
    }

    /// The Fast DDS ping-pong (UDP on loopback, samples as large as the gateway's).
    fn fastdds(&mut self, bin: &Path, cpus: Cpus) -> anyhow::Result<Rtt> {
        let dom = self.slot().dom.to_string();
        let mut pong = Command::new(bin);
        pong.args([&dom, "pong"]).stdout(Stdio::null());
        let mut ping = Command::new(bin);
        ping.args([&dom, "ping", &self.args.samples.to_string()]);
        let out = ping_pong("fastdds", pong, ping, cpus)?;
        let line = out.lines().find(|l| l.starts_with("rtt_us")).context("no output from the Fast DDS ping")?;
        let num = |key: &str| -> Option<f64> {
            line.split_whitespace().find_map(|w| w.strip_prefix(key)).and_then(|v| v.parse().ok())
        };
        match (num("p50="), num("p99="), num("lost=")) {
            (Some(p50), Some(p99), Some(lost)) => Ok(Rtt { p50, p99, lost: lost as u32 }),
            _ => bail!("unexpected output from the Fast DDS ping: {line}"),
        }
    }
}

/// Runs `pong` in the background and `ping` to its end, on the placement's ping-pong CPUs;
/// returns what ping printed.
fn ping_pong(name: &str, mut pong: Command, mut ping: Command, cpus: Cpus) -> anyhow::Result<String> {
    let (ping_cpu, pong_cpu) = cpus.ping_pong();
    pong.stdin(Stdio::null()).stderr(Stdio::null());
    let _pong = start(&format!("{name} pong"), pong, pong_cpu)?;
    ping.stdin(Stdio::null()).stderr(Stdio::null());
    os::die_with_parent_on_spawn(&mut ping, Some(ping_cpu));
    let out = ping.output().with_context(|| format!("running {name}"))?;
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}
