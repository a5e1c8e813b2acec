//! `tutti-demo uav-node --index N`: one UAV external component of the demo. It connects to
//! domain `multiuav_uavN` with the Rust participant; each framework step it reads the
//! formation commands and the step's simulated time (PUBLISH), flies the 6-DOF model up to
//! that time, and writes Latitude, Longitude, Elevation, Airspeed, Heading and Time
//! (SUBSCRIBE). It logs the altitude it computes to a CSV file, whether connected or not.
//!
//! SIGUSR1 disconnects, SIGUSR2 reconnects (the monitoring script sends them). While
//! disconnected the UAV keeps flying in simulated time: it follows the co-simulation's clock,
//! which it reads from the domain's segment header without holding a connection (so it stays
//! in step with the framework even when the machine is too loaded for real time), or, when
//! the segment cannot be read, the wall clock at the demo's speed. On reconnection it reads
//! the step's time again. SIGTERM or SIGINT ends it.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use tutti_core::ddf::Role;
use tutti_core::shm::segment::{namespace_from_env, Segment};
use tutti_core::shm::{ConnectOptions, Participant, ShmError};

use crate::f64_at;
use crate::scenario::UAVS;
use tutti_uav::{FormationCommand, Uav, DEFAULT_DT};

use crate::CliResult;

#[derive(Debug, clap::Args)]
pub struct NodeArgs {
    /// The UAV (1..4): slot in the formation, domain multiuav_uavN.
    #[arg(long)]
    index: usize,
    /// The domain (default multiuav_uavN).
    #[arg(long)]
    domain: Option<String>,
    /// Simulated seconds per wall second (pacing while disconnected).
    #[arg(long, default_value_t = 4.0)]
    speed: f64,
    /// CSV of the state the model computes (`UAV_LOG_HEADER`).
    #[arg(long)]
    out: PathBuf,
    /// Start disconnected (until SIGUSR2).
    #[arg(long)]
    start_disconnected: bool,
}

