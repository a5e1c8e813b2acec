//! The Zenoh engine: ROS 2 topics and services in rmw_zenoh's wire format
//! ([`crate::rmw_zenoh`]), over the `zenoh` crate (docs/gateway.md, "Zenoh").
//!
//! One Zenoh session is one ROS 2 node, as an rmw_zenoh node is:
//!
//! * the node and each of its publishers, subscriptions and services hold a liveliness token
//!   (`@ros2_lv/…`, [`Entity`]) for as long as the engine lives; an entity's GID is the
//!   XXH3-128 of its token's key, as rmw_zenoh derives it;
//! * a writer is zenoh-ext's advanced publisher on the topic's data key, with rmw_zenoh's
//!   options for its QoS ([`zenoh_options::publisher_options`]); each sample is the CDR
//!   encapsulation header and body, with the 33-byte attachment (sequence number, source
//!   timestamp, GID);
//! * a reader is an advanced subscriber taking samples of other sessions only (so the engine's
//!   own samples never reach it, and [`Engine::own_samples`] stays 0); a sample without a
//!   valid attachment is dropped, counted and logged once;
//! * a service is a complete queryable; each query waits, keyed by its client's GID and
//!   sequence number as rmw_zenoh keys them, until its response is written
//!   (`rmw_zenoh_cpp/src/detail/rmw_service_data.cpp:321-363`, `383-454`);
//! * discovery is the liveliness tokens of the domain (`@ros2_lv/<domain>/**`, with their
//!   history): [`Engine::remote`] lists other sessions' publishers and subscriptions, with the
//!   QoS their tokens carry. A token that cannot be read is counted and logged once.
//!
//! Zenoh has no ownership: every writer's samples reach a reader ([`Engine::arbitrates_ownership`]
//! is false) and remote endpoints are all SHARED.

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use ::zenoh::bytes::ZBytes;
use ::zenoh::liveliness::LivelinessToken;
use ::zenoh::qos::{CongestionControl as ZCongestion, Reliability as ZReliability};
use ::zenoh::query::{Query, Queryable};
use ::zenoh::sample::{Locality, Sample, SampleKind};
use ::zenoh::{Config, Session, Wait};
use zenoh_ext::{
    AdvancedPublisher, AdvancedPublisherBuilderExt, AdvancedSubscriber, AdvancedSubscriberBuilderExt, CacheConfig,
    HistoryConfig, MissDetectionConfig, RecoveryConfig,
};

use crate::cdr::HEADER_LE;
use crate::rmw_zenoh::qos::{self as rq, QosProfile, RmwDuration};
use crate::rmw_zenoh::zenoh_options::{self, CongestionControl, ZenohReliability};
use crate::rmw_zenoh::{gid_of_key, liveliness, Attachment, DataKey, Entity, EntityKind, NodeInfo, TopicInfo, ZenohId};
use crate::{
    Data, Decode, EndpointId, EndpointQos, Engine, EngineConfig, EngineError, EngineKind, Ownership, PeerId, Qos,
    Reliability, Remote, ReplyTo, Request, RequestSink, Responder, Route, Service, Sink, TopicType, Writer,
};

mod config;

pub use config::{session_config, CONFIG_ENV, DEFAULT_CONNECT, OVERRIDE_ENV};

/// The type hash a token and a key carry for a type ROS 2 does not know: all zeros, as
/// rosidl writes an unset hash.
const NO_TYPE_HASH: &str = "RIHS01_0000000000000000000000000000000000000000000000000000000000000000";

/// How many queries may wait for their responses at once; beyond it the oldest is answered
/// with nothing (its client times out, as it would with a server gone).
const MAX_PENDING: usize = 4096;

/// A session of the engine.
pub struct Zenoh {
    session: Session,
    domain_id: u16,
    zid: ZenohId,
    node: NodeInfo,
    /// rmw_zenoh's counter of node and entity ids (the node takes 0).
    next_id: AtomicU64,
    kept: Mutex<Kept>,
    graph: Arc<Graph>,
    pending: Arc<Pending>,
    bad: Arc<BadInput>,
}

/// What lives as long as the engine: tokens, subscribers, queryables.
#[derive(Default)]
struct Kept {
    tokens: Vec<LivelinessToken>,
    subscribers: Vec<AdvancedSubscriber<()>>,
    queryables: Vec<Queryable<()>>,
    graph_subscriber: Option<::zenoh::pubsub::Subscriber<()>>,
}

