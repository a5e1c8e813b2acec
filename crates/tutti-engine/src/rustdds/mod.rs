//! The pure-Rust engine: ros2-client over rustdds.
//!
//! Every endpoint is created through ros2-client's `Node`, so that ros_discovery_info lists
//! it under the gateway's node (plain rustdds endpoints work on the wire but are not
//! attributed to any node). Topics are created with rustdds directly, because only the
//! topic can carry OWNERSHIP (ros2-client's `QosProfile` has none).
//!
//! Data path: a write hands the sample to rustdds' event-loop thread, which sends it; a
//! received sample is decoded through serde by a task on this engine's own tokio runtime
//! (one worker thread) and handed to the sink there. Known limits (docs/gateway.md): one
//! datagram and two thread hops per sample; no unicast peers (`--peer` is refused);
//! EXCLUSIVE ownership is not matched with Cyclone's readers; matching is read from the
//! discovery database, since rustdds 0.15 has no working matched-endpoint queries.
//!
//! Type hashes: every endpoint announces its type's ROS 2 hash as USER_DATA
//! (`typehash=RIHS01_…;`), ros2-client's own (`ros_discovery_info`, `/parameter_events`)
//! included: the participant is told the USER_DATA of each type before any endpoint of it
//! is made (`set_user_data_of_type`, a patch of the vendored rustdds:
//! vendor/rustdds/TUTTI-PATCHES.md).
//!
//! The services' endpoints ([`Engine::serve`]) are plain rustdds endpoints instead: ros2-client's
//! node endpoints neither hand over a sample's identity nor write a related sample identity, and
//! its `Node` adds no endpoint it did not make to its announcement, so these are not listed under
//! the node on `ros_discovery_info` (docs/ros2.md, "Wire forms"). They serve both wire forms,
//! chosen request by request (`crate::dds::rpc`).

use std::collections::HashMap;
use std::convert::Infallible;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use futures::{Stream, StreamExt};
use ros2_client::builtin_topics::{parameter_events, ros_discovery};
use ros2_client::dds::rustdds::{bytes::Bytes, no_key, RepresentationIdentifier};
use ros2_client::dds::rustdds::{policy, QosPolicies};
use ros2_client::dds::rustdds::{DomainParticipant, DomainParticipantBuilder, RTPSEntity, Topic, TopicKind};
use ros2_client::dds::rustdds::{SequenceNumber, Timestamp, WriteOptionsBuilder, GUID};
use ros2_client::dds::{Publisher, Subscription};
use ros2_client::{Context, Gid, MessageInfo, Node, NodeName, NodeOptions};
use serde::Serialize;
use tutti_core::ddf::Leaf;
use tutti_core::mapping::{Ownership, Qos, Reliability};

use crate::cdr::stock::{self, Stock};
use crate::cdr::{split_header, CdrError, Payload, PreEncoded, SetSeed};
use crate::cyclone::ros_remote;
use crate::dds::rpc::{self, Replies, ReplyWriter, SampleIdentity};
use crate::dds::{data_topic, endpoint, peer_of, reply_topic, request_topic};
use crate::{
    Data, Decode, EndpointId, EndpointQos, Engine, EngineConfig, EngineError, EngineKind, PeerId, Remote, RequestSink,
    Responder, Service, Sink, TopicType, Writer,
};

mod qos;
mod seed;

/// The participant, the node and the topics created so far.
pub struct Rustdds {
    participant: DomainParticipant,
    node: Mutex<Node>,
    own: PeerId,
    own_samples: Arc<AtomicU64>,
    /// The services' responses (a thread of its own), made on the first service.
    replies: Mutex<Option<Replies>>,
    topics: Mutex<HashMap<String, Topic>>,
    /// The publisher and subscriber of the plain rustdds endpoints, made on first use.
    plain: Mutex<Option<(ros2_client::dds::rustdds::Publisher, ros2_client::dds::rustdds::Subscriber)>>,
    rt: Option<tokio::runtime::Runtime>,
    // Last, so that the node goes before the context.
    _context: Context,
}

impl std::fmt::Debug for Rustdds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rustdds").field("own", &self.own).finish()
    }
}

fn guid(g: &Gid) -> [u8; 16] {
    let mut b = [0u8; 16];
    b.copy_from_slice(&g.as_bytes()[..16]);
    b
}

