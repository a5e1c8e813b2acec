//! Times the DDF reader the way `tutti-bench ddf` does, without building the CLI (which
//! pulls in DDS): quick-xml's events alone, `raw::parse` and the full `parse_bytes`, N runs
//! after one warm-up.
//!
//! ```text
//! cargo run -p tutti-core --release --example ddf_time -- [FILE] [N]
//! ```
//!
//! Meant for comparing two builds run alternately on the same machine; the published
//! figures come from `tutti-bench ddf`. Besides the wall-clock times that `tutti-bench`
//! reports, it prints the median CPU time of the thread, steadier when the machine is busy.

use std::hint::black_box;
use std::time::{Duration, Instant};

fn main() {
    let mut args = std::env::args().skip(1);
    let file = args.next().unwrap_or_else(|| "ddf/large-1000.ddf".into());
    let n: usize = args.next().map_or(50, |s| s.parse().expect("N must be a number"));
    let bytes = std::fs::read(&file).unwrap_or_else(|e| panic!("cannot read {file}: {e}"));
    let text = std::str::from_utf8(&bytes).expect("the DDF is not UTF-8");
    tutti_core::ddf::parse_bytes(&bytes, &file).expect("the DDF is invalid");
    report("quick-xml", time(n, || black_box(events(black_box(text)))));
    report("raw::parse", time(n, || black_box(tutti_core::ddf::raw::parse(black_box(text)).is_ok())));
    report("parse_bytes", time(n, || black_box(tutti_core::ddf::parse_bytes(black_box(&bytes), &file).is_ok())));
}

/// quick-xml's reader alone, with the configuration `raw::parse` uses: the floor for the tree.
fn events(text: &str) -> bool {
    let mut reader = quick_xml::Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    loop {
        match reader.read_event() {
            Ok(quick_xml::events::Event::Eof) => return true,
            Ok(_) => {}
            Err(_) => return false,
        }
    }
}

/// Wall-clock and thread CPU durations of `n` runs of `f` after one untimed run, each sorted.
fn time(n: usize, mut f: impl FnMut() -> bool) -> (Vec<Duration>, Vec<Duration>) {
    f();
    let (mut wall, mut cpu): (Vec<_>, Vec<_>) = (0..n.max(1))
        .map(|_| {
            let (start, start_cpu) = (Instant::now(), cpu_now());
            f();
            (start.elapsed(), cpu_now().saturating_sub(start_cpu))
        })
        .unzip();
    wall.sort_unstable();
    cpu.sort_unstable();
    (wall, cpu)
}

/// CPU time of this thread: unlike wall-clock time, it does not count the time other
/// processes had the CPU, so it compares builds better on a busy machine.
fn cpu_now() -> Duration {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
    Duration::new(t.tv_sec as u64, t.tv_nsec as u32)
}

fn report(name: &str, (wall, cpu): (Vec<Duration>, Vec<Duration>)) {
    // Nearest rank, as `tutti-bench` computes it.
    let rank = |s: &[Duration], q: f64| s[((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    println!(
        "{name:<12} min {:>8.3}  p50 {:>8.3}  p99 {:>8.3} ms   cpu p50 {:>8.3} ms",
        ms(wall[0]),
        ms(rank(&wall, 0.5)),
        ms(rank(&wall, 0.99)),
        ms(rank(&cpu, 0.5))
    );
}
