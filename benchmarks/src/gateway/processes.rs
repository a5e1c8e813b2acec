//! The processes of a sub-run (the framework, the gateway, the DDS peers) and the cores
//! they run on.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use anyhow::{bail, Context as _};
use tutti_core::shm::{os, DomainHost, Framework, FrameworkOptions, WaitMode};
use tutti_gateway::in_process::{GatewaySink, InProcess};
use tutti_gateway::EngineKind;
use tutti_host::{ChildProcess, SIGINT};

use super::modes::peer_opts;
use super::{Bench, GatewayMode, Slot, ITEMS};
use crate::load_ddf;

/// The log filter of the benchmark's children: errors only, nothing from the DDS stack.
const QUIET_LOG: &str = "error,rustdds=off,ros2_client=off";

/// The gateway of a sub-run, wherever it runs.
pub(super) enum Gw {
    Process(ChildProcess),
    /// `_handle` is kept for its drop, which stops the gateway's threads.
    InProcess {
        _handle: InProcess,
        sink: GatewaySink,
    },
}

impl Gw {
    /// Fails if a gateway process has exited.
    pub(super) fn check(&mut self) -> anyhow::Result<()> {
        match self {
            Gw::Process(kid) => check_alive(&mut [kid]),
            Gw::InProcess { .. } => Ok(()),
        }
    }

    /// The framework just published `host`'s step with `set`: an in-process gateway writes it
    /// to DDS (what its step sink does in a host); a separate one finds it in shared memory.
    /// `more`: the framework steps on at once (flat out), as a host that is catching up says.
    pub(super) fn published(&mut self, host: &DomainHost, sim: f64, set: &[u8], more: bool) {
        if let Gw::InProcess { sink, .. } = self {
            sink.send(0, host.current_step(), sim, set, more);
        }
    }

    /// Sends what a flat-out run left in the writers' batches.
    pub(super) fn flush(&mut self) {
        if let Gw::InProcess { sink, .. } = self {
            sink.flush();
        }
    }
}

/// The benchmark's DDF: one domain `name` whose PUBLISH and SUBSCRIBE sets are 8 x float64.
pub(super) fn ddf_text(name: &str, synchronous: bool) -> String {
    let items: String = (0..ITEMS).map(|i| format!("<item name=\"v{i}\"><type>double</type></item>")).collect();
    let sync = if synchronous { "yes" } else { "no" };
    format!(
        "<orchestra><domain name=\"{name}\"><synchronous>{sync}</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>\
         <block name=\"{name}/Publish\">{items}</block><block name=\"{name}/Subscribe\">{items}</block></domain></orchestra>"
    )
}

/// Starts a child pinned to `cpu`; dropped, it gets SIGINT and 3 s to leave (a gateway
/// says goodbye on DDS), then SIGKILL.
pub(super) fn start(name: &str, cmd: Command, cpu: usize) -> anyhow::Result<ChildProcess> {
    Ok(ChildProcess::spawn(name, cmd, Some(cpu))?.stop_on_drop(Some(SIGINT), Duration::from_secs(3)))
}

/// Fails if one of `kids` has exited (a gateway or a peer that could not start or died).
pub(super) fn check_alive(kids: &mut [&mut ChildProcess]) -> anyhow::Result<()> {
    for kid in kids.iter_mut() {
        if let Some(status) = kid.poll() {
            bail!("{} exited ({status})", kid.name);
        }
    }
    Ok(())
}

/// Pins this process's main thread (the framework) to `cpu`.
pub(super) fn pin_self(cpu: usize) {
    let _ = os::pin_to_cpu(cpu);
}

/// Every item of the benchmark's set set to `v`.
pub(super) fn fill(data: &mut [u8], v: f64) {
    for c in data.chunks_exact_mut(8) {
        c.copy_from_slice(&v.to_ne_bytes());
    }
}

/// The first item of a set.
pub(super) fn first_item(set: &[u8]) -> f64 {
    set.get(..8).and_then(|b| b.try_into().ok()).map_or(f64::NAN, f64::from_ne_bytes)
}

/// Where the framework (this process), the gateway and the DDS peer run.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cpus {
    pub key: &'static str,
    pub name: &'static str,
    pub fw: usize,
    pub gw: usize,
    pub peer: usize,
}

impl Cpus {
    const SAME: Cpus = Cpus { key: "same", name: "same core (all on CPU 0)", fw: 0, gw: 0, peer: 0 };
    const SPLIT: Cpus =
        Cpus { key: "split", name: "two cores (gateway CPU 1; framework and DDS peer CPU 0)", fw: 0, gw: 1, peer: 0 };
    const APART: Cpus =
        Cpus { key: "apart", name: "two cores (framework and gateway CPU 0; DDS peer CPU 1)", fw: 0, gw: 0, peer: 1 };

    pub(super) fn parse(s: &str) -> anyhow::Result<Vec<Cpus>> {
        Ok(match s {
            "same" => vec![Cpus::SAME],
            "split" => vec![Cpus::SPLIT],
            "apart" => vec![Cpus::APART],
            "both" => vec![Cpus::SAME, Cpus::SPLIT],
            "all" => vec![Cpus::SAME, Cpus::SPLIT, Cpus::APART],
            "none" => Vec::new(),
            other => bail!("--placement {other}: expected same, split, apart, both, all or none"),
        })
    }

    /// How the framework and the gateway wait for each other in shared memory: spinning,
    /// except in lock-step on one core, where a spinner holds the core the other one needs
    /// (until it yields, every few thousand looks: a few hundred µs a step).
    pub(super) fn wait(self, synchronous: bool) -> WaitMode {
        if synchronous && self.fw == self.gw {
            WaitMode::Block
        } else {
            WaitMode::Spin
        }
    }

