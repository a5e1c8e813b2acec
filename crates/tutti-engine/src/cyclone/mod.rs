//! The Cyclone DDS engine, through `cyclors` (Cyclone DDS 11.0.1 built from its bundled source).
//!
//! Topics carry a "blob" sertype that knows the DDS type name only: samples go in and out as
//! pre-encoded CDR (`ddsi_serdata_from_ser_iov` + `dds_writecdr`, `dds_takecdr` +
//! `ddsi_serdata_to_ser_ref`), so matching is by type name (no XTypes type information on the
//! wire) and the CDR codec above this layer is the only one.
//!
//! * Writers batch (`dds_qset_writer_batching`, per writer, rather than the process-wide
//!   `dds_write_set_batch`): `writer`. Readers in the same process get a sample at once
//!   either way.
//! * Readers take up to 64 samples per `dds_takecdr` in a data-available listener, which
//!   Cyclone runs on its receive thread ("recv") for remote writers and on the writing thread
//!   itself for writers in the same process; Cyclone never runs the listener of one reader twice
//!   at once. Cyclone hands a reader the samples of its own participant's writers: the listener
//!   drops them and counts them (`reader`).
//! * Discovery: DCPSPublication / DCPSSubscription built-in readers (`discovery`).
//! * Services: a request reader and a reply writer per service, in rmw_cyclonedds's form only
//!   (Cyclone DDS reads and writes no sample identity: docs/ros2.md, "Wire forms"), paired by
//!   the DDS layer's `crate::dds::rpc`.
//! * Config (`config`): the participant's domain is created explicitly with
//!   `dds_create_domain`, whose configuration is `$CYCLONEDDS_URI` (when set: an explicit
//!   config replaces the environment, so it goes first) followed by a fragment without the
//!   `<CycloneDDS><Domain>` wrapper, which Cyclone accepts in XML strings: one receive thread
//!   per socket (unless the environment's config sets it), the interfaces and the peers.
//!   Checked against Cyclone 11.0.1's config trace: the fragment applies on top of the
//!   environment's config; list elements add up (`Peer`s of both are used), single values are
//!   overridden by the fragment (`MaxAutoParticipantIndex` 50). An interface that
//!   `CYCLONEDDS_URI` selects already makes Cyclone refuse the domain ("the same interface may
//!   not be selected twice"): then the domain is made again with the peers only, keeping the
//!   environment's interfaces (with a warning). The domain then also outlives the participant
//!   in Cyclone, so it is deleted after it.
//! * Type hashes: every reader and writer carries its type's ROS 2 hash as USER_DATA
//!   (`dds_qset_userdata`: `typehash=RIHS01_…;`, [`TopicType`]), as rmw_cyclonedds does, so that a
//!   ROS 2 Jazzy peer finds the hash it looks for in discovery.
//! * Lease: the participant announces [`EngineConfig::participant_lease`] as its automatic
//!   liveliness (participant QoS), so that the other participants drop a killed gateway's
//!   endpoints after it rather than after Cyclone's default 10 s.

use std::ptr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use cyclors::{
    dds_create_writer, dds_entity_t, dds_get_children, dds_get_entity_sertype, dds_write_flush, ddsi_sertype,
};
use tutti_core::cdr::HEADER_LE;
use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};
use tutti_ros2::{Struct, Value};

pub use self::config::security_xml;
use self::discovery::Discovery;
use self::native::{blob_topic, delete_entity, entity_error, entity_guid, lock, retcode, write_pieces, NativeQos};
use self::reader::{Deliver, ReaderCtx};
use self::writer::CycloneWriter;
use crate::dds::rpc::{self, Replies};
use crate::dds::{data_topic, peer_of, reply_topic, request_topic, ros_topic, PREFIX_LEN};
use crate::{
    Decode, Engine, EngineConfig, EngineError, EngineKind, PeerId, Remote, RequestSink, Responder, Service, Sink,
    TopicType, Writer,
};

mod config;
mod discovery;
mod native;
mod reader;
mod writer;

/// ROS 2's graph topic and its type.
const DISCOVERY_TOPIC: &str = "ros_discovery_info";
const DISCOVERY_TYPE: &str = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";
const DISCOVERY_MESSAGE: &str = "rmw_dds_common/msg/ParticipantEntitiesInfo";

/// The entities this engine created, for `ros_discovery_info`.
#[derive(Default)]
struct Endpoints {
    readers: Vec<[u8; 16]>,
    writers: Vec<[u8; 16]>,
}

