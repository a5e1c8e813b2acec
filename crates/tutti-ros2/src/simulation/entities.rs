//! `simulation_interfaces`' entity services over a run's bodies (docs/ros2.md, "Entities"):
//! `get_entities`, `get_entity_state`, `get_entities_states`, `get_entity_info` and
//! `set_entity_state`, answered from the poses an [`Entities`] source reads (the gateway's
//! mapping of DDF items, docs/gateway.md "Entities"), and the poses themselves: a geodetic
//! position and attitude turned into a local ENU frame (REP-103) about a declared origin.
//!
//! Filters: `filter` is a regular expression matched against the whole name as POSIX
//! extended expressions match (any match within the name counts; the `regex` crate's syntax,
//! which is ERE's for everything ERE has); `categories` any of; `tags` any or all of; `bounds`
//! a sphere or an axis-aligned box about the entity's position (a convex hull is
//! `RESULT_FEATURE_UNSUPPORTED`).

use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};

use crate::{registry, Message, Struct, Value};

use super::{result, BadRequest, Outcome};

/// A pose: position (m) and orientation (a unit quaternion, x y z w), in the entity's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub position: [f64; 3],
    pub orientation: [f64; 4],
}

/// What a source says of one entity: its pose and its linear velocity (m/s, in the same
/// frame; zero where the mapping names no speed), and the simulated time of the step they
/// were written for (`header.stamp`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Body {
    pub pose: Pose,
    pub velocity: [f64; 3],
    pub sim_time: f64,
}

/// What the services tell of one entity.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EntityInfo {
    pub name: String,
    /// `simulation_interfaces/msg/EntityCategory`.
    pub category: u8,
    pub description: String,
    pub tags: Vec<String>,
    /// The frame its pose is in (`header.frame_id`, the parent frame on `/tf`).
    pub frame: String,
    /// Why `set_entity_state` cannot move it (None: it can).
    pub read_only: Option<String>,
}

/// Why a source could not read or write an entity, in its own words.
pub type SourceError = Box<dyn std::error::Error + Send + Sync>;

/// Where the entities' states come from and go to.
pub trait Entities: Send {
    /// The entities, in the order the services list them.
    fn list(&self) -> &[EntityInfo];
    /// The bodies of entities `which` (indexes into [`list`](Self::list)), read at one step
    /// boundary (each as last written: an entity whose writer is gone keeps its last step's);
    /// or why they cannot be read now (the domain is not running).
    fn read(&mut self, which: &[usize]) -> Result<Vec<Body>, SourceError>;
    /// Moves entity `i` to `pose` (velocity `velocity`): its items are written as the
    /// mapping says. Err: why not (refused with `RESULT_OPERATION_FAILED`).
    fn write(&mut self, i: usize, pose: &Pose, velocity: [f64; 3]) -> Result<(), SourceError>;
}

/// `simulation_interfaces/msg/SimulatorFeatures` values of the entity services.
pub mod feature {
    pub const ENTITY_TAGS: u16 = 4;
    pub const ENTITY_BOUNDS_BOX: u16 = 6;
    pub const ENTITY_CATEGORIES: u16 = 8;
    pub const ENTITY_STATE_GETTING: u16 = 10;
    pub const ENTITY_STATE_SETTING: u16 = 11;
    pub const ENTITY_INFO_GETTING: u16 = 12;
}

/// The features a run with `entities` serves (none without entities).
pub fn features(entities: &[EntityInfo]) -> Vec<u16> {
    if entities.is_empty() {
        return Vec::new();
    }
    let mut f = vec![
        feature::ENTITY_TAGS,
        feature::ENTITY_BOUNDS_BOX,
        feature::ENTITY_CATEGORIES,
        feature::ENTITY_STATE_GETTING,
        feature::ENTITY_INFO_GETTING,
    ];
    if entities.iter().any(|e| e.read_only.is_none()) {
        f.push(feature::ENTITY_STATE_SETTING);
    }
    f.sort_unstable();
    f
}

/// `simulation_interfaces/msg/Bounds` types.
mod bounds {
    pub const EMPTY: u64 = 0;
    pub const BOX: u64 = 1;
    pub const SPHERE: u64 = 3;
}

