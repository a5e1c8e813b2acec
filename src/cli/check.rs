//! `tutti check DDF...`: validate files, report every problem.

use std::path::PathBuf;

use super::{CliResult, Failure};

/// Validate DDF files: every problem of every file is reported as FILE:LINE:COL: error: MESSAGE.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Exit status: 0 when every file is valid, 2 otherwise.\n\nExample:\n  tutti check ddf/multiuav.ddf ddf/product-sample.ddf"
)]
pub struct Args {
    /// DDF files to validate.
    #[arg(required = true, value_name = "DDF")]
    files: Vec<PathBuf>,
    /// Print nothing for valid files.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(args: Args) -> CliResult {
    let mut bad = 0;
    for file in &args.files {
        match tutti_core::ddf::load(file) {
            Ok(model) => {
                if !args.quiet {
                    let items: usize = model.domains.iter().map(|d| d.leaves().count()).sum();
                    println!(
                        "{}: ok ({}, {})",
                        file.display(),
                        super::count(model.domains.len(), "domain"),
                        super::count(items, "item")
                    );
                }
            }
            Err(e) => {
                eprintln!("{e}");
                bad += 1;
            }
        }
    }
    if bad == 0 {
        Ok(())
    } else {
        Err(Failure::invalid(anyhow::anyhow!("{bad} of {} files invalid", args.files.len())))
    }
}
