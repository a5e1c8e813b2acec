//! `tutti bench ddf`: placeholder.

use super::super::CliResult;

#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> CliResult {
    Err(anyhow::anyhow!("not yet implemented").into())
}
