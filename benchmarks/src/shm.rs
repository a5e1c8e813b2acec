//! `tutti-bench shm`: round trips between two processes through shared-memory domains, for
//! asynchronous and synchronous sets, spin and blocking waits, several set sizes, on one
//! core and on two; iceoryx2's publish-subscribe ping-pong runs in the same run as the peer.
//!
//! * async: the framework publishes a set whose first word is a sequence number; the peer
//!   polls the PUBLISH generation, snapshots the set and commits it back whole as its
//!   SUBSCRIBE set; the framework polls the SUBSCRIBE generation and reads the set. The
//!   round trip ends when the framework holds the echoed set.
//! * sync: one lock-step `step()` of the framework: publish, the peer's `subscribe_lock`,
//!   `publish_lock`, commit of the whole set, and the framework's read of the answer.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use tutti_core::ddf;
use tutti_core::ddf::Role;
use tutti_core::shm::{os, ConnectOptions, Framework, FrameworkOptions, Participant, ShmError, WaitMode};

use crate::CliResult;
use crate::{iceoryx, percentiles, relax, warmup};

/// Measure shared-memory round trips (and iceoryx2's, as the peer in the same run).
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti-bench shm\n  tutti-bench shm --iterations 50000 --sizes 8,1024\n  tutti-bench shm --placement two --no-peer"
)]
pub struct Args {
    /// Measured round trips per configuration, in total over the rounds.
    #[arg(long, default_value_t = 20_000)]
    iterations: usize,
    /// The configurations of one size take turns in this many rounds, so that a change in
    /// the machine's state during the run (another VM, a migrated vCPU) falls on tutti and
    /// the peer alike. Each round starts its processes afresh, with a warm-up.
    #[arg(long, default_value_t = 4)]
    rounds: usize,
    /// Set sizes in bytes (multiples of 8).
    #[arg(long, value_delimiter = ',', default_values_t = vec![8usize, 1024, 65536])]
    sizes: Vec<usize>,
    /// Core placements: two (ping on CPU 0, pong on CPU 1) and/or one (both on CPU 0).
    #[arg(long, value_delimiter = ',', default_values_t = vec![String::from("two"), String::from("one")])]
    placement: Vec<String>,
    /// Skip the iceoryx2 peer.
    #[arg(long)]
    no_peer: bool,
    /// Copy the whole echoed set on the ping side rather than reading its sequence word only
    /// (as iceoryx2's ping does).
    #[arg(long)]
    read_all: bool,
    /// The pong takes a snapshot of each set (`subscribe_lock`) and answers from it
    /// (`commit_all_with`), rather than answering from the set where it lies (`answer_with`).
    #[arg(long)]
    snapshot: bool,
}

/// Hidden: the pong side of a tutti round trip.
#[derive(Debug, clap::Args)]
pub struct PongArgs {
    #[arg(long)]
    namespace: String,
    #[arg(long)]
    sync: bool,
    #[arg(long)]
    spin: bool,
    #[arg(long)]
    cpu: Option<usize>,
    /// Yield the core while polling (both processes on one core).
    #[arg(long)]
    yield_spin: bool,
    /// Answer from a snapshot (`subscribe_lock` + `commit_all_with`) rather than in place.
    #[arg(long)]
    snapshot: bool,
}

fn model(size: usize, sync: bool) -> anyhow::Result<ddf::Model> {
    let yn = if sync { "yes" } else { "no" };
    let words = size / 8;
    let text = format!(
        r#"<orchestra><domain name="bench"><synchronous>{yn}</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
        <set name="PUBLISH"><item name="data"><type>unsigned int64</type><length>{words}</length></item></set>
        <set name="SUBSCRIBE"><item name="data"><type>unsigned int64</type><length>{words}</length></item></set>
        </domain></orchestra>"#
    );
    Ok(ddf::parse_str(&text, "bench.ddf")?)
}

fn first_word(b: &[u8]) -> u64 {
    u64::from_ne_bytes(b[..8].try_into().unwrap_or([0; 8]))
}

