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

fn fly(args: NodeArgs) -> anyhow::Result<()> {
    anyhow::ensure!((1..=UAVS).contains(&args.index), "--index must be 1..{UAVS}");
    anyhow::ensure!(args.speed > 0.0, "--speed must be positive");
    let domain = args.domain.clone().unwrap_or_else(|| format!("multiuav_uav{}", args.index));
    let who = format!("uav{}", args.index);
    let formation = tutti_uav::scenario::default_formation();
    let uav = formation.build_uav(args.index - 1).map_err(|e| anyhow::anyhow!("UAV {}: {e}", args.index))?;
    let file = File::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let mut log = BufWriter::new(file);
    writeln!(log, "{UAV_LOG_HEADER}")?;

    let disconnect = Arc::new(AtomicBool::new(false));
    let reconnect = Arc::new(AtomicBool::new(false));
    let stop = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, disconnect.clone())?;
    signal_hook::flag::register(signal_hook::consts::SIGUSR2, reconnect.clone())?;
    signal_hook::flag::register(signal_hook::consts::SIGTERM, stop.clone())?;
    signal_hook::flag::register(signal_hook::consts::SIGINT, stop.clone())?;

    let opts = ConnectOptions { name: format!("uav model {}", args.index), ..Default::default() };
    let connect = || -> anyhow::Result<Participant> {
        let mut p =
            Participant::connect(&domain, ConnectOptions { connect_timeout: Duration::from_secs(10), ..opts.clone() })
                .with_context(|| format!("{who}: connecting to {domain}"))?;
        // Short lock timeouts: signals are looked at between locks.
        p.set_timeout(Duration::from_millis(250));
        Ok(p)
    };
    let mut node = Node { uav, log, connected: false, logged: f64::NAN };
    let mut part: Option<(Participant, Items)> = None;
    if args.start_disconnected {
        eprintln!("{who}: started disconnected");
    } else {
        let p = connect()?;
        let items = Items::of(&p)?;
        part = Some((p, items));
        node.connected = true;
    }
    // While disconnected: the segment whose clock to follow, else a wall-clock anchor.
    let mut anchor = (Instant::now(), node.uav.time());
    let mut clock: Option<Segment> = None;
    let mut result = Ok(());
    while !stop.load(Ordering::SeqCst) {
        if disconnect.swap(false, Ordering::SeqCst) {
            if let Some((p, _)) = part.take() {
                p.disconnect();
                node.connected = false;
                anchor = (Instant::now(), node.uav.time());
                clock = Segment::open(&namespace_from_env(), &domain).ok();
                eprintln!("{who}: disconnected at t={:.2}s", node.uav.time());
            }
        }
        if reconnect.swap(false, Ordering::SeqCst) && part.is_none() {
            match connect() {
                Ok(p) => {
                    let items = Items::of(&p)?;
                    part = Some((p, items));
                    node.connected = true;
                    clock = None;
                    eprintln!("{who}: connected again at t={:.2}s", node.uav.time());
                }
                Err(e) => eprintln!("{who}: {e:#}"),
            }
        }
        let Some((p, items)) = part.as_mut() else {
            // Disconnected: fly on with the co-simulation's clock.
            std::thread::sleep(Duration::from_millis(5));
            let t = match clock.as_ref().filter(|seg| seg.framework_alive()) {
                Some(seg) => seg.sim_time(),
                None => anchor.1 + anchor.0.elapsed().as_secs_f64() * args.speed,
            };
            node.fly_to(t)?;
            continue;
        };
        match p.subscribe_lock() {
            Ok(_) => {}
            Err(ShmError::Timeout { .. }) => continue,
            Err(ShmError::FrameworkStopped { .. }) => break,
            Err(e) => {
                result = Err(anyhow::anyhow!("{who}: reading the commands of {domain}: {e}"));
                break;
            }
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
            Ok(()) => {}
            Err(ShmError::Timeout { .. }) => {}
            Err(ShmError::FrameworkStopped { .. }) => break,
            Err(e) => {
                result = Err(anyhow::anyhow!("{who}: writing the state to {domain}: {e}"));
                break;
            }
        }
    }
    if let Some((p, _)) = part.take() {
        p.disconnect();
    }
    node.log.flush().context("writing the altitude log")?;
    result
}