impl Rustdds {
    /// Joins DDS domain `cfg.domain_id` (restricted to `cfg.interfaces` when given) and
    /// announces the node `cfg.node_name`.
    pub fn open(cfg: &EngineConfig) -> Result<Rustdds, EngineError> {
        if !cfg.peers.is_empty() {
            return Err(EngineError::PeersUnsupported);
        }
        let ns = if cfg.node_namespace.is_empty() { "/" } else { cfg.node_namespace.as_str() };
        let node_name = NodeName::new(ns, &cfg.node_name)
            .map_err(|e| EngineError::NodeName { name: cfg.node_name.clone(), detail: format!("{e:?}") })?;
        let mut b = DomainParticipantBuilder::new(cfg.domain_id);
        if !cfg.interfaces.is_empty() {
            b = b.with_only_networks(cfg.interfaces.clone());
        }
        let participant =
            b.build().map_err(|e| EngineError::dds(format!("a participant in DDS domain {}", cfg.domain_id), e))?;
        // The endpoints ros2-client makes itself: the node's announcement and its parameter events.
        for ty in [ros_discovery::TYPE_NAME, parameter_events::TYPE_NAME] {
            announce_type_hash(&participant, &TopicType::stock(ty))?;
        }
        let context = Context::from_domain_participant(participant.clone())
            .map_err(|e| EngineError::dds("the ROS 2 context", e))?;
        let node = context
            .new_node(node_name, NodeOptions::new().enable_rosout(false))
            .map_err(|e| EngineError::dds(format!("the ROS 2 node '{}'", cfg.node_name), format!("{e:?}")))?;
        let own = peer_of(&guid(&Gid::from(participant.guid())));
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("tutti-rustdds")
            .enable_all()
            .build()
            .map_err(EngineError::Runtime)?;
        Ok(Rustdds {
            participant,
            node: Mutex::new(node),
            own,
            own_samples: Arc::new(AtomicU64::new(0)),
            replies: Mutex::new(None),
            topics: Mutex::new(HashMap::new()),
            plain: Mutex::new(None),
            rt: Some(rt),
            _context: context,
        })
    }

    /// Topic `name` of type `ty`, made once; the endpoints made on it after this call announce
    /// `ty`'s hash.
    fn topic(&self, name: &str, ty: &TopicType, q: &Qos) -> Result<Topic, EngineError> {
        announce_type_hash(&self.participant, ty)?;
        let mut topics = self.topics.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(t) = topics.get(name) {
            return Ok(t.clone());
        }
        let t = self
            .participant
            .create_topic(name.to_string(), ty.name.clone(), &qos::topic_qos(q), TopicKind::NoKey)
            .map_err(|e| EngineError::dds(format!("topic {name}"), e))?;
        topics.insert(name.to_string(), t.clone());
        Ok(t)
    }

    /// A node publisher on `topic` (type `ty`) with the writer QoS `q`.
    fn publisher<M: Serialize>(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Publisher<M>, EngineError> {
        let t = self.topic(topic, ty, q)?;
        self.node
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .create_publisher::<M>(&t, Some(qos::profile(q)))
            .map_err(|e| EngineError::dds(format!("a writer on {topic}"), e))
    }

    /// A node subscription on `topic` (type `ty`) with the reader QoS `q`.
    fn subscription<M: 'static>(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Subscription<M>, EngineError> {
        let t = self.topic(topic, ty, q)?;
        self.node
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .create_subscription::<M>(&t, Some(qos::profile(q)))
            .map_err(|e| EngineError::dds(format!("a reader on {topic}"), e))
    }

    /// A reader of per-item topic `topic`: each stock message is read through its interface's
    /// spec ([`seed::ValueSeed`]) and made the bytes of `leaf`.
    fn item_reader(
        &self,
        topic: &str,
        ty: &TopicType,
        q: &Qos,
        leaf: Arc<Leaf>,
        sink: Sink,
    ) -> Result<(), EngineError> {
        let sub: Subscription<tutti_ros2::Value> = self.subscription(topic, ty, q)?;
        let path: Arc<str> = Arc::from(leaf.path.as_str());
        let message = Stock::of(&leaf).message();
        let to_payload = move |v: tutti_ros2::Value| {
            stock::leaf_of(&leaf, &v).map(|bytes| Payload::Item { path: path.clone(), bytes })
        };
        let own = (self.own, self.own_samples.clone());
        if let Some(rt) = &self.rt {
            rt.spawn(async move { pump(sub.async_stream_seed(seed::ValueSeed(message)), to_payload, sink, own).await });
        }
        Ok(())
    }
}

