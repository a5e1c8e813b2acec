//! The figures through the gateway: round trips, throughput each way, the synchronous set
//! and lock-step, and the engine alone on the same paths.

use std::time::{Duration, Instant};

use anyhow::bail;
use tutti_core::shm::DomainHost;
use tutti_gateway::EngineKind;

use super::figures::{rate, LockStep, Rtt};
use super::modes::{peer_opts, sink_result};
use super::processes::{check_alive, fill, first_item, pin_self, Cpus, Gw};
use super::{Bench, GatewayMode, ITEMS, PATIENCE};
use crate::peers::Received;

impl Bench<'_> {
    /// The gateway round trip back to back, then paced at 1 kHz (same processes).
    pub(super) fn round_trip(&mut self, e: EngineKind, cpus: Cpus, mode: GatewayMode) -> anyhow::Result<(Rtt, Rtt)> {
        let slot = self.slot();
        let mut fw = self.framework(&slot, false, cpus)?;
        let host = &mut fw.domains[0];
        let mut gw = self.start_gateway(e, &slot, false, cpus, mode)?;
        let mut echo = self.echo_peer(e, &slot, false, cpus.peer)?;
        pin_self(cpus.fw);
        let mut data = vec![0u8; ITEMS * 8];
        let mut seq = 0f64;
        let mut send = |host: &mut DomainHost, gw: &mut Gw, seq: f64| {
            fill(&mut data, seq);
            host.publish_step(&data, seq)?;
            gw.published(host, seq, &data, false);
            anyhow::Ok(())
        };
        let back = |host: &mut DomainHost| host.read_subscribe().map_or(f64::NAN, first_item);
        // Until the echo path works end to end.
        let end = Instant::now() + PATIENCE;
        loop {
            seq += 1.0;
            send(host, &mut gw, seq)?;
            let t = Instant::now();
            while t.elapsed() < Duration::from_millis(100) && back(host) != seq {
                std::hint::spin_loop();
            }
            if back(host) == seq {
                break;
            }
            gw.check()?;
            check_alive(&mut [&mut echo])?;
            if Instant::now() > end {
                bail!("no echo within {} s (is the loopback interface up?)", PATIENCE.as_secs());
            }
        }
        let mut measure = |paced: bool| -> anyhow::Result<Rtt> {
            let mut times = Vec::with_capacity(self.args.samples as usize);
            let mut lost = 0;
            let start = Instant::now();
            for k in 0..self.args.samples {
                if paced {
                    // One round trip per millisecond, as ddsperf's `ping 1kHz`: everything may
                    // go idle between them.
                    let due = start + Duration::from_millis(u64::from(k));
                    if let Some(wait) = due.checked_duration_since(Instant::now()) {
                        std::thread::sleep(wait);
                    }
                }
                seq += 1.0;
                let t = Instant::now();
                send(host, &mut gw, seq)?;
                let mut spins = 0u32;
                while back(host) != seq && t.elapsed() < Duration::from_secs(1) {
                    // Spin, but give the core away between looks: the echo and the gateway may
                    // share it (a pure spinner is only preempted at the end of its time slice).
                    spins += 1;
                    crate::relax(spins >= 16);
                }
                if back(host) == seq {
                    times.push(t.elapsed().as_secs_f64() * 1e6);
                } else {
                    lost += 1;
                    gw.check()?;
                    check_alive(&mut [&mut echo])?;
                }
            }
            Rtt::of(times, lost)
        };
        let hot = measure(false)?;
        let paced = measure(true)?;
        Ok((hot, paced))
    }

    /// The echo pinged by a participant of the same engine in this process (where the
    /// gateway was), with no gateway and no shared memory: what the engine itself costs on
    /// this path. `in_listener`: each ping is written on the receive thread as the last one's
    /// answer arrives (as ddsperf pings), rather than by a thread that waits for the answer.
    pub(super) fn engine_ping(&mut self, e: EngineKind, cpus: Cpus, in_listener: bool) -> anyhow::Result<Rtt> {
        let slot = self.slot();
        let _echo = self.echo_peer(e, &slot, false, cpus.peer)?;
        let (mut opts, d) = peer_opts(&self.async_ddf, slot.dom, e, self.zenoh_router.as_deref())?;
        opts.node_name = "tutti_bench_ping".into();
        pin_self(cpus.gw);
        let t = if in_listener {
            crate::peers::ping_in_listener(&opts, &d, self.args.samples, PATIENCE)
        } else {
            crate::peers::ping(&opts, &d, self.args.samples, PATIENCE)
        };
        pin_self(cpus.fw);
        let t = t?;
        let lost = self.args.samples.saturating_sub(t.len() as u32);
        Rtt::of(t, lost)
    }

    /// shm -> DDS: this process steps flat out (an asynchronous set: publishes, yielding
    /// between steps so a peer on the same core runs; a synchronous one: publishes and
    /// completes each step, the gateway's lock-step reader taking part); the gateway sends
    /// what it sees; a sink in another process counts what arrives over `--duration`
    /// (for the synchronous set a Cyclone reader with the domain's QoS, checking the steps'
    /// order).
    pub(super) fn outbound(
        &mut self,
        e: EngineKind,
        cpus: Cpus,
        synchronous: bool,
        mode: GatewayMode,
    ) -> anyhow::Result<Received> {
        let slot = self.slot();
        let mut fw = self.framework(&slot, synchronous, cpus)?;
        let host = &mut fw.domains[0];
        pin_self(cpus.fw);
        let mut gw = self.start_gateway(e, &slot, synchronous, cpus, mode)?;
        let ddf = self.ddf(synchronous).to_string_lossy();
        let mut what = vec!["--sink", &ddf, "publish"];
        if synchronous {
            what.push("--ordered");
        }
        // The synchronous set's sink of the rustdds engine's runs reads with Cyclone: a rustdds
        // KEEP_ALL reader acknowledges samples as they arrive and then drops those its reader
        // task has not taken when its cache holds more than 64 (docs/gateway.md, "Not done /
        // known limits"), which would count rustdds' reader, not the gateway, as losing steps.
        let sink_engine = if synchronous && e == EngineKind::Rustdds { EngineKind::Cyclone } else { e };
        let mut sink = self.peer(sink_engine, &slot, cpus.peer, &what)?;
        let mut data = vec![0u8; ITEMS * 8];
        let end = Instant::now() + self.args.duration + PATIENCE + Duration::from_secs(10);
        let mut k = 0u64;
        while sink.poll().is_none() {
            if k % 1024 == 0 {
                gw.check()?;
                if Instant::now() > end {
                    bail!("the sink did not finish");
                }
            }
            k += 1;
            fill(&mut data, k as f64);
            host.publish_step(&data, k as f64)?;
            // Flat out: another step follows at once.
            gw.published(host, k as f64, &data, true);
            if synchronous {
                host.complete_step()?;
            } else {
                std::thread::yield_now();
            }
        }
        gw.flush();
        sink_result(&mut sink)
    }

    /// DDS -> shm: a source writes SUBSCRIBE samples flat out; the commits the gateway makes
    /// in shared memory are counted over `--duration`.
    pub(super) fn inbound(&mut self, e: EngineKind, cpus: Cpus, mode: GatewayMode) -> anyhow::Result<f64> {
        let slot = self.slot();
        let fw = self.framework(&slot, false, cpus)?;
        let host = &fw.domains[0];
        pin_self(cpus.fw);
        let mut gw = self.start_gateway(e, &slot, false, cpus, mode)?;
        let mut source = self.peer(e, &slot, cpus.peer, &["--source", &self.async_ddf.to_string_lossy()])?;
        let commits = || host.status().subscribe_commits;
        let c0 = commits();
        let end = Instant::now() + PATIENCE;
        while commits() < c0 + 100 {
            gw.check()?;
            check_alive(&mut [&mut source])?;
            if Instant::now() > end {
                bail!("no commits from DDS within {} s", PATIENCE.as_secs());
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        let (c1, t) = (commits(), Instant::now());
        std::thread::sleep(self.args.duration);
        Ok((commits() - c1) as f64 / t.elapsed().as_secs_f64())
    }

    /// The same source and a sink on the gateway's and the peer's cores, without the
    /// gateway: the engine's own ceiling.
    pub(super) fn alone(&mut self, e: EngineKind, cpus: Cpus) -> anyhow::Result<f64> {
        let slot = self.slot();
        let ddf = self.async_ddf.to_string_lossy();
        let mut sink = self.peer(e, &slot, cpus.gw, &["--sink", &ddf, "subscribe"])?;
        let _source = self.peer(e, &slot, cpus.peer, &["--source", &ddf])?;
        Ok(rate(&sink_result(&mut sink)?))
    }

    /// Lock-step across DDS: this process steps a synchronous domain flat out; the DDS echo
    /// answers each step through the gateway, whose commit for the step completes it.
    pub(super) fn lock_step(&mut self, e: EngineKind, cpus: Cpus, mode: GatewayMode) -> anyhow::Result<LockStep> {
        let slot = self.slot();
        let mut fw = self.framework(&slot, true, cpus)?;
        let host = &mut fw.domains[0];
        pin_self(cpus.fw);
        let mut gw = self.start_gateway(e, &slot, true, cpus, mode)?;
        let mut echo = self.echo_peer(e, &slot, true, cpus.peer)?;
        let mut data = vec![0u8; ITEMS * 8];
        let mut k = 0u64;
        // One step (published, handed to an in-process gateway, completed); true when the
        // SUBSCRIBE set it read is the echo's answer to it.
        let mut step = |host: &mut DomainHost, gw: &mut Gw| -> anyhow::Result<bool> {
            k += 1;
            fill(&mut data, k as f64);
            host.publish_step(&data, k as f64)?;
            gw.published(host, k as f64, &data, false);
            host.complete_step()?;
            Ok(first_item(host.subscribe()) == k as f64)
        };
        let end = Instant::now() + PATIENCE;
        let mut tries = 0u64;
        while !step(host, &mut gw)? {
            tries += 1;
            if tries % 256 == 0 {
                gw.check()?;
                check_alive(&mut [&mut echo])?;
                if Instant::now() > end {
                    bail!("no step answered within {} s", PATIENCE.as_secs());
                }
            }
        }
        let (mut steps, mut unanswered) = (0u64, 0u64);
        let t = Instant::now();
        while t.elapsed() < self.args.duration {
            steps += 1;
            if !step(host, &mut gw)? {
                unanswered += 1;
            }
        }
        gw.check()?;
        check_alive(&mut [&mut echo])?;
        Ok(LockStep { per_s: steps as f64 / t.elapsed().as_secs_f64(), unanswered })
    }
}
