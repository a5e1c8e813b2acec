//! `tutti host DDF`: a generic framework that creates every domain of a DDF and steps them
//! at a fixed period; optionally records both sets of every domain (MCAP or CSV) and runs the
//! DDS / ROS 2 gateway in its own process (`--gateway`). The run is the `tutti-host` crate's
//! [`Host`], the gateway `tutti_gateway::in_process`; this module parses, builds their
//! options and prints.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use tutti_core::parse::{parse_duration, parse_wait};
use tutti_core::shm::WaitMode;
use tutti_gateway::in_process::InProcess;
use tutti_host::{Host, HostError, HostOptions};

use super::{load_ddf, CliResult, Failure};

/// Run the framework of every domain in a DDF: create the segments, step at a fixed period.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti host ddf/multiuav.ddf --step 10ms --duration 60s\n  tutti host examples/event/tank.ddf --step 1ms --speed 0 --steps 100000   # as fast as possible\n  tutti host ddf/product-sample.ddf --set grid_clock/tick=1 --record out/run.csv\n  tutti host ddf/multiuav.ddf --step 10ms --duration 60s --record out/run.mcap   # Foxglove, ros2 bag\n  TUTTI_NAMESPACE=lab2 tutti host ddf/large-1000.ddf --step 1ms\n  sudo tutti host ddf/multiuav.ddf --step 1ms --realtime --cpu 1 --priority 80\n  tutti host ddf/multiuav.ddf --wait-for multiuav_uav2=1 --record run.mcap   # replay later: tutti replay\n  tutti host ddf/multiuav.ddf --connect 'multiuav_uav2/subscribe/Elevation -> multiuav_uav2/publish/Altitude'\n  ROS_DOMAIN_ID=7 tutti host ddf/multiuav.ddf --gateway   # the DDS / ROS 2 gateway in this process\n  tutti host ddf/multiuav.ddf --gateway=examples/gateway.json5\n\nWith --gateway, the gateway reads the environment as tutti gateway does (ROS_DOMAIN_ID,\nROS_LOCALHOST_ONLY, ROS_AUTOMATIC_DISCOVERY_RANGE, TUTTI_DDS, TUTTI_GATEWAY_INTERFACE,\nCYCLONEDDS_URI, ZENOH_SESSION_CONFIG_URI, ZENOH_CONFIG_OVERRIDE, RUST_LOG); its config file's keys win over the environment.\n\nStop with Ctrl-C: the segments are removed on exit."
)]
pub struct Args {
    /// The DDF whose domains to host.
    #[arg(value_name = "DDF")]
    file: PathBuf,
    /// Step period (e.g. 1ms, 500us, 0.1s).
    #[arg(long, default_value = "10ms", value_parser = parse_duration)]
    step: Duration,
    /// Stop after this long (default: run until Ctrl-C).
    #[arg(long, value_parser = parse_duration)]
    duration: Option<Duration>,
    /// Stop after this many steps (with --duration, whichever comes first).
    #[arg(long)]
    steps: Option<u64>,
    /// Simulated seconds per wall-clock second; 0: as fast as the participants go, where
    /// event-driven domains jump over the steps nobody is due at (docs/timing.md).
    #[arg(long, default_value = "1", value_parser = parse_speed)]
    speed: f64,
    /// Record both sets of every domain at every step, by FILE's extension: `.mcap` (one
    /// file, ROS 2 CDR with schemas: Foxglove, ros2 bag) or CSV (one file per domain when
    /// there are several: FILE's stem + '-DOMAIN.csv'). Repeatable.
    #[arg(long, value_name = "FILE")]
    record: Vec<PathBuf>,
    /// When the loop falls behind, run the late steps back to back instead of skipping them:
    /// simulated time stays at one step per period (it then lags the wall clock), so a run's
    /// results do not depend on the machine's load.
    #[arg(long)]
    catch_up: bool,
    /// Longest wait for the participants of a synchronous step, and for a seed.
    #[arg(long, default_value = tutti_core::defaults::STEP_TIMEOUT_TEXT, value_parser = parse_duration)]
    timeout: Duration,
    /// How the framework waits for participants: adaptive (yield up to 50 µs, then block; the default), adaptive:DURATION, block, spin or poll:DURATION.
    #[arg(long, default_value = "adaptive", value_parser = parse_wait)]
    wait: WaitMode,
    /// Connection slots per domain: participants, recorders and gateways at once.
    #[arg(long, default_value_t = tutti_core::shm::DEFAULT_CONNECTIONS, value_parser = clap::value_parser!(u32).range(1..=4096))]
    slots: u32,
    /// Give a PUBLISH item a value: DOMAIN/ITEM=VALUE (repeatable; arrays get it in every element).
    #[arg(long = "set", value_name = "DOMAIN/ITEM=VALUE")]
    sets: Vec<String>,
    /// Hold participants in connect (wait-to-go) for this long after start.
    #[arg(long, value_parser = parse_duration)]
    hold: Option<Duration>,
    /// Before the first step, hold participants in wait-to-go until N writers (participants
    /// that have committed once) are connected to DOMAIN, so that they answer every step
    /// from the first; repeatable.
    #[arg(long = "wait-for", value_name = "DOMAIN=N", value_parser = tutti_host::parse_wait_for)]
    wait_for: Vec<(String, usize)>,
    /// Copy an output to an input at every step: 'FROM -> TO [* GAIN] [+ OFFSET]', each end
    /// DOMAIN/ROLE/ITEM (FROM a subscribe item, TO a publish item); repeatable. The value
    /// reaches the input at the next step (docs/run.md, "Connections").
    #[arg(long = "connect", value_name = "CONNECTION", value_parser = tutti_host::connect::parse_connection)]
    connections: Vec<tutti_host::connect::ConnectionSpec>,
    /// How the connections are applied within a step: 'delayed' (each carries its output's
    /// value of the step before) or 'feedthrough' (domains fed by other domains are
    /// evaluated again within the step, in graph order; docs/run.md, "Connections").
    #[arg(long, value_name = "ORDERING", default_value = "delayed")]
    ordering: tutti_host::connect::StepOrder,
    /// Run the DDS / ROS 2 gateway in this process, as `tutti gateway DDF --config CONFIG`
    /// would (the config file is optional; its `duration` and `mirror` keys do not apply):
    /// the framework's PUBLISH sets go to DDS from each step, with no poller in between.
    /// Give CONFIG as --gateway=CONFIG, or after the DDF.
    #[arg(long, value_name = "CONFIG", num_args = 0..=1)]
    gateway: Option<Option<PathBuf>>,
    #[command(flatten)]
    rt: super::RealtimeArgs,
    /// Print no progress lines.
    #[arg(short, long)]
    quiet: bool,
}

