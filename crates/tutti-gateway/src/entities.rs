//! The run's entities as the gateway reads and moves them (docs/gateway.md, "Entities"):
//! each entity's items, read from its domain's set as a passive observer (no connection, so
//! reading never paces nor stalls the domain), turned into a pose
//! ([`tutti_ros2::simulation::entities`]); and `set_entity_state`'s write, a commit of the
//! entity's items by a connection of the gateway's that lasts the one commit.
//!
//! A read takes every set it needs at one step boundary: a set whose last write belongs to the
//! step before the newest one seen (its writer is answering the newest step right now) is read
//! again, until all agree or 100 ms have passed; a set older than that (its writer left)
//! is taken as it stands, each body stamped with the step its values were written for.

use std::time::{Duration, Instant};

use tutti_core::ddf::{Leaf, Model, Role, ScalarType, Value as DdfValue};
use tutti_core::shm::observer::{Look, Observer};
use tutti_core::shm::{ConnKind, ConnectOptions, Participant, Stamp};
use tutti_ros2::simulation::entities::{
    geodesy, navigation_to_enu, navigation_velocity, quaternion, roll_pitch_yaw, Body, Entities, EntityInfo, Pose,
    SourceError,
};

use crate::config::{Attitude, Entity, Form};

/// Why an entity could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum EntityIoError {
    #[error("domain '{domain}' is not running")]
    NotRunning { domain: String },
    #[error("domain '{domain}': its {role} set did not hold still")]
    Unsteady { domain: String, role: Role },
    #[error("domain '{domain}' as it runs has no {role} item '{path}'")]
    NoItem { domain: String, role: &'static str, path: String },
    #[error("item '{path}' lies beyond its set")]
    Beyond { path: String },
    /// The entity cannot be moved: why (a PUBLISH set, a synchronous domain).
    #[error("{0}")]
    ReadOnly(String),
    /// Its write was refused by the core (a set another writer owns, …).
    #[error(transparent)]
    Shm(#[from] tutti_core::shm::ShmError),
}

/// The longest a read waits for the sets it takes to agree on one step.
const SETTLE: Duration = Duration::from_millis(100);
/// Attempts at a consistent copy of a set before it is looked at again.
const READ_TRIES: u32 = 64;

/// One set the entities read: its domain followed, its bytes as last read.
struct Source {
    live: Observer,
    role: Role,
    buf: Vec<u8>,
    stamp: Stamp,
}

/// The entities of a run, read from (and written to) their domains.
pub struct DomainEntities {
    namespace: String,
    entities: Vec<Entity>,
    info: Vec<EntityInfo>,
    sources: Vec<Source>,
    /// Per entity, its source.
    source_of: Vec<usize>,
    timeout: Duration,
}

impl std::fmt::Debug for DomainEntities {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DomainEntities").field("entities", &self.info).finish()
    }
}

/// Why `set_entity_state` cannot move entity `e` of the DDF `model`, if it cannot.
fn read_only(e: &Entity, model: &Model) -> Option<String> {
    let d = model.domain(&e.domain)?;
    if e.role == Role::Publish {
        return Some(format!(
            "its items are in the PUBLISH set of domain '{}', which only the framework writes",
            e.domain
        ));
    }
    if d.flags.synchronous {
        return Some(format!(
            "domain '{}' is synchronous: its SUBSCRIBE set is answered in lock-step by its participants, and the \
             gateway does not join the lock-step for one write",
            e.domain
        ));
    }
    None
}

impl DomainEntities {
    /// The entities of `entities` (checked against `model`) in the shared-memory namespace
    /// `namespace`; a write waits at most `timeout` to connect.
    pub fn new(entities: &[Entity], model: &Model, namespace: &str, timeout: Duration) -> DomainEntities {
        let mut sources: Vec<Source> = Vec::new();
        let mut source_of = Vec::new();
        for e in entities {
            let at = sources.iter().position(|s| s.live.domain == e.domain && s.role == e.role);
            let at = at.unwrap_or_else(|| {
                sources.push(Source {
                    live: Observer::new(e.domain.clone()),
                    role: e.role,
                    buf: Vec::new(),
                    stamp: Stamp::default(),
                });
                sources.len() - 1
            });
            source_of.push(at);
        }
        let info = entities
            .iter()
            .map(|e| EntityInfo {
                name: e.name.clone(),
                category: e.category,
                description: e.description.clone(),
                tags: e.tags.clone(),
                frame: e.frame.clone(),
                read_only: read_only(e, model),
            })
            .collect();
        DomainEntities {
            namespace: namespace.to_string(),
            entities: entities.to_vec(),
            info,
            sources,
            source_of,
            timeout,
        }
    }

