//! `tutti-bench studio`: what watching costs a real-time host. The framework of a DDF steps
//! every domain at a fixed rate (the stepping loop of `bench record`) for `--duration`,
//! alone and with a `tutti studio` (a child process) streaming the live monitor with
//! `--items` items plotted to a reader of its event stream, in alternating rounds; it prints
//! the step lateness and overruns of each, and the events the monitor delivered per second.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context as _};
use tutti_core::shm::{Framework, FrameworkOptions};

use crate::nearest_rank;
use crate::record::{step_run, Stepping};
use crate::{load_ddf, CliResult};

/// Step lateness at a fixed rate with and without the studio's live monitor plotting items.
#[derive(Debug, clap::Args)]
#[command(after_help = "Example:\n  cargo run --release -p tutti-bench -- studio --duration 20s --rounds 2 --items 20")]
pub struct Args {
    #[command(flatten)]
    run: Stepping,
    /// Rounds of the two runs (alone, monitored), interleaved.
    #[arg(long, default_value_t = 2)]
    rounds: u32,
    /// Items the monitor plots (the first ones of the DDF, PUBLISH then SUBSCRIBE).
    #[arg(long, default_value_t = 20)]
    items: usize,
}

/// A studio child process and a reader of its monitor stream, counting events.
struct Watcher {
    _studio: tutti_host::ChildProcess,
    stop: Arc<AtomicBool>,
    events: Arc<AtomicU64>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Watcher {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }
}

fn watch(namespace: &str, file: &std::path::Path, items: &[String]) -> anyhow::Result<Watcher> {
    let exe = crate::tutti_exe()?;
    let root = file.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(std::path::Path::new("."));
    let mut cmd = Command::new(exe);
    cmd.args(["studio", "--listen", "127.0.0.1:0", "--read-only", "--root"])
        .arg(root)
        .env("TUTTI_NAMESPACE", namespace)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    let mut studio = tutti_host::ChildProcess::spawn("tutti studio", cmd, None)?;
    let stderr = studio.child.stderr.take().context("the studio's stderr")?;
    let mut lines = BufReader::new(stderr).lines();
    let addr = loop {
        match lines.next() {
            Some(Ok(line)) => {
                if let Some(url) = line.strip_prefix("tutti studio: listening on http://") {
                    break url.trim_end_matches('/').to_string();
                }
            }
            _ => bail!("the studio stopped before it listened"),
        }
    };
    std::thread::spawn(move || for _ in lines.by_ref() {});
    let mut conn = TcpStream::connect(&addr).with_context(|| format!("connecting to the studio at {addr}"))?;
    conn.set_read_timeout(Some(Duration::from_millis(200)))?;
    let query: String = items.iter().map(|i| i.replace('#', "%23").replace('/', "%2F")).collect::<Vec<_>>().join(",");
    write!(conn, "GET /api/monitor?items={query} HTTP/1.1\r\nHost: {addr}\r\nAccept: text/event-stream\r\n\r\n")?;
    let stop = Arc::new(AtomicBool::new(false));
    let events = Arc::new(AtomicU64::new(0));
    let reader = {
        let (stop, events) = (stop.clone(), events.clone());
        let wanted = items.len();
        std::thread::spawn(move || {
            let mut buf = vec![0u8; 1 << 16];
            let mut tail = Vec::new();
            let mut last_step = 0u64;
            while !stop.load(Ordering::SeqCst) {
                match conn.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => {
                        tail.extend_from_slice(&buf[..n]);
                        // Whole events only (an event ends with a blank line); an event counts
                        // when it carries a value for every item asked for, from a step after
                        // the last one counted: an event saying "no running framework" is not
                        // a delivered value.
                        while let Some(end) = tail.windows(2).position(|w| w == b"\n\n") {
                            let event: Vec<u8> = tail.drain(..end + 2).collect();
                            let text = String::from_utf8_lossy(&event);
                            let Some(data) = text.lines().find_map(|l| l.strip_prefix("data: ")) else { continue };
                            let Ok(v) = serde_json::from_str::<serde_json::Value>(data) else { continue };
                            let Some(values) = v["values"].as_object() else { continue };
                            let live: Vec<u64> = values
                                .values()
                                .filter(|x| x.get("v").is_some())
                                .filter_map(|x| x["step"].as_u64())
                                .collect();
                            let step = live.iter().copied().max().unwrap_or(0);
                            if live.len() == wanted && step > last_step {
                                last_step = step;
                                events.fetch_add(1, Ordering::Relaxed);
                            }
                        }
                    }
                    Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
                    Err(_) => break,
                }
            }
        })
    };
    Ok(Watcher { _studio: studio, stop, events, reader: Some(reader) })
}

pub fn run(args: Args) -> CliResult {
    let model = load_ddf(&args.run.file)?;
    let items: Vec<String> = model
        .domains
        .iter()
        .flat_map(|d| d.leaves().map(move |(role, leaf)| format!("{}#{role}#{}", d.name, leaf.path)))
        .take(args.items)
        .collect();
    println!(
        "monitoring cost: {} ({} domains), step {:?}, {:?} per run, {} round(s), interleaved; the monitor plots {} item(s)",
        args.run.file.display(),
        model.domains.len(),
        args.run.step,
        args.run.duration,
        args.rounds,
        items.len()
    );
    println!(
        "{:<28} {:>12} {:>12} {:>12} {:>9} {:>10}",
        "run", "late p50 µs", "late p99 µs", "late max µs", "overruns", "events/s"
    );
    for round in 1..=args.rounds {
        for monitored in [false, true] {
            let name = if monitored { "studio monitor" } else { "no monitor" };
            eprintln!("bench studio: round {round}: {name}");
            let opts = FrameworkOptions {
                namespace: format!("benchstudio{}x{round}x{}", std::process::id(), u8::from(monitored)),
                timeout: Duration::from_millis(50),
                ..Default::default()
            };
            let mut fw = Framework::create(&model, &opts).context("creating the domains")?;
            let watcher = if monitored { Some(watch(&opts.namespace, &args.run.file, &items)?) } else { None };
            // Let the studio find the segments before measuring.
            if watcher.is_some() {
                std::thread::sleep(Duration::from_millis(500));
            }
            let before = watcher.as_ref().map_or(0, |w| w.events.load(Ordering::Relaxed));
            let (mut late, overruns, secs) =
                step_run(&model, &mut fw, args.run.step, args.run.duration, |_, _| Ok(()))?;
            let events = watcher.as_ref().map_or(0, |w| w.events.load(Ordering::Relaxed)) - before;
            drop(watcher);
            if monitored && events == 0 {
                return Err(anyhow::anyhow!(
                    "the studio's monitor delivered no live value during the run (its events carried no value of the items asked for)"
                )
                .into());
            }
            drop(fw);
            late.sort();
            let us = |d: Duration| d.as_secs_f64() * 1e6;
            println!(
                "{:<28} {:>12.1} {:>12.1} {:>12.1} {:>9} {:>10}",
                format!("{name} #{round}"),
                us(nearest_rank(&late, 0.5)),
                us(nearest_rank(&late, 0.99)),
                us(late[late.len() - 1]),
                overruns,
                if monitored { format!("{:.1}", events as f64 / secs) } else { "-".to_string() }
            );
        }
    }
    Ok(())
}
