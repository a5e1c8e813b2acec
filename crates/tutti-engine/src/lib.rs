//! tutti's engine layer: all the gateway needs from a middleware that carries ROS 2 topics
//! and services, and nothing more (docs/architecture.md, "The engine layer").
//!
//! Routes, the QoS table, exclusivity, stats and the mirror are written once above this
//! layer; an [`Engine`] only moves pre-encoded CDR bytes between ROS 2 topics and the
//! gateway, serves ROS 2 services, and tells who is on the other side. Everything it is
//! handed is in ROS 2's own terms, whatever the wire:
//!
//! * names are ROS 2 names (`/NS/DOMAIN/publish`, the service `/NS/step_simulation`); a DDS
//!   engine makes them `rt/…` topics and `rq/…Request` / `rr/…Reply` pairs, another engine
//!   makes them whatever its wire needs;
//! * QoS is tutti's own vocabulary ([`Qos`]: reliability, history, durability, exclusivity
//!   with its strength, lifespan), which each engine maps to its own;
//! * identity is the engine's: an endpoint is an [`EndpointId`], the ROS 2 global id (GID)
//!   the engine gives it and the [`PeerId`] it belongs to (a DDS participant's GUID prefix, a
//!   Zenoh session's id). An engine never hands its own participant's samples to a sink (echo
//!   suppression is the engine's: [`Engine::own_samples`] counts what it dropped);
//! * a service is an engine operation ([`Engine::serve`]): requests come with an opaque
//!   [`ReplyTo`], and the engine pairs the response with its request in its own wire form.
//!
//! Three engines implement it: [`cyclone`] (Cyclone DDS through `cyclors`, the default, always
//! built, with DDS Security: [`security`]), `rustdds` (ros2-client over rustdds; cargo feature
//! `rustdds`, on by default) and `zenoh` (cargo feature `zenoh`, on by default), which speaks
//! [`rmw_zenoh`]'s wire format (keys, liveliness tokens, QoS strings, attachments, GIDs).
//! [`EngineKind::built`] lists those of this build, and [`for_each_engine!`] expands one
//! item per built engine: the conformance suite (`tests/conformance.rs`), the command-line
//! tests and the tests' DDS domain-id bands all take their list from it.

#![deny(unsafe_op_in_unsafe_fn)]

use std::collections::{BTreeSet, HashMap};
use std::fmt;
use std::net::IpAddr;
use std::sync::Arc;
use std::time::Duration;

use tutti_core::ddf::Leaf;
pub use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};
use tutti_ros2::TypeHash;

use crate::cdr::{stock, CdrError, Payload, SetCodec};

pub mod cdr;
pub mod cyclone;
mod dds;
mod error;
pub mod keys;
pub mod rmw_zenoh;
#[cfg(feature = "rustdds")]
pub mod rustdds;
pub mod security;
#[cfg(feature = "zenoh")]
pub mod zenoh;

pub use error::{EngineError, UnknownEngine};

/// The participant (DDS: the 12-byte GUID prefix, zero-padded) or session (Zenoh: its id) an
/// endpoint belongs to: endpoints of one peer are one process's, one node's.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct PeerId(pub [u8; 16]);

impl fmt::Debug for PeerId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

/// One endpoint (a writer, a reader, a service's client) as its engine names it: its ROS 2
/// global id (rmw's GID: a DDS endpoint's GUID) and the peer it belongs to.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct EndpointId {
    pub gid: [u8; 16],
    pub peer: PeerId,
}

impl EndpointId {
    /// A short printable form (the GID in hex), for connection names and logs.
    pub fn short(&self) -> String {
        self.gid.iter().map(|b| format!("{b:02x}")).collect()
    }
}

impl fmt::Debug for EndpointId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.short())
    }
}

