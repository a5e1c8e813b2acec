//! `tutti demo`: runnable case studies. `tutti demo uav` is the paper's multi-UAV
//! co-simulation (section 7) with its figures reproduced; see docs/uav-demo.md.

use clap::Subcommand;

use super::CliResult;

mod analysis;
mod node;
mod plot;
mod scenario;
mod uav;

/// Run a case study: `tutti demo uav` (the paper's UAV formation, Figures 5 and 6).
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: DemoCommand,
}

#[derive(Debug, Subcommand)]
enum DemoCommand {
    /// The UAV formation co-simulation: framework, four UAV components, a Python monitoring
    /// script, two C components and the gateway; CSVs, figures and checks in --out.
    Uav(uav::UavArgs),
    /// Check and draw the results of a finished `tutti demo uav` run again.
    UavReport(uav::ReportArgs),
    /// One UAV component (started by `tutti demo uav`).
    #[command(hide = true)]
    UavNode(node::NodeArgs),
}

/// The float64 at byte `off` of a set.
fn f64_at(buf: &[u8], off: usize) -> f64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&buf[off..off + 8]);
    f64::from_ne_bytes(b)
}

pub fn run(args: Args) -> CliResult {
    match args.command {
        DemoCommand::Uav(a) => uav::run(a),
        DemoCommand::UavReport(a) => uav::run_report(a),
        DemoCommand::UavNode(a) => node::run(a),
    }
}