/// The other sessions' entities, by token key, and their peers by GID (looked up for every
/// sample received).
struct Graph {
    own: ZenohId,
    entities: Mutex<Entities>,
}

#[derive(Default)]
struct Entities {
    by_key: HashMap<String, (Entity, EndpointId)>,
    peers: HashMap<[u8; 16], PeerId>,
}

/// A query's key: its client's GID and its sequence number.
type QueryKey = ([u8; 16], i64);

/// Queries waiting for their responses, by [`QueryKey`], and the order they came in.
#[derive(Default)]
struct Pending {
    queries: Mutex<(HashMap<QueryKey, Query>, VecDeque<QueryKey>)>,
}

/// Bad input from the network: counted, each kind logged once.
#[derive(Default)]
struct BadInput {
    attachments: AtomicU64,
    tokens: AtomicU64,
}

impl BadInput {
    fn attachment(&self, key: &str, why: &dyn std::fmt::Display) {
        if self.attachments.fetch_add(1, Ordering::Relaxed) == 0 {
            tracing::warn!("zenoh: a sample or query on {key} without a valid attachment dropped ({why}); later ones are counted only");
        }
    }

    fn token(&self, key: &str, why: &dyn std::fmt::Display) {
        if self.tokens.fetch_add(1, Ordering::Relaxed) == 0 {
            tracing::warn!(
                "zenoh: a liveliness token that is not rmw_zenoh's ignored: {key}: {why}; later ones are counted only"
            );
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn zerr(what: impl Into<String>, detail: impl std::fmt::Display) -> EngineError {
    EngineError::Zenoh { what: what.into(), detail: detail.to_string() }
}

/// The peer of a session: its id, little-endian, as Zenoh keeps it.
fn peer_of(zid: ZenohId) -> PeerId {
    PeerId(zid.to_le_bytes())
}

/// ROS 2's rule for a node name (rmw's `rmw_validate_node_name`): letters, digits and
/// underscores, not starting with a digit.
fn check_node_name(name: &str) -> Result<(), &'static str> {
    if name.is_empty() {
        return Err("it is empty");
    }
    if !name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
        return Err("only letters, digits and underscores");
    }
    if name.starts_with(|c: char| c.is_ascii_digit()) {
        return Err("it starts with a digit");
    }
    Ok(())
}

/// Nanoseconds since the Unix epoch (rmw_zenoh's `get_system_time_in_ns`).
fn now_ns() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// A tutti QoS as an rmw profile, adapted as rmw_zenoh adapts it.
pub fn profile(q: &Qos) -> QosProfile {
    let (history, depth) = match q.history {
        crate::History::KeepAll => (rq::History::KeepAll, 0),
        crate::History::KeepLast(n) => (rq::History::KeepLast, u64::from(n)),
    };
    let lifespan = q
        .lifespan
        .map_or(RmwDuration::INFINITE, |d| RmwDuration { sec: d.as_secs(), nsec: u64::from(d.subsec_nanos()) });
    let p = QosProfile {
        reliability: match q.reliability {
            Reliability::Reliable => rq::Reliability::Reliable,
            Reliability::BestEffort => rq::Reliability::BestEffort,
        },
        durability: match q.durability {
            crate::Durability::Volatile => rq::Durability::Volatile,
            crate::Durability::TransientLocal { .. } => rq::Durability::TransientLocal,
        },
        history,
        depth,
        lifespan,
        ..QosProfile::ZENOH_DEFAULT
    };
    // Every policy here is a known one: adapting only fills in defaults.
    p.adapted().unwrap_or(p)
}

/// The QoS a token announced, in the engine layer's terms (no ownership on Zenoh).
fn endpoint_qos(p: &QosProfile) -> EndpointQos {
    EndpointQos {
        reliability: if p.reliability == rq::Reliability::BestEffort {
            Reliability::BestEffort
        } else {
            Reliability::Reliable
        },
        transient_local: p.durability == rq::Durability::TransientLocal,
        ownership: Ownership::Shared,
    }
}

impl std::fmt::Debug for Zenoh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Zenoh").field("zid", &self.zid).field("node", &self.node).finish_non_exhaustive()
    }
}

