//! `tutti-demo`: runnable case studies. `tutti-demo uav` is the paper's multi-UAV
//! co-simulation (section 7) with its figures reproduced; see docs/uav-demo.md.
//!
//! A workspace member of its own beside `tutti-uav`, so that `tutti` links none of what only
//! the demo needs (plotters, resvg). The demo's scenario is a launch file run by `tutti run`
//! (the `tutti` executable next to this one, [`tutti_exe`]): the framework, the FMU component
//! and the gateway are `tutti`; its UAV components are this executable again (`tutti-demo
//! uav-node`).
//!
//! Modules: `scenario` (the script and its constants) ← `node` (one UAV component) ←
//! `analysis` (the checks) ← `plot` (the figures); `sim` (the launch file and its run) ←
//! `recording` (the framework's tables from the run's recording) ← `uav` (the command: its
//! options, the run and its report).

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod analysis;
mod node;
mod plot;
mod recording;
mod scenario;
mod sim;
mod uav;

/// Run a case study: `tutti-demo uav` (the paper's UAV formation, Figures 5 and 6).
#[derive(Debug, Parser)]
#[command(name = "tutti-demo", version)]
struct Args {
    #[command(subcommand)]
    command: DemoCommand,
}

pub use tutti_exit::{tutti_exe, CliResult, Failure, RealtimeArgs, EXIT_FAILURE};

#[derive(Debug, Subcommand)]
enum DemoCommand {
    /// The UAV formation co-simulation: framework, four UAV components, a Python monitoring
    /// script, two C components and the gateway; CSVs, figures and checks in --out.
    Uav(uav::UavArgs),
    /// Check and draw the results of a finished `tutti-demo uav` run again.
    UavReport(uav::ReportArgs),
    /// One UAV component (started by `tutti-demo uav`).
    #[command(hide = true)]
    UavNode(node::NodeArgs),
}

/// The float64 at byte `off` of a set.
fn f64_at(buf: &[u8], off: usize) -> f64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&buf[off..off + 8]);
    f64::from_ne_bytes(b)
}

fn main() -> ExitCode {
    let result = match Args::parse().command {
        DemoCommand::Uav(a) => uav::run(a),
        DemoCommand::UavReport(a) => uav::run_report(a),
        DemoCommand::UavNode(a) => node::run(a),
    };
    tutti_exit::exit(result)
}