/// Calls `$callback! { $($args)* name: Kind, … }` with one `name: Kind` pair per engine of
/// this build, in [`EngineKind::built`]'s order (`cyclone: Cyclone`, then `rustdds: Rustdds`
/// where the `rustdds` feature is on, then `zenoh: Zenoh` where the `zenoh` feature is on).
/// The one list of engines that tests expand: a test suite run against every engine is
/// written once, and an engine added here is tested by all of them.
///
/// ```
/// macro_rules! names {
///     ($($name:ident: $kind:ident),* $(,)?) => { &[$(stringify!($name)),*] };
/// }
/// let built: &[&str] = tutti_engine::for_each_engine!(names);
/// assert_eq!(built[0], "cyclone");
/// assert_eq!(built.len(), tutti_engine::EngineKind::built().len());
/// ```
#[macro_export]
macro_rules! for_each_engine {
    ($callback:ident $(, $($args:tt)*)?) => {
        $crate::__engines_rustdds! { $callback [$($($args)*)?] [cyclone: Cyclone] [zenoh] }
    };
}

/// [`for_each_engine!`] for the engines that speak DDS only (Cyclone, and rustdds where
/// built): the tests whose peers are DDS participants.
#[macro_export]
macro_rules! for_each_dds_engine {
    ($callback:ident $(, $($args:tt)*)?) => {
        $crate::__engines_rustdds! { $callback [$($($args)*)?] [cyclone: Cyclone] [] }
    };
}

#[cfg(feature = "rustdds")]
#[doc(hidden)]
#[macro_export]
macro_rules! __engines_rustdds {
    ($cb:ident [$($args:tt)*] [$($list:tt)*] [$($z:ident)?]) => {
        $crate::__engines_zenoh! { $cb [$($args)*] [$($list)*, rustdds: Rustdds] [$($z)?] }
    };
}

#[cfg(not(feature = "rustdds"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __engines_rustdds {
    ($cb:ident [$($args:tt)*] [$($list:tt)*] [$($z:ident)?]) => {
        $crate::__engines_zenoh! { $cb [$($args)*] [$($list)*] [$($z)?] }
    };
}

#[cfg(feature = "zenoh")]
#[doc(hidden)]
#[macro_export]
macro_rules! __engines_zenoh {
    ($cb:ident [$($args:tt)*] [$($list:tt)*] [zenoh]) => { $cb! { $($args)* $($list)*, zenoh: Zenoh } };
    ($cb:ident [$($args:tt)*] [$($list:tt)*] []) => { $cb! { $($args)* $($list)* } };
}

#[cfg(not(feature = "zenoh"))]
#[doc(hidden)]
#[macro_export]
macro_rules! __engines_zenoh {
    ($cb:ident [$($args:tt)*] [$($list:tt)*] [$($z:ident)?]) => { $cb! { $($args)* $($list)* } };
}

/// The engines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum EngineKind {
    /// Cyclone DDS, through `cyclors`.
    #[default]
    Cyclone,
    /// rustdds and ros2-client (pure Rust).
    Rustdds,
    /// Zenoh, in rmw_zenoh's wire format.
    Zenoh,
}

impl EngineKind {
    pub const fn name(self) -> &'static str {
        match self {
            EngineKind::Cyclone => "cyclone",
            EngineKind::Rustdds => "rustdds",
            EngineKind::Zenoh => "zenoh",
        }
    }

    /// Every engine, built or not.
    pub const ALL: [EngineKind; 3] = [EngineKind::Cyclone, EngineKind::Rustdds, EngineKind::Zenoh];

    /// The engines this build contains (the order of [`for_each_engine!`]).
    pub fn built() -> &'static [EngineKind] {
        macro_rules! kinds {
            ($($name:ident: $kind:ident),* $(,)?) => { &[$(EngineKind::$kind),*] };
        }
        for_each_engine!(kinds)
    }

    /// Whether this build contains the engine.
    pub fn is_built(self) -> bool {
        EngineKind::built().contains(&self)
    }

    /// Its place in [`EngineKind::ALL`]: tests give each engine a band of DDS domain ids of
    /// its own by it, so that one test's runs on every engine go in parallel.
    pub const fn index(self) -> usize {
        match self {
            EngineKind::Cyclone => 0,
            EngineKind::Rustdds => 1,
            EngineKind::Zenoh => 2,
        }
    }

    /// What its wire is called where the gateway speaks of its readers and writers: "DDS" or
    /// "Zenoh".
    pub const fn network(self) -> &'static str {
        match self {
            EngineKind::Cyclone | EngineKind::Rustdds => "DDS",
            EngineKind::Zenoh => "Zenoh",
        }
    }

    /// Whether it speaks DDS (its wire carries `rt/` topics and a DDS domain id).
    pub fn is_dds(self) -> bool {
        matches!(self, EngineKind::Cyclone | EngineKind::Rustdds)
    }
}