impl Zenoh {
    /// Opens a session as `cfg` says (docs/gateway.md, "Zenoh": the router at
    /// [`DEFAULT_CONNECT`] unless told otherwise) and declares the node's token.
    pub fn open(cfg: &EngineConfig) -> Result<Zenoh, EngineError> {
        check_node_name(&cfg.node_name)
            .map_err(|detail| EngineError::NodeName { name: cfg.node_name.clone(), detail: detail.into() })?;
        if !cfg.peers.is_empty() {
            return Err(EngineError::ZenohPeers);
        }
        let config: Config = session_config(cfg)?;
        let session = ::zenoh::open(config).wait().map_err(|e| zerr("a session", e))?;
        let zid: ZenohId = session.zid().to_string().parse().map_err(|e| zerr("the session's id", e))?;
        let namespace = if cfg.node_namespace.is_empty() { "/".to_string() } else { cfg.node_namespace.clone() };
        let node = NodeInfo {
            domain_id: u64::from(cfg.domain_id),
            namespace,
            name: cfg.node_name.clone(),
            enclave: "/".into(),
        };
        let graph = Arc::new(Graph { own: zid, entities: Mutex::new(Entities::default()) });
        let engine = Zenoh {
            session,
            domain_id: cfg.domain_id,
            zid,
            node,
            next_id: AtomicU64::new(0),
            kept: Mutex::new(Kept::default()),
            graph,
            pending: Arc::new(Pending::default()),
            bad: Arc::new(BadInput::default()),
        };
        engine.watch_graph()?;
        engine.declare(EntityKind::Node)?;
        if engine.session.info().routers_zid().wait().next().is_none() {
            tracing::warn!(
                "zenoh: no Zenoh router reached yet (rmw_zenoh's nodes meet at one: start rmw_zenohd, or give \
                 --zenoh-connect); the session keeps trying"
            );
        }
        Ok(engine)
    }

    /// Follows the domain's liveliness tokens, those declared before included.
    fn watch_graph(&self) -> Result<(), EngineError> {
        let (graph, bad) = (self.graph.clone(), self.bad.clone());
        let key = liveliness::subscription_key(u64::from(self.domain_id));
        let sub = self
            .session
            .liveliness()
            .declare_subscriber(&key)
            .history(true)
            .callback(move |s: Sample| graph.update(&s, &bad))
            .wait()
            .map_err(|e| zerr(format!("the liveliness subscriber on {key}"), e))?;
        lock(&self.kept).graph_subscriber = Some(sub);
        Ok(())
    }

    /// Declares the token of a new entity of the node: the entity and its id.
    fn declare(&self, kind: EntityKind) -> Result<(Entity, EndpointId), EngineError> {
        let node_id = 0;
        let entity_id = match kind {
            EntityKind::Node => node_id,
            _ => self.next_id.fetch_add(1, Ordering::Relaxed) + 1,
        };
        let entity = Entity { zid: self.zid, node_id, entity_id, node: self.node.clone(), kind };
        let key = entity.to_key().map_err(|e| zerr("a liveliness token", e))?;
        let token = self
            .session
            .liveliness()
            .declare_token(&key)
            .wait()
            .map_err(|e| zerr(format!("the liveliness token {key}"), e))?;
        lock(&self.kept).tokens.push(token);
        let id = EndpointId { gid: gid_of_key(&key), peer: peer_of(self.zid) };
        Ok((entity, id))
    }

    /// The topic of an entity on ROS 2 topic `name` of type `ty` with `q`.
    fn topic(&self, name: &str, ty: &TopicType, q: QosProfile) -> TopicInfo {
        TopicInfo {
            name: name.to_string(),
            type_name: ty.name.clone(),
            type_hash: ty.hash.map_or_else(|| NO_TYPE_HASH.to_string(), |h| h.to_string()),
            qos: q,
        }
    }

    fn data_key(&self, topic: &TopicInfo) -> Result<String, EngineError> {
        DataKey::for_topic(u64::from(self.domain_id), topic)
            .to_keyexpr()
            .map_err(|e| zerr(format!("the key of {}", topic.name), e))
    }

    /// How many samples and queries (first) and tokens (second) from the network were dropped
    /// as malformed.
    pub fn bad_input_by_kind(&self) -> (u64, u64) {
        (self.bad.attachments.load(Ordering::Relaxed), self.bad.tokens.load(Ordering::Relaxed))
    }
}