/// `simulation_interfaces/msg/TagsFilter` modes.
const FILTER_MODE_ALL: u64 = 1;

/// WGS-84, and a geodetic position in a local East-North-Up frame.
pub mod geodesy {
    /// WGS-84 semi-major axis (m).
    pub const A: f64 = 6_378_137.0;
    /// WGS-84 flattening.
    pub const F: f64 = 1.0 / 298.257_223_563;

    /// Earth-centred, earth-fixed coordinates (m) of latitude, longitude (degrees) and
    /// height above the ellipsoid (m).
    pub fn ecef(lat_deg: f64, lon_deg: f64, h: f64) -> [f64; 3] {
        let e2 = F * (2.0 - F);
        let (lat, lon) = (lat_deg.to_radians(), lon_deg.to_radians());
        let n = A / (1.0 - e2 * lat.sin().powi(2)).sqrt();
        [(n + h) * lat.cos() * lon.cos(), (n + h) * lat.cos() * lon.sin(), (n * (1.0 - e2) + h) * lat.sin()]
    }

    /// A geodetic point in the East-North-Up frame whose origin is the geodetic point
    /// `origin` (latitude, longitude in degrees, height in m).
    pub fn enu(origin: [f64; 3], lat_deg: f64, lon_deg: f64, h: f64) -> [f64; 3] {
        let o = ecef(origin[0], origin[1], origin[2]);
        let p = ecef(lat_deg, lon_deg, h);
        let d = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
        let (lat, lon) = (origin[0].to_radians(), origin[1].to_radians());
        let (sl, cl, sp, cp) = (lon.sin(), lon.cos(), lat.sin(), lat.cos());
        [
            -sl * d[0] + cl * d[1],
            -sp * cl * d[0] - sp * sl * d[1] + cp * d[2],
            cp * cl * d[0] + cp * sl * d[1] + sp * d[2],
        ]
    }

    /// [`enu`]'s inverse: the latitude, longitude (degrees) and height (m) of the point
    /// `p` of the ENU frame about `origin` (Bowring's iteration, to well under a millimetre).
    pub fn geodetic(origin: [f64; 3], p: [f64; 3]) -> (f64, f64, f64) {
        let o = ecef(origin[0], origin[1], origin[2]);
        let (lat, lon) = (origin[0].to_radians(), origin[1].to_radians());
        let (sl, cl, sp, cp) = (lon.sin(), lon.cos(), lat.sin(), lat.cos());
        let [e, n, u] = p;
        let x = o[0] - sl * e - sp * cl * n + cp * cl * u;
        let y = o[1] + cl * e - sp * sl * n + cp * sl * u;
        let z = o[2] + cp * n + sp * u;
        let e2 = F * (2.0 - F);
        let r = x.hypot(y);
        let mut phi = z.atan2(r * (1.0 - e2));
        let mut h = 0.0;
        for _ in 0..10 {
            let nn = A / (1.0 - e2 * phi.sin().powi(2)).sqrt();
            h = r / phi.cos() - nn;
            phi = z.atan2(r * (1.0 - e2 * nn / (nn + h)));
        }
        (phi.to_degrees(), y.atan2(x).to_degrees(), h)
    }
}

/// The orientation (x y z w) of a body of yaw, pitch and roll (radians) about the frame's z,
/// then the body's y, then its x (REP-103: z up, x forward, y left).
pub fn quaternion(roll: f64, pitch: f64, yaw: f64) -> [f64; 4] {
    let (sr, cr) = (roll / 2.0).sin_cos();
    let (sp, cp) = (pitch / 2.0).sin_cos();
    let (sy, cy) = (yaw / 2.0).sin_cos();
    [sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy]
}

/// Roll, pitch and yaw (radians) of a unit quaternion (x y z w): [`quaternion`]'s inverse.
pub fn roll_pitch_yaw(q: [f64; 4]) -> (f64, f64, f64) {
    let [x, y, z, w] = q;
    let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
    let pitch = (2.0 * (w * y - z * x)).clamp(-1.0, 1.0).asin();
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    (roll, pitch, yaw)
}

