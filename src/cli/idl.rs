//! `tutti idl DDF --out DIR`: placeholder until the generator lands.

use std::path::PathBuf;

use super::CliResult;

/// Write OMG IDL 4 for every set, and a ROS 2 interface package.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[arg(value_name = "DDF")]
    file: PathBuf,
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> CliResult {
    let _ = (args.file, args.out);
    Err(anyhow::anyhow!("not yet implemented").into())
}