impl Graph {
    fn update(&self, s: &Sample, bad: &BadInput) {
        let key = s.key_expr().as_str();
        match s.kind() {
            SampleKind::Put => match Entity::parse(key) {
                Ok(e) if e.zid == self.own => {}
                Ok(e) => {
                    let id = EndpointId { gid: gid_of_key(key), peer: peer_of(e.zid) };
                    let mut entities = lock(&self.entities);
                    entities.peers.insert(id.gid, id.peer);
                    entities.by_key.insert(key.to_string(), (e, id));
                }
                Err(why) => bad.token(key, &why),
            },
            SampleKind::Delete => {
                let mut entities = lock(&self.entities);
                if let Some((_, id)) = entities.by_key.remove(key) {
                    entities.peers.remove(&id.gid);
                }
            }
        }
    }

    /// The peer of the entity whose GID is `gid` (a zero peer for one not known yet).
    fn peer_of_gid(&self, gid: &[u8; 16]) -> PeerId {
        lock(&self.entities).peers.get(gid).copied().unwrap_or_default()
    }
}

/// Why a sample or query has no attachment rmw_zenoh would read.
#[derive(Debug, thiserror::Error)]
enum BadAttachment {
    #[error("no attachment")]
    Missing,
    #[error(transparent)]
    Malformed(#[from] crate::rmw_zenoh::AttachmentError),
}

/// The attachment of a sample or query.
fn attachment_of(a: Option<&ZBytes>) -> Result<Attachment, BadAttachment> {
    let a = a.ok_or(BadAttachment::Missing)?;
    Ok(Attachment::decode_prefix(&a.to_bytes()).map(|(a, _)| a)?)
}

/// Samples a writer holds at most before it puts them without waiting for a flush.
const BATCH: usize = 64;

/// A writer: an advanced publisher and its attachment's state. As the Cyclone engine's
/// writers batch, it holds what it writes until [`Writer::flush`] (or until [`BATCH`] wait,
/// or it is dropped), then puts the samples one after the other, each with its attachment
/// made when it was written: Zenoh packs the puts of a burst into one message on the link,
/// where a put at a time would wake Zenoh's transmission task and cost a send each
/// (docs/benchmarks.md, "The Zenoh engine beside Zenoh's own ping-pong"). The gateway flushes
/// whenever nothing more is waiting.
struct ZenohWriter {
    out: Arc<Held>,
    gid: [u8; 16],
    sequence: i64,
}

/// A writer's publisher and the samples it holds (payload, attachment), in order; the lock
/// is held while they are put, so that a flush from another thread keeps that order.
struct Held {
    publisher: AdvancedPublisher<'static>,
    samples: Mutex<Vec<(Vec<u8>, [u8; crate::rmw_zenoh::attachment::ENCODED_LEN])>>,
}

impl Held {
    /// Puts what is held; false when Zenoh refused one (its session is closed).
    fn flush(&self) -> bool {
        let mut held = lock(&self.samples);
        let mut ok = true;
        for (payload, attachment) in held.drain(..) {
            ok &= self.publisher.put(payload).attachment(attachment.to_vec()).wait().is_ok();
        }
        ok
    }
}

impl ZenohWriter {
    fn hold(&mut self, payload: Vec<u8>) -> bool {
        let attachment =
            Attachment { sequence_number: self.sequence, source_timestamp: now_ns(), source_gid: self.gid };
        self.sequence += 1;
        let full = {
            let mut held = lock(&self.out.samples);
            held.push((payload, attachment.encode()));
            held.len() >= BATCH
        };
        !full || self.out.flush()
    }
}

impl Writer for ZenohWriter {
    fn write(&mut self, body: &[u8]) -> bool {
        let mut payload = Vec::with_capacity(HEADER_LE.len() + body.len());
        payload.extend_from_slice(&HEADER_LE);
        payload.extend_from_slice(body);
        self.hold(payload)
    }

    fn write_serialized(&mut self, raw: &[u8]) -> bool {
        self.hold(raw.to_vec())
    }

    fn flush(&mut self) {
        if !self.out.flush() {
            tracing::debug!("zenoh: a held sample was refused (the session is closed)");
        }
    }

