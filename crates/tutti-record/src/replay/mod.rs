//! An MCAP recording read back, for `tutti replay`: the DDF it carries (or one given
//! instead), and every recorded step of every domain with both sets in shared-memory layout
//! and the domain's connection count at that step (from the `/tutti/events` channel). The
//! framework that replays it is [`Replay`].
//!
//! The whole recording is read into memory: a step costs the two sets' sizes plus some 60
//! bytes, so a minute of the 4-domain UAV DDF at 1 kHz takes about 100 MB.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use tutti_core::cdr::SetCodec;
use tutti_core::ddf::{Model, Role};
use tutti_core::mapping;

use crate::mcap::read::{Attachment, McapFile, Metadata};
use crate::mcap::{DDF_MEDIA_TYPE, EVENTS_TOPIC, METADATA_NAME};
use crate::{io_error, RecordError};

mod run;

pub use run::{Comparison, Difference, DifferingStep, Replay, ReplayEvent, ReplayOptions, ReplaySummary};

/// One recorded step of one domain.
#[derive(Debug, Clone)]
pub struct RecordedStep {
    /// The step number the framework gave it.
    pub step: u64,
    /// Simulated time, seconds.
    pub sim_time: f64,
    /// Wall-clock time it was recorded, nanoseconds since the Unix epoch.
    pub log_time: u64,
    /// The PUBLISH set, in shared-memory layout.
    pub publish: Vec<u8>,
    /// The SUBSCRIBE set the framework read for the step, in shared-memory layout.
    pub subscribe: Option<Vec<u8>>,
    /// Connections of the domain during the step (0 when the recording has no events).
    pub connections: u32,
}

/// The recorded steps of one domain, in step order.
#[derive(Debug, Clone)]
pub struct RecordedDomain {
    pub name: String,
    pub steps: Vec<RecordedStep>,
}

/// A recording read back.
#[derive(Debug)]
pub struct Recording {
    /// The file name of the DDF the recording was made with.
    pub ddf_name: String,
    /// Its model, with only the domains the recording has steps of, in DDF order.
    pub model: Model,
    /// The steps of each domain of `model`, in the same order.
    pub domains: Vec<RecordedDomain>,
}

/// A message of a set channel.
struct SetMessage {
    domain: usize,
    role: Role,
}

impl Recording {
    /// Reads `path`, with the DDF it carries.
    pub fn read(path: &Path) -> Result<Recording, RecordError> {
        Recording::read_with(path, None)
    }

