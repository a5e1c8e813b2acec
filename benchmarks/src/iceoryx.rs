//! The peer of `tutti-bench shm`: iceoryx2 (0.10) publish-subscribe ping-pong between two
//! processes, busy polling, measured the same way as tutti's round trips. The pong side is
//! this binary again, run as the hidden `tutti-bench iox-pong`.
//!
//! Each run uses its own iceoryx2 `Config` (root dir `/tmp/iceoryx2_pp<pid>_<n>/`, shm prefix
//! `iox2_pp<pid>_<n>_`) plus pid-unique service names, so parallel runs never collide and all
//! files of a run can be removed afterwards without touching anyone else's iceoryx2 state.

use iceoryx2::prelude::*;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use crate::CliResult;
use crate::{relax, warmup};
use tutti_host::ChildProcess;

type Res<T> = Result<T, Box<dyn std::error::Error>>;
const STOP: u64 = u64::MAX;
const SHM_DIR: &str = "/dev/shm";

/// Returns one round-trip time in ns per iteration (warm-up excluded). Panics on failure.
/// Payload: `[u8]` slice of `size` bytes (>= 8); the first 8 bytes carry a sequence number.
/// Ping writes the whole payload into shared memory, pong copies it into its own sample (echo).
/// If both processes share one CPU the spin loop calls `sched_yield`, otherwise it pure-spins.
pub fn run_iceoryx2_pingpong(size: usize, iterations: usize, cpu_ping: usize, cpu_pong: usize) -> Vec<f64> {
    assert!(size >= 8, "payload must hold the 8-byte sequence number");
    let yield_spin = cpu_ping == cpu_pong;
    let (tag, mut guard) = run_tag();
    pin_current_thread(cpu_ping);
    let r = ping(&tag, size, iterations, cpu_pong, yield_spin, &mut guard);
    drop(guard); // stops child (if still alive) and removes this run's files
    r.unwrap_or_else(|e| panic!("iceoryx2 ping-pong failed: {e}"))
}

/// Hidden: the pong side of the iceoryx2 ping-pong.
#[derive(Debug, clap::Args)]
pub struct PongArgs {
    tag: String,
    size: usize,
    #[arg(long)]
    cpu: usize,
    /// Yield the core while polling (both processes on one core).
    #[arg(long)]
    yield_spin: bool,
}

/// The pong side (`tutti-bench iox-pong TAG SIZE --cpu N [--yield-spin]`).
pub fn pong_main(a: PongArgs) -> CliResult {
    pong(&a.tag, a.size, a.cpu, a.yield_spin).map_err(|e| anyhow::anyhow!("iceoryx2 pong: {e}"))?;
    Ok(())
}

fn config(tag: &str) -> Res<Config> {
    let mut c = Config::default();
    c.global.prefix = FileName::new(format!("iox2_pp{tag}_").as_bytes())?;
    c.global.set_root_path(&Path::new(root_dir(tag).as_bytes())?);
    Ok(c)
}
fn root_dir(tag: &str) -> String {
    format!("/tmp/iceoryx2_pp{tag}/")
}
pub(crate) fn node(tag: &str) -> Res<Node<ipc::Service>> {
    Ok(NodeBuilder::new()
        .config(&config(tag)?)
        // Disabled: otherwise iceoryx2 installs SIGINT/SIGTERM handlers and Ctrl-C would not stop
        // a busy-spinning benchmark.
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()?)
}
fn svc_name(tag: &str, dir: &str) -> Res<ServiceName> {
    Ok(ServiceName::new(&format!("iox2pp/{tag}/{dir}"))?)
}

