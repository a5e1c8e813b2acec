//! MCAP: one file for the run, in the `ros2` profile, as `ros2 bag record` would write it.
//!
//! * a channel per set, named like its ROS 2 topic (`/DOMAIN/publish`, `/DOMAIN/subscribe`),
//!   message encoding `cdr`: each message is the sample the gateway would send (plain CDR,
//!   little-endian, encapsulation header first: `step`, `sim_time`, then the items);
//! * its schema is `ros2msg`, named `PKG/msg/TYPE`: the `.msg` that `tutti idl` writes, with
//!   the `.msg` of every nested bus type appended after a `MSG: PKG/msg/BUS` separator line
//!   (`tutti_ros2::idl::ros2msg`, which the gateway's Foxglove server uses too);
//! * log time = wall-clock time, publish time = simulated time (nanoseconds);
//! * `/tutti/events` (JSON): a `start` message at a domain's first recorded step (its
//!   connections and exclusive owner then), then one whenever its connection count
//!   (`connect`, `disconnect`) or its exclusive owner (`owner`) changes;
//! * the DDF, as read when the recording started, as an attachment named like its file
//!   (media type `application/xml`), and a `tutti` metadata record (`ddf`, `package`);
//! * chunks compressed with zstd, with message indexes and a summary, so that readers seek.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use ::mcap::records::MessageHeader;
use ::mcap::{Compression, WriteOptions, Writer};
use tutti_core::cdr::{SetCodec, HEADER_LE};
use tutti_core::ddf::{Model, Role};
use tutti_core::mapping;
use tutti_ros2::idl::ros2msg::{self, SchemaError};

use super::{create_parent, io_error, RecordError, Recorder, Step};

pub mod read;

/// The channel of connection events.
pub const EVENTS_TOPIC: &str = "/tutti/events";

const EVENT_SCHEMA: &str = r#"{"type":"object","properties":{"domain":{"type":"string"},"step":{"type":"integer"},"sim_time":{"type":"number"},"kind":{"type":"string","enum":["start","connect","disconnect","owner"]},"connections":{"type":"integer"},"change":{"type":"integer"},"owner_pid":{"type":["integer","null"]}}}"#;

/// The media type of the DDF attachment.
pub const DDF_MEDIA_TYPE: &str = "application/xml";
/// The name of the metadata record that describes the recording.
pub const METADATA_NAME: &str = "tutti";

struct SetChannel {
    id: u16,
    codec: SetCodec,
}

struct DomainChannels {
    name: String,
    publish: SetChannel,
    subscribe: SetChannel,
    /// Connections and exclusive owner at the last recorded step (None before the first).
    last: Option<(u32, Option<u32>)>,
}

/// An MCAP recording being written.
pub struct McapRecorder {
    path: PathBuf,
    writer: Writer<BufWriter<File>>,
    domains: Vec<DomainChannels>,
    events: u16,
    event_seq: u32,
    /// The message being written (header and body), and the body alone.
    message: Vec<u8>,
    body: Vec<u8>,
}

impl std::fmt::Debug for McapRecorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapRecorder").field("path", &self.path).finish()
    }
}

