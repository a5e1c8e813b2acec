//! The DDS engine layer: all the gateway needs from a DDS implementation, and nothing more.
//!
//! Routes, the CDR codec, the QoS table, exclusivity, echo suppression, stats and the mirror
//! are written once above this layer; an [`Engine`] only moves pre-encoded CDR bytes
//! between topics and the gateway, and tells who is on the other side. Two engines
//! implement it: [`cyclone`] (Cyclone DDS through `cyclors`, the default, always built) and
//! `rustdds` (the pure-Rust stack, ros2-client over rustdds; cargo feature `rustdds`, on by
//! default). [`EngineKind::built`] lists those of this build.

use std::collections::{BTreeSet, HashMap};
use std::fmt;
use std::net::IpAddr;
use std::sync::Arc;
use std::time::Duration;

use tutti_core::ddf::Leaf;
use tutti_core::mapping::{Ownership, Qos, Reliability};
use tutti_ros2::TypeHash;

use crate::cdr::{stock, CdrError, Payload, SetCodec};
pub use crate::error::UnknownEngine;
use crate::GatewayError;

pub mod cyclone;
#[cfg(feature = "rustdds")]
pub mod rustdds;

/// Bytes of a GUID prefix (the participant part of an endpoint GUID).
pub const PREFIX_LEN: usize = 12;

/// The GUID of a DDS endpoint: the 12-byte prefix of its participant and its entity id.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Guid(pub [u8; 16]);

impl Guid {
    /// The participant part.
    pub fn prefix(&self) -> [u8; PREFIX_LEN] {
        let mut p = [0u8; PREFIX_LEN];
        p.copy_from_slice(&self.0[..PREFIX_LEN]);
        p
    }

    /// A short printable form, for connection names and logs.
    pub fn short(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }
}

impl fmt::Debug for Guid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.short())
    }
}

/// The two engines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EngineKind {
    /// Cyclone DDS, through `cyclors`.
    #[default]
    Cyclone,
    /// rustdds and ros2-client (pure Rust).
    Rustdds,
}

impl EngineKind {
    pub fn name(self) -> &'static str {
        match self {
            EngineKind::Cyclone => "cyclone",
            EngineKind::Rustdds => "rustdds",
        }
    }

    /// Both engines, built or not.
    pub const ALL: [EngineKind; 2] = [EngineKind::Cyclone, EngineKind::Rustdds];

    /// The engines this build contains, for tests and benchmarks that run against each.
    pub fn built() -> &'static [EngineKind] {
        if cfg!(feature = "rustdds") {
            &EngineKind::ALL
        } else {
            &[EngineKind::Cyclone]
        }
    }

    /// Whether this build contains the engine.
    pub fn is_built(self) -> bool {
        EngineKind::built().contains(&self)
    }
}

impl std::str::FromStr for EngineKind {
    type Err = UnknownEngine;
    fn from_str(s: &str) -> Result<Self, UnknownEngine> {
        match s.trim().to_ascii_lowercase().as_str() {
            "cyclone" | "cyclonedds" => Ok(EngineKind::Cyclone),
            "rustdds" => Ok(EngineKind::Rustdds),
            other => Err(UnknownEngine { name: other.to_string() }),
        }
    }
}

impl fmt::Display for EngineKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The type of a topic's endpoints: its DDS name and, for a ROS 2 type, the type hash every
/// endpoint of it announces in its USER_DATA (`typehash=RIHS01_…;`, docs/gateway.md "Type
/// hashes"), as ROS 2 Jazzy's endpoints do.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicType {
    /// The DDS type name (`PKG::msg::dds_::TYPE_`).
    pub name: String,
    /// None: a plain DDS type, announced without USER_DATA.
    pub hash: Option<TypeHash>,
}

impl TopicType {
    /// A ROS 2 type with its hash (a set's type: `tutti_ros2::idl::type_hashes`).
    pub fn ros2(name: &str, hash: TypeHash) -> TopicType {
        TopicType { name: name.to_string(), hash: Some(hash) }
    }

