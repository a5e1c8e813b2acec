//! `tutti-bench rtapi-threads`: how long `RTPublishLock` takes in a client that reads in one
//! thread and writes in another through the RTAPI (as VILLASnode's Orchestra node does),
//! next to a client that reads, then writes, in one thread (the product's pattern), in the
//! same run.
//!
//! A framework steps a synchronous domain every `--period`; the reader thread loops on
//! `RTSubscribeLock`/`RTSubscribeUnlock` (so it spends nearly all its time waiting for the
//! next step); the writer thread calls `RTPublishLock`, writes an item, `RTPublishUnlock`,
//! every `--write-every`, and times each `RTPublishLock`. No mutex of the client's own.

use std::ffi::c_void;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use rtapi::codes::{message, RTAPIReturn_t, RTAPI_SUCCESS};
use rtapi::*;
use tutti_core::shm::{Framework, FrameworkOptions};

use crate::percentiles;

#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  tutti-bench rtapi-threads --seconds 10")]
pub struct Args {
    /// Seconds each row runs.
    #[arg(long, default_value_t = 10)]
    seconds: u64,
    /// The framework's step period.
    #[arg(long, default_value = "1ms", value_parser = humantime::parse_duration)]
    period: Duration,
    /// How often the writer writes.
    #[arg(long, default_value = "2ms", value_parser = humantime::parse_duration)]
    write_every: Duration,
}

const DDF: &str = r#"<orchestra><domain name="bench"><synchronous>yes</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>
<set name="PUBLISH"><item name="x"><type>float64</type></item></set>
<set name="SUBSCRIBE"><item name="y"><type>float64</type></item></set></domain></orchestra>"#;

fn ok(rc: RTAPIReturn_t, what: &str) -> anyhow::Result<()> {
    if rc != RTAPI_SUCCESS {
        bail!("{what}: {}", message(rc).to_string_lossy());
    }
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let ns = format!("bench-rtapi-{}", std::process::id());
    // The library reads the namespace from the environment at connect (set before any
    // other thread starts).
    std::env::set_var("TUTTI_NAMESPACE", &ns);
    let stop = tutti_exit::stop_flag()?;
    let model = tutti_core::ddf::parse_str(DDF, "rtapi-threads.ddf").context("the benchmark's DDF")?;
    let opts = FrameworkOptions { namespace: ns.clone(), timeout: Duration::from_secs(5), ..Default::default() };
    let fw = Framework::create(&model, &opts).context("creating the framework")?;
    let stepping = Arc::new(AtomicBool::new(true));
    let framework = step_on_a_thread(fw, args.period, stepping.clone(), stop.clone());
    let result = connect().and_then(|y| {
        println!(
            "RTPublishLock latency (µs): framework step {:?}, a write every {:?}, {} s a row",
            args.period, args.write_every, args.seconds
        );
        println!(
            "{:<26} {:>7} {:>7} {:>9} {:>9} {:>9} {:>10}",
            "client", "writes", "reads", "p50", "p99", "p99.9", "max"
        );
        for two_threads in [false, true] {
            one_row(&args, two_threads, y, &stop)?;
        }
        Ok(())
    });
    RTDisconnect();
    stepping.store(false, Ordering::Release);
    let _ = framework.join();
    result
}

/// Steps the framework's domain every `period` on a thread of its own until `stepping` is
/// cleared or `stop` set; the framework (and its segment) goes with the thread.
fn step_on_a_thread(
    mut fw: Framework,
    period: Duration,
    stepping: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
) -> thread::JoinHandle<()> {
    thread::spawn(move || {
        let d = &mut fw.domains[0];
        let mut k = 0u64;
        let mut next = Instant::now();
        while stepping.load(Ordering::Acquire) && !stop.load(Ordering::Acquire) {
            k += 1;
            if d.step(&(k as f64).to_ne_bytes(), k as f64 * period.as_secs_f64()).is_err() {
                break;
            }
            next += period;
            if let Some(left) = next.checked_duration_since(Instant::now()) {
                thread::sleep(left);
            }
        }
    })
}