/// A navigation attitude in ENU terms: `heading` (degrees clockwise from north), `pitch`
/// (degrees, nose up) and `roll` (degrees, right wing down) as REP-103's yaw (from east,
/// counter-clockwise), pitch (about the body's y, which points left: nose up is negative) and
/// roll (about x, forward: right wing down is positive), radians.
pub fn navigation_to_enu(heading: f64, pitch: f64, roll: f64) -> (f64, f64, f64) {
    (roll.to_radians(), -pitch.to_radians(), std::f64::consts::FRAC_PI_2 - heading.to_radians())
}

/// The ENU velocity of a body moving at `speed` (m/s) along its heading and pitch (degrees).
pub fn navigation_velocity(speed: f64, heading: f64, pitch: f64) -> [f64; 3] {
    let (h, p) = (heading.to_radians(), pitch.to_radians());
    [speed * p.cos() * h.sin(), speed * p.cos() * h.cos(), speed * p.sin()]
}

fn vector(v: [f64; 3]) -> Value {
    Struct::new().with("x", v[0]).with("y", v[1]).with("z", v[2]).into()
}

fn read_vector(v: Option<&Value>) -> [f64; 3] {
    let c = |k: &str| v.and_then(|v| v.get(k)).and_then(Value::as_f64).unwrap_or(0.0);
    [c("x"), c("y"), c("z")]
}

/// An `EntityState` of `body` in `frame`, stamped with its step's simulated time.
pub fn state_value(body: &Body, frame: &str) -> Value {
    Struct::new()
        .with("header", header(frame, body.sim_time))
        .with("pose", pose_value(&body.pose))
        .with("twist", Struct::new().with("linear", vector(body.velocity)))
        .into()
}

/// `/tf` (under the gateway's ROS namespace), where each entity's pose goes as a transform.
pub const TF_TOPIC: &str = "tf";
/// Each entity's `geometry_msgs/msg/PoseStamped` topic: `<entity>/pose`.
pub fn pose_topic(entity: &str) -> String {
    format!("{entity}/pose")
}

fn embedded(name: &str) -> Message<'static> {
    match registry().message(name) {
        Some(m) => m,
        None => unreachable!("{name} is an embedded interface"),
    }
}

/// `tf2_msgs/msg/TFMessage`.
pub fn tf_message() -> Message<'static> {
    embedded("tf2_msgs/msg/TFMessage")
}

/// `geometry_msgs/msg/PoseStamped`.
pub fn pose_message() -> Message<'static> {
    embedded("geometry_msgs/msg/PoseStamped")
}

/// tf2_ros's broadcaster QoS (`DynamicBroadcasterQoS`): reliable, volatile, keep last 100.
pub fn tf_qos() -> Qos {
    Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(100),
        durability: Durability::Volatile,
        ownership: Ownership::Shared,
        lifespan: None,
    }
}

/// A `geometry_msgs/Pose` value of `pose`.
fn pose_value(pose: &Pose) -> Value {
    let [x, y, z, w] = pose.orientation;
    let orientation = Struct::new().with("x", x).with("y", y).with("z", z).with("w", w);
    Struct::new().with("position", vector(pose.position)).with("orientation", orientation).into()
}

fn header(frame: &str, t: f64) -> Value {
    Struct::new().with("stamp", crate::clock::stamp(t).value()).with("frame_id", frame).into()
}

/// The `TFMessage` of `bodies`: a transform per entity, from its frame to the entity.
pub fn tf_value<'a>(bodies: impl IntoIterator<Item = (&'a EntityInfo, &'a Body)>) -> Value {
    let transforms: Vec<Value> = bodies
        .into_iter()
        .map(|(e, b)| {
            let [x, y, z, w] = b.pose.orientation;
            let rotation = Struct::new().with("x", x).with("y", y).with("z", z).with("w", w);
            let transform = Struct::new().with("translation", vector(b.pose.position)).with("rotation", rotation);
            Struct::new()
                .with("header", header(&e.frame, b.sim_time))
                .with("child_frame_id", e.name.as_str())
                .with("transform", transform)
                .into()
        })
        .collect();
    Struct::new().with("transforms", transforms).into()
}

/// The `PoseStamped` of `body` in `frame`.
pub fn pose_stamped(body: &Body, frame: &str) -> Value {
    Struct::new().with("header", header(frame, body.sim_time)).with("pose", pose_value(&body.pose)).into()
}

