//! `tutti bench …`: benchmarks that print percentiles and compare against a peer in the
//! same run. Results are recorded in `docs/benchmarks.md`.

use clap::Subcommand;

use super::CliResult;

mod ddf;
mod gateway;

/// Run a benchmark.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Debug, Subcommand)]
enum What {
    /// Parse and validate a large DDF (default: the 1,000-domain file) and print the time.
    Ddf(ddf::Args),
    /// Round trip and throughput through the DDS gateway, next to Cyclone's ddsperf.
    Gateway(gateway::Args),
}

pub fn run(args: Args) -> CliResult {
    match args.what {
        What::Ddf(a) => ddf::run(a),
        What::Gateway(a) => gateway::run(a),
    }
}