    /// A stock ROS 2 type (`std_msgs`, `rosgraph_msgs/Clock`, …), with the hash ROS 2 gives
    /// it when `tutti_ros2::registry` holds it.
    pub fn stock(name: &str) -> TopicType {
        TopicType { name: name.to_string(), hash: tutti_ros2::registry().hash_of_dds_type(name) }
    }

    /// A type ROS 2 does not know: no type hash.
    pub fn plain(name: &str) -> TopicType {
        TopicType { name: name.to_string(), hash: None }
    }

    /// The USER_DATA its endpoints announce (`typehash=RIHS01_…;`), if any.
    pub fn user_data(&self) -> Option<String> {
        self.hash.map(|h| h.user_data())
    }
}

/// How a participant joins DDS.
#[derive(Debug, Clone, Default)]
pub struct EngineConfig {
    /// DDS domain id (ROS_DOMAIN_ID).
    pub domain_id: u16,
    /// Addresses DDS may use; empty: the engine's default (Cyclone: `CYCLONEDDS_URI`).
    pub interfaces: Vec<IpAddr>,
    /// Unicast discovery peers (addresses or host names), for networks without multicast.
    pub peers: Vec<String>,
    /// The ROS 2 node the participant announces on `ros_discovery_info`.
    pub node_name: String,
    /// Its namespace ("/" for none).
    pub node_namespace: String,
    /// The lease the participant announces: how long the other participants keep it, and
    /// its endpoints, once it has gone silent (killed: no goodbye). A reliable DDS writer
    /// keeps every sample a killed gateway's reader never acknowledged until then, and may
    /// block on a full history. None: the engine's default. Cyclone only: rustdds 0.15
    /// always announces 50 s (docs/gateway.md, "Departures").
    pub participant_lease: Option<Duration>,
}

/// How the samples of a reader are decoded into a [`Payload`].
#[derive(Debug, Clone)]
pub enum Decode {
    /// A typed set (`tutti idl`'s struct).
    Set(Arc<SetCodec>),
    /// One item of per-item mode: its leaf and its path.
    Item(Arc<Leaf>, Arc<str>),
    /// None: the sink takes the serialized sample as it is ([`Data::Raw`]); engines that
    /// decode as they read refuse such a reader.
    Raw,
}

/// One sample as a reader delivers it.
#[derive(Debug)]
pub enum Data<'a> {
    /// The serialized sample, encapsulation header included (decoded above the engine).
    Raw(&'a [u8]),
    /// Already decoded by the engine (rustdds decodes through serde as it reads).
    Decoded(Result<Payload, CdrError>),
}

impl Data<'_> {
    /// The sample as a [`Payload`]: as the engine decoded it, or decoded here from its
    /// serialized form by `decode`.
    pub fn into_payload(self, decode: &Decode) -> Result<Payload, CdrError> {
        match self {
            Data::Decoded(r) => r,
            Data::Raw(raw) => match decode {
                Decode::Set(codec) => codec.decode(raw).map(Payload::Set),
                Decode::Item(leaf, path) => {
                    stock::decode(leaf, raw).map(|bytes| Payload::Item { path: path.clone(), bytes })
                }
                Decode::Raw => Err(CdrError::Unexpected("a raw sample is no set nor item")),
            },
        }
    }
}

/// Where a reader's samples go: called on the engine's receive path with the writer's GUID.
/// It must not block for long: on Cyclone it runs on the receive thread.
pub type Sink = Arc<dyn Fn(Guid, Data<'_>) + Send + Sync>;

/// A sample's identity on the wire: the GUID of its writer and the writer's sequence number
/// for it. A reply of a service in Fast DDS's form carries its request's as its *related
/// sample identity* (docs/ros2.md, "Wire forms").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SampleIdentity {
    pub writer: Guid,
    pub sequence: i64,
}