impl Rustdds {
    /// The publisher and subscriber of the plain rustdds endpoints.
    fn plain(
        &self,
    ) -> Result<(ros2_client::dds::rustdds::Publisher, ros2_client::dds::rustdds::Subscriber), EngineError> {
        let mut plain = self.plain.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(p) = plain.as_ref() {
            return Ok(p.clone());
        }
        let q = ros2_client::dds::rustdds::QosPolicies::default();
        let p = self.participant.create_publisher(&q).map_err(|e| EngineError::dds("a DDS publisher", e))?;
        let s = self.participant.create_subscriber(&q).map_err(|e| EngineError::dds("a DDS subscriber", e))?;
        *plain = Some((p.clone(), s.clone()));
        Ok((p, s))
    }
}

/// A serialized sample as a plain rustdds reader hands it: its body and its byte order.
struct RawSample {
    le: bool,
    body: Vec<u8>,
}

/// Reads a sample's body as it is, in either byte order of plain CDR.
#[derive(Clone)]
struct RawAdapter;

impl no_key::DeserializerAdapter<RawSample> for RawAdapter {
    type Error = Infallible;
    type Decoded = RawSample;

    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &[RepresentationIdentifier::CDR_LE, RepresentationIdentifier::CDR_BE]
    }

    fn transform_decoded(decoded: RawSample) -> RawSample {
        decoded
    }
}

impl no_key::DefaultDecoder<RawSample> for RawAdapter {
    type Decoder = RawAdapter;
    const DECODER: RawAdapter = RawAdapter;
}

impl<'de> no_key::Decode<'de, RawSample> for RawAdapter {
    type Error = Infallible;

    fn decode_bytes(self, bytes: &'de [u8], encoding: RepresentationIdentifier) -> Result<RawSample, Infallible> {
        Ok(RawSample { le: encoding == RepresentationIdentifier::CDR_LE, body: bytes.to_vec() })
    }
}

/// Writes a little-endian body as it is.
#[derive(Debug)]
struct RawBody(Vec<u8>);

impl no_key::SerializerAdapter<RawBody> for RawAdapter {
    type Error = Infallible;

    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }

    fn to_bytes(value: &RawBody) -> Result<Bytes, Infallible> {
        Ok(Bytes::copy_from_slice(&value.0))
    }
}

/// A plain rustdds writer, which can write a related sample identity, and says which readers
/// are in step with it: they have answered one of its heartbeats, so a reply written now is
/// delivered to them (`readers_in_step`, vendor/rustdds/TUTTI-PATCHES.md, 4). A reader that
/// has only matched may not be: Cyclone DDS takes the first heartbeat it sees from a writer as
/// its starting point and skips every sample up to that heartbeat's last, so a reply written
/// before then and lost on the way (a full socket buffer under load) was never repaired, and
/// the client waited for ever.
struct RelatedWriter {
    writer: no_key::DataWriter<RawBody, RawAdapter>,
}

impl RelatedWriter {
    fn write_with(&mut self, body: &[u8], related: Option<SampleIdentity>) -> bool {
        let options = WriteOptionsBuilder::new().source_timestamp(Timestamp::now());
        let options = match related {
            Some(r) => options.related_sample_identity(ros2_client::dds::rustdds::SampleIdentity {
                writer_guid: GUID::from_bytes(r.writer),
                sequence_number: SequenceNumber::from(r.sequence),
            }),
            None => options,
        };
        match self.writer.write_with_options(RawBody(body.to_vec()), options.build()) {
            Ok(_) => true,
            Err(e) => {
                tracing::debug!("DDS write failed: {e:?}");
                false
            }
        }
    }
}

impl ReplyWriter for RelatedWriter {
    fn write(&mut self, body: &[u8]) -> bool {
        self.write_with(body, None)
    }

    fn write_related(&mut self, body: &[u8], related: SampleIdentity) -> bool {
        self.write_with(body, Some(related))
    }

    fn reaching_readers_of(&mut self, peer: PeerId) -> Option<usize> {
        Some(self.writer.readers_in_step().iter().filter(|g| peer_of(&g.to_bytes()) == peer).count())
    }
}

/// Tells `participant` the USER_DATA of the endpoints of type `ty` (none without a hash).
fn announce_type_hash(participant: &DomainParticipant, ty: &TopicType) -> Result<(), EngineError> {
    let user_data = ty.user_data().map(String::into_bytes).unwrap_or_default();
    participant
        .set_user_data_of_type(&ty.name, user_data)
        .map_err(|e| EngineError::dds(format!("the type hash of {}", ty.name), e))
}