/// A `geometry_msgs/Pose` value as a [`Pose`]; None where its quaternion is not one (not of
/// length 1 within 1e-6, or not numbers).
pub fn pose_of(v: &Value) -> Option<Pose> {
    let position = read_vector(v.get("position"));
    let o = v.get("orientation");
    let c = |k: &str, d: f64| o.and_then(|o| o.get(k)).and_then(Value::as_f64).unwrap_or(d);
    let q = [c("x", 0.0), c("y", 0.0), c("z", 0.0), c("w", 1.0)];
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    let finite = position.iter().chain(&q).all(|c| c.is_finite());
    (finite && (norm - 1.0).abs() <= 1e-6).then(|| Pose { position, orientation: q.map(|c| c / norm) })
}

/// Which entities pass `filters` (an `EntityFilters` value); `read` gives their positions
/// where bounds ask for them.
fn filtered(list: &[EntityInfo], filters: Option<&Value>, source: &mut dyn Entities) -> Result<Vec<usize>, Outcome> {
    let field = |k: &str| filters.and_then(|f| f.get(k));
    let pattern = field("filter").and_then(Value::as_str).unwrap_or("");
    let regex = if pattern.is_empty() {
        None
    } else {
        Some(regex::Regex::new(pattern).map_err(|e| {
            Outcome::new(result::OPERATION_FAILED, format!("the filter '{pattern}' is no regular expression: {e}"))
        })?)
    };
    let categories: Vec<u64> = field("categories")
        .and_then(Value::as_array)
        .map(|c| c.iter().filter_map(|c| c.get("category").and_then(Value::as_u64)).collect())
        .unwrap_or_default();
    let tags = field("tags");
    let wanted: Vec<&str> = tags
        .and_then(|t| t.get("tags"))
        .and_then(Value::as_array)
        .map(|t| t.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    let all_tags = tags.and_then(|t| t.get("filter_mode")).and_then(Value::as_u64) == Some(FILTER_MODE_ALL);
    let mut out: Vec<usize> = (0..list.len())
        .filter(|&i| {
            let e = &list[i];
            let tagged = |t: &&str| e.tags.iter().any(|x| x == t);
            regex.as_ref().map_or(true, |r| r.is_match(&e.name))
                && (categories.is_empty() || categories.contains(&u64::from(e.category)))
                && (wanted.is_empty() || if all_tags { wanted.iter().all(tagged) } else { wanted.iter().any(tagged) })
        })
        .collect();
    let bounds = field("bounds");
    let kind = bounds.and_then(|b| b.get("type")).and_then(Value::as_u64).unwrap_or(bounds::EMPTY);
    if kind == bounds::EMPTY || out.is_empty() {
        return Ok(out);
    }
    let points: Vec<[f64; 3]> = bounds
        .and_then(|b| b.get("points"))
        .and_then(Value::as_array)
        .map(|p| p.iter().map(|p| read_vector(Some(p))).collect())
        .unwrap_or_default();
    let inside: Box<dyn Fn([f64; 3]) -> bool> = match (kind, points.as_slice()) {
        (bounds::SPHERE, [c, r, ..]) => {
            let (c, r) = (*c, r[0]);
            Box::new(move |p| (0..3).map(|k| (p[k] - c[k]).powi(2)).sum::<f64>() <= r * r)
        }
        (bounds::BOX, [a, b]) => {
            let (a, b) = (*a, *b);
            Box::new(move |p| (0..3).all(|k| p[k] >= a[k].min(b[k]) && p[k] <= a[k].max(b[k])))
        }
        (bounds::SPHERE | bounds::BOX, _) => {
            return Err(Outcome::new(
                result::OPERATION_FAILED,
                format!("bounds of type {kind} with {} points: a sphere or a box needs 2", points.len()),
            ))
        }
        _ => {
            return Err(Outcome::new(
                result::FEATURE_UNSUPPORTED,
                format!("bounds of type {kind}: only a sphere (3) and a box (1) filter entities here"),
            ))
        }
    };
    let bodies = source.read(&out).map_err(|why| Outcome::new(result::OPERATION_FAILED, why.to_string()))?;
    let keep: Vec<bool> = bodies.iter().map(|b| inside(b.pose.position)).collect();
    let mut k = keep.iter();
    out.retain(|_| k.next().copied().unwrap_or(false));
    Ok(out)
}

/// What each entity service answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntityCall {
    List,
    State,
    States,
    Info,
    Set,
}