/// Connects this process to the domain `bench`; returns the address of item y's staging
/// buffer.
fn connect() -> anyhow::Result<usize> {
    let (mut y_key, mut x_key, mut y_buf) = (0u16, 0u16, std::ptr::null_mut::<c_void>());
    // SAFETY: valid C strings and out-pointers.
    unsafe {
        ok(RTConnect(c"bench".as_ptr(), 10), "RTConnect")?;
        ok(RTGetKeyForItem(c"y".as_ptr(), &mut y_key), "RTGetKeyForItem")?;
        ok(RTGetKeyForItem(c"x".as_ptr(), &mut x_key), "RTGetKeyForItem")?;
        ok(RTGetBuffer(0, y_key, &mut y_buf), "RTGetBuffer")?;
    }
    Ok(y_buf as usize)
}

/// One row: `--seconds` of timed `RTPublishLock`s, by a writer thread beside a reader
/// thread looping on `RTSubscribeLock` (`two_threads`), or by one thread that reads each
/// step, then answers it. `y`: the address of item y's staging buffer.
fn one_row(args: &Args, two_threads: bool, y: usize, stop: &AtomicBool) -> anyhow::Result<()> {
    let reading = Arc::new(AtomicBool::new(two_threads));
    // The reader counts its reads and says why it stopped, if not told to.
    let reader = two_threads.then(|| {
        let reading = reading.clone();
        thread::spawn(move || -> anyhow::Result<u64> {
            let mut reads = 0;
            while reading.load(Ordering::Acquire) {
                ok(RTSubscribeLock(), "the reader's RTSubscribeLock")?;
                ok(RTSubscribeUnlock(), "the reader's RTSubscribeUnlock")?;
                reads += 1;
            }
            Ok(reads)
        })
    });
    let samples = write_loop(args, two_threads, y, stop);
    reading.store(false, Ordering::Release);
    let samples = samples?;
    let reads = match reader.map(|r| r.join()) {
        None => samples.len() as u64,
        Some(Ok(r)) => r?,
        Some(Err(_)) => bail!("the reader thread panicked"),
    };
    let row = if two_threads { "writer + looping reader" } else { "one thread: read, write" };
    if samples.is_empty() || reads == 0 {
        println!("{row:<26} not run (stopped)");
        return Ok(());
    }
    let (p50, p99, p999, max) = percentiles(&samples);
    println!("{row:<26} {:>7} {:>7} {p50:>9.2} {p99:>9.2} {p999:>9.2} {max:>10.1}", samples.len(), reads);
    Ok(())
}

/// The writer's `--seconds`: each `RTPublishLock` timed (ns), a new value written to item y
/// (at `y`) and committed; every `--write-every` with a reader thread beside it, else after
/// reading each step.
fn write_loop(args: &Args, two_threads: bool, y: usize, stop: &AtomicBool) -> anyhow::Result<Vec<f64>> {
    let mut samples = Vec::new();
    let end = Instant::now() + Duration::from_secs(args.seconds);
    let mut next = Instant::now();
    let mut v = 0.0f64;
    while Instant::now() < end && !stop.load(Ordering::Acquire) {
        if !two_threads {
            // One thread: read the step, then answer it (the product's pattern).
            ok(RTSubscribeLock(), "RTSubscribeLock")?;
            ok(RTSubscribeUnlock(), "RTSubscribeUnlock")?;
        }
        let t = Instant::now();
        ok(RTPublishLock(), "RTPublishLock")?;
        samples.push(t.elapsed().as_nanos() as f64);
        v += 1.0;
        // SAFETY: `y` is the connection's staging buffer of item y (8 bytes).
        unsafe { (y as *mut f64).write_unaligned(v) };
        ok(RTPublishUnlock(), "RTPublishUnlock")?;
        if two_threads {
            next += args.write_every;
            if let Some(left) = next.checked_duration_since(Instant::now()) {
                thread::sleep(left);
            }
        }
    }
    Ok(samples)
}