impl Drop for Rustdds {
    fn drop(&mut self) {
        self.replies.lock().unwrap_or_else(PoisonError::into_inner).take();
        if let Some(rt) = self.rt.take() {
            rt.shutdown_background();
        }
    }
}

/// The task of one reader: every sample (or error) to the sink, decoded by `to_payload`.
/// Our own participant's samples are dropped and counted (rustdds hands a participant none of
/// them today; the check keeps echo suppression the engine's whatever it does).
async fn pump<M, E: std::fmt::Debug>(
    stream: impl Stream<Item = Result<(M, MessageInfo), E>>,
    mut to_payload: impl FnMut(M) -> Result<Payload, CdrError>,
    sink: Sink,
    (own, own_samples): (PeerId, Arc<AtomicU64>),
) {
    futures::pin_mut!(stream);
    while let Some(r) = stream.next().await {
        match r {
            Ok((m, info)) => {
                let writer = endpoint(guid(&info.publisher_gid()));
                if writer.peer == own {
                    own_samples.fetch_add(1, Ordering::Relaxed);
                } else {
                    sink(writer, Data::Decoded(to_payload(m)));
                }
            }
            Err(e) => sink(EndpointId::default(), Data::Decoded(Err(CdrError::Engine(format!("{e:?}"))))),
        }
    }
}

/// A writer of pre-encoded bodies: rustdds' serde publisher writes a tuple of bytes
/// verbatim.
struct RustddsWriter(Publisher<PreEncoded>);

impl Writer for RustddsWriter {
    /// rustdds writes its own little-endian encapsulation header: a big-endian sample is
    /// refused.
    fn write_serialized(&mut self, raw: &[u8]) -> bool {
        match split_header(raw) {
            Ok((true, body)) => self.write(body),
            _ => false,
        }
    }

    fn write(&mut self, body: &[u8]) -> bool {
        match self.0.publish(PreEncoded(body.to_vec())) {
            Ok(()) => true,
            Err(e) => {
                tracing::debug!("DDS write failed: {e:?}");
                false
            }
        }
    }
}

impl Rustdds {
    /// Every remote endpoint by its DDS topic (our own participant's left out).
    fn raw_remote(participant: &DomainParticipant, own: PeerId) -> Remote {
        let mut r = Remote::default();
        for w in participant.discovered_writers() {
            let id = endpoint(guid(&Gid::from(w.writer_proxy.remote_writer_guid)));
            if id.peer != own {
                r.writers.entry(w.publication_topic_data.topic_name.clone()).or_default().insert(id);
                r.qos.insert(id, endpoint_qos(&w.publication_topic_data.qos(), true));
            }
        }
        for rd in participant.discovered_readers() {
            let id = endpoint(guid(&Gid::from(rd.reader_proxy.remote_reader_guid)));
            if id.peer != own {
                r.readers.entry(rd.subscription_topic_data.topic_name().clone()).or_default().insert(id);
                r.qos.insert(id, endpoint_qos(&rd.subscription_topic_data.qos(), false));
            }
        }
        r
    }

    /// A plain reader on DDS topic `topic` whose samples go to `sink` with their identity and
    /// related sample identity, as a service's requests.
    fn request_reader(&self, topic: &str, ty: &TopicType, sink: RequestSink) -> Result<(), EngineError> {
        let q = rpc::qos();
        let t = self.topic(topic, ty, &q)?;
        let (_, subscriber) = self.plain()?;
        let reader = subscriber
            .create_simple_datareader_no_key::<RawSample, RawAdapter>(&t, Some(qos::profile(&q).into()))
            .map_err(|e| EngineError::dds(format!("a reader on {topic}"), e))?;
        let Some(rt) = &self.rt else { return Ok(()) };
        rt.spawn(async move {
            let stream = reader.as_async_stream();
            futures::pin_mut!(stream);
            while let Some(r) = stream.next().await {
                let dcc = match r {
                    Ok(dcc) => dcc,
                    Err(e) => {
                        tracing::debug!("a request lost: {e:?}");
                        continue;
                    }
                };
                let related = dcc.related_sample_identity().map(|r| SampleIdentity {
                    writer: r.writer_guid.to_bytes(),
                    sequence: i64::from(r.sequence_number),
                });
                let (writer, sequence) = (dcc.writer_guid.to_bytes(), i64::from(dcc.sequence_number));
                let sample = dcc.into_value();
                let header = if sample.le { [0, 1, 0, 0] } else { [0, 0, 0, 0] };
                let raw = [&header[..], &sample.body].concat();
                rpc::deliver(rpc::Incoming { writer, sequence: Some(sequence), related, raw: &raw }, &sink);
            }
        });
        Ok(())
    }

