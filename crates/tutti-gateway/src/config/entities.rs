//! The `entities` key (docs/gateway.md, "Entities"): the run's bodies as ROS 2 entities, each
//! named with the domain, set and items that give its position and attitude, in one of two
//! forms: geodetic (latitude, longitude, altitude, heading, and optionally pitch, roll and
//! speed, turned into a local ENU frame about a declared origin) or Cartesian (x, y, z and a
//! quaternion or roll, pitch and yaw).
//!
//! Each entry is checked where it stands, so that a mistake is reported as FILE:LINE:COLUMN:
//! its shape always; its domain, set and items against the DDF when the reader has one in
//! scope ([`with_model`]: `tutti gateway`, and the second pass over a launch file). The same
//! check runs again when the options are made from the keys ([`check_all`]), for a reader
//! that had no DDF in scope.

use std::cell::RefCell;

use serde::{Deserialize, Deserializer};
use tutti_config::sections::Section;
use tutti_core::ddf::{Domain, Model, Role, ScalarType};

pub use crate::error::EntityError;

/// `entities: [...]`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EntityKeys {
    pub entities: Option<Vec<Entity>>,
    /// How often the poses go out on `/tf` and `<entity>/pose` (Hz; none: every step).
    #[serde(default, deserialize_with = "super::values::de_rate")]
    pub pose_rate: Option<f64>,
}

impl Section for EntityKeys {
    const KEYS: &'static [&'static str] = &["entities", "pose_rate"];

    fn over(self, lower: Self) -> Self {
        EntityKeys { entities: self.entities.or(lower.entities), pose_rate: self.pose_rate.or(lower.pose_rate) }
    }
}

/// One entity, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Entity {
    pub name: String,
    /// `simulation_interfaces/msg/EntityCategory`.
    pub category: u8,
    pub description: String,
    pub tags: Vec<String>,
    /// The frame its pose is in: `header.frame_id`, and the parent frame on `/tf`.
    pub frame: String,
    pub domain: String,
    pub role: Role,
    pub form: Form,
}

/// Where an entity's pose comes from: item paths of its set.
#[derive(Debug, Clone, PartialEq)]
pub enum Form {
    Geodetic {
        /// Latitude and longitude (degrees) and altitude (m) of the ENU frame's origin.
        origin: [f64; 3],
        latitude: String,
        longitude: String,
        altitude: String,
        /// Degrees clockwise from north.
        heading: String,
        /// Degrees, nose up.
        pitch: Option<String>,
        /// Degrees, right wing down.
        roll: Option<String>,
        /// m/s along the heading (and pitch).
        speed: Option<String>,
    },
    Cartesian {
        x: String,
        y: String,
        z: String,
        attitude: Attitude,
    },
}

/// A Cartesian entity's attitude.
#[derive(Debug, Clone, PartialEq)]
pub enum Attitude {
    /// Radians, REP-103 (each absent one is 0).
    RollPitchYaw { roll: Option<String>, pitch: Option<String>, yaw: Option<String> },
    /// A quaternion's x, y, z and w.
    Quaternion([String; 4]),
}