    /// The CPUs of a ping-pong between two DDS programs (ping, pong): one per core when the
    /// DDS sides of the placement are on two cores.
    pub(super) fn ping_pong(self) -> (usize, usize) {
        (self.gw.min(self.peer), self.gw.max(self.peer))
    }
}

impl Bench<'_> {
    pub(super) fn ddf(&self, synchronous: bool) -> &Path {
        if synchronous {
            &self.sync_ddf
        } else {
            &self.async_ddf
        }
    }

    /// A `tutti` child on engine `e` in `slot`'s DDS domain and namespace.
    pub(super) fn tutti(&self, e: EngineKind, slot: &Slot, args: &[&str]) -> Command {
        self.command(&self.exe, e, slot, args)
    }

    /// `exe ARGS` for `slot` and engine `e`.
    fn command(&self, exe: &Path, e: EngineKind, slot: &Slot, args: &[&str]) -> Command {
        let mut cmd = Command::new(exe);
        cmd.args(args).args(["--ros-domain-id", &slot.dom.to_string(), "--dds", e.name()]);
        if let (EngineKind::Zenoh, Some(router)) = (e, &self.zenoh_router) {
            cmd.args(["--zenoh-connect", router]);
        }
        cmd.env("TUTTI_NAMESPACE", &slot.ns).env("RUST_LOG", QUIET_LOG).stdin(Stdio::null());
        if let Some(ks) = &self.secured {
            let enclave =
                if exe == self.exe { super::security::GATEWAY_ENCLAVE } else { super::security::PEER_ENCLAVE };
            cmd.envs(tutti_gateway::engine::security::SecuritySettings::enforce_env(ks, enclave));
        }
        cmd
    }

    /// `tutti gateway` on the benchmark's DDF, on `cpu`, as fast as it goes.
    fn gateway(&self, e: EngineKind, slot: &Slot, synchronous: bool, cpus: Cpus) -> anyhow::Result<ChildProcess> {
        let ddf = self.ddf(synchronous).to_string_lossy();
        let wait = if cpus.wait(synchronous) == WaitMode::Spin { "spin" } else { "block" };
        let mut args = vec!["gateway", &ddf, "--interface", "127.0.0.1", "--poll", "0", "--wait", wait, "-q"];
        // The synchronous runs measure every step through DDS: the gateway reads in lock-step
        // (by default a DDS reader never holds the framework back, and a framework stepping
        // flat out with no one to wait for would outrun it).
        if synchronous {
            args.push("--every-step");
        }
        start("the gateway", self.tutti(e, slot, &args), cpus.gw)
    }

    /// The gateway of a sub-run: `tutti gateway` (see [`Bench::gateway`]), or started in
    /// this process for the framework `fw` has just created, its threads (the engine's
    /// receive threads, the manager, the poller) on the gateway's CPU.
    pub(super) fn start_gateway(
        &self,
        e: EngineKind,
        slot: &Slot,
        synchronous: bool,
        cpus: Cpus,
        mode: GatewayMode,
    ) -> anyhow::Result<Gw> {
        if mode == GatewayMode::Process {
            return Ok(Gw::Process(self.gateway(e, slot, synchronous, cpus)?));
        }
        let (mut opts, _) = peer_opts(self.ddf(synchronous), slot.dom, e, self.zenoh_router.as_deref())?;
        opts.poll = Duration::ZERO;
        opts.wait = cpus.wait(synchronous);
        if let Some(ks) = &self.secured {
            opts.security = Some(super::security::enclave(ks, super::security::GATEWAY_ENCLAVE)?);
        }
        // Threads inherit the CPU of the thread that starts them.
        pin_self(cpus.gw);
        let started = tutti_gateway::in_process::start(opts, &slot.ns, Duration::from_secs(3600), Box::new(|_| {}));
        pin_self(cpus.fw);
        let (gw, sink) = started.context("starting the gateway in this process")?;
        Ok(Gw::InProcess { _handle: gw, sink })
    }

    /// A DDS peer of the benchmark (`--echo`, `--sink`, `--source` …) on `cpu`.
    pub(super) fn peer(&self, e: EngineKind, slot: &Slot, cpu: usize, what: &[&str]) -> anyhow::Result<ChildProcess> {
        let window = format!("{}ms", self.args.duration.as_millis());
        let args: Vec<&str> = ["gateway", "--duration", &window].into_iter().chain(what.iter().copied()).collect();
        let mut cmd = self.command(&self.bench_exe, e, slot, &args);
        cmd.stdout(Stdio::piped());
        start(&format!("the DDS peer ({})", what.first().unwrap_or(&"")), cmd, cpu)
    }

    pub(super) fn echo_peer(
        &self,
        e: EngineKind,
        slot: &Slot,
        synchronous: bool,
        cpu: usize,
    ) -> anyhow::Result<ChildProcess> {
        self.peer(e, slot, cpu, &["--echo", &self.ddf(synchronous).to_string_lossy()])
    }

    /// The framework of the benchmark's domain in `slot`'s namespace.
    pub(super) fn framework(&self, slot: &Slot, synchronous: bool, cpus: Cpus) -> anyhow::Result<Framework> {
        let model = load_ddf(self.ddf(synchronous)).map_err(|f| f.error)?;
        let wait = cpus.wait(synchronous);
        let opts = FrameworkOptions { namespace: slot.ns.clone(), wait, ..Default::default() };
        Framework::create(&model, &opts).context("creating the benchmark domain")
    }
}