    /// A plain writer on DDS topic `topic`, which writes related sample identities.
    fn reply_writer(&self, topic: &str, ty: &TopicType) -> Result<RelatedWriter, EngineError> {
        let q = rpc::qos();
        let t = self.topic(topic, ty, &q)?;
        let (publisher, _) = self.plain()?;
        let writer = publisher
            .create_datawriter_no_key::<RawBody, RawAdapter>(&t, Some(qos::profile(&q).into()))
            .map_err(|e| EngineError::dds(format!("a writer on {topic}"), e))?;
        Ok(RelatedWriter { writer })
    }
}

impl Engine for Rustdds {
    fn kind(&self) -> EngineKind {
        EngineKind::Rustdds
    }

    fn location(&self) -> String {
        format!("DDS domain {}", self.participant.domain_id())
    }

    fn domain_id(&self) -> u16 {
        self.participant.domain_id()
    }

    fn own_peer(&self) -> PeerId {
        self.own
    }

    fn own_samples(&self) -> u64 {
        self.own_samples.load(Ordering::Relaxed)
    }

    fn arbitrates_ownership(&self) -> bool {
        false
    }

    fn writer(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Box<dyn Writer>, EngineError> {
        Ok(Box::new(RustddsWriter(self.publisher::<PreEncoded>(&data_topic(topic), ty, q)?)))
    }

    fn reader(&self, topic: &str, ty: &TopicType, q: &Qos, decode: Decode, sink: Sink) -> Result<(), EngineError> {
        let topic = &data_topic(topic);
        match decode {
            Decode::Set(codec) => {
                let sub = self.subscription(topic, ty, q)?;
                let own = (self.own, self.own_samples.clone());
                if let Some(rt) = &self.rt {
                    rt.spawn(async move {
                        pump(sub.async_stream_seed(SetSeed(codec)), |s| Ok(Payload::Set(s)), sink, own).await;
                    });
                }
            }
            Decode::Item(leaf, _) => self.item_reader(topic, ty, q, leaf, sink)?,
            Decode::Raw => {
                return Err(EngineError::dds(format!("a reader on {topic}"), "rustdds readers decode what they read"))
            }
        }
        Ok(())
    }

    fn serve(&self, service: &Service<'_>, requests: RequestSink) -> Result<Box<dyn Responder>, EngineError> {
        let (rq, rr) = (request_topic(service.name), reply_topic(service.name));
        let writer = self.reply_writer(&rr, service.response)?;
        let responder = {
            let mut replies = self.replies.lock().unwrap_or_else(PoisonError::into_inner);
            if replies.is_none() {
                let (participant, own) = (self.participant.clone(), self.own);
                *replies = Some(Replies::start(Arc::new(move || Rustdds::raw_remote(&participant, own)))?);
            }
            replies.as_ref().map(|r| r.responder(rq.clone(), rr, Box::new(writer)))
        };
        self.request_reader(&rq, service.request, requests)?;
        match responder {
            Some(r) => Ok(Box::new(r)),
            None => Err(EngineError::dds("the services' replies", "no reply thread")),
        }
    }

    fn remote(&self) -> Remote {
        ros_remote(Rustdds::raw_remote(&self.participant, self.own))
    }

    /// ros2-client announces the node and its endpoints as they are created.
    fn announce(&self) -> Result<(), EngineError> {
        Ok(())
    }
}

/// The terms of a discovered endpoint's QoS; those it did not announce have their DDS
/// defaults (RELIABLE for a writer, BEST_EFFORT for a reader, VOLATILE, SHARED).
fn endpoint_qos(q: &QosPolicies, writer: bool) -> EndpointQos {
    let reliability = match q.reliability() {
        Some(policy::Reliability::Reliable { .. }) => Reliability::Reliable,
        Some(policy::Reliability::BestEffort) => Reliability::BestEffort,
        None if writer => Reliability::Reliable,
        None => Reliability::BestEffort,
    };
    let transient_local = matches!(
        q.durability(),
        Some(policy::Durability::TransientLocal | policy::Durability::Transient | policy::Durability::Persistent)
    );
    let ownership = match q.ownership() {
        Some(policy::Ownership::Exclusive { strength }) => Ownership::Exclusive { strength },
        _ => Ownership::Shared,
    };
    EndpointQos { reliability, transient_local, ownership }
}