/// The PUBLISH and SUBSCRIBE offsets the node uses.
struct Items {
    commands: [usize; 5],
    time: usize,
    outputs: [(&'static str, usize); 6],
}

impl Items {
    fn of(p: &Participant) -> anyhow::Result<Items> {
        let off = |role: Role, path: &str| -> anyhow::Result<usize> {
            let (_, leaf) = p.leaf(role, path)?;
            anyhow::ensure!(leaf.size == 8 && leaf.length == 1, "{path} must be a float64 scalar");
            Ok(leaf.offset as usize)
        };
        let mut commands = [0; 5];
        for (c, name) in commands.iter_mut().zip(["Autopilot", "X", "Y", "Z", "Airspeed"]) {
            *c = off(Role::Publish, name)?;
        }
        let mut outputs = [("", 0); 6];
        for (o, name) in outputs.iter_mut().zip(["Latitude", "Longitude", "Elevation", "Airspeed", "Heading", "Time"]) {
            *o = (name, off(Role::Subscribe, name)?);
        }
        Ok(Items { commands, time: off(Role::Publish, "Time")?, outputs })
    }
}

struct Node {
    uav: Uav,
    log: BufWriter<File>,
    connected: bool,
    logged: f64,
}

impl Node {
    /// Flies up to simulated time `t` in steps of at most DEFAULT_DT; logs a row when the
    /// clock moved (a UAV ahead of the framework's clock waits for it).
    fn fly_to(&mut self, t: f64) -> anyhow::Result<()> {
        while self.uav.time() + 1e-9 < t {
            let dt = (t - self.uav.time()).min(DEFAULT_DT);
            self.uav.step(dt);
        }
        if self.uav.time() > self.logged + 1e-9 || self.logged.is_nan() {
            self.logged = self.uav.time();
            let o = self.uav.outputs();
            writeln!(
                self.log,
                "{},{},{},{},{},{},{}",
                self.uav.time(),
                o.lat_deg,
                o.lon_deg,
                self.uav.altitude_msl(),
                o.heading_deg,
                o.airspeed,
                u8::from(self.connected)
            )?;
        }
        Ok(())
    }
}

/// The columns of a UAV's log, units in their names: simulated time, position (WGS-84),
/// altitude above mean sea level, heading (from north, clockwise), airspeed, and whether the
/// UAV was connected to its domain.
pub const UAV_LOG_HEADER: &str = "time_s,latitude_deg,longitude_deg,altitude_m,heading_deg,airspeed_mps,connected";

pub fn run(args: NodeArgs) -> CliResult {
    Ok(fly(args)?)
}

/// The signals the monitoring script and the demo send: SIGUSR1 disconnects, SIGUSR2
/// connects again, SIGTERM or SIGINT stops.
struct Signals {
    disconnect: Arc<AtomicBool>,
    reconnect: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
}

impl Signals {
    fn register() -> anyhow::Result<Signals> {
        let s = Signals {
            disconnect: Arc::new(AtomicBool::new(false)),
            reconnect: Arc::new(AtomicBool::new(false)),
            stop: Arc::new(AtomicBool::new(false)),
        };
        signal_hook::flag::register(signal_hook::consts::SIGUSR1, s.disconnect.clone())?;
        signal_hook::flag::register(signal_hook::consts::SIGUSR2, s.reconnect.clone())?;
        signal_hook::flag::register(signal_hook::consts::SIGTERM, s.stop.clone())?;
        signal_hook::flag::register(signal_hook::consts::SIGINT, s.stop.clone())?;
        Ok(s)
    }
}

/// The component's tie to its domain: connected (a participant and its items), or not (the
/// segment whose clock to follow, else a wall-clock anchor).
struct Link {
    domain: String,
    who: String,
    name: String,
    part: Option<(Participant, Items)>,
    anchor: (Instant, f64),
    clock: Option<Segment>,
}

/// What a step of the exchange says about the loop.
enum Flow {
    Go,
    Stop,
}

impl Link {
    fn open(&self) -> anyhow::Result<Participant> {
        let opts =
            ConnectOptions { name: self.name.clone(), connect_timeout: Duration::from_secs(10), ..Default::default() };
        let mut p = Participant::connect(&self.domain, opts)
            .with_context(|| format!("{}: connecting to {}", self.who, self.domain))?;
        // Short lock timeouts: signals are looked at between locks.
        p.set_timeout(Duration::from_millis(250));
        Ok(p)
    }

    fn connect(&mut self, node: &mut Node, p: Participant) -> anyhow::Result<()> {
        let items = Items::of(&p)?;
        self.part = Some((p, items));
        self.clock = None;
        node.connected = true;
        Ok(())
    }

    /// Disconnects or connects again as the signals ask.
    fn follow_signals(&mut self, node: &mut Node, signals: &Signals) -> anyhow::Result<()> {
        if signals.disconnect.swap(false, Ordering::SeqCst) {
            if let Some((p, _)) = self.part.take() {
                p.disconnect();
                node.connected = false;
                self.anchor = (Instant::now(), node.uav.time());
                self.clock = Segment::open(&namespace_from_env(), &self.domain).ok();
                eprintln!("{}: disconnected at t={:.2}s", self.who, node.uav.time());
            }
        }
        if signals.reconnect.swap(false, Ordering::SeqCst) && self.part.is_none() {
            match self.open() {
                Ok(p) => {
                    self.connect(node, p)?;
                    eprintln!("{}: connected again at t={:.2}s", self.who, node.uav.time());
                }
                Err(e) => eprintln!("{}: {}", self.who, tutti_exit::said_once(&e)),
            }
        }
        Ok(())
    }

    /// Disconnected: flies on with the co-simulation's clock.
    fn fly_alone(&self, node: &mut Node, speed: f64) -> anyhow::Result<()> {
        std::thread::sleep(Duration::from_millis(5));
        let t = match self.clock.as_ref().filter(|seg| seg.framework_alive()) {
            Some(seg) => seg.sim_time(),
            None => self.anchor.1 + self.anchor.0.elapsed().as_secs_f64() * speed,
        };
        node.fly_to(t)
    }

    /// One step connected: read the commands and the time, fly to it, write the state.
    fn exchange(&mut self, node: &mut Node) -> anyhow::Result<Flow> {
        let Some((p, items)) = self.part.as_mut() else { return Ok(Flow::Go) };
        match p.subscribe_lock() {
            Ok(_) => {}
            Err(ShmError::Timeout { .. }) => return Ok(Flow::Go),
            Err(ShmError::FrameworkStopped { .. }) => return Ok(Flow::Stop),
            Err(e) => anyhow::bail!("{}: reading the commands of {}: {e}", self.who, self.domain),
        }
        let snap = p.snapshot();
        let c = items.commands.map(|off| f64_at(snap, off));
        let t = f64_at(snap, items.time);
        node.uav.apply_command(&FormationCommand::from_ddf(c[0], c[1], c[2], c[3], c[4]));
        // The framework's clock: catch up after a reconnection, or wait while ahead.
        node.fly_to(t)?;
        let out = node.uav.outputs();
        let values = [out.lat_deg, out.lon_deg, out.elevation_m, out.airspeed, out.heading_deg, out.time];
        let step = (|| -> Result<(), ShmError> {
            p.publish_lock()?;
            for ((name, _), v) in items.outputs.iter().zip(values) {
                p.stage(name, &v.to_ne_bytes())?;
            }
            p.commit()
        })();
        match step {
            Ok(()) | Err(ShmError::Timeout { .. }) => Ok(Flow::Go),
            Err(ShmError::FrameworkStopped { .. }) => Ok(Flow::Stop),
            Err(e) => anyhow::bail!("{}: writing the state to {}: {e}", self.who, self.domain),
        }
    }
}

fn fly(args: NodeArgs) -> anyhow::Result<()> {
    anyhow::ensure!((1..=UAVS).contains(&args.index), "--index must be 1..{UAVS}");
    anyhow::ensure!(args.speed > 0.0, "--speed must be positive");
    let formation = tutti_uav::scenario::default_formation();
    let uav = formation.build_uav(args.index - 1).map_err(|e| anyhow::anyhow!("UAV {}: {e}", args.index))?;
    let file = File::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let mut log = BufWriter::new(file);
    writeln!(log, "{UAV_LOG_HEADER}")?;
    let signals = Signals::register()?;
    let mut node = Node { uav, log, connected: false, logged: f64::NAN };
    let mut link = Link {
        domain: args.domain.clone().unwrap_or_else(|| format!("multiuav_uav{}", args.index)),
        who: format!("uav{}", args.index),
        name: format!("uav model {}", args.index),
        part: None,
        anchor: (Instant::now(), node.uav.time()),
        clock: None,
    };
    if args.start_disconnected {
        eprintln!("{}: started disconnected", link.who);
    } else {
        let p = link.open()?;
        link.connect(&mut node, p)?;
    }
    let mut result = Ok(());
    while !signals.stop.load(Ordering::SeqCst) {
        link.follow_signals(&mut node, &signals)?;
        if link.part.is_none() {
            link.fly_alone(&mut node, args.speed)?;
            continue;
        }
        match link.exchange(&mut node) {
            Ok(Flow::Go) => {}
            Ok(Flow::Stop) => break,
            Err(e) => {
                result = Err(e);
                break;
            }
        }
    }
    if let Some((p, _)) = link.part.take() {
        p.disconnect();
    }
    node.log.flush().context("writing the altitude log")?;
    result
}