impl std::str::FromStr for EngineKind {
    type Err = UnknownEngine;
    fn from_str(s: &str) -> Result<Self, UnknownEngine> {
        match s.trim().to_ascii_lowercase().as_str() {
            "cyclone" | "cyclonedds" => Ok(EngineKind::Cyclone),
            "rustdds" => Ok(EngineKind::Rustdds),
            "zenoh" | "rmw_zenoh" => Ok(EngineKind::Zenoh),
            other => Err(UnknownEngine { name: other.to_string() }),
        }
    }
}

impl fmt::Display for EngineKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The type of a topic's endpoints: its wire name and, for a ROS 2 type, the type hash every
/// endpoint of it announces (docs/gateway.md, "Type hashes"), as ROS 2 Jazzy's endpoints do.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicType {
    /// The type's name as ROS 2 puts it on the wire (`PKG::msg::dds_::TYPE_`).
    pub name: String,
    /// None: a type ROS 2 does not know, announced without a hash.
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

    /// What its DDS endpoints announce in their USER_DATA (`typehash=RIHS01_…;`), if anything.
    pub fn user_data(&self) -> Option<String> {
        self.hash.map(|h| h.user_data())
    }
}

/// How an engine joins its middleware.
#[derive(Debug, Clone, Default)]
pub struct EngineConfig {
    /// The ROS domain (`ROS_DOMAIN_ID`): the DDS domain id of a DDS engine.
    pub domain_id: u16,
    /// Addresses the engine may use; empty: the engine's default (Cyclone: `CYCLONEDDS_URI`).
    pub interfaces: Vec<IpAddr>,
    /// Unicast discovery peers (addresses or host names), for networks without multicast.
    pub peers: Vec<String>,
    /// The ROS 2 node the engine announces.
    pub node_name: String,
    /// Its namespace ("/" for none).
    pub node_namespace: String,
    /// The lease the participant announces: how long the others keep it, and its endpoints,
    /// once it has gone silent (killed: no goodbye). A reliable writer keeps every sample a
    /// killed gateway's reader never acknowledged until then, and may block on a full
    /// history. None: the engine's default. Cyclone only: rustdds 0.15 always announces 50 s
    /// (docs/gateway.md, "Departures").
    pub participant_lease: Option<Duration>,
    /// Zenoh: the endpoints to connect to (`tcp/HOST:PORT`); empty: the configuration's
    /// (`ZENOH_SESSION_CONFIG_URI`, else rmw_zenoh's router at `tcp/localhost:7447`).
    pub zenoh_connect: Vec<String>,
    /// Zenoh: the endpoints to listen on; empty: the configuration's.
    pub zenoh_listen: Vec<String>,
    /// DDS Security: the enclave whose identity and permissions the participant takes
    /// ([`security::SecuritySettings::resolve`]); None: unsecured. Cyclone only.
    pub security: Option<security::Enclave>,
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

/// Where a reader's samples go: called on the engine's receive path with the writer's id,
/// never with a sample of the engine's own participant. It must not block for long: on
/// Cyclone it runs on the receive thread.
pub type Sink = Arc<dyn Fn(EndpointId, Data<'_>) + Send + Sync>;

/// A writer of pre-encoded samples.
pub trait Writer: Send {
    /// Writes one sample whose CDR body (little-endian, no encapsulation header) is `body`;
    /// false when the engine refused it.
    fn write(&mut self, body: &[u8]) -> bool;
    /// Writes one serialized sample as it is, encapsulation header first (plain CDR in
    /// either byte order); false when the engine refused it, or when it writes only
    /// little-endian samples (rustdds).
    fn write_serialized(&mut self, raw: &[u8]) -> bool;
    /// Sends what batching held back (a no-op where writes are not batched).
    fn flush(&mut self) {}
    /// A flush that another thread may call while this writer writes (None: the engine does
    /// not batch): it bounds in time how long a batched sample waits.
    fn flusher(&self) -> Option<Flusher> {
        None
    }
}

/// A writer's flush, callable from any thread.
pub type Flusher = Arc<dyn Fn() + Send + Sync>;

/// A ROS 2 service an engine serves: its name and the types of its two messages.
#[derive(Debug, Clone, Copy)]
pub struct Service<'a> {
    /// Its ROS 2 name (`/NS/step_simulation`, `/NS/simulate_steps/_action/send_goal`).
    pub name: &'a str,
    /// `PKG::srv::dds_::NAME_Request_`, with its hash.
    pub request: &'a TopicType,
    /// `PKG::srv::dds_::NAME_Response_`, with its hash.
    pub response: &'a TopicType,
}

/// Whom a response goes to: the request it answers, in the form its client asked (opaque;
/// each engine fills it in and reads it back).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReplyTo(pub(crate) Route);

/// How a response finds its request, per engine family.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Route {
    Dds(dds::ReplyTo),
    /// The client's GID and the request's sequence number, as rmw_zenoh keys its queries.
    #[cfg_attr(not(feature = "zenoh"), allow(dead_code))]
    Zenoh {
        client: [u8; 16],
        sequence: i64,
    },
}

