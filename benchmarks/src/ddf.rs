//! `tutti-bench ddf`: how long parsing and validating a large DDF takes.
//!
//! The file is read once; then, after one untimed warm-up, each phase runs `--iterations`
//! times: the XML reader alone (`raw::parse`, the floor any validation adds to), the full
//! `parse_bytes` from memory (XML, validation, layouts, hashes), and `load` from the file
//! (the same plus `open` and `read`). Results are in `docs/benchmarks.md`.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context as _;

use crate::nearest_rank;
use crate::{CliResult, Failure};

/// The default input, as the checkout has it.
const DEFAULT: &str = "ddf/large-1000.ddf";

/// Time parsing and validating a DDF: min, p50, p99 and max over N runs.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  cargo run --release -p tutti-bench -- ddf --iterations 200\n\nWithout --file: ddf/large-1000.ddf of the current directory, or, outside a checkout, the same\nfile generated (1,000 domains of 20 items) into a temporary file."
)]
pub struct Args {
    /// The DDF to parse (default: ddf/large-1000.ddf).
    #[arg(long, value_name = "DDF")]
    file: Option<PathBuf>,
    /// Timed runs of each phase.
    #[arg(long, value_name = "N", default_value_t = 50, value_parser = clap::value_parser!(u32).range(1..))]
    iterations: u32,
}

/// A generated copy of the default input, removed when dropped.
struct Generated(PathBuf);

impl Drop for Generated {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

pub fn run(args: Args) -> CliResult {
    let mut generated = None;
    let file = match args.file {
        Some(f) => f,
        None if std::path::Path::new(DEFAULT).exists() => PathBuf::from(DEFAULT),
        None => {
            // Outside a checkout: the committed file is this generator's output.
            let path = std::env::temp_dir().join(format!("tutti-bench-large-1000-{}.ddf", std::process::id()));
            std::fs::write(&path, tutti_core::ddf::synth::large_ddf(1000, 20))
                .with_context(|| format!("writing {}", path.display()))?;
            eprintln!("{DEFAULT} is not here: timing the same file generated as {}", path.display());
            generated.insert(Generated(path)).0.clone()
        }
    };
    let args = Resolved { file, iterations: args.iterations };
    let shown = args.file.display().to_string();
    let bytes = std::fs::read(&args.file).with_context(|| format!("cannot read {shown}")).map_err(Failure::invalid)?;
    // Validate once (and warm caches and the allocator) before timing anything.
    let model = tutti_core::ddf::parse_bytes(&bytes, &shown).map_err(Failure::invalid)?;
    let text = std::str::from_utf8(&bytes).context("the DDF is not UTF-8")?;
    let leaves: usize = model.domains.iter().map(|d| d.leaves().count()).sum();
    let n = args.iterations;

    let raw = time(n, || {
        black_box(tutti_core::ddf::raw::parse(black_box(text)).is_ok());
    });
    let full = time(n, || {
        black_box(tutti_core::ddf::parse_bytes(black_box(&bytes), &shown).is_ok());
    });
    let load = time(n, || {
        black_box(tutti_core::ddf::load(black_box(&args.file)).is_ok());
    });

    println!(
        "DDF parse and validate: {shown}, {} bytes, {} domains, {leaves} items; {n} runs per phase after 1 warm-up, single thread",
        bytes.len(),
        model.domains.len(),
    );
    println!("{:<44} {:>9} {:>9} {:>9} {:>9} {:>10}", "phase (ms)", "min", "p50", "p99", "max", "MB/s p50");
    for (name, stats) in [
        ("XML to tree only (raw::parse)", &raw),
        ("parse + validate + layout (parse_bytes)", &full),
        ("read + parse + validate (load)", &load),
    ] {
        let mbps = bytes.len() as f64 / 1e6 / stats.p50.as_secs_f64();
        println!(
            "{name:<44} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {mbps:>10.1}",
            ms(stats.min),
            ms(stats.p50),
            ms(stats.p99),
            ms(stats.max)
        );
    }
    Ok(())
}

/// The arguments with the input chosen.
struct Resolved {
    file: PathBuf,
    iterations: u32,
}

/// Order statistics of a set of timings.
#[derive(Debug)]
struct Stats {
    min: Duration,
    p50: Duration,
    p99: Duration,
    max: Duration,
}

fn time(n: u32, mut f: impl FnMut()) -> Stats {
    let mut samples: Vec<Duration> = (0..n)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed()
        })
        .collect();
    samples.sort_unstable();
    Stats {
        min: samples[0],
        p50: nearest_rank(&samples, 0.50),
        p99: nearest_rank(&samples, 0.99),
        max: samples[samples.len() - 1],
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let s: Vec<Duration> = (1..=100).map(Duration::from_millis).collect();
        assert_eq!(nearest_rank(&s, 0.50), Duration::from_millis(50));
        assert_eq!(nearest_rank(&s, 0.99), Duration::from_millis(99));
        assert_eq!(nearest_rank(&s[..1], 0.99), Duration::from_millis(1));
        assert_eq!(nearest_rank(&s[..3], 0.50), Duration::from_millis(2));
    }
}
