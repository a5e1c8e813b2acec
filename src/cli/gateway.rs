//! `tutti gateway DDF`: bridge every domain of a DDF to DDS / ROS 2 (SPEC section 5).

use std::net::IpAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use super::show::ProfileArg;
use anyhow::Context;
use clap::ValueEnum;
use tutti_core::shm::WaitMode;
use tutti_gateway::{ClockSource, EngineKind, GatewayError, GatewayOptions, TypeMode};

use super::host::{parse_duration, parse_wait};
use super::{load_ddf, CliResult, Failure};

/// Bridge every domain of a DDF to DDS / ROS 2: each set is a topic (rt/DOMAIN/publish,
/// rt/DOMAIN/subscribe) bridged both ways, with the QoS the DDF's flags call for; the
/// gateway is one ROS 2 node. With --mirror it hosts local copies of the domains fed from
/// DDS, so components on another machine connect through shared memory.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti gateway ddf/multiuav.ddf\n  ROS_DOMAIN_ID=7 tutti gateway ddf/multiuav.ddf --ros2-types per-item\n  tutti gateway ddf/product-sample.ddf --qos-profile dds --strength 10\n  TUTTI_NAMESPACE=site2 tutti gateway ddf/multiuav.ddf --mirror --interface 192.0.2.2\n  tutti gateway ddf/multiuav.ddf --mirror --peer 192.0.2.1   # discovery without multicast\n  tutti gateway ddf/multiuav.ddf --dds rustdds\n  tutti gateway ddf/multiuav.ddf --clock multiuav_uav1 --clock-rate 100   # /clock for use_sim_time\n\nEnvironment:\n  ROS_DOMAIN_ID            DDS domain when --ros-domain-id is absent (default 0)\n  TUTTI_DDS                default for --dds\n  CYCLONEDDS_URI           Cyclone DDS configuration (cyclone engine)\n  TUTTI_NAMESPACE          namespace of the shared-memory segments\n  TUTTI_GATEWAY_INTERFACE  default for --interface (comma-separated addresses)\n  RUST_LOG                 log filter (default: info, DDS internals off)\n\nStop with Ctrl-C. Exit status: 0 stopped cleanly, 2 invalid input, 1 runtime failure."
)]
pub struct Args {
    /// The DDF whose domains to bridge.
    #[arg(value_name = "DDF")]
    file: PathBuf,
    /// DDS domain id, 0-232 (default: ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(0..=232))]
    ros_domain_id: Option<u16>,
    /// Type mapping: one struct per set (tutti idl's types) or one stock-typed topic per item.
    #[arg(long, value_enum, default_value_t = Types::Typed)]
    ros2_types: Types,
    /// QoS profile: ros2 (every endpoint SHARED, so rclpy matches) or dds (EXCLUSIVE
    /// ownership on the wire where multiplePublishAllowed=no).
    #[arg(long, value_enum, default_value_t = ProfileArg::Ros2)]
    qos_profile: ProfileArg,
    /// OWNERSHIP_STRENGTH of the gateway's writers in the dds profile.
    #[arg(long, default_value_t = 0)]
    strength: i32,
    /// Host local copies of the domains, fed from DDS (the other side of a co-simulation
    /// that spans machines).
    #[arg(long)]
    mirror: bool,
    /// ROS 2 node name.
    #[arg(long, default_value = "tutti_gateway")]
    node_name: String,
    /// Address of a network interface DDS may use (repeatable; default: all interfaces).
    #[arg(long = "interface", value_name = "ADDR")]
    interfaces: Vec<IpAddr>,
    /// DDS engine: cyclone (Cyclone DDS, the default) or rustdds (pure Rust).
    #[arg(long = "dds", env = "TUTTI_DDS", default_value = "cyclone", value_name = "ENGINE")]
    engine: EngineKind,
    /// Unicast discovery peer (address or host name; repeatable), for networks without
    /// multicast, e.g. the other machine of a --mirror pair (cyclone engine).
    #[arg(long = "peer", value_name = "ADDR")]
    peers: Vec<String>,
    /// Publish this domain's simulated time on /clock (rosgraph_msgs/msg/Clock, for ROS 2
    /// nodes with use_sim_time); default: the first synchronous domain; `none`: no /clock.
    #[arg(long, value_name = "DOMAIN")]
    clock: Option<String>,
    /// At most this many /clock samples a second (default: one per step).
    #[arg(long, value_name = "HZ", value_parser = parse_rate)]
    clock_rate: Option<f64>,
    /// Longest shared-memory wait; with --mirror, the framework's step timeout.
    #[arg(long, default_value = "1s", value_parser = parse_duration)]
    timeout: Duration,
    /// How shared-memory waits wait: block, spin, or poll:DURATION.
    #[arg(long, default_value = "block", value_parser = parse_wait)]
    wait: WaitMode,
    /// How often an idle asynchronous set is checked for changes (0: keep polling).
    #[arg(long, default_value = "500us", value_parser = parse_duration)]
    poll: Duration,
    /// Period of the status line on stderr.
    #[arg(long, default_value = "5s", value_parser = parse_duration)]
    status_every: Duration,
    /// Stop after this long (default: run until Ctrl-C).
    #[arg(long, value_parser = parse_duration)]
    duration: Option<Duration>,
    /// Print no status lines.
    #[arg(short, long)]
    quiet: bool,
    /// ROS namespace of every topic and of the node (rt/NS/DOMAIN/publish, /NS/NODE).
    #[arg(long, value_name = "NS", default_value = "")]
    ros_namespace: String,
    /// Bridge every domain of the DDF from the start, not only those a framework hosts in
    /// TUTTI_NAMESPACE.
    #[arg(long)]
    all_domains: bool,
    /// How long a DDS writer of a synchronous domain may owe a step's answer, silent, before
    /// its lock-step share is released.
    #[arg(long, default_value = "1s", value_parser = parse_duration)]
    lease: Duration,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Types {
    Typed,
    PerItem,
}

/// A positive rate in Hz.
fn parse_rate(s: &str) -> Result<f64, String> {
    match s.trim().trim_end_matches("Hz").trim_end_matches("hz").parse::<f64>() {
        Ok(r) if r > 0.0 && r.is_finite() => Ok(r),
        _ => Err(format!("'{s}' is not a rate in Hz (e.g. 100)")),
    }
}

/// The DDS domain: the flag, else ROS_DOMAIN_ID, else 0.
fn domain_id(flag: Option<u16>) -> Result<u16, Failure> {
    if let Some(id) = flag {
        return Ok(id);
    }
    match std::env::var("ROS_DOMAIN_ID") {
        Ok(s) if !s.trim().is_empty() => s
            .trim()
            .parse::<u16>()
            .ok()
            .filter(|&d| d <= 232)
            .ok_or_else(|| Failure::invalid(anyhow::anyhow!("ROS_DOMAIN_ID='{s}' is not a DDS domain id (0-232)"))),
        _ => Ok(0),
    }
}

fn interfaces(flag: Vec<IpAddr>) -> Result<Vec<IpAddr>, Failure> {
    if !flag.is_empty() {
        return Ok(flag);
    }
    match std::env::var("TUTTI_GATEWAY_INTERFACE") {
        Ok(s) if !s.trim().is_empty() => s
            .split(',')
            .map(|a| {
                a.trim()
                    .parse::<IpAddr>()
                    .map_err(|e| Failure::invalid(anyhow::anyhow!("TUTTI_GATEWAY_INTERFACE: '{a}': {e}")))
            })
            .collect(),
        _ => Ok(Vec::new()),
    }
}

pub fn run(args: Args) -> CliResult {
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,rustdds=off,ros2_client=off")),
        )
        .with_writer(std::io::stderr)
        // Colour only for a terminal: logs piped to a file or another program stay plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_target(false)
        .try_init();
    let model = load_ddf(&args.file)?;
    let mut opts = GatewayOptions::new(&args.file, model);
    opts.ros_domain_id = domain_id(args.ros_domain_id)?;
    opts.types = match args.ros2_types {
        Types::Typed => TypeMode::Typed,
        Types::PerItem => TypeMode::PerItem,
    };
    opts.profile = args.qos_profile.into();
    opts.strength = args.strength;
    opts.mirror = args.mirror;
    opts.node_name = args.node_name;
    opts.interfaces = interfaces(args.interfaces)?;
    opts.engine = args.engine;
    opts.peers = args.peers;
    opts.clock = match args.clock.as_deref() {
        None => ClockSource::FirstSynchronous,
        Some("none") => ClockSource::Off,
        Some(d) => ClockSource::Domain(d.to_string()),
    };
    opts.clock_rate = args.clock_rate;
    opts.timeout = args.timeout;
    opts.wait = args.wait;
    opts.poll = args.poll;
    opts.ros_namespace = args.ros_namespace;
    opts.hosted_only = !args.all_domains;
    opts.lease = args.lease;

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst)).context("installing the signal handler")?;
    }
    if let Some(d) = args.duration {
        let stop = stop.clone();
        std::thread::spawn(move || {
            std::thread::sleep(d);
            stop.store(true, Ordering::SeqCst);
        });
    }
    let quiet = args.quiet;
    let shown = args.file.display().to_string();
    let mut on_status = |line: &str| {
        if !quiet {
            eprintln!("tutti gateway: {line}");
        }
    };
    match tutti_gateway::run(opts, stop, args.status_every, &mut on_status) {
        Ok(stats) => {
            if !quiet {
                eprintln!("tutti gateway: stopped | {stats}");
            }
            Ok(())
        }
        Err(e @ GatewayError::Invalid(_)) => Err(Failure::invalid(anyhow::anyhow!("{shown}: {e}"))),
        Err(e) => Err(Failure::from(anyhow::Error::new(e).context(format!("gateway for {shown}")))),
    }
}