/// One request to a served service.
#[derive(Debug)]
pub struct Request<'a> {
    /// Who asked: the client's request writer (its peer is the client's node).
    pub client: EndpointId,
    /// The byte order of `body`.
    pub little_endian: bool,
    /// The CDR body of the request message (after the encapsulation header, and after any
    /// header of the engine's own: the message's first field is at 0).
    pub body: &'a [u8],
    /// What the response must carry to reach its client.
    pub reply_to: ReplyTo,
}

/// Where a service's requests go; as a [`Sink`], it must not block for long.
pub type RequestSink = Arc<dyn Fn(Request<'_>) + Send + Sync>;

/// The response side of a served service.
pub trait Responder: Send {
    /// Sends `body` (the little-endian CDR body of the response message, its first field at
    /// 0) as the response to the request `to`. The engine delivers it once its client can
    /// receive it: a DDS engine keeps it until the client's reply reader has matched (for as
    /// long as the client may still be waiting), so a response is never written to nobody.
    fn respond(&mut self, to: &ReplyTo, body: &[u8]);
}

/// Remote (not our peer's) endpoints per ROS 2 topic name, and the QoS each announced.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Remote {
    pub writers: HashMap<String, BTreeSet<EndpointId>>,
    pub readers: HashMap<String, BTreeSet<EndpointId>>,
    pub qos: HashMap<EndpointId, EndpointQos>,
}

/// The QoS a remote endpoint announced: the terms that decide matching and delivery (not
/// the history: it decides neither).
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
    pub fn writers_on<'a>(&'a self, topic: &str) -> impl Iterator<Item = EndpointId> + 'a {
        self.writers.get(topic).into_iter().flatten().copied()
    }

    /// Remote readers on any of `topics` (each once).
    pub fn readers_on(&self, topics: &[String]) -> BTreeSet<EndpointId> {
        topics.iter().filter_map(|t| self.readers.get(t)).flatten().copied().collect()
    }
}