    fn flusher(&self) -> Option<crate::Flusher> {
        let out = self.out.clone();
        Some(Arc::new(move || {
            out.flush();
        }))
    }
}

impl Drop for ZenohWriter {
    fn drop(&mut self) {
        self.out.flush();
    }
}

/// Responses to the queries of one service.
struct ZenohResponder {
    key: String,
    pending: Arc<Pending>,
}

impl Responder for ZenohResponder {
    fn respond(&mut self, to: &ReplyTo, body: &[u8]) {
        let Route::Zenoh { client, sequence } = to.0 else {
            return tracing::warn!("zenoh: a response addressed as DDS addresses it dropped");
        };
        let Some(query) = self.pending.take(client, sequence) else {
            return tracing::debug!("zenoh: no query waits for response {sequence} of {client:02x?}");
        };
        let attachment = Attachment { sequence_number: sequence, source_timestamp: now_ns(), source_gid: client };
        let payload = [&HEADER_LE[..], body].concat();
        if let Err(e) = query.reply(&self.key, payload).attachment(attachment.encode().to_vec()).wait() {
            tracing::warn!("zenoh: a response on {}: {e}", self.key);
        }
    }
}

impl Pending {
    fn put(&self, client: [u8; 16], sequence: i64, query: Query) {
        let mut q = lock(&self.queries);
        let (map, order) = &mut *q;
        if map.insert((client, sequence), query).is_none() {
            order.push_back((client, sequence));
        }
        while map.len() > MAX_PENDING {
            match order.pop_front() {
                Some(k) => {
                    map.remove(&k);
                }
                None => break,
            }
        }
    }

    fn take(&self, client: [u8; 16], sequence: i64) -> Option<Query> {
        let mut q = lock(&self.queries);
        let (map, order) = &mut *q;
        let query = map.remove(&(client, sequence))?;
        order.retain(|k| *k != (client, sequence));
        Some(query)
    }
}

impl Engine for Zenoh {
    fn kind(&self) -> EngineKind {
        EngineKind::Zenoh
    }

    fn location(&self) -> String {
        format!("Zenoh, ROS domain {}", self.domain_id)
    }

    fn domain_id(&self) -> u16 {
        self.domain_id
    }

    fn own_peer(&self) -> PeerId {
        peer_of(self.zid)
    }

    fn own_samples(&self) -> u64 {
        0
    }

    fn arbitrates_ownership(&self) -> bool {
        false
    }

    fn bad_input(&self) -> u64 {
        let (samples, tokens) = self.bad_input_by_kind();
        samples + tokens
    }

