//! `tutti gateway DDF`: bridge every domain of a DDF to DDS / ROS 2 (`docs/gateway.md`).

use std::net::{IpAddr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Duration;

use clap::ValueEnum;
use tutti_core::ddf::Model;
use tutti_core::mapping::Profile;
use tutti_core::shm::WaitMode;
use tutti_gateway::config::{self, ConfigFile, EngineKeys, GatewayKeys, PlanKeys, Strategy};
use tutti_gateway::foxglove::FoxgloveKeys;
use tutti_gateway::http::HttpKeys;
use tutti_gateway::{EngineKind, GatewayOptions, TypeMode};

use super::{load_ddf, CliResult, Failure};

/// Bridge every domain of a DDF to DDS / ROS 2: each set is a topic (rt/DOMAIN/publish,
/// rt/DOMAIN/subscribe) bridged both ways, with the QoS the DDF's flags call for; the
/// gateway is one ROS 2 node. With --mirror it hosts local copies of the domains fed from
/// DDS, so components on another machine connect through shared memory. Every option can
/// also come from a --config file (flags given here win over it).
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Examples:\n  tutti gateway ddf/multiuav.ddf\n  ROS_DOMAIN_ID=7 tutti gateway ddf/multiuav.ddf --ros2-types per-item\n  tutti gateway ddf/product-sample.ddf --qos-profile dds --strength 10\n  TUTTI_NAMESPACE=site2 tutti gateway ddf/multiuav.ddf --mirror --interface 192.0.2.2\n  tutti gateway ddf/multiuav.ddf --mirror --peer 192.0.2.1   # discovery without multicast\n  tutti gateway ddf/multiuav.ddf --peer 192.0.2.2 --lookahead 10   # the mirror's answers 10 steps late\n  tutti gateway ddf/multiuav.ddf --mirror --peer 192.0.2.1 --lookahead 10   # its side of that link\n  tutti gateway ddf/multiuav.ddf --engine rustdds\n  tutti gateway ddf/multiuav.ddf --engine zenoh   # for rmw_zenoh nodes; run rmw_zenohd first\n  tutti gateway ddf/multiuav.ddf --security --security-keystore keys --enclave /tutti/gateway --security-strategy Enforce\n  tutti gateway ddf/multiuav.ddf --clock multiuav_uav1 --clock-rate 100   # /clock for use_sim_time\n  tutti gateway ddf/multiuav.ddf --config examples/gateway.json5   # tutti show --config shows its topics\n  tutti gateway ddf/multiuav.ddf --ros-namespace sim1 --http 127.0.0.1:9100   # /sim1/...; curl .../metrics\n\nEnvironment (a flag, then the --config file, win over these):\n  ROS_DOMAIN_ID            DDS domain (default 0)\n  ROS_LOCALHOST_ONLY=1     DDS on loopback only (as ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST)\n  ROS_AUTOMATIC_DISCOVERY_RANGE  SUBNET or SYSTEM_DEFAULT: as configured; LOCALHOST: loopback only;\n                           OFF: refused unless --peer is given\n  TUTTI_DDS                default for --engine\n  CYCLONEDDS_URI           Cyclone DDS configuration (cyclone engine)\n  ZENOH_SESSION_CONFIG_URI Zenoh session config file, as rmw_zenoh reads it (zenoh engine)\n  ZENOH_CONFIG_OVERRIDE    key=value;... laid over it, as rmw_zenoh does (zenoh engine)\n  ROS_SECURITY_ENABLE=true DDS Security (SROS2), as --security\n  ROS_SECURITY_KEYSTORE    default for --security-keystore\n  ROS_SECURITY_ENCLAVE_OVERRIDE  default for --enclave\n  ROS_SECURITY_STRATEGY    default for --security-strategy (Enforce or Permissive)\n  TUTTI_NAMESPACE          namespace of the shared-memory segments\n  TUTTI_GATEWAY_INTERFACE  default for --interface (comma-separated addresses)\n  RUST_LOG                 log filter (default: info, DDS internals off, Zenoh's warnings only)\n\nStop with Ctrl-C. Exit status: 0 stopped cleanly, 2 invalid input, 1 runtime failure."
)]
pub struct Args {
    /// The DDF whose domains to bridge.
    #[arg(value_name = "DDF")]
    file: PathBuf,
    /// Read options from this JSON5 file: its keys are these flags with '_' for '-', plus
    /// allow, deny and topics (which sets, per-topic QoS, rate and name); see
    /// examples/gateway.json5.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// DDS domain id, 0-232 (default: ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "N", value_parser = domain_ids())]
    ros_domain_id: Option<u16>,
    /// Type mapping: one struct per set (tutti idl's types; the default) or one stock-typed
    /// topic per item.
    #[arg(long, value_enum)]
    ros2_types: Option<Types>,
    /// QoS profile: ros2 (the default: every endpoint SHARED, so rclpy matches) or dds
    /// (EXCLUSIVE ownership on the wire where multiplePublishAllowed=no).
    #[arg(long, value_enum)]
    qos_profile: Option<ProfileArg>,
    /// OWNERSHIP_STRENGTH of the gateway's writers in the dds profile (default 0).
    #[arg(long, value_name = "N")]
    strength: Option<i32>,
    /// Host local copies of the domains, fed from DDS (the other side of a co-simulation
    /// that spans machines).
    #[arg(long)]
    mirror: bool,
    /// ROS 2 node name (default tutti_gateway).
    #[arg(long, value_name = "NAME")]
    node_name: Option<String>,
    /// ROS namespace of every topic and of the node: /NS/DOMAIN/publish, node /NS/NAME.
    #[arg(long, value_name = "NS", value_parser = config::parse_namespace)]
    ros_namespace: Option<String>,
    /// Bridge every domain of the DDF from the start, not only those a framework hosts in
    /// TUTTI_NAMESPACE.
    #[arg(long)]
    all_domains: bool,
    /// DDS readers of a synchronous PUBLISH set get every step: the gateway reads it in
    /// lock-step, so the framework waits for its copy of each step (default: DDS readers
    /// never hold a domain back, and a step the framework outruns them on is skipped).
    #[arg(long)]
    every_step: bool,
    /// Offer no simulation_interfaces services (docs/ros2.md): bridge data only, never
    /// control the run.
    #[arg(long)]
    passive: bool,
    /// Take the answers of a synchronous domain's remote writers (a mirror on another site)
    /// K steps late, so that the framework runs up to K steps ahead of the link: K for every
    /// synchronous domain, or DOMAIN=K (repeatable); default 0, lock-step. Give a --mirror the
    /// home's K too: it steps the home's latest K + 1 steps and skips older ones (docs/run.md,
    /// "Sites and lookahead").
    #[arg(long = "lookahead", value_name = "K|DOMAIN=K", value_parser = config::parse_lookahead)]
    lookahead: Vec<config::Lookahead>,
    /// Address of a network interface DDS may use (repeatable; default: all interfaces).
    #[arg(long = "interface", value_name = "ADDR")]
    interfaces: Vec<IpAddr>,
    /// Engine: cyclone (Cyclone DDS, the default), rustdds (pure Rust DDS) or zenoh (rmw_zenoh's
    /// wire format, through a Zenoh router); `--dds` is an alias.
    #[arg(long = "engine", visible_alias = "dds", value_name = "ENGINE")]
    engine: Option<EngineKind>,
    /// Unicast discovery peer (an IPv4 address or a host name that resolves, with an optional
    /// :PORT; repeatable), for networks without multicast, e.g. the other machine of a
    /// --mirror pair (cyclone engine).
    #[arg(long = "peer", value_name = "ADDR", value_parser = config::parse_peer)]
    peers: Vec<String>,
    /// Zenoh endpoint to connect to (repeatable; zenoh engine; default: the router at
    /// tcp/localhost:7447, as rmw_zenoh nodes do, or ZENOH_SESSION_CONFIG_URI's).
    #[arg(long = "zenoh-connect", value_name = "ENDPOINT")]
    zenoh_connect: Vec<String>,
    /// Zenoh endpoint to listen on (repeatable; zenoh engine; default tcp/localhost:0).
    #[arg(long = "zenoh-listen", value_name = "ENDPOINT")]
    zenoh_listen: Vec<String>,
    /// Run the DDS participant under DDS Security, as an SROS2 node does with
    /// ROS_SECURITY_ENABLE=true (cyclone engine; docs/security.md).
    #[arg(long)]
    security: bool,
    /// The SROS2 keystore (default: ROS_SECURITY_KEYSTORE).
    #[arg(long, value_name = "DIR")]
    security_keystore: Option<PathBuf>,
    /// The gateway's enclave in the keystore, like /tutti/gateway (default:
    /// ROS_SECURITY_ENCLAVE_OVERRIDE, else /).
    #[arg(long, value_name = "NAME")]
    enclave: Option<String>,
    /// Enforce: refuse to start unless the enclave's files check out; Permissive: warn and
    /// run unsecured (default: ROS_SECURITY_STRATEGY, else Permissive, as rcl).
    #[arg(long, value_name = "STRATEGY", value_parser = |s: &str| s.parse::<Strategy>())]
    security_strategy: Option<Strategy>,
    /// Publish this domain's simulated time on /clock (rosgraph_msgs/msg/Clock, for ROS 2
    /// nodes with use_sim_time); default: the first synchronous domain; `none`: no /clock.
    #[arg(long, value_name = "DOMAIN")]
    clock: Option<String>,
    /// At most this many /clock samples a second (default: one per step).
    #[arg(long, value_name = "HZ", value_parser = config::parse_rate)]
    clock_rate: Option<f64>,
    /// Longest shared-memory wait; with --mirror, the framework's step timeout (default 1s).
    #[arg(long, value_name = "DURATION", value_parser = config::parse_period)]
    timeout: Option<Duration>,
    /// How shared-memory waits wait: adaptive (yield up to 50 µs, then block; the default), adaptive:DURATION, block, spin or poll:DURATION.
    #[arg(long, value_name = "MODE", value_parser = config::parse_wait_mode)]
    wait: Option<WaitMode>,
    /// How often an idle asynchronous set is checked for changes (default 500us; 0: keep
    /// polling).
    #[arg(long, value_name = "DURATION", value_parser = config::parse_span)]
    poll: Option<Duration>,
    /// How long a DDS writer of a synchronous domain may owe a step's answer, silent, before
    /// its lock-step share is released (default 1s); also the lease the gateway's DDS
    /// participant announces (at least 2s; Cyclone engine), after which DDS peers forget a
    /// killed gateway.
    #[arg(long, value_name = "DURATION", value_parser = config::parse_period)]
    lease: Option<Duration>,
    /// Serve the counters over HTTP: JSON at /stats, Prometheus text at /metrics (port 0:
    /// any free port, logged).
    #[arg(long, value_name = "ADDR")]
    http: Option<SocketAddr>,
    /// Serve the bridged sets live over the Foxglove WebSocket protocol (default address
    /// 127.0.0.1:8765; port 0: any free port, logged).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = tutti_gateway::foxglove::DEFAULT_ADDR)]
    foxglove: Option<SocketAddr>,
    /// Period of the status line on stderr (default 5s).
    #[arg(long, value_name = "DURATION", value_parser = config::parse_period)]
    status_every: Option<Duration>,
    /// Stop after this long (default: run until Ctrl-C).
    #[arg(long, value_name = "DURATION", value_parser = config::parse_span)]
    duration: Option<Duration>,
    /// Print no status lines.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Types {
    Typed,
    PerItem,
}