impl Form {
    /// Every item it reads, with what each stands for.
    pub fn items(&self) -> Vec<(&'static str, &str)> {
        let mut out: Vec<(&'static str, &str)> = Vec::new();
        match self {
            Form::Geodetic { latitude, longitude, altitude, heading, pitch, roll, speed, .. } => {
                out.extend(
                    [("latitude", latitude), ("longitude", longitude), ("altitude", altitude), ("heading", heading)]
                        .map(|(w, i)| (w, i.as_str())),
                );
                out.extend(
                    [("pitch", pitch), ("roll", roll), ("speed", speed)]
                        .into_iter()
                        .filter_map(|(w, i)| Some((w, i.as_deref()?))),
                );
            }
            Form::Cartesian { x, y, z, attitude } => {
                out.extend([("x", x), ("y", y), ("z", z)].map(|(w, i)| (w, i.as_str())));
                match attitude {
                    Attitude::RollPitchYaw { roll, pitch, yaw } => out.extend(
                        [("roll", roll), ("pitch", pitch), ("yaw", yaw)]
                            .into_iter()
                            .filter_map(|(w, i)| Some((w, i.as_deref()?))),
                    ),
                    Attitude::Quaternion(q) => {
                        out.extend(["qx", "qy", "qz", "qw"].into_iter().zip(q.iter().map(String::as_str)))
                    }
                }
            }
        }
        out
    }
}

/// An entity as the file writes it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Written {
    name: String,
    #[serde(default)]
    category: Option<String>,
    #[serde(default)]
    description: String,
    #[serde(default)]
    tags: Vec<String>,
    #[serde(default)]
    frame: Option<String>,
    domain: String,
    set: String,
    geodetic: Option<WrittenGeodetic>,
    cartesian: Option<WrittenCartesian>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WrittenGeodetic {
    origin: [f64; 3],
    latitude: String,
    longitude: String,
    altitude: String,
    heading: String,
    pitch: Option<String>,
    roll: Option<String>,
    speed: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WrittenCartesian {
    x: String,
    y: String,
    z: String,
    roll: Option<String>,
    pitch: Option<String>,
    yaw: Option<String>,
    qx: Option<String>,
    qy: Option<String>,
    qz: Option<String>,
    qw: Option<String>,
}

/// `simulation_interfaces/msg/EntityCategory` by the names the file may give.
const CATEGORIES: &[(&str, u8)] =
    &[("object", 0), ("robot", 1), ("human", 2), ("dynamic_object", 4), ("static_object", 5)];

impl Written {
    fn check(self) -> Result<Entity, EntityError> {
        let name = self.name;
        let shape = |why: String| EntityError::Shape(name.clone(), why);
        tutti_ros2::names::topic_name(&name)
            .map_err(|e| shape(format!("its name is also its topic's (`{name}/pose`): {e}")))?;
        if name.contains('/') {
            return Err(shape("a name has no '/': it is a frame of /tf too".into()));
        }
        let category = match self.category.as_deref() {
            None => 0,
            Some(c) => CATEGORIES.iter().find(|(n, _)| *n == c).map(|(_, v)| *v).ok_or_else(|| {
                let names: Vec<&str> = CATEGORIES.iter().map(|(n, _)| *n).collect();
                shape(format!("category '{c}': use one of {}", names.join(", ")))
            })?,
        };
        let role = match self.set.to_ascii_lowercase().as_str() {
            "publish" => Role::Publish,
            "subscribe" => Role::Subscribe,
            s => return Err(shape(format!("set '{s}': use publish or subscribe"))),
        };
        let form = match (self.geodetic, self.cartesian) {
            (Some(g), None) => {
                let [lat, lon, alt] = g.origin;
                if !(lat.abs() <= 90.0 && lon.abs() <= 180.0 && alt.is_finite()) {
                    return Err(shape(format!(
                        "origin [{lat}, {lon}, {alt}]: a latitude within ±90°, a longitude within ±180° and an altitude"
                    )));
                }
                Form::Geodetic {
                    origin: g.origin,
                    latitude: g.latitude,
                    longitude: g.longitude,
                    altitude: g.altitude,
                    heading: g.heading,
                    pitch: g.pitch,
                    roll: g.roll,
                    speed: g.speed,
                }
            }
            (None, Some(c)) => {
                let rpy = c.roll.is_some() || c.pitch.is_some() || c.yaw.is_some();
                let attitude = match (c.qx, c.qy, c.qz, c.qw) {
                    (None, None, None, None) => Attitude::RollPitchYaw { roll: c.roll, pitch: c.pitch, yaw: c.yaw },
                    (Some(x), Some(y), Some(z), Some(w)) if !rpy => Attitude::Quaternion([x, y, z, w]),
                    (Some(_), Some(_), Some(_), Some(_)) => {
                        return Err(shape("give a quaternion (qx, qy, qz, qw) or roll, pitch and yaw, not both".into()))
                    }
                    _ => return Err(shape("a quaternion needs all of qx, qy, qz and qw".into())),
                };
                Form::Cartesian { x: c.x, y: c.y, z: c.z, attitude }
            }
            (Some(_), Some(_)) => return Err(shape("give `geodetic` or `cartesian`, not both".into())),
            (None, None) => return Err(shape("give its pose's items: `geodetic` or `cartesian`".into())),
        };
        let e = Entity {
            name,
            category,
            description: self.description,
            tags: self.tags,
            frame: self.frame.unwrap_or_else(|| "world".into()),
            domain: self.domain,
            role,
            form,
        };
        MODEL.with(|m| m.borrow().as_ref().map_or(Ok(()), |m| check(&e, m)))?;
        Ok(e)
    }
}

impl<'de> Deserialize<'de> for Entity {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        tutti_config::de::then(d, Written::check)
    }
}

thread_local! {
    /// The DDF the entities are checked against while a file is read ([`with_model`]).
    static MODEL: RefCell<Option<Model>> = const { RefCell::new(None) };
}

/// Runs `f` (which reads a config file) with `model` in scope, so that each entity's domain,
/// set and items are checked where the entity stands.
pub fn with_model<T>(model: &Model, f: impl FnOnce() -> T) -> T {
    struct Clear;
    impl Drop for Clear {
        fn drop(&mut self) {
            MODEL.with(|m| m.borrow_mut().take());
        }
    }
    MODEL.with(|m| *m.borrow_mut() = Some(model.clone()));
    let _clear = Clear;
    f()
}

/// Checks entity `e` against the DDF `model`: its domain, and each item in its set, a
/// number.
pub fn check(e: &Entity, model: &Model) -> Result<(), EntityError> {
    let names = || model.domains.iter().map(|d| d.name.as_str()).collect::<Vec<_>>().join(", ");
    let d: &Domain = model.domain(&e.domain).ok_or_else(|| EntityError::NoDomain {
        entity: e.name.clone(),
        domain: e.domain.clone(),
        domains: names(),
    })?;
    let leaves = &d.set(e.role).layout.leaves;
    for (what, item) in e.form.items() {
        let Some(leaf) = leaves.iter().find(|l| l.path == item) else {
            let items: Vec<&str> = leaves.iter().map(|l| l.path.as_str()).collect();
            let items = if items.is_empty() { "none".into() } else { items.join(", ") };
            let why =
                format!("domain '{}' has no {} item '{item}' (its {what}; items: {items})", d.name, e.role.lower());
            return Err(EntityError::Item { entity: e.name.clone(), why });
        };
        if leaf.length != 1 || leaf.ty == ScalarType::Boolean {
            let ty = if leaf.length == 1 {
                "boolean".to_string()
            } else {
                format!("an array of {} {}", leaf.length, leaf.ty.canonical())
            };
            let why = format!(
                "item '{item}' of domain '{}' ({what}) is {ty}, not one number: a position or an angle is a scalar of \
                 a numeric type",
                d.name
            );
            return Err(EntityError::Item { entity: e.name.clone(), why });
        }
    }
    Ok(())
}

/// Checks every entity against `model`, and that no name is given twice.
pub fn check_all(entities: &[Entity], model: &Model) -> Result<(), EntityError> {
    for (i, e) in entities.iter().enumerate() {
        if entities[..i].iter().any(|o| o.name == e.name) {
            return Err(EntityError::Twice(e.name.clone()));
        }
        check(e, model)?;
    }
    Ok(())
}