impl McapRecorder {
    pub fn create(path: &Path, model: &Model, ddf_path: &Path) -> Result<McapRecorder, RecordError> {
        let format_error = |detail: String| RecordError::Format { path: path.display().to_string(), detail };
        let mcap_error = |e: ::mcap::McapError| format_error(e.to_string());
        create_parent(path)?;
        let file = File::create(path).map_err(io_error(path))?;
        let mut writer = WriteOptions::new()
            .compression(Some(Compression::Zstd))
            .profile("ros2")
            .create(BufWriter::new(file))
            .map_err(mcap_error)?;
        let package = mapping::package_name(ddf_path);
        let schema_error = |e: SchemaError| format_error(e.to_string());
        let defs = ros2msg::message_definitions(model, &package).map_err(schema_error)?;
        let no_metadata = BTreeMap::new();
        let mut domains = Vec::with_capacity(model.domains.len());
        for d in &model.domains {
            let mut channel = |role: Role| -> Result<SetChannel, RecordError> {
                let names = mapping::set_names(&package, &d.name, role);
                let schema = ros2msg::set_schema(&defs, &package, &d.name, role).map_err(schema_error)?;
                let schema_id =
                    writer.add_schema(&schema.name, "ros2msg", schema.text.as_bytes()).map_err(mcap_error)?;
                let id = writer.add_channel(schema_id, &names.ros2_topic, "cdr", &no_metadata).map_err(mcap_error)?;
                Ok(SetChannel { id, codec: SetCodec::new(&d.set(role).layout) })
            };
            let publish = channel(Role::Publish)?;
            let subscribe = channel(Role::Subscribe)?;
            domains.push(DomainChannels { name: d.name.clone(), publish, subscribe, last: None });
        }
        // The DDF inside, so that the recording replays on its own (`tutti replay`).
        let ddf_text = std::fs::read(ddf_path).map_err(io_error(ddf_path))?;
        let ddf_name = ddf_path.file_name().map_or_else(|| "run.ddf".into(), |n| n.to_string_lossy().into_owned());
        let now = super::now_ns();
        let attachment = ::mcap::Attachment {
            log_time: now,
            create_time: now,
            name: ddf_name.clone(),
            media_type: DDF_MEDIA_TYPE.into(),
            data: std::borrow::Cow::Owned(ddf_text),
        };
        writer.attach(&attachment).map_err(mcap_error)?;
        let metadata = BTreeMap::from([("ddf".to_string(), ddf_name), ("package".to_string(), package.clone())]);
        writer
            .write_metadata(&::mcap::records::Metadata { name: METADATA_NAME.into(), metadata })
            .map_err(mcap_error)?;
        let event_schema =
            writer.add_schema("tutti/Event", "jsonschema", EVENT_SCHEMA.as_bytes()).map_err(mcap_error)?;
        let events = writer.add_channel(event_schema, EVENTS_TOPIC, "json", &no_metadata).map_err(mcap_error)?;
        Ok(McapRecorder {
            path: path.to_path_buf(),
            writer,
            domains,
            events,
            event_seq: 0,
            message: Vec::new(),
            body: Vec::new(),
        })
    }

    fn error(&self, e: ::mcap::McapError) -> RecordError {
        RecordError::Format { path: self.path.display().to_string(), detail: e.to_string() }
    }
}

/// Seconds as nanoseconds (negative and non-finite times as zero).
fn nanos(secs: f64) -> u64 {
    let ns = (secs * 1e9).round();
    if ns.is_finite() && ns > 0.0 {
        ns as u64
    } else {
        0
    }
}

