//! `tutti studio [DDF...]`: the web app (crate `tutti-studio`): a DDF editor, a live
//! monitor of the namespace and run control. This module only reads the arguments, starts
//! the server, says where it listens and waits for Ctrl-C.

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::Context as _;
use tutti_core::shm::segment::namespace_from_env;
use tutti_studio::{Config, Running};

use super::{CliResult, Failure};

/// A web app to author DDFs and watch a running co-simulation live.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti studio ddf/multiuav.ddf\n  tutti studio --root ~/cosim --read-only\n  tutti studio --listen 0.0.0.0:8470   (prints a token the page must be opened with)\n\nThen open the address it prints (default http://127.0.0.1:8470/). Walkthrough: docs/studio.md."
)]
pub struct Args {
    /// DDFs to offer first (under --root).
    #[arg(value_name = "DDF")]
    files: Vec<String>,
    /// Address to listen on; anything but a loopback address requires a token.
    #[arg(long, default_value = "127.0.0.1:8470", value_name = "ADDR")]
    listen: SocketAddr,
    /// Files are opened and saved only under this folder (default: the current folder).
    #[arg(long, default_value = ".", value_name = "DIR")]
    root: PathBuf,
    /// No saving and no run control.
    #[arg(long)]
    read_only: bool,
}

pub fn run(args: Args) -> CliResult {
    let token = if args.listen.ip().is_loopback() {
        None
    } else {
        Some(tutti_studio::make_token().context("making the access token")?)
    };
    let config = Config {
        listen: args.listen,
        root: args.root,
        files: args.files,
        read_only: args.read_only,
        token: token.clone(),
        namespace: namespace_from_env(),
        tutti_exe: std::env::current_exe().ok(),
    };
    let running = Running::start(config).map_err(|e| {
        if e.is_usage() {
            Failure::invalid(e)
        } else {
            Failure::from(anyhow::Error::from(e))
        }
    })?;
    match &token {
        Some(t) => eprintln!("tutti studio: listening on http://{}/?token={t}", running.addr()),
        None => eprintln!("tutti studio: listening on http://{}/", running.addr()),
    }
    let stop = super::stop_flag()?;
    while !stop.load(std::sync::atomic::Ordering::SeqCst) {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    running.stop();
    Ok(())
}
