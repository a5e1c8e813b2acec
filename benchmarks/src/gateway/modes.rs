//! The hidden peer modes (`--echo`, `--sink`, `--source`): the DDS peers of the benchmark,
//! child processes of it.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context as _};
use tutti_core::ddf::Role;
use tutti_gateway::{EngineKind, GatewayOptions};
use tutti_host::ChildProcess;

use super::{Args, PATIENCE};
use crate::peers::Received;
use crate::{load_ddf, CliResult};

/// The sink's "samples seconds lost misordered skipped-joining" line; waits for it to exit.
pub(super) fn sink_result(kid: &mut ChildProcess) -> anyhow::Result<Received> {
    let mut line = String::new();
    if let Some(out) = kid.child.stdout.take() {
        BufReader::new(out).read_line(&mut line)?;
    }
    let v: Vec<f64> = line.split_whitespace().filter_map(|w| w.parse().ok()).collect();
    match v[..] {
        [samples, secs, lost, misordered, skipped_joining] if secs > 0.0 => Ok(Received {
            samples: samples as u64,
            secs,
            lost: lost as u64,
            misordered: misordered as u64,
            skipped_joining: skipped_joining as u64,
        }),
        _ => bail!("the sink received nothing"),
    }
}

/// The options of a peer (or an in-process gateway) on `engine` in DDS domain `domain_id`,
/// on loopback; on Zenoh, connected to the run's router at `zenoh_router`.
pub(super) fn peer_opts(
    ddf: &Path,
    domain_id: u16,
    engine: EngineKind,
    zenoh_router: Option<&str>,
) -> anyhow::Result<(GatewayOptions, tutti_core::ddf::Domain)> {
    let model = load_ddf(ddf).map_err(|f| f.error)?;
    let mut opts = GatewayOptions::new(ddf, model.clone());
    opts.ros_domain_id = domain_id;
    opts.engine = engine;
    opts.interfaces = vec![std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST)];
    opts.zenoh_connect = zenoh_router.into_iter().map(str::to_string).collect();
    // A peer of a secured run takes its enclave as rcl would (ROS_SECURITY_*, set by the run).
    opts.security = tutti_gateway::engine::security::SecuritySettings::from_env()?.resolve(engine)?;
    let d = model.domains.first().context("the DDF has no domain")?.clone();
    Ok((opts, d))
}

pub(super) fn echo(ddf: &Path, args: &Args) -> CliResult {
    let (opts, d) = peer_opts(ddf, args.ros_domain_id, args.dds, args.zenoh_connect.as_deref())?;
    crate::peers::run(&opts, &d, tutti_exit::stop_flag()?).map_err(anyhow::Error::new)?;
    Ok(())
}

pub(super) fn sink(ddf: &Path, role: &str, args: &Args) -> CliResult {
    let (opts, d) = peer_opts(ddf, args.ros_domain_id, args.dds, args.zenoh_connect.as_deref())?;
    let role = if role == "publish" { Role::Publish } else { Role::Subscribe };
    let r = crate::peers::sink(&opts, &d, role, args.duration, PATIENCE, args.ordered).map_err(anyhow::Error::new)?;
    println!("{} {} {} {} {}", r.samples, r.secs, r.lost, r.misordered, r.skipped_joining);
    Ok(())
}

pub(super) fn source(ddf: &Path, args: &Args) -> CliResult {
    let (opts, d) = peer_opts(ddf, args.ros_domain_id, args.dds, args.zenoh_connect.as_deref())?;
    crate::peers::source(&opts, &d, Duration::from_millis(500), tutti_exit::stop_flag()?)
        .map_err(anyhow::Error::new)?;
    Ok(())
}