impl Recorder for McapRecorder {
    fn step(&mut self, domain: usize, s: &Step<'_>) -> Result<(), RecordError> {
        let Some(d) = self.domains.get_mut(domain) else { return Ok(()) };
        let sequence = s.step as u32;
        let (log_time, publish_time) = (s.wall_ns, nanos(s.sim_time));
        for (ch, set) in [(&d.publish, s.publish), (&d.subscribe, s.subscribe)] {
            ch.codec.encode(s.step, s.sim_time, set, &mut self.body);
            self.message.clear();
            self.message.extend_from_slice(&HEADER_LE);
            self.message.extend_from_slice(&self.body);
            let header = MessageHeader { channel_id: ch.id, sequence, log_time, publish_time };
            if let Err(e) = self.writer.write_to_known_channel(&header, &self.message) {
                return Err(RecordError::Format { path: self.path.display().to_string(), detail: e.to_string() });
            }
        }
        let now = (s.connections, s.owner_pid);
        let mut events = Vec::new();
        match d.last.replace(now) {
            None => events.push(serde_json::json!({
                "kind": "start", "connections": s.connections, "owner_pid": s.owner_pid,
            })),
            Some((connections, owner_pid)) => {
                if connections != s.connections {
                    let change = i64::from(s.connections) - i64::from(connections);
                    events.push(serde_json::json!({
                        "kind": if change > 0 { "connect" } else { "disconnect" },
                        "connections": s.connections,
                        "change": change,
                    }));
                }
                if owner_pid != s.owner_pid {
                    events.push(serde_json::json!({ "kind": "owner", "owner_pid": s.owner_pid }));
                }
            }
        }
        let name = d.name.clone();
        for mut event in events {
            event["domain"] = name.clone().into();
            event["step"] = s.step.into();
            event["sim_time"] = s.sim_time.into();
            self.event_seq += 1;
            let header = MessageHeader { channel_id: self.events, sequence: self.event_seq, log_time, publish_time };
            let text = event.to_string();
            if let Err(e) = self.writer.write_to_known_channel(&header, text.as_bytes()) {
                return Err(self.error(e));
            }
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<(), RecordError> {
        match self.writer.finish() {
            Ok(_) => Ok(()),
            Err(e) => Err(self.error(e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, SystemTime, UNIX_EPOCH};

    fn model() -> (Model, PathBuf) {
        let ddf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../ddf/product-sample.ddf");
        (tutti_core::ddf::load(&ddf).unwrap(), ddf)
    }

    #[test]
    fn every_set_of_every_step_is_a_cdr_message_on_its_topic() {
        let (m, ddf) = model();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let mut rec = crate::create(&path, &m, &ddf).unwrap();
        let t0 = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO).as_nanos() as u64;
        let sets: Vec<(Vec<u8>, Vec<u8>)> = m
            .domains
            .iter()
            .map(|d| {
                let p: Vec<u8> = (0..d.publish.layout.size).map(|i| i as u8).collect();
                (p, d.subscribe.layout.default_bytes())
            })
            .collect();
        for k in 1..=3u64 {
            for (i, (p, s)) in sets.iter().enumerate() {
                let step = Step {
                    step: k,
                    sim_time: k as f64 * 0.5,
                    wall_ns: t0 + k,
                    elapsed_s: 0.0,
                    connections: k as u32,
                    owner_pid: (k == 3).then_some(42),
                    publish: p,
                    subscribe: s,
                };
                rec.step(i, &step).unwrap();
            }
        }
        rec.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut n = 0;
        let mut events = 0;
        for msg in ::mcap::MessageStream::new(&bytes).unwrap() {
            let msg = msg.unwrap();
            if msg.channel.topic == EVENTS_TOPIC {
                events += 1;
                continue;
            }
            let (di, d) = m
                .domains
                .iter()
                .enumerate()
                .find(|(_, d)| msg.channel.topic.starts_with(&format!("/{}/", d.name)))
                .unwrap();
            let role = if msg.channel.topic.ends_with("/publish") { Role::Publish } else { Role::Subscribe };
            let schema = msg.channel.schema.as_ref().unwrap();
            assert_eq!(schema.encoding, "ros2msg");
            assert_eq!(msg.channel.message_encoding, "cdr");
            let decoded = SetCodec::new(&d.set(role).layout).decode(&msg.data).unwrap();
            let want = if role == Role::Publish { &sets[di].0 } else { &sets[di].1 };
            // Padding does not travel: compare the leaves.
            for leaf in &d.set(role).layout.leaves {
                assert_eq!(decoded.data[leaf.range()], want[leaf.range()], "{}", leaf.path);
            }
            assert_eq!(msg.publish_time, nanos(decoded.sim_time));
            assert_eq!(u64::from(msg.sequence), decoded.step);
            n += 1;
        }
        assert_eq!(n, 3 * 2 * m.domains.len());
        // Per domain: its start, a connection change at steps 2 and 3, an owner at step 3.
        assert_eq!(events, 4 * m.domains.len());
        let recording = crate::replay::Recording::read(&path).unwrap();
        assert_eq!(recording.ddf_name, "product-sample.ddf");
        assert_eq!(recording.model.domains.len(), m.domains.len());
    }
}