/// The response to `call` of request `req` from `source` (`service` names the service in a
/// [`BadRequest`]).
pub fn answer(
    call: EntityCall,
    service: &'static str,
    req: &Value,
    source: &mut dyn Entities,
) -> Result<Value, BadRequest> {
    let list = source.list().to_vec();
    let named = |req: &Value| -> Result<Result<usize, Outcome>, BadRequest> {
        let name = req.get("entity").and_then(Value::as_str).ok_or(BadRequest { service, field: "entity" })?;
        Ok(list
            .iter()
            .position(|e| e.name == name)
            .ok_or_else(|| Outcome::new(result::NOT_FOUND, format!("no entity '{name}'"))))
    };
    let with = |o: Outcome| Struct::new().with("result", o.value());
    let ok = || Outcome::new(result::OK, "");
    Ok(match call {
        EntityCall::List => match filtered(&list, req.get("filters"), source) {
            Ok(which) => {
                let names: Vec<Value> = which.iter().map(|&i| Value::from(list[i].name.as_str())).collect();
                with(ok()).with("entities", names)
            }
            Err(o) => with(o),
        },
        EntityCall::States => {
            let read = filtered(&list, req.get("filters"), source).and_then(|which| {
                Ok((source.read(&which).map_err(|w| Outcome::new(result::OPERATION_FAILED, w.to_string()))?, which))
            });
            match read {
                Ok((bodies, which)) => {
                    let names: Vec<Value> = which.iter().map(|&i| Value::from(list[i].name.as_str())).collect();
                    let states: Vec<Value> =
                        which.iter().zip(&bodies).map(|(&i, b)| state_value(b, &list[i].frame)).collect();
                    with(ok()).with("entities", names).with("states", states)
                }
                Err(o) => with(o),
            }
        }
        EntityCall::State => match named(req)? {
            Ok(i) => match source.read(&[i]) {
                Ok(bodies) => with(ok()).with("state", state_value(&bodies[0], &list[i].frame)),
                Err(why) => with(Outcome::new(result::OPERATION_FAILED, why.to_string())),
            },
            Err(o) => with(o),
        },
        EntityCall::Info => match named(req)? {
            Ok(i) => {
                let e = &list[i];
                let tags: Vec<Value> = e.tags.iter().map(|t| Value::from(t.as_str())).collect();
                let info = Struct::new()
                    .with("category", Struct::new().with("category", e.category))
                    .with("description", e.description.as_str())
                    .with("tags", tags);
                with(ok()).with("info", info)
            }
            Err(o) => with(o),
        },
        EntityCall::Set => match named(req)? {
            Err(o) => with(o),
            Ok(i) => with(set(&list[i], i, req, source)),
        },
    }
    .into())
}

/// `SetEntityState_Response.INVALID_POSE`.
const INVALID_POSE: u8 = 101;