/// One participant of a ROS 2 graph, as the gateway uses it.
pub trait Engine: Send + Sync {
    fn kind(&self) -> EngineKind;
    /// Where it is, for status lines (`DDS domain 5`).
    fn location(&self) -> String;
    /// The ROS domain it joined (`ROS_DOMAIN_ID`).
    fn domain_id(&self) -> u16;
    /// Our own peer: endpoints of it are ours (never listed by [`Engine::remote`], never
    /// handed to a sink).
    fn own_peer(&self) -> PeerId;
    /// How many samples of our own writers the engine received and dropped (echo
    /// suppression): an engine whose readers see their own participant's samples (Cyclone)
    /// counts them here.
    fn own_samples(&self) -> u64;
    /// How many samples, requests and announcements from the network the engine dropped as
    /// malformed before any sink saw them (Zenoh: no valid attachment, a token that is not
    /// rmw_zenoh's); a DDS engine's stack drops such input itself, unseen: 0.
    fn bad_input(&self) -> u64 {
        0
    }
    /// Whether the engine's EXCLUSIVE readers deliver only the strongest live writer's
    /// samples (Cyclone); rustdds' readers deliver every writer's, and only the core's
    /// first-writer rule applies above it.
    fn arbitrates_ownership(&self) -> bool;
    /// A writer on ROS 2 topic `topic` (of type `ty`, whose hash it announces) with QoS `q`.
    fn writer(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Box<dyn Writer>, EngineError>;
    /// A reader on ROS 2 topic `topic` (of type `ty`, whose hash it announces) with QoS `q`;
    /// its samples go to `sink` for as long as the engine lives. `decode` is used by
    /// engines that decode as they read.
    fn reader(&self, topic: &str, ty: &TopicType, q: &Qos, decode: Decode, sink: Sink) -> Result<(), EngineError>;
    /// Serves `service` with ROS 2's services QoS: its requests go to `requests` for as long
    /// as the engine lives, and their responses go through the returned [`Responder`].
    fn serve(&self, service: &Service<'_>, requests: RequestSink) -> Result<Box<dyn Responder>, EngineError>;
    /// The remote endpoints discovered so far (our own peer's left out), by ROS 2 topic name.
    fn remote(&self) -> Remote;
    /// Announces (again) the node with every endpoint created so far.
    fn announce(&self) -> Result<(), EngineError>;
}

/// Opens a participant of engine `kind`; an engine this build does not contain is refused.
pub fn open(kind: EngineKind, cfg: &EngineConfig) -> Result<Box<dyn Engine>, EngineError> {
    if cfg.security.is_some() && !security::engine_does_security(kind) {
        return Err(security::SecurityError::Unsupported { engine: kind.name() }.into());
    }
    match kind {
        EngineKind::Cyclone => Ok(Box::new(cyclone::Cyclone::open(cfg)?)),
        #[cfg(feature = "rustdds")]
        EngineKind::Rustdds => Ok(Box::new(rustdds::Rustdds::open(cfg)?)),
        #[cfg(not(feature = "rustdds"))]
        EngineKind::Rustdds => Err(EngineError::NotBuilt { engine: kind.name() }),
        #[cfg(feature = "zenoh")]
        EngineKind::Zenoh => Ok(Box::new(zenoh::Zenoh::open(cfg)?)),
        #[cfg(not(feature = "zenoh"))]
        EngineKind::Zenoh => Err(EngineError::NotBuilt { engine: kind.name() }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_build_names_its_engines_and_refuses_the_others() {
        assert!(EngineKind::Cyclone.is_built());
        assert_eq!(EngineKind::Rustdds.is_built(), cfg!(feature = "rustdds"));
        assert_eq!(EngineKind::Zenoh.is_built(), cfg!(feature = "zenoh"));
        assert_eq!("CycloneDDS".parse::<EngineKind>(), Ok(EngineKind::Cyclone));
        assert_eq!("zenoh".parse::<EngineKind>(), Ok(EngineKind::Zenoh));
        assert!(!EngineKind::Zenoh.is_dds() && EngineKind::Rustdds.is_dds());
        let e = "opendds".parse::<EngineKind>().unwrap_err();
        assert_eq!(e.to_string(), "unknown engine 'opendds' (expected cyclone, rustdds or zenoh)");
        for kind in [EngineKind::Rustdds, EngineKind::Zenoh] {
            if !kind.is_built() {
                let e = open(kind, &EngineConfig::default()).map(|_| ()).unwrap_err();
                assert!(
                    e.is_invalid() && matches!(e, EngineError::NotBuilt { engine } if engine == kind.name()),
                    "{e}"
                );
            }
        }
    }

    #[test]
    fn the_engine_list_is_one_and_in_order() {
        let built = EngineKind::built();
        assert_eq!(built[0], EngineKind::Cyclone);
        assert!(built.windows(2).all(|w| w[0].index() < w[1].index()));
        assert_eq!(EngineKind::ALL.iter().filter(|k| k.is_built()).count(), built.len());
    }
}