/// `--qos-profile` (here and in `tutti show`).
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ProfileArg {
    Ros2,
    Dds,
}

impl From<ProfileArg> for Profile {
    fn from(p: ProfileArg) -> Self {
        match p {
            ProfileArg::Ros2 => Profile::Ros2,
            ProfileArg::Dds => Profile::Dds,
        }
    }
}

/// `--ros-domain-id`'s parser: a ROS domain id (`tutti_ros2::names::DOMAIN_IDS`).
fn domain_ids() -> clap::builder::RangedI64ValueParser<u16> {
    let ids = tutti_ros2::names::DOMAIN_IDS;
    clap::value_parser!(u16).range(i64::from(*ids.start())..=i64::from(*ids.end()))
}

impl Args {
    /// The flags given, as config keys (those not given are None, so the file's show through).
    fn flags(&self) -> ConfigFile {
        ConfigFile {
            source: None,
            engine: EngineKeys {
                ros_domain_id: self.ros_domain_id,
                engine: self.engine,
                interface: (!self.interfaces.is_empty()).then(|| self.interfaces.clone()),
                peer: (!self.peers.is_empty()).then(|| self.peers.clone()),
                zenoh_connect: (!self.zenoh_connect.is_empty()).then(|| self.zenoh_connect.clone()),
                zenoh_listen: (!self.zenoh_listen.is_empty()).then(|| self.zenoh_listen.clone()),
                security_enable: self.security.then_some(true),
                security_keystore: self.security_keystore.clone(),
                enclave: self.enclave.clone(),
                security_strategy: self.security_strategy,
            },
            gateway: GatewayKeys {
                ros2_types: self.ros2_types.map(|t| match t {
                    Types::Typed => TypeMode::Typed,
                    Types::PerItem => TypeMode::PerItem,
                }),
                qos_profile: self.qos_profile.map(Into::into),
                strength: self.strength,
                mirror: self.mirror.then_some(true),
                node_name: self.node_name.clone(),
                clock: self.clock.clone(),
                clock_rate: self.clock_rate,
                timeout: self.timeout,
                wait: self.wait,
                poll: self.poll,
                status_every: self.status_every,
                duration: self.duration,
                quiet: self.quiet.then_some(true),
                ros_namespace: self.ros_namespace.clone(),
                hosted_only: self.all_domains.then_some(false),
                lease: self.lease,
                every_step: self.every_step.then_some(true),
                passive: self.passive.then_some(true),
                lookahead: self.lookahead.iter().cloned().reduce(|a, b| b.over(a)),
            },
            http: HttpKeys { http: self.http },
            foxglove: FoxgloveKeys { foxglove: self.foxglove },
            plan: PlanKeys::default(),
            // Config keys only: a list of entities is a file's.
            entities: Default::default(),
        }
    }
}