/// One sample of a reader made by [`Engine::identified_reader`]: its serialized form and what
/// the wire says of it beyond its writer.
#[derive(Debug)]
pub struct Identified<'a> {
    /// The writer's GUID.
    pub writer: Guid,
    /// The writer's sequence number for the sample; None where the engine does not read
    /// it (Cyclone).
    pub sequence: Option<i64>,
    /// The related sample identity the sample carries (an inline QoS parameter), if any; always
    /// None where the engine does not read it (Cyclone).
    pub related: Option<SampleIdentity>,
    /// The serialized sample, encapsulation header included.
    pub raw: &'a [u8],
}

/// Where an identified reader's samples go; as a [`Sink`], it must not block for long.
pub type IdentifiedSink = Arc<dyn Fn(Identified<'_>) + Send + Sync>;

/// A writer of pre-encoded samples.
pub trait Writer: Send {
    /// Writes one sample whose CDR body (little-endian, no encapsulation header) is `body`;
    /// false when DDS refused it.
    fn write(&mut self, body: &[u8]) -> bool;
    /// Writes one serialized sample as it is, encapsulation header first (plain CDR in
    /// either byte order); false when DDS refused it, or when the engine writes only
    /// little-endian samples (rustdds).
    fn write_serialized(&mut self, raw: &[u8]) -> bool;
    /// Writes one sample whose CDR body (little-endian, no encapsulation header) is `body`,
    /// carrying `related` as its related sample identity; false when DDS refused it, or when
    /// the engine cannot write one (Cyclone; only [`Engine::related_writer`]'s writers can).
    fn write_related(&mut self, body: &[u8], related: SampleIdentity) -> bool {
        let _ = (body, related);
        false
    }
    /// How many readers of the participant whose GUID prefix is `prefix` this writer has
    /// matched (a sample written now reaches those); None where the engine cannot say
    /// (then discovery decides). Discovery may show a reader before the writer has matched
    /// it (rustdds), and a reliable, volatile writer gives a reader it has not matched
    /// nothing: the services' replies ask this first (docs/ros2.md, "Wire forms").
    fn matched_readers_of(&mut self, prefix: [u8; PREFIX_LEN]) -> Option<usize> {
        let _ = prefix;
        None
    }
    /// Takes in the match statuses the engine has queued for this writer, so that
    /// [`matched_readers_of`](Self::matched_readers_of) stays right between questions where
    /// the engine queues only a few and drops the rest (rustdds); a no-op elsewhere.
    fn take_match_statuses(&mut self) {}
    /// Sends what batching held back (a no-op where writes are not batched).
    fn flush(&mut self) {}
    /// A flush that another thread may call while this writer writes (None: the engine does
    /// not batch): it bounds in time how long a batched sample waits.
    fn flusher(&self) -> Option<Flusher> {
        None
    }
}

/// A writer's flush, callable from any thread.
pub type Flusher = std::sync::Arc<dyn Fn() + Send + Sync>;

/// Remote (not our participant's) endpoints per topic name, and the QoS each announced.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Remote {
    pub writers: HashMap<String, BTreeSet<Guid>>,
    pub readers: HashMap<String, BTreeSet<Guid>>,
    pub qos: HashMap<Guid, EndpointQos>,
}

/// The QoS a remote endpoint announced in discovery: the terms that decide matching and
/// delivery (not the history: it decides neither).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EndpointQos {
    pub reliability: Reliability,
    /// TRANSIENT_LOCAL (else VOLATILE).
    pub transient_local: bool,
    /// SHARED, or EXCLUSIVE with the strength announced (a reader's is 0).
    pub ownership: Ownership,
}

impl Remote {
    /// Remote writers on `topic`.
    pub fn writers_on<'a>(&'a self, topic: &str) -> impl Iterator<Item = Guid> + 'a {
        self.writers.get(topic).into_iter().flatten().copied()
    }

    /// Remote readers on any of `topics` (each once).
    pub fn readers_on(&self, topics: &[String]) -> BTreeSet<Guid> {
        topics.iter().filter_map(|t| self.readers.get(t)).flatten().copied().collect()
    }
}