/// What writers share with the engine: the participant lives until the engine and every
/// writer are gone.
struct Inner {
    participant: dds_entity_t,
    /// The domain we created with a config, deleted after the participant if nobody else uses it.
    domain: Option<dds_entity_t>,
    endpoints: Mutex<Endpoints>,
    /// The listeners' states, freed after the participant is deleted.
    contexts: Mutex<Vec<Arc<ReaderCtx>>>,
}

impl Drop for Inner {
    fn drop(&mut self) {
        // Deleting the participant deletes its readers, waiting for running listeners.
        delete_entity(self.participant);
        if let Some(d) = self.domain {
            // SAFETY: counting only (null buffer of size 0).
            let children = unsafe { dds_get_children(d, ptr::null_mut(), 0) };
            if children == 0 {
                delete_entity(d);
            }
        }
        lock(&self.contexts).clear();
    }
}

/// The `ros_discovery_info` writer, created on the first announce.
struct Announcer {
    writer: dds_entity_t,
    sertype: *const ddsi_sertype,
}

// SAFETY: `sertype` is only read by Cyclone (thread-safe) and stays valid as long as `writer`, which
// lives as long as the participant that `Cyclone` owns.
unsafe impl Send for Announcer {}

/// A Cyclone DDS participant.
pub struct Cyclone {
    inner: Arc<Inner>,
    domain_id: u16,
    guid: [u8; 16],
    node_name: String,
    node_namespace: String,
    discovery: Arc<Mutex<Discovery>>,
    announcer: Mutex<Option<Announcer>>,
    own_samples: Arc<AtomicU64>,
    /// The services' responses (a thread of its own), made on the first service.
    replies: Mutex<Option<Replies>>,
}

impl std::fmt::Debug for Cyclone {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cyclone")
            .field("domain_id", &self.domain_id)
            .field("participant", &self.inner.participant)
            .field("guid", &crate::dds::endpoint(self.guid))
            .finish()
    }
}

impl Cyclone {
    /// Joins `cfg.domain_id`: the participant, its discovery readers.
    pub fn open(cfg: &EngineConfig) -> Result<Cyclone, EngineError> {
        let domain = config::domain(cfg)?;
        let domain_id = u32::from(cfg.domain_id);
        let participant = config::create_participant(domain_id, cfg.participant_lease, cfg.security.as_ref())?;
        if participant < 0 {
            if let Some(d) = domain {
                delete_entity(d);
            }
            return Err(EngineError::dds(format!("a participant on domain {domain_id}"), retcode(participant)));
        }
        // From here on, dropping `inner` cleans up.
        let inner = Arc::new(Inner {
            participant,
            domain,
            endpoints: Mutex::new(Endpoints::default()),
            contexts: Mutex::new(Vec::new()),
        });
        let guid = entity_guid(participant).map_err(|r| EngineError::dds("the participant's GUID", retcode(r)))?;
        let discovery = Arc::new(Mutex::new(Discovery::new(participant)?));
        tracing::debug!("cyclone: participant {:?} on domain {domain_id}", crate::dds::endpoint(guid));
        Ok(Cyclone {
            inner,
            domain_id: cfg.domain_id,
            guid,
            node_name: cfg.node_name.clone(),
            node_namespace: if cfg.node_namespace.is_empty() { "/".into() } else { cfg.node_namespace.clone() },
            discovery,
            announcer: Mutex::new(None),
            own_samples: Arc::new(AtomicU64::new(0)),
            replies: Mutex::new(None),
        })
    }

    fn own_prefix(&self) -> [u8; PREFIX_LEN] {
        let mut p = [0u8; PREFIX_LEN];
        p.copy_from_slice(&self.guid[..PREFIX_LEN]);
        p
    }