    /// Reads source `i` once; its step's simulated time and the time of one step.
    fn read_source(&mut self, i: usize) -> Result<(Stamp, Option<f64>), EntityIoError> {
        let s = &mut self.sources[i];
        let seg = match s.live.look(&self.namespace) {
            Look::Fresh | Look::Same => s.live.segment(),
            _ => None,
        };
        let Some(seg) = seg else {
            return Err(EntityIoError::NotRunning { domain: s.live.domain.clone() });
        };
        let size = seg.info.set(s.role).size as usize;
        s.buf.resize(size, 0);
        let Some((_, stamp)) = seg.try_read_set_stamped(s.role, &mut s.buf, READ_TRIES) else {
            return Err(EntityIoError::Unsteady { domain: s.live.domain.clone(), role: s.role });
        };
        s.stamp = stamp;
        Ok((stamp, seg.sim_step()))
    }

    /// Reads the sources in `which` at one step boundary (see the module's words).
    fn read_sources(&mut self, which: &[usize]) -> Result<(), EntityIoError> {
        let end = Instant::now() + SETTLE;
        loop {
            let mut stamps = Vec::with_capacity(which.len());
            for &i in which {
                stamps.push(self.read_source(i)?);
            }
            let newest = stamps.iter().map(|(s, _)| s.sim_time).fold(f64::NEG_INFINITY, f64::max);
            // A set one step behind the newest is being answered now: read it again.
            let answering = stamps.iter().any(|(s, step)| {
                let step = step.unwrap_or(0.0);
                s.sim_time < newest && step > 0.0 && newest - s.sim_time < 1.5 * step
            });
            if !answering || Instant::now() >= end {
                return Ok(());
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }

    /// The number item `path` of source `i` holds.
    fn number(&self, i: usize, path: &str) -> Result<f64, EntityIoError> {
        let s = &self.sources[i];
        let seg = s.live.segment().ok_or_else(|| EntityIoError::NotRunning { domain: s.live.domain.clone() })?;
        let leaf = seg.info.set(s.role).leaf(path).ok_or_else(|| EntityIoError::NoItem {
            domain: s.live.domain.clone(),
            role: s.role.lower(),
            path: path.to_string(),
        })?;
        let bytes = s.buf.get(leaf.range()).ok_or_else(|| EntityIoError::Beyond { path: path.to_string() })?;
        Ok(leaf.ty.decode(bytes).as_f64())
    }

    /// Entity `k`'s body from its source's bytes.
    fn body(&self, k: usize) -> Result<Body, EntityIoError> {
        let i = self.source_of[k];
        let get = |path: &str| self.number(i, path);
        let opt = |path: &Option<String>| path.as_deref().map_or(Ok(0.0), get);
        let (pose, velocity) = match &self.entities[k].form {
            Form::Geodetic { origin, latitude, longitude, altitude, heading, pitch, roll, speed } => {
                let (h, p, r) = (get(heading)?, opt(pitch)?, opt(roll)?);
                let position = geodesy::enu(*origin, get(latitude)?, get(longitude)?, get(altitude)?);
                let (roll, pitch, yaw) = navigation_to_enu(h, p, r);
                let velocity = navigation_velocity(opt(speed)?, h, p);
                (Pose { position, orientation: quaternion(roll, pitch, yaw) }, velocity)
            }
            Form::Cartesian { x, y, z, attitude } => {
                let position = [get(x)?, get(y)?, get(z)?];
                let orientation = match attitude {
                    Attitude::RollPitchYaw { roll, pitch, yaw } => quaternion(opt(roll)?, opt(pitch)?, opt(yaw)?),
                    Attitude::Quaternion(q) => {
                        let q = [get(&q[0])?, get(&q[1])?, get(&q[2])?, get(&q[3])?];
                        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
                        // Nothing written yet (all zero): the identity.
                        if norm > 0.0 {
                            q.map(|c| c / norm)
                        } else {
                            [0.0, 0.0, 0.0, 1.0]
                        }
                    }
                };
                (Pose { position, orientation }, [0.0; 3])
            }
        };
        Ok(Body { pose, velocity, sim_time: self.sources[i].stamp.sim_time })
    }

    /// The items entity `k` is written as for `pose` and `velocity`: (path, value).
    fn items_for(&self, k: usize, pose: &Pose, velocity: [f64; 3]) -> Vec<(String, f64)> {
        let (roll, pitch, yaw) = roll_pitch_yaw(pose.orientation);
        let mut out: Vec<(String, f64)> = Vec::new();
        let mut put = |path: &Option<String>, v: f64| {
            if let Some(p) = path {
                out.push((p.clone(), v));
            }
        };
        match &self.entities[k].form {
            Form::Geodetic { origin, latitude, longitude, altitude, heading, pitch: p, roll: r, speed } => {
                let (lat, lon, h) = geodesy::geodetic(*origin, pose.position);
                put(&Some(latitude.clone()), lat);
                put(&Some(longitude.clone()), lon);
                put(&Some(altitude.clone()), h);
                put(&Some(heading.clone()), (90.0 - yaw.to_degrees()).rem_euclid(360.0));
                put(p, -pitch.to_degrees());
                put(r, roll.to_degrees());
                put(speed, velocity.iter().map(|c| c * c).sum::<f64>().sqrt());
            }
            Form::Cartesian { x, y, z, attitude } => {
                put(&Some(x.clone()), pose.position[0]);
                put(&Some(y.clone()), pose.position[1]);
                put(&Some(z.clone()), pose.position[2]);
                match attitude {
                    Attitude::RollPitchYaw { roll: r, pitch: p, yaw: y } => {
                        put(r, roll);
                        put(p, pitch);
                        put(y, yaw);
                    }
                    Attitude::Quaternion(q) => {
                        for (path, v) in q.iter().zip(pose.orientation) {
                            put(&Some(path.clone()), v);
                        }
                    }
                }
            }
        }
        out
    }
}

/// When the entities' poses are worth sending again (to `/tf` and the pose topics, or to a
/// Foxglove client): a domain of theirs moved on (a new step, or its time set back) and a read
/// finds an entity written for another step than the poses last sent. A domain's step word
/// moves a moment before its set holds the step's values; a read in between finds the poses
/// sent already, and the next look reads again.
#[derive(Debug, Default)]
pub struct NewPoses {
    /// Each domain's (step, time resets) when the poses were last sent.
    seen: Vec<Option<(u64, u32)>>,
    /// The steps' simulated times of the poses last sent.
    sent: Vec<f64>,
}

impl NewPoses {
    /// The poses of `source` if they are new: `marks` is each domain's (step, time resets)
    /// now (None: not running); `force` sends them whatever (a new subscriber).
    pub fn take(
        &mut self,
        marks: Vec<Option<(u64, u32)>>,
        force: bool,
        source: &mut DomainEntities,
    ) -> Option<Vec<Body>> {
        if !force && marks == self.seen {
            return None;
        }
        let reset = marks.iter().zip(&self.seen).any(|(a, b)| a.map(|m| m.1) != b.map(|m| m.1));
        let all: Vec<usize> = (0..source.list().len()).collect();
        let bodies = source.read(&all).ok()?;
        let stamps: Vec<f64> = bodies.iter().map(|b| b.sim_time).collect();
        if !force && !reset && stamps == self.sent {
            return None;
        }
        (self.seen, self.sent) = (marks, stamps);
        Some(bodies)
    }
}

/// `v` in the bytes of `leaf`'s type (an integer item gets `v` rounded).
fn encode(leaf: &Leaf, v: f64) -> Vec<u8> {
    let value = match leaf.ty {
        ScalarType::Float32 | ScalarType::Float64 => DdfValue::Float(v),
        ty if ty.is_signed_int() => DdfValue::Int(v.round() as i64),
        ScalarType::Boolean => DdfValue::Bool(v != 0.0),
        _ => DdfValue::UInt(v.round().max(0.0) as u64),
    };
    let mut out = vec![0; leaf.size as usize];
    leaf.ty.encode(value, &mut out);
    out
}

impl Entities for DomainEntities {
    fn list(&self) -> &[EntityInfo] {
        &self.info
    }

    fn read(&mut self, which: &[usize]) -> Result<Vec<Body>, SourceError> {
        let mut sources: Vec<usize> = which.iter().map(|&k| self.source_of[k]).collect();
        sources.sort_unstable();
        sources.dedup();
        self.read_sources(&sources)?;
        Ok(which.iter().map(|&k| self.body(k)).collect::<Result<_, _>>()?)
    }

    fn write(&mut self, k: usize, pose: &Pose, velocity: [f64; 3]) -> Result<(), SourceError> {
        Ok(self.commit(k, pose, velocity)?)
    }
}

impl DomainEntities {
    /// Writes entity `k`'s items for `pose` and `velocity` in one commit of a connection of its
    /// own, which leaves at once.
    fn commit(&self, k: usize, pose: &Pose, velocity: [f64; 3]) -> Result<(), EntityIoError> {
        if let Some(why) = &self.info[k].read_only {
            return Err(EntityIoError::ReadOnly(why.clone()));
        }
        let e = &self.entities[k];
        let opts = ConnectOptions {
            namespace: self.namespace.clone(),
            name: format!("gateway:{}", e.name),
            kind: ConnKind::Remote,
            timeout: self.timeout,
            connect_timeout: self.timeout,
            skip_wait_to_go: true,
            ..Default::default()
        };
        let mut p = Participant::connect(&e.domain, opts)?;
        p.publish_lock()?;
        for (path, v) in self.items_for(k, pose, velocity) {
            let (_, leaf) = p.leaf(Role::Subscribe, &path)?;
            let bytes = encode(leaf, v);
            p.stage(&path, &bytes)?;
        }
        let done = p.commit();
        p.disconnect();
        Ok(done?)
    }
}