    /// Reads `path`; with `ddf`, that DDF describes its domains instead of the one inside
    /// (needed for a recording made by another tool, which has none).
    pub fn read_with(path: &Path, ddf: Option<&Path>) -> Result<Recording, RecordError> {
        let format = |detail: String| RecordError::Format { path: path.display().to_string(), detail };
        let damaged = |error| RecordError::Mcap { path: path.display().to_string(), error };
        let bytes = std::fs::read(path).map_err(io_error(path))?;
        // Every length in the file is checked before use: a damaged or hostile file is an
        // error at its byte offset (crate::mcap::read).
        let file = McapFile::parse(&bytes).map_err(damaged)?;
        let (model, ddf_name) = match ddf {
            Some(ddf) => {
                let model = tutti_core::ddf::load(ddf)
                    .map_err(|e| RecordError::Format { path: ddf.display().to_string(), detail: e.to_string() })?;
                (model, ddf.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned()))
            }
            None => {
                let attachments = file.attachments().map_err(damaged)?;
                embedded_ddf(&attachments).map_err(|e| format(e.to_string()))?
            }
        };
        let package = package_of(&file.metadata().map_err(damaged)?)
            .unwrap_or_else(|| mapping::package_name(Path::new(&ddf_name)));
        // Each set's topic, as the recorder named it.
        let mut by_topic: HashMap<String, (usize, Role)> = HashMap::new();
        for (i, d) in model.domains.iter().enumerate() {
            for role in [Role::Publish, Role::Subscribe] {
                by_topic.insert(mapping::set_names(&package, &d.name, role).ros2_topic, (i, role));
            }
        }
        let codecs: Vec<[SetCodec; 2]> = model
            .domains
            .iter()
            .map(|d| [SetCodec::new(&d.publish.layout), SetCodec::new(&d.subscribe.layout)])
            .collect();
        let mut steps: Vec<BTreeMap<u64, RecordedStep>> = vec![BTreeMap::new(); model.domains.len()];
        // Connection counts from each domain's events: (step, count from then on).
        let mut counts: Vec<Vec<(u64, u32)>> = vec![Vec::new(); model.domains.len()];
        let mut channels: HashMap<u16, Option<SetMessage>> = HashMap::new();
        for msg in file.messages() {
            let msg = msg.map_err(damaged)?;
            let topic = &msg.channel.topic;
            if topic == EVENTS_TOPIC {
                if let Some((domain, step, connections)) = connection_event(&msg.data) {
                    if let Some(i) = model.domains.iter().position(|d| d.name == domain) {
                        counts[i].push((step, connections));
                    }
                }
                continue;
            }
            let set = channels.entry(msg.channel.id).or_insert_with(|| {
                let ours = msg.channel.message_encoding == "cdr";
                by_topic.get(topic.as_str()).filter(|_| ours).map(|&(domain, role)| SetMessage { domain, role })
            });
            let Some(set) = set else { continue };
            let decoded = codecs[set.domain][set.role as usize]
                .decode(&msg.data)
                .map_err(|e| format(format!("{} ({topic}, message {}): {e}", msg.at, msg.sequence)))?;
            let entry = steps[set.domain].entry(decoded.step).or_insert_with(|| RecordedStep {
                step: decoded.step,
                sim_time: decoded.sim_time,
                log_time: msg.log_time,
                publish: Vec::new(),
                subscribe: None,
                connections: 0,
            });
            match set.role {
                Role::Publish => {
                    entry.publish = decoded.data;
                    entry.sim_time = decoded.sim_time;
                    entry.log_time = msg.log_time;
                }
                Role::Subscribe => entry.subscribe = Some(decoded.data),
            }
        }
        let mut domains = Vec::new();
        let mut kept = Vec::new();
        for (i, (d, steps)) in model.domains.iter().zip(steps).enumerate() {
            // A step without its PUBLISH set cannot be replayed.
            let mut steps: Vec<RecordedStep> = steps.into_values().filter(|s| !s.publish.is_empty()).collect();
            if steps.is_empty() {
                continue;
            }
            let mut events = counts[i].iter().peekable();
            let mut connections = 0;
            for s in &mut steps {
                while let Some(&(_, c)) = events.next_if(|(k, _)| *k <= s.step) {
                    connections = c;
                }
                s.connections = connections;
            }
            domains.push(RecordedDomain { name: d.name.clone(), steps });
            kept.push(d.name.clone());
        }
        let mut model = model;
        model.domains.retain(|d| kept.contains(&d.name));
        Ok(Recording { ddf_name, model, domains })
    }
}

/// Why the DDF a recording carries cannot be had.
#[derive(Debug, thiserror::Error)]
pub enum EmbeddedDdfError {
    #[error("no DDF inside (recorded by another tool?): give the DDF with --ddf")]
    Missing,
    #[error(transparent)]
    Invalid(#[from] tutti_core::ddf::DdfError),
}

/// The DDF attachment: its model and file name.
fn embedded_ddf(attachments: &[Attachment<'_>]) -> Result<(Model, String), EmbeddedDdfError> {
    let a = attachments.iter().find(|a| a.media_type == DDF_MEDIA_TYPE).ok_or(EmbeddedDdfError::Missing)?;
    let model = tutti_core::ddf::parse_bytes(a.data, &format!("{} (inside the recording)", a.name))?;
    Ok((model, a.name.clone()))
}

/// The ROS 2 package the recorder named its types after.
fn package_of(metadata: &[Metadata]) -> Option<String> {
    metadata.iter().find(|m| m.name == METADATA_NAME)?.entries.get("package").cloned()
}

/// (domain, step, connections) of an event that gives a connection count.
fn connection_event(data: &[u8]) -> Option<(String, u64, u32)> {
    let v: serde_json::Value = serde_json::from_slice(data).ok()?;
    let connections = u32::try_from(v.get("connections")?.as_u64()?).ok()?;
    Some((v.get("domain")?.as_str()?.to_string(), v.get("step")?.as_u64()?, connections))
}
