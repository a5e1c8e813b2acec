//! Subcommands of `tutti`, one module each. Exit status: 0 success, 2 invalid input or
//! usage, 1 runtime failure (`docs/cli.md`).

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod check;
mod ctl;
mod fmu;
mod gateway;
mod host;
mod idl;
mod record;
mod replay;
mod run;
mod show;
mod ssp;
mod status;
mod studio;

pub use tutti_exit::{enter_realtime, load_ddf, CliResult, Failure, RealtimeArgs};

/// `tutti --version`: the version, the commit built and the gateway's engines (build.rs).
const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    " (commit ",
    env!("TUTTI_BUILD_COMMIT"),
    "; engines: ",
    env!("TUTTI_BUILD_ENGINES"),
    ")"
);

#[derive(Debug, Parser)]
#[command(
    name = "tutti",
    version = VERSION,
    about = "Real-time co-simulation data layer: shared-memory domains described by a DDF, an RTAPI for C, Rust and Python components, and a DDS / ROS 2 gateway",
    after_help = "Examples:\n  tutti check ddf/multiuav.ddf\n  tutti show ddf/multiuav.ddf --json\n  tutti idl ddf/multiuav.ddf --out idl/multiuav\n\nEnvironment:\n  TUTTI_NAMESPACE   namespace of the shared-memory segments (default: tutti)\n  ROS_DOMAIN_ID     DDS domain of the gateway when --ros-domain-id is absent"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    Check(check::Args),
    Show(show::Args),
    Idl(idl::Args),
    Host(host::Args),
    Status(status::Args),
    Ctl(ctl::Args),
    Record(record::Args),
    Replay(replay::Args),
    Gateway(gateway::Args),
    Studio(studio::Args),
    Fmu(fmu::Args),
    Run(run::Args),
    Ssp(ssp::Args),
}

/// The flag Ctrl-C (or SIGTERM) raises: a command's loop stops when it is set.
pub fn stop_flag() -> Result<std::sync::Arc<std::sync::atomic::AtomicBool>, Failure> {
    Ok(tutti_exit::stop_flag()?)
}

pub fn run(cli: Cli) -> ExitCode {
    let result = match cli.command {
        Command::Check(a) => check::run(a),
        Command::Show(a) => show::run(a),
        Command::Idl(a) => idl::run(a),
        Command::Host(a) => host::run(a),
        Command::Status(a) => status::run(a),
        Command::Ctl(a) => ctl::run(a),
        Command::Record(a) => record::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Gateway(a) => gateway::run(a),
        Command::Studio(a) => studio::run(a),
        Command::Fmu(a) => fmu::run(a),
        Command::Run(a) => run::run(a),
        Command::Ssp(a) => ssp::run(a),
    };
    tutti_exit::exit(result)
}

/// `1 domain`, `4 domains`: a count with its noun.
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}