    /// A writer and its topic on our participant, on DDS topic `topic`.
    fn create_writer(
        &self,
        topic: &str,
        ty: &TopicType,
        q: &Qos,
        batching: bool,
    ) -> Result<(dds_entity_t, dds_entity_t, *const ddsi_sertype), EngineError> {
        let t = blob_topic(self.inner.participant, topic, &ty.name)?;
        let qos = NativeQos::new(q, ty, batching).inspect_err(|_| delete_entity(t))?;
        // SAFETY: live participant and topic, a valid QoS, no listener.
        let w = unsafe { dds_create_writer(self.inner.participant, t, qos.0, ptr::null()) };
        if w < 0 {
            delete_entity(t);
            return Err(entity_error(format!("a writer on {topic}"), w));
        }
        let mut sertype: *const ddsi_sertype = ptr::null();
        // SAFETY: `sertype` is a valid out-parameter.
        let r = unsafe { dds_get_entity_sertype(w, &mut sertype) };
        if r < 0 || sertype.is_null() {
            delete_entity(w);
            delete_entity(t);
            return Err(EngineError::dds(format!("a writer on {topic}"), retcode(r)));
        }
        Ok((t, w, sertype))
    }

    /// A [`CycloneWriter`] on DDS topic `topic`, listed among our endpoints.
    fn dds_writer(&self, topic: &str, ty: &TopicType, q: &Qos, batching: bool) -> Result<CycloneWriter, EngineError> {
        let (t, w, sertype) = self.create_writer(topic, ty, q, batching)?;
        let guid = match entity_guid(w) {
            Ok(g) => g,
            Err(r) => {
                delete_entity(w);
                delete_entity(t);
                return Err(EngineError::dds(format!("a writer on {topic}"), retcode(r)));
            }
        };
        lock(&self.inner.endpoints).writers.push(guid);
        Ok(CycloneWriter { inner: self.inner.clone(), topic: t, writer: w, sertype, guid })
    }

    /// A writer on the DDS topic `topic` itself (not a ROS 2 topic's `rt/` one): for tools and
    /// tests that speak DDS below ROS 2 (a service's `rq/` and `rr/` topics).
    pub fn raw_writer(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Box<dyn Writer>, EngineError> {
        Ok(Box::new(self.dds_writer(topic, ty, q, true)?))
    }

    /// A reader on the DDS topic `topic` itself (`ros_discovery_info`, a service's `rq/` and
    /// `rr/` topics), whose samples go to `sink` raw.
    pub fn raw_reader(&self, topic: &str, ty: &TopicType, q: &Qos, sink: Sink) -> Result<(), EngineError> {
        let own = (self.own_peer(), self.own_samples.clone());
        reader::create(&self.inner, topic, ty, q, Deliver::Data(sink), own)
    }

    /// What the services' replies consult: discovery by DDS topic.
    fn raw_discovery(&self) -> rpc::Discovery {
        let (discovery, own) = (self.discovery.clone(), self.own_prefix());
        Arc::new(move || lock(&discovery).remote(&own))
    }
}

impl Engine for Cyclone {
    fn kind(&self) -> EngineKind {
        EngineKind::Cyclone
    }

    fn location(&self) -> String {
        format!("DDS domain {}", self.domain_id)
    }

    fn domain_id(&self) -> u16 {
        self.domain_id
    }

    fn own_peer(&self) -> PeerId {
        peer_of(&self.guid)
    }

    fn own_samples(&self) -> u64 {
        self.own_samples.load(Ordering::Relaxed)
    }

    fn arbitrates_ownership(&self) -> bool {
        true
    }