fn ping(
    tag: &str,
    size: usize,
    iters: usize,
    cpu_pong: usize,
    yield_spin: bool,
    guard: &mut RunGuard,
) -> Res<Vec<f64>> {
    let node = node(tag)?;
    let mk = |dir| -> Res<_> {
        Ok(node
            .service_builder(&svc_name(tag, dir)?)
            .publish_subscribe::<[u8]>()
            .max_publishers(1)
            .max_subscribers(1)
            .history_size(0)
            .subscriber_max_buffer_size(2)
            .create()?)
    };
    let (svc_ping, svc_pong) = (mk("ping")?, mk("pong")?);
    let publisher = svc_ping.publisher_builder().initial_max_slice_len(size).create()?;
    let subscriber = svc_pong.subscriber_builder().create()?;

    let mut cmd = Command::new(std::env::current_exe()?);
    cmd.args(["iox-pong", tag, &size.to_string(), "--cpu", &cpu_pong.to_string()]).stdin(Stdio::null());
    if yield_spin {
        cmd.arg("--yield-spin");
    }
    let kid =
        guard.child.insert(ChildProcess::spawn("the iceoryx2 pong", cmd, None)?.stop_on_drop(None, Duration::ZERO));
    // wait until pong has its subscriber on "ping" and publisher on "pong"
    let t = Instant::now();
    while svc_ping.dynamic_config().number_of_subscribers() < 1 || svc_pong.dynamic_config().number_of_publishers() < 1
    {
        if let Some(st) = kid.poll() {
            return Err(format!("pong exited early: {st}").into());
        }
        if t.elapsed() > Duration::from_secs(10) {
            return Err("pong did not come up within 10 s".into());
        }
        std::thread::sleep(Duration::from_millis(1));
    }

    let mut buf = vec![0xA5u8; size];
    let warmup = warmup(iters);
    let mut rtts = Vec::with_capacity(iters);
    for seq in 0..(warmup + iters) as u64 {
        let t0 = Instant::now();
        buf[..8].copy_from_slice(&seq.to_le_bytes());
        publisher.loan_slice_uninit(size)?.write_from_slice(&buf).send()?;
        let mut spins = 0u64;
        loop {
            if let Some(s) = subscriber.receive()? {
                let p = s.payload();
                if p.len() == size && p[..8] == seq.to_le_bytes() {
                    break;
                }
                continue; // stale duplicate (only possible after a resend below)
            }
            spins += 1;
            if spins & 0xFFFF == 0 {
                let waited = t0.elapsed();
                if waited > Duration::from_secs(5) {
                    return Err(format!("no echo for seq {seq} within 5 s").into());
                }
                // first messages may race connection setup: resend during warm-up only
                if seq < warmup as u64 && waited > Duration::from_millis(20) {
                    publisher.loan_slice_uninit(size)?.write_from_slice(&buf).send()?;
                }
            }
            relax(yield_spin);
        }
        let dt = t0.elapsed().as_nanos() as f64;
        if seq >= warmup as u64 {
            rtts.push(dt);
        }
    }
    // graceful stop so pong drops its node and removes its own iceoryx2 files
    buf[..8].copy_from_slice(&STOP.to_le_bytes());
    publisher.loan_slice_uninit(size)?.write_from_slice(&buf).send()?;
    // Still running after 2 s: RunGuard kills it.
    kid.wait(Duration::from_secs(2));
    Ok(rtts)
}

fn pong(tag: &str, size: usize, cpu: usize, yield_spin: bool) -> Res<()> {
    pin_current_thread(cpu);
    let node = node(tag)?;
    let open = |dir| -> Res<_> { Ok(node.service_builder(&svc_name(tag, dir)?).publish_subscribe::<[u8]>().open()?) };
    let (svc_ping, svc_pong) = (open("ping")?, open("pong")?);
    let subscriber = svc_ping.subscriber_builder().create()?;
    let publisher = svc_pong.publisher_builder().initial_max_slice_len(size).create()?;
    let ppid = std::os::unix::process::parent_id();
    let mut spins = 0u64;
    loop {
        if let Some(s) = subscriber.receive()? {
            let p = s.payload();
            if p[..8] == STOP.to_le_bytes() {
                return Ok(());
            }
            publisher.loan_slice_uninit(p.len())?.write_from_slice(p).send()?;
            continue;
        }
        spins += 1;
        // orphaned (ping died / was killed)? -> stop spinning
        if spins & 0xF_FFFF == 0 && std::os::unix::process::parent_id() != ppid {
            return Err("ping process is gone".into());
        }
        relax(yield_spin);
    }
}

/// Pins the calling thread to `cpu`.
fn pin_current_thread(cpu: usize) {
    if let Err(e) = tutti_core::shm::os::pin_to_cpu(cpu) {
        panic!("pinning to cpu {cpu}: {e}");
    }
}

/// A run's own tag (its config's root dir and shm prefix), with the guard that removes its
/// files when dropped; earlier runs' files whose process is gone are removed first.
pub(crate) fn run_tag() -> (String, RunGuard) {
    static RUN: AtomicUsize = AtomicUsize::new(0);
    let tag = format!("{}_{}", std::process::id(), RUN.fetch_add(1, Ordering::Relaxed));
    remove_stale_runs();
    (tag.clone(), RunGuard { tag, child: None })
}

/// Kills the child if still running and removes everything iceoryx2 created for this run.
pub(crate) struct RunGuard {
    tag: String,
    child: Option<ChildProcess>,
}
impl Drop for RunGuard {
    fn drop(&mut self) {
        drop(self.child.take());
        remove_run_files(&self.tag);
    }
}
fn remove_run_files(tag: &str) {
    let _ = std::fs::remove_dir_all(root_dir(tag));
    let prefix = format!("iox2_pp{tag}_");
    if let Ok(rd) = std::fs::read_dir(SHM_DIR) {
        for e in rd.flatten() {
            if e.file_name().to_string_lossy().starts_with(&prefix) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}
/// Removes files of earlier runs whose ping process no longer exists (e.g. killed by Ctrl-C).
fn remove_stale_runs() {
    let mut tags = Vec::new();
    for (dir, pre) in [("/tmp", "iceoryx2_pp"), (SHM_DIR, "iox2_pp")] {
        for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if let Some(rest) = name.strip_prefix(pre) {
                let mut it = rest.split('_');
                if let (Some(pid), Some(n)) = (it.next(), it.next()) {
                    // (nested, not a let-chain, so this also compiles in edition 2021)
                    if pid.parse::<u32>().is_ok()
                        && n.parse::<u32>().is_ok()
                        && !std::path::Path::new(&format!("/proc/{pid}")).exists()
                    {
                        tags.push(format!("{pid}_{n}"));
                    }
                }
            }
        }
    }
    tags.sort();
    tags.dedup();
    tags.iter().for_each(|t| remove_run_files(t));
}