    fn writer(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Box<dyn Writer>, EngineError> {
        let p = profile(q);
        let info = self.topic(topic, ty, p);
        let key = self.data_key(&info)?;
        let o = zenoh_options::publisher_options(&p);
        let mut b = self
            .session
            .declare_publisher(key.clone())
            .congestion_control(match o.congestion_control {
                CongestionControl::Block => ZCongestion::Block,
                CongestionControl::Drop => ZCongestion::Drop,
            })
            .reliability(match o.reliability {
                ZenohReliability::Reliable => ZReliability::Reliable,
                ZenohReliability::BestEffort => ZReliability::BestEffort,
            })
            .advanced();
        if let Some(cache) = o.cache {
            let depth = usize::try_from(cache.max_samples).unwrap_or(usize::MAX);
            b = b.cache(CacheConfig::default().max_samples(depth)).publisher_detection();
            if let Some(ms) = cache.miss_detection_heartbeat_ms {
                b = b.sample_miss_detection(
                    MissDetectionConfig::default().sporadic_heartbeat(Duration::from_millis(ms)),
                );
            }
        }
        // The token first: a reader's session learns of the writer (its GID's peer) before
        // its first sample, which comes after it on the same link.
        let (_, id) = self.declare(EntityKind::Publisher(info))?;
        let publisher = b.wait().map_err(|e| zerr(format!("a publisher on {key}"), e))?;
        let out = Arc::new(Held { publisher, samples: Mutex::new(Vec::with_capacity(BATCH)) });
        Ok(Box::new(ZenohWriter { out, gid: id.gid, sequence: 1 }))
    }

    fn reader(&self, topic: &str, ty: &TopicType, q: &Qos, decode: Decode, sink: Sink) -> Result<(), EngineError> {
        let _ = decode; // samples are handed over serialized (Data::Raw)
        let p = profile(q);
        let info = self.topic(topic, ty, p);
        let key = self.data_key(&info)?;
        let o = zenoh_options::subscriber_options(&p, true);
        let (graph, bad, what) = (self.graph.clone(), self.bad.clone(), key.clone());
        let callback = move |s: Sample| {
            let a = match attachment_of(s.attachment()) {
                Ok(a) => a,
                Err(why) => return bad.attachment(&what, &why),
            };
            let from = EndpointId { gid: a.source_gid, peer: graph.peer_of_gid(&a.source_gid) };
            sink(from, Data::Raw(&s.payload().to_bytes()));
        };
        let mut b = self
            .session
            .declare_subscriber(key.clone())
            .callback(callback)
            .allowed_origin(if o.remote_only { Locality::Remote } else { Locality::Any })
            .advanced();
        if let Some(h) = o.history {
            let depth = usize::try_from(h.max_samples).unwrap_or(usize::MAX);
            b = b
                .subscriber_detection()
                .query_timeout(Duration::from_millis(h.query_timeout_ms))
                .history(HistoryConfig::default().detect_late_publishers().max_samples(depth));
            if h.recovery_by_heartbeat {
                b = b.recovery(RecoveryConfig::default().heartbeat());
            }
        }
        let sub = b.wait().map_err(|e| zerr(format!("a subscriber on {key}"), e))?;
        self.declare(EntityKind::Subscription(info))?;
        lock(&self.kept).subscribers.push(sub);
        Ok(())
    }

    fn serve(&self, service: &Service<'_>, requests: RequestSink) -> Result<Box<dyn Responder>, EngineError> {
        let name = crate::rmw_zenoh::type_names::service_of_request(&service.request.name);
        let ty = TopicType { hash: service_hash(&name), name };
        let q = Qos {
            reliability: Reliability::Reliable,
            history: crate::History::KeepLast(10),
            durability: crate::Durability::Volatile,
            ownership: Ownership::Shared,
            lifespan: None,
        };
        let info = self.topic(service.name, &ty, profile(&q));
        let key = self.data_key(&info)?;
        let (graph, bad, pending, what) = (self.graph.clone(), self.bad.clone(), self.pending.clone(), key.clone());
        let callback = move |query: Query| {
            let a = match attachment_of(query.attachment()) {
                Ok(a) => a,
                Err(why) => return bad.attachment(&what, &why),
            };
            let raw = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
            let Ok((little_endian, body)) = crate::cdr::split_header(&raw) else {
                return bad.attachment(&what, &"a request that is not plain CDR");
            };
            let client = EndpointId { gid: a.source_gid, peer: graph.peer_of_gid(&a.source_gid) };
            let reply_to = ReplyTo(Route::Zenoh { client: a.source_gid, sequence: a.sequence_number });
            let body = body.to_vec();
            pending.put(a.source_gid, a.sequence_number, query);
            requests(Request { client, little_endian, body: &body, reply_to });
        };
        let queryable = self
            .session
            .declare_queryable(key.clone())
            .complete(zenoh_options::QUERYABLE_COMPLETE)
            .callback(callback)
            .wait()
            .map_err(|e| zerr(format!("a queryable on {key}"), e))?;
        self.declare(EntityKind::Service(info))?;
        lock(&self.kept).queryables.push(queryable);
        Ok(Box::new(ZenohResponder { key, pending: self.pending.clone() }))
    }

    fn remote(&self) -> Remote {
        let mut r = Remote::default();
        for (e, id) in lock(&self.graph.entities).by_key.values() {
            let (list, topic) = match &e.kind {
                EntityKind::Publisher(t) => (&mut r.writers, t),
                EntityKind::Subscription(t) => (&mut r.readers, t),
                _ => continue,
            };
            list.entry(topic.name.clone()).or_default().insert(*id);
            r.qos.insert(*id, endpoint_qos(&topic.qos));
        }
        r
    }

    fn announce(&self) -> Result<(), EngineError> {
        // The tokens announce each entity as it is made.
        Ok(())
    }
}

/// The hash of a service type (`pkg::srv::dds_::Name_`), where ROS 2's interfaces that tutti
/// carries know it (the simulation interfaces, their actions' services).
fn service_hash(service_type: &str) -> Option<tutti_ros2::TypeHash> {
    tutti_ros2::registry().hash(&crate::rmw_zenoh::type_names::ros_type_name(service_type))
}