impl Args {
    fn options(&self) -> HostOptions {
        HostOptions {
            step: self.step,
            speed: self.speed,
            duration: self.duration,
            steps: self.steps,
            catch_up: self.catch_up,
            timeout: self.timeout,
            wait: self.wait,
            namespace: None,
            sets: self.sets.clone(),
            hold: self.hold,
            wait_for: self.wait_for.clone(),
            hold_until_start: false,
            connections: self.connections.clone(),
            ordering: self.ordering,
            ddf_name: self.file.display().to_string(),
            slots: self.slots,
            ..Default::default()
        }
    }
}

/// `--speed`: a factor, or 0 for as fast as possible (an infinite speed).
fn parse_speed(s: &str) -> anyhow::Result<f64> {
    match s.trim().parse::<f64>() {
        Ok(0.0) => Ok(f64::INFINITY),
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => anyhow::bail!("'{s}' is not a speed: a factor like 1, 0.5 or 10, or 0 for as fast as possible"),
    }
}

/// A run's error with its exit status: 2 for options that cannot apply, else 1.
fn host_failure(e: HostError) -> Failure {
    Failure::classed(e.is_invalid(), e)
}

pub fn run(args: Args) -> CliResult {
    let model = load_ddf(&args.file)?;
    let stop = super::stop_flag()?;
    let started = Instant::now();
    let mut host = Host::new(&model, args.options()).map_err(host_failure)?;
    host.serve_control(stop.clone(), None).map_err(host_failure)?;
    if !args.quiet {
        eprintln!(
            "host: {} domain(s) of {} created in {:.1} ms (namespace {}), step {:?}",
            host.framework().domains.len(),
            args.file.display(),
            started.elapsed().as_secs_f64() * 1e3,
            host.namespace(),
            args.step
        );
    }
    let gateway = match &args.gateway {
        Some(config) => Some(start_gateway(&args.file, &model, config.as_deref(), args.quiet, "host", &mut host)?),
        None => None,
    };
    for path in &args.record {
        let recorder = tutti_record::create(path, &model, &args.file).context("starting the recording")?;
        host.add_sink(Box::new(tutti_record::RecordingSink(recorder)));
    }
    super::enter_realtime(&args.rt, "host", args.quiet);
    let quiet = args.quiet;
    let summary = host
        .run(&stop, |report| {
            if !quiet {
                eprintln!("host: {report}");
            }
        })
        .map_err(host_failure)?;
    if !quiet && summary.started {
        eprintln!("host: {summary}");
    }
    if let Some(gw) = gateway {
        let stats = gw.stop();
        if !quiet {
            eprintln!("host: gateway: stopped | {stats}");
        }
    }
    Ok(())
}

/// `--gateway [CONFIG]`: the gateway for `host`'s domains in this process, its sink added to
/// the host (first, so DDS has each step before the recordings take it); its status lines
/// start with `who` (`host`, `replay`).
pub fn start_gateway(
    file: &std::path::Path,
    model: &tutti_core::ddf::Model,
    config: Option<&std::path::Path>,
    quiet: bool,
    who: &'static str,
    host: &mut Host,
) -> Result<InProcess, Failure> {
    super::gateway::init_logging();
    let flags = tutti_gateway::config::ConfigFile::default();
    let (opts, keys) = super::gateway::configured(file, model.clone(), flags, config)?;
    let quiet = quiet || keys.gateway.quiet.unwrap_or(false);
    let status_every = keys.gateway.status_every.unwrap_or(Duration::from_secs(5));
    let on_status = Box::new(move |line: &str| {
        if !quiet {
            eprintln!("{who}: gateway: {line}");
        }
    });
    let (gw, sink) = tutti_gateway::in_process::start(opts, host.namespace(), status_every, on_status)
        .map_err(|e| Failure::classed(e.is_invalid(), anyhow::Error::new(e).context("starting the gateway")))?;
    host.add_sink(Box::new(sink));
    Ok(gw)
}