/// The gateway's log filter unless `RUST_LOG` says otherwise: info, the DDS stacks' internals
/// off, Zenoh's warnings only.
const DEFAULT_LOG: &str = "info,rustdds=off,ros2_client=off,zenoh=warn,zenoh_transport=warn,zenoh_ext=warn";

/// The gateway's log on stderr (`RUST_LOG`, default [`DEFAULT_LOG`]); once per process.
pub fn init_logging() {
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(DEFAULT_LOG)),
        )
        .with_writer(std::io::stderr)
        // Colour only for a terminal: logs piped to a file or another program stay plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_target(false)
        .try_init();
}

/// What the gateway serves for DDF `file` (read into `model`): `flags` laid over the config
/// file `config` (if any), over the environment; and the keys as laid. The rules are checked
/// against the DDF before anything starts (tutti show --config shows the same plan). Shared
/// by `tutti gateway` and `tutti host --gateway`.
pub fn configured(
    file: &Path,
    model: Model,
    flags: ConfigFile,
    config: Option<&Path>,
) -> Result<(GatewayOptions, ConfigFile), Failure> {
    // The entities are checked against the DDF where each stands in the file.
    let keys = config::with_model(&model, || flags.layered(config)).map_err(Failure::invalid)?;
    let opts = GatewayOptions::configured(file, model, &keys).map_err(Failure::invalid)?;
    config::resolve(&opts).map_err(Failure::invalid)?;
    Ok((opts, keys))
}

pub fn run(args: Args) -> CliResult {
    init_logging();
    let model = load_ddf(&args.file)?;
    let (opts, keys) = configured(&args.file, model, args.flags(), args.config.as_deref())?;

    let stop = super::stop_flag()?;
    if let Some(d) = keys.gateway.duration {
        let stop = stop.clone();
        std::thread::spawn(move || {
            std::thread::sleep(d);
            stop.store(true, Ordering::SeqCst);
        });
    }
    let quiet = keys.gateway.quiet.unwrap_or(false);
    let shown = args.file.display().to_string();
    let mut on_status = |line: &str| {
        if !quiet {
            eprintln!("tutti gateway: {line}");
        }
    };
    let status_every = keys.gateway.status_every.unwrap_or(Duration::from_secs(5));
    match tutti_gateway::run(opts, stop, status_every, &mut on_status) {
        Ok(stats) => {
            if !quiet {
                eprintln!("tutti gateway: stopped | {stats}");
            }
            Ok(())
        }
        Err(e) if e.is_invalid() => Err(Failure::invalid(anyhow::anyhow!("{shown}: {e}"))),
        Err(e) => Err(Failure::from(anyhow::Error::new(e).context(format!("gateway for {shown}")))),
    }
}