struct Config<'a> {
    size: usize,
    sync: bool,
    spin: bool,
    cpus: (usize, usize),
    iterations: usize,
    read_all: bool,
    snapshot: bool,
    label: &'a str,
}

fn run_tutti(c: &Config<'_>) -> anyhow::Result<Vec<f64>> {
    let namespace =
        format!("bench{}-{}", std::process::id(), c.label.replace(|ch: char| !ch.is_ascii_alphanumeric(), ""));
    let wait = if c.spin { WaitMode::Spin } else { WaitMode::Block };
    let opts =
        FrameworkOptions { namespace: namespace.clone(), timeout: Duration::from_secs(10), wait, ..Default::default() };
    let mut fw = Framework::create(&model(c.size, c.sync)?, &opts)?;
    os::pin_to_cpu(c.cpus.0).context("pinning the ping side")?;
    let same_core = c.cpus.0 == c.cpus.1;
    let mut cmd = Command::new(std::env::current_exe()?);
    cmd.args(["shm-pong", "--namespace", &namespace, "--cpu", &c.cpus.1.to_string()]);
    if c.sync {
        cmd.arg("--sync");
    }
    if c.spin {
        cmd.arg("--spin");
    }
    if same_core {
        cmd.arg("--yield-spin");
    }
    if c.snapshot {
        cmd.arg("--snapshot");
    }
    cmd.stdin(Stdio::null());
    let mut child = tutti_host::ChildProcess::spawn("the pong process", cmd, None)?.stop_on_drop(None, Duration::ZERO);
    let host = &mut fw.domains[0];
    let started = Instant::now();
    while host.connection_count() == 0 {
        if let Some(status) = child.poll() {
            bail!("pong exited early: {status}");
        }
        if started.elapsed() > Duration::from_secs(10) {
            bail!("pong did not connect within 10 s");
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let mut payload = vec![0xa5u8; c.size];
    // The same warm-up as the iceoryx2 ping-pong: as many round trips as measured, at most 10,000.
    let warmup = warmup(c.iterations);
    let mut rtts = Vec::with_capacity(c.iterations);
    for seq in 1..=(warmup + c.iterations) as u64 {
        payload[..8].copy_from_slice(&seq.to_ne_bytes());
        let t0 = Instant::now();
        if c.sync {
            host.publish_step(&payload, 0.0)?;
            let report = if c.read_all { host.complete_step()? } else { host.await_step()? };
            if report.timed_out > 0 {
                bail!("step {seq} timed out");
            }
            let answer = if c.read_all {
                first_word(host.subscribe())
            } else {
                let mut word = [0u8; 8];
                host.read_subscribe_at(0, &mut word)?;
                u64::from_ne_bytes(word)
            };
            // The first step may complete before the pong has declared itself a reader.
            if seq > 1 && answer != seq {
                bail!("step {seq}: the answer carries {answer}");
            }
        } else {
            host.publish_step(&payload, 0.0)?;
            let mut turns = 0u64;
            let mut word = [0u8; 8];
            loop {
                // The echo is complete when its sequence word is this one: read that word
                // only, as iceoryx2's ping does (`--read-all` copies the whole set).
                if c.read_all {
                    if first_word(host.read_subscribe()?) == seq {
                        break;
                    }
                } else if host.read_subscribe_at(0, &mut word).is_ok() && u64::from_ne_bytes(word) == seq {
                    break;
                }
                turns += 1;
                if turns % 65_536 == 0 && t0.elapsed() > Duration::from_secs(10) {
                    bail!("no echo of {seq} within 10 s");
                }
                relax(same_core);
            }
        }
        let rtt = t0.elapsed().as_nanos() as f64;
        if seq > warmup as u64 {
            rtts.push(rtt);
        }
    }
    drop(fw);
    child.wait(Duration::from_secs(5));
    Ok(rtts)
}

/// The hardware floor of one round trip: two threads pinned like the ping and the pong, a
/// ring of four buffers each way, and nothing but the copies (the ping's payload into the
/// ring, the pong's copy across, the ping's look at the answer's first word): no seqlock,
/// no handshake, no checks.
fn run_floor(size: usize, iterations: usize, cpus: (usize, usize)) -> anyhow::Result<Vec<f64>> {
    use std::sync::atomic::AtomicU64;
    use std::sync::Arc;
    use tutti_core::shm::bucket::{copy_words, store_bytes};
    const RING: usize = 4;
    struct Rings {
        publish: Vec<AtomicU64>,
        answer: Vec<AtomicU64>,
        published: AtomicU64,
        answered: AtomicU64,
    }
    let words = size / 8;
    let zeros = || (0..RING * words).map(|_| AtomicU64::new(0)).collect::<Vec<_>>();
    let r = Arc::new(Rings {
        publish: zeros(),
        answer: zeros(),
        published: AtomicU64::new(0),
        answered: AtomicU64::new(0),
    });
    let same = cpus.0 == cpus.1;
    let wait = move || relax(same);
    let pong = {
        let r = r.clone();
        std::thread::spawn(move || {
            let _ = os::pin_to_cpu(cpus.1);
            let mut last = 0;
            loop {
                let g = r.published.load(std::sync::atomic::Ordering::Acquire);
                if g == last {
                    wait();
                    continue;
                }
                if g == u64::MAX {
                    return;
                }
                last = g;
                let at = (g as usize % RING) * words;
                copy_words(&r.answer[at..at + words], &r.publish[at..at + words]);
                r.answered.store(g, std::sync::atomic::Ordering::Release);
            }
        })
    };
    os::pin_to_cpu(cpus.0).context("pinning the ping side")?;
    let mut payload = vec![0xa5u8; size];
    let warmup = warmup(iterations);
    let mut rtts = Vec::with_capacity(iterations);
    let mut result = Ok(());
    for k in 1..=(warmup + iterations) as u64 {
        payload[..8].copy_from_slice(&k.to_ne_bytes());
        let at = (k as usize % RING) * words;
        let t0 = Instant::now();
        store_bytes(&r.publish[at..at + words], &payload);
        r.published.store(k, std::sync::atomic::Ordering::Release);
        let mut turns = 0u64;
        while r.answered.load(std::sync::atomic::Ordering::Acquire) != k {
            turns += 1;
            if turns % 65_536 == 0 && t0.elapsed() > Duration::from_secs(10) {
                result = Err(anyhow::anyhow!("no answer to {k} within 10 s"));
                break;
            }
            wait();
        }
        if result.is_err() {
            break;
        }
        let _ = r.answer[at].load(std::sync::atomic::Ordering::Relaxed);
        if k > warmup as u64 {
            rtts.push(t0.elapsed().as_nanos() as f64);
        }
    }
    r.published.store(u64::MAX, std::sync::atomic::Ordering::Release);
    let _ = pong.join();
    result.map(|()| rtts)
}

/// The pong side: echo every PUBLISH set back as the SUBSCRIBE set.
pub fn pong(a: PongArgs) -> CliResult {
    if let Some(cpu) = a.cpu {
        os::pin_to_cpu(cpu).context("pinning the pong side")?;
    }
    let wait = if a.spin { WaitMode::Spin } else { WaitMode::Block };
    let opts = ConnectOptions {
        namespace: a.namespace,
        name: "bench pong".into(),
        wait,
        timeout: Duration::from_secs(10),
        ..Default::default()
    };
    let mut p = Participant::connect("bench", opts).context("connecting")?;
    let result: Result<(), ShmError> = (|| {
        let echo = |p: &mut Participant| -> Result<(), ShmError> {
            if a.snapshot {
                p.subscribe_lock()?;
                p.publish_lock()?;
                p.commit_all_with(|snapshot, out| out.copy_from_slice(snapshot))
            } else {
                p.answer_with(|publish, out| out.copy_from_slice(publish)).map(drop)
            }
        };
        if a.sync {
            loop {
                echo(&mut p)?;
            }
        }
        // Answer the value there is at once: the ping may have published its first set
        // between our connect and this line, and waits for its echo.
        let mut last = u64::MAX;
        let mut turns = 0u64;
        loop {
            let g = p.segment().generation(Role::Publish);
            if g == last {
                turns += 1;
                if turns % 65_536 == 0 {
                    p.check()?;
                }
                relax(a.yield_spin);
                continue;
            }
            last = g;
            echo(&mut p)?;
        }
    })();
    match result {
        Err(ShmError::FrameworkStopped { .. } | ShmError::ConnectionLost { .. }) => Ok(()),
        Err(e) => Err(anyhow::Error::from(e).into()),
        Ok(()) => Ok(()),
    }
}

pub fn run(args: Args) -> CliResult {
    if let Some(bad) = args.sizes.iter().find(|s| **s < 8 || **s % 8 != 0) {
        return Err(crate::Failure::invalid(anyhow::anyhow!("--sizes: {bad} is not a multiple of 8 bytes")));
    }
    let cpus_online = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let rounds = args.rounds.max(1);
    let chunk = (args.iterations / rounds).max(1);
    println!(
        "tutti-bench shm: {} round trips per row in {rounds} interleaved rounds (each after a warm-up), {} CPUs online; times in µs",
        chunk * rounds,
        cpus_online
    );
    println!(
        "{:<8} {:<9} {:<22} {:>7} {:>9} {:>9} {:>9} {:>10}",
        "cores", "system", "mode", "bytes", "p50", "p99", "p99.9", "max"
    );
    for placement in &args.placement {
        let cpus = match placement.as_str() {
            "two" if cpus_online >= 2 => (0, 1),
            "two" => {
                println!("two      (skipped: one CPU online)");
                continue;
            }
            "one" => (0, 0),
            other => return Err(crate::Failure::invalid(anyhow::anyhow!("--placement: '{other}' is not one or two"))),
        };
        let same = cpus.0 == cpus.1;
        for &size in &args.sizes {
            // Spinning both sides on one core only measures time slices; there the
            // synchronous rows block, and the polling loops yield.
            let mut rows: Vec<(&str, bool, bool)> = vec![("async, poll", false, true)];
            if !same {
                rows.push(("sync step, spin", true, true));
            }
            rows.push(("sync step, block", true, false));
            let mut tutti: Vec<Vec<f64>> = vec![Vec::new(); rows.len()];
            let mut peer = Vec::new();
            let mut floor = Vec::new();
            let progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
            for round in 0..rounds {
                if progress {
                    eprint!("\r{placement} core(s), {size} bytes: round {}/{rounds} ", round + 1);
                }
                for (i, &(label, sync, spin)) in rows.iter().enumerate() {
                    let c = Config {
                        size,
                        sync,
                        spin,
                        cpus,
                        iterations: chunk,
                        read_all: args.read_all,
                        snapshot: args.snapshot,
                        label: &format!("{placement}{size}{label}{round}"),
                    };
                    let rtts =
                        run_tutti(&c).with_context(|| format!("tutti {label}, {size} bytes, {placement} core(s)"))?;
                    tutti[i].extend(rtts);
                }
                if !args.no_peer {
                    peer.extend(iceoryx::run_iceoryx2_pingpong(size, chunk, cpus.0, cpus.1));
                }
                floor.extend(run_floor(size, chunk, cpus).context("the memcpy floor")?);
            }
            if progress {
                eprint!("\r{:60}\r", "");
            }
            for ((label, _, spin), rtts) in rows.iter().zip(&tutti) {
                let mode = if same && *spin { format!("{label}+yield") } else { label.to_string() };
                print_row(placement, "tutti", &mode, size, rtts);
            }
            if !args.no_peer {
                let mode = if same { "pub/sub, poll+yield" } else { "pub/sub, poll" };
                print_row(placement, "iceoryx2", mode, size, &peer);
            }
            print_row(placement, "memcpy", if same { "floor, poll+yield" } else { "floor, poll" }, size, &floor);
        }
    }
    Ok(())
}

fn print_row(cores: &str, system: &str, mode: &str, size: usize, rtts_ns: &[f64]) {
    let (p50, p99, p999, max) = percentiles(rtts_ns);
    println!("{cores:<8} {system:<9} {mode:<22} {size:>7} {p50:>9.2} {p99:>9.2} {p999:>9.2} {max:>10.1}");
}