fn set(e: &EntityInfo, i: usize, req: &Value, source: &mut dyn Entities) -> Outcome {
    if let Some(why) = &e.read_only {
        return Outcome::new(result::FEATURE_UNSUPPORTED, format!("entity '{}' cannot be moved: {why}", e.name));
    }
    let state = req.get("state");
    let frame = state.and_then(|s| s.path("header.frame_id")).and_then(Value::as_str).unwrap_or("");
    if !frame.is_empty() && frame != e.frame {
        return Outcome::new(
            result::OPERATION_FAILED,
            format!("entity '{}' is placed in frame '{}', not '{frame}'", e.name, e.frame),
        );
    }
    let Some(pose) = state.and_then(|s| s.get("pose")).and_then(pose_of) else {
        return Outcome::new(
            INVALID_POSE,
            "the pose's orientation is not a unit quaternion, or a number is not finite",
        );
    };
    let velocity = read_vector(state.and_then(|s| s.path("twist.linear")));
    match source.write(i, &pose, velocity) {
        Ok(()) => Outcome::new(result::OK, ""),
        Err(why) => Outcome::new(result::OPERATION_FAILED, why.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_geodetic_point_north_east_and_up_of_the_origin() {
        let o = [45.0, 7.0, 100.0];
        let p = geodesy::enu(o, 45.0, 7.0, 100.0);
        assert!(p.iter().all(|c| c.abs() < 1e-6), "{p:?}");
        let up = geodesy::enu(o, 45.0, 7.0, 150.0);
        assert!((up[2] - 50.0).abs() < 1e-6 && up[0].abs() < 1e-6 && up[1].abs() < 1e-6, "{up:?}");
        // One arc-minute of latitude is about a nautical mile.
        let north = geodesy::enu(o, 45.0 + 1.0 / 60.0, 7.0, 100.0);
        assert!((north[1] - 1852.0).abs() < 5.0 && north[0].abs() < 1e-6, "{north:?}");
        let east = geodesy::enu(o, 45.0, 7.001, 100.0);
        assert!(east[0] > 78.0 && east[0] < 79.0 && east[1].abs() < 0.01, "{east:?}");
        for p in [[0.0, 0.0, 0.0], [1234.5, -987.25, 321.0], [-40_000.0, 25_000.0, -50.0]] {
            let (lat, lon, h) = geodesy::geodetic(o, p);
            let back = geodesy::enu(o, lat, lon, h);
            assert!((0..3).all(|k| (back[k] - p[k]).abs() < 1e-6), "{p:?} -> {back:?}");
        }
    }

    #[test]
    fn quaternions_and_angles_agree() {
        for (r, p, y) in [(0.1, -0.2, 0.3), (0.0, 0.0, 3.0), (-1.0, 0.5, -2.0)] {
            let q = quaternion(r, p, y);
            assert!((q.iter().map(|c| c * c).sum::<f64>() - 1.0).abs() < 1e-12);
            let (r2, p2, y2) = roll_pitch_yaw(q);
            assert!((r - r2).abs() < 1e-12 && (p - p2).abs() < 1e-12 && (y - y2).abs() < 1e-12, "{r2} {p2} {y2}");
        }
        // Heading east is REP-103's yaw 0; north is pi/2.
        assert!(navigation_to_enu(90.0, 0.0, 0.0).2.abs() < 1e-12);
        assert!((navigation_to_enu(0.0, 0.0, 0.0).2 - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let v = navigation_velocity(10.0, 90.0, 0.0);
        assert!((v[0] - 10.0).abs() < 1e-12 && v[1].abs() < 1e-12);
    }

    struct Fixed(Vec<EntityInfo>, Vec<Body>);

    impl Entities for Fixed {
        fn list(&self) -> &[EntityInfo] {
            &self.0
        }
        fn read(&mut self, which: &[usize]) -> Result<Vec<Body>, SourceError> {
            Ok(which.iter().map(|&i| self.1[i]).collect())
        }
        fn write(&mut self, i: usize, pose: &Pose, velocity: [f64; 3]) -> Result<(), SourceError> {
            self.1[i] = Body { pose: *pose, velocity, sim_time: 2.0 };
            Ok(())
        }
    }

    fn fixed() -> Fixed {
        let info = |name: &str, category, tags: &[&str], read_only: Option<&str>| EntityInfo {
            name: name.into(),
            category,
            description: format!("{name}'s"),
            tags: tags.iter().map(|t| t.to_string()).collect(),
            frame: "world".into(),
            read_only: read_only.map(str::to_string),
        };
        let at = |x: f64| Body {
            pose: Pose { position: [x, 0.0, 0.0], orientation: [0.0, 0.0, 0.0, 1.0] },
            velocity: [0.0; 3],
            sim_time: 1.5,
        };
        Fixed(
            vec![
                info("uav1", 1, &["air", "lead"], Some("its domain's writer")),
                info("uav2", 1, &["air"], None),
                info("box", 5, &[], None),
            ],
            vec![at(0.0), at(10.0), at(100.0)],
        )
    }

    fn names(v: &Value) -> Vec<&str> {
        v.get("entities").and_then(Value::as_array).unwrap().iter().filter_map(Value::as_str).collect()
    }

    fn code(v: &Value) -> u64 {
        v.path("result.result").and_then(Value::as_u64).unwrap()
    }

    #[test]
    fn filters_by_name_category_tags_and_bounds() {
        let mut f = fixed();
        let list = |filters: Value, f: &mut Fixed| {
            answer(EntityCall::List, "get_entities", &Struct::new().with("filters", filters).into(), f).unwrap()
        };
        assert_eq!(names(&list(Struct::new().into(), &mut f)), ["uav1", "uav2", "box"]);
        assert_eq!(names(&list(Struct::new().with("filter", "^uav").into(), &mut f)), ["uav1", "uav2"]);
        let cat = |c: u8| Value::from(Struct::new().with("category", c));
        assert_eq!(names(&list(Struct::new().with("categories", vec![cat(5)]).into(), &mut f)), ["box"]);
        let tags = |t: &[&str], mode: u8| {
            Struct::new().with(
                "tags",
                Struct::new()
                    .with("tags", t.iter().map(|t| Value::from(*t)).collect::<Vec<_>>())
                    .with("filter_mode", mode),
            )
        };
        assert_eq!(names(&list(tags(&["lead", "air"], 0).into(), &mut f)), ["uav1", "uav2"]);
        assert_eq!(names(&list(tags(&["lead", "air"], 1).into(), &mut f)), ["uav1"]);
        let sphere = Struct::new().with(
            "bounds",
            Struct::new().with("type", 3u8).with("points", vec![vector([9.0, 0.0, 0.0]), vector([2.0, 0.0, 0.0])]),
        );
        assert_eq!(names(&list(sphere.into(), &mut f)), ["uav2"]);
        let hull = Struct::new().with("bounds", Struct::new().with("type", 2u8));
        assert_eq!(code(&list(hull.into(), &mut f)), u64::from(result::FEATURE_UNSUPPORTED));
        let bad = Struct::new().with("filter", "(");
        assert_eq!(code(&list(bad.into(), &mut f)), u64::from(result::OPERATION_FAILED));
    }

    #[test]
    fn states_info_and_setting() {
        let mut f = fixed();
        let one =
            |call, name: &str, f: &mut Fixed| answer(call, "x", &Struct::new().with("entity", name).into(), f).unwrap();
        let s = one(EntityCall::State, "uav2", &mut f);
        assert_eq!(code(&s), 1);
        assert_eq!(s.path("state.pose.position.x").and_then(Value::as_f64), Some(10.0));
        assert_eq!(s.path("state.header.stamp.sec").and_then(Value::as_i64), Some(1));
        assert_eq!(s.path("state.header.frame_id").and_then(Value::as_str), Some("world"));
        assert_eq!(code(&one(EntityCall::State, "nobody", &mut f)), u64::from(result::NOT_FOUND));
        let i = one(EntityCall::Info, "box", &mut f);
        assert_eq!(i.path("info.category.category").and_then(Value::as_u64), Some(5));
        let pose = Struct::new()
            .with("position", vector([1.0, 2.0, 3.0]))
            .with("orientation", Struct::new().with("x", 0.0).with("y", 0.0).with("z", 0.0).with("w", 1.0));
        let set = |name: &str, pose: Struct, f: &mut Fixed| {
            let req = Struct::new().with("entity", name).with("state", Struct::new().with("pose", pose));
            answer(EntityCall::Set, "set_entity_state", &req.into(), f).unwrap()
        };
        assert_eq!(code(&set("uav2", pose.clone(), &mut f)), 1);
        assert_eq!(f.1[1].pose.position, [1.0, 2.0, 3.0]);
        let refused = set("uav1", pose, &mut f);
        assert_eq!(code(&refused), u64::from(result::FEATURE_UNSUPPORTED));
        assert!(refused.path("result.error_message").and_then(Value::as_str).unwrap().contains("writer"));
        let skewed = Struct::new().with("orientation", Struct::new().with("x", 1.0).with("w", 1.0));
        assert_eq!(code(&set("uav2", skewed, &mut f)), u64::from(INVALID_POSE));
        let states = answer(EntityCall::States, "x", &Struct::new().into(), &mut f).unwrap();
        assert_eq!(names(&states), ["uav1", "uav2", "box"]);
        assert_eq!(states.get("states").and_then(Value::as_array).map(<[Value]>::len), Some(3));
        assert_eq!(features(&f.0), vec![4, 6, 8, 10, 11, 12]);
    }
}