/// A DDS participant, as the gateway uses it.
pub trait Engine: Send + Sync {
    fn kind(&self) -> EngineKind;
    /// Whether the engine's EXCLUSIVE readers deliver only the strongest live writer's
    /// samples (Cyclone); rustdds' readers deliver every writer's, and only the core's
    /// first-writer rule applies above it.
    fn arbitrates_ownership(&self) -> bool;
    /// The DDS domain id it joined.
    fn domain_id(&self) -> u16;
    /// The GUID prefix of its participant: endpoints with it are our own.
    fn own_prefix(&self) -> [u8; PREFIX_LEN];
    /// A writer on `topic` (of type `ty`, whose hash it announces) with QoS `q`.
    fn writer(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Box<dyn Writer>, GatewayError>;
    /// A reader on `topic` (of type `ty`, whose hash it announces) with QoS `q`; its samples
    /// go to `sink` for as long as the engine lives. `decode` is used by engines that decode
    /// as they read.
    fn reader(&self, topic: &str, ty: &TopicType, q: &Qos, decode: Decode, sink: Sink) -> Result<(), GatewayError>;
    /// A reader on `topic` (as [`Engine::reader`], raw) whose samples go to `sink` with
    /// their identity and related sample identity, where the engine reads them. By default a
    /// raw reader that reads neither (Cyclone DDS offers neither: docs/ros2.md, "Wire forms").
    fn identified_reader(
        &self,
        topic: &str,
        ty: &TopicType,
        q: &Qos,
        sink: IdentifiedSink,
    ) -> Result<(), GatewayError> {
        let raw: Sink = Arc::new(move |writer: Guid, data: Data<'_>| {
            if let Data::Raw(raw) = data {
                sink(Identified { writer, sequence: None, related: None, raw });
            }
        });
        self.reader(topic, ty, q, Decode::Raw, raw)
    }
    /// A writer on `topic` (as [`Engine::writer`]) whose [`Writer::write_related`] works where
    /// the engine can write a related sample identity. By default [`Engine::writer`]'s.
    fn related_writer(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Box<dyn Writer>, GatewayError> {
        self.writer(topic, ty, q)
    }
    /// The remote endpoints discovered so far (our own participant's left out).
    fn remote(&self) -> Remote;
    /// Announces (again) the node with every endpoint created so far on `ros_discovery_info`.
    fn announce(&self) -> Result<(), GatewayError>;
}

/// Opens a participant of engine `kind`; an engine this build does not contain is refused.
pub fn open(kind: EngineKind, cfg: &EngineConfig) -> Result<Box<dyn Engine>, GatewayError> {
    match kind {
        EngineKind::Cyclone => Ok(Box::new(cyclone::Cyclone::open(cfg)?)),
        #[cfg(feature = "rustdds")]
        EngineKind::Rustdds => Ok(Box::new(rustdds::Rustdds::open(cfg)?)),
        #[cfg(not(feature = "rustdds"))]
        EngineKind::Rustdds => Err(GatewayError::EngineNotBuilt { engine: kind.name() }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_build_names_its_engines_and_refuses_the_others() {
        assert!(EngineKind::Cyclone.is_built());
        assert_eq!(EngineKind::Rustdds.is_built(), cfg!(feature = "rustdds"));
        assert_eq!("CycloneDDS".parse::<EngineKind>(), Ok(EngineKind::Cyclone));
        let e = "opendds".parse::<EngineKind>().unwrap_err();
        assert_eq!(e.to_string(), "unknown DDS engine 'opendds' (expected cyclone or rustdds)");
        if !EngineKind::Rustdds.is_built() {
            let e = open(EngineKind::Rustdds, &EngineConfig::default()).map(|_| ()).unwrap_err();
            assert!(e.is_invalid() && matches!(e, GatewayError::EngineNotBuilt { engine: "rustdds" }), "{e}");
        }
    }
}