    fn writer(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Box<dyn Writer>, EngineError> {
        Ok(Box::new(self.dds_writer(&data_topic(topic), ty, q, true)?))
    }

    fn reader(&self, topic: &str, ty: &TopicType, q: &Qos, _decode: Decode, sink: Sink) -> Result<(), EngineError> {
        let own = (self.own_peer(), self.own_samples.clone());
        reader::create(&self.inner, &data_topic(topic), ty, q, Deliver::Data(sink), own)
    }

    fn serve(&self, service: &Service<'_>, requests: RequestSink) -> Result<Box<dyn Responder>, EngineError> {
        let (rq, rr) = (request_topic(service.name), reply_topic(service.name));
        let writer = self.dds_writer(&rr, service.response, &rpc::qos(), false)?;
        let responder = {
            let mut replies = lock(&self.replies);
            if replies.is_none() {
                *replies = Some(Replies::start(self.raw_discovery())?);
            }
            replies.as_ref().map(|r| r.responder(rq.clone(), rr, Box::new(writer)))
        };
        let own = (self.own_peer(), self.own_samples.clone());
        reader::create(&self.inner, &rq, service.request, &rpc::qos(), Deliver::Requests(requests), own)?;
        match responder {
            Some(r) => Ok(Box::new(r)),
            None => Err(EngineError::dds("the services' replies", "no reply thread")),
        }
    }

    fn remote(&self) -> Remote {
        let raw = lock(&self.discovery).remote(&self.own_prefix());
        ros_remote(raw)
    }

    fn announce(&self) -> Result<(), EngineError> {
        let mut body = Vec::new();
        {
            let eps = lock(&self.inner.endpoints);
            encode_participant_info(
                &mut body,
                &self.guid,
                &self.node_namespace,
                &self.node_name,
                &eps.readers,
                &eps.writers,
            );
        }
        let mut announcer = lock(&self.announcer);
        let a = match announcer.as_mut() {
            Some(a) => a,
            None => {
                let q = Qos {
                    reliability: Reliability::Reliable,
                    history: History::KeepLast(1),
                    durability: Durability::TransientLocal { depth: 1 },
                    ownership: Ownership::Shared,
                    lifespan: None,
                };
                let (_, writer, sertype) =
                    self.create_writer(DISCOVERY_TOPIC, &TopicType::stock(DISCOVERY_TYPE), &q, false)?;
                announcer.insert(Announcer { writer, sertype })
            }
        };
        // SAFETY: the sertype of `a.writer`, alive as long as our participant.
        if !unsafe { write_pieces(a.writer, a.sertype, &[&HEADER_LE, &body]) } {
            return Err(EngineError::dds("a ros_discovery_info sample", "write refused"));
        }
        // SAFETY: any handle is accepted.
        unsafe { dds_write_flush(a.writer) };
        Ok(())
    }
}

impl Drop for Cyclone {
    fn drop(&mut self) {
        // The reply thread first: it consults discovery, which goes with the participant.
        lock(&self.replies).take();
    }
}

/// Discovery by DDS topic as the engine layer shows it: data topics by their ROS 2 names,
/// the other DDS topics (services, `ros_discovery_info`) left out.
pub(crate) fn ros_remote(raw: Remote) -> Remote {
    let mut remote = Remote { qos: raw.qos, ..Remote::default() };
    for (topic, ids) in raw.writers {
        if let Some(t) = ros_topic(&topic) {
            remote.writers.insert(t, ids);
        }
    }
    for (topic, ids) in raw.readers {
        if let Some(t) = ros_topic(&topic) {
            remote.readers.insert(t, ids);
        }
    }
    remote
}

/// `rmw_dds_common/msg/ParticipantEntitiesInfo` with one node, as plain little-endian CDR
/// (no encapsulation header), encoded by its interface's codec.
fn encode_participant_info(
    out: &mut Vec<u8>,
    participant: &[u8; 16],
    namespace: &str,
    name: &str,
    readers: &[[u8; 16]],
    writers: &[[u8; 16]],
) {
    let gid =
        |g: &[u8; 16]| Value::from(Struct::new().with("data", g.iter().map(|b| Value::from(*b)).collect::<Vec<_>>()));
    let gids = |gs: &[[u8; 16]]| gs.iter().map(gid).collect::<Vec<_>>();
    let node = Struct::new()
        .with("node_namespace", namespace)
        .with("node_name", name)
        .with("reader_gid_seq", gids(readers))
        .with("writer_gid_seq", gids(writers));
    let info = Struct::new().with("gid", gid(participant)).with("node_entities_info_seq", vec![Value::from(node)]);
    out.clear();
    let Some(m) = tutti_ros2::registry().message(DISCOVERY_MESSAGE) else { return };
    if let Err(e) = m.encode_into(&info.into(), out) {
        // A name longer than the message's bound (256) is the only way here.
        tracing::warn!("cyclone: the node's announcement: {e}");
        out.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn participant_info_layout() {
        let mut out = Vec::new();
        let g = |b: u8| [b; 16];
        encode_participant_info(&mut out, &g(1), "/", "ab", &[g(2)], &[g(3), g(4)]);
        let mut want = vec![1u8; 16];
        want.extend_from_slice(&1u32.to_le_bytes());
        want.extend_from_slice(&2u32.to_le_bytes());
        want.extend_from_slice(b"/\0\0\0");
        want.extend_from_slice(&3u32.to_le_bytes());
        want.extend_from_slice(b"ab\0\0");
        want.extend_from_slice(&1u32.to_le_bytes());
        want.extend_from_slice(&[2u8; 16]);
        want.extend_from_slice(&2u32.to_le_bytes());
        want.extend_from_slice(&[3u8; 16]);
        want.extend_from_slice(&[4u8; 16]);
        assert_eq!(out, want);
    }
}
