//! The Cyclone DDS engine, through `cyclors` (Cyclone DDS 11.0.1 built from its bundled source).
//!
//! Topics carry a "blob" sertype that knows the DDS type name only: samples go in and out as
//! pre-encoded CDR (`ddsi_serdata_from_ser_iov` + `dds_writecdr`, `dds_takecdr` +
//! `ddsi_serdata_to_ser_ref`), so matching is by type name (no XTypes type information on the
//! wire) and the CDR codec above this layer is the only one.
//!
//! * Writers batch (`dds_qset_writer_batching`, per writer, rather than the process-wide
//!   `dds_write_set_batch`): a write stays in the writer's packing buffer until
//!   [`Writer::flush`] (`dds_write_flush`) or until the buffer fills (an unflushed write may
//!   never leave; docs/benchmarks.md has the cost of batching). Every writer of the gateway
//!   flushes when nothing more is waiting (and on drop). Readers in the same process get a sample
//!   at once either way. A writer deletes its DDS writer when dropped and keeps the participant
//!   alive until then.
//! * Readers take up to 64 (`TAKE_BATCH`) samples per `dds_takecdr` in a data-available listener,
//!   which Cyclone runs on its receive thread ("recv") for remote writers and on the writing
//!   thread itself for writers in the same process. Cyclone never runs the listener of one reader
//!   twice at once. Samples of our own writers are NOT filtered here (echo suppression lives above
//!   the engine).
//! * Discovery: DCPSPublication / DCPSSubscription built-in readers, drained into incremental
//!   maps whenever [`Engine::remote`] is called.
//! * Config: the participant's domain is created explicitly with `dds_create_domain`, whose
//!   configuration is `$CYCLONEDDS_URI` (when set: an explicit config replaces the environment,
//!   so it goes first) followed by a fragment without the `<CycloneDDS><Domain>` wrapper, which
//!   Cyclone accepts in XML strings: one receive thread per socket (`RECEIVE_THREADS`, unless
//!   the environment's config sets it), the interfaces and the peers. Checked against Cyclone
//!   11.0.1's config trace: the fragment applies on top of the environment's config; list elements
//!   add up (`Peer`s of both are used), single values are overridden by the fragment
//!   (`MaxAutoParticipantIndex` 50). An interface that `CYCLONEDDS_URI` selects already makes
//!   Cyclone refuse the domain ("the same interface may not be selected twice"): then the domain is
//!   made again with the peers only, keeping the environment's interfaces (with a warning).
//!   The domain then also outlives the participant in Cyclone, so it is deleted after it.
//! * Type hashes: every reader and writer carries its type's ROS 2 hash as USER_DATA
//!   (`dds_qset_userdata`: `typehash=RIHS01_…;`, [`TopicType`]), as rmw_cyclonedds does, so that a
//!   ROS 2 Jazzy peer finds the hash it looks for in discovery.
//! * Lease: the participant announces [`EngineConfig::participant_lease`] as its automatic
//!   liveliness (participant QoS), so that the other participants drop a killed gateway's
//!   endpoints after it rather than after Cyclone's default 10 s.

use std::collections::HashMap;
use std::ffi::{c_char, c_void, CStr, CString};
use std::mem::MaybeUninit;
use std::net::IpAddr;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use cyclors::{
    cdds_create_blob_topic, dds_builtintopic_endpoint_t, dds_builtintopic_free_endpoint, dds_create_domain,
    dds_create_listener, dds_create_participant, dds_create_qos, dds_create_reader, dds_create_writer, dds_delete,
    dds_delete_listener, dds_delete_qos, dds_durability_kind_DDS_DURABILITY_TRANSIENT_LOCAL,
    dds_durability_kind_DDS_DURABILITY_VOLATILE, dds_entity_t, dds_get_children, dds_get_entity_sertype, dds_get_guid,
    dds_get_matched_publication_data, dds_guid_t, dds_history_kind_DDS_HISTORY_KEEP_ALL,
    dds_history_kind_DDS_HISTORY_KEEP_LAST, dds_instance_handle_t, dds_instance_state_DDS_IST_ALIVE,
    dds_liveliness_kind_DDS_LIVELINESS_AUTOMATIC, dds_lset_data_available, dds_ownership_kind_DDS_OWNERSHIP_EXCLUSIVE,
    dds_ownership_kind_DDS_OWNERSHIP_SHARED, dds_qget_durability, dds_qget_ownership, dds_qget_ownership_strength,
    dds_qget_reliability, dds_qos_t, dds_qset_durability, dds_qset_durability_service, dds_qset_history,
    dds_qset_liveliness, dds_qset_ownership, dds_qset_ownership_strength, dds_qset_reliability, dds_qset_userdata,
    dds_qset_writer_batching, dds_reliability_kind_DDS_RELIABILITY_BEST_EFFORT,
    dds_reliability_kind_DDS_RELIABILITY_RELIABLE, dds_return_loan, dds_return_t, dds_sample_info_t, dds_strretcode,
    dds_take, dds_takecdr, dds_write_flush, dds_writecdr, ddsi_serdata, ddsi_serdata_from_ser_iov,
    ddsi_serdata_kind_SDK_DATA, ddsi_serdata_size, ddsi_serdata_to_ser_ref, ddsi_serdata_to_ser_unref,
    ddsi_serdata_unref, ddsi_sertype, ddsrt_iovec_t, DDS_ANY_STATE, DDS_BUILTIN_TOPIC_DCPSPUBLICATION,
    DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, DDS_RETCODE_OUT_OF_RESOURCES, DDS_RETCODE_PRECONDITION_NOT_MET,
};
use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};

use super::{
    Data, Decode, EndpointQos, Engine, EngineConfig, EngineKind, Guid, Remote, Sink, TopicType, Writer, PREFIX_LEN,
};
use crate::cdr::HEADER_LE;
use crate::GatewayError;

/// Samples taken per `dds_takecdr` in a reader's listener.
const TAKE_BATCH: usize = 64;
/// Samples taken per `dds_take` on a built-in topic.
const BUILTIN_BATCH: usize = 32;
/// How long a reliable write may block on a full history (ns).
const MAX_BLOCKING_NS: i64 = 100_000_000;
/// ROS 2's graph topic and its type.
const DISCOVERY_TOPIC: &str = "ros_discovery_info";
const DISCOVERY_TYPE: &str = "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_";

/// Cyclone's text for a return code.
fn retcode(ret: dds_return_t) -> String {
    // SAFETY: dds_strretcode accepts any value and returns a pointer to a static NUL-terminated string.
    let s = unsafe { dds_strretcode(ret) };
    if s.is_null() {
        return format!("return code {ret}");
    }
    // SAFETY: non-null and static (above).
    unsafe { CStr::from_ptr(s) }.to_string_lossy().into_owned()
}

fn c_string(what: &'static str, s: &str) -> Result<CString, GatewayError> {
    CString::new(s).map_err(|_| GatewayError::NulByte { what, value: s.escape_debug().to_string() })
}

/// Escapes a value for an XML attribute in double quotes.
fn xml_attr(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// The configuration for `dds_create_domain`, or None when there is nothing to add to
/// `CYCLONEDDS_URI` (`env`): its value first, then the fragment for `interfaces` and `cfg.peers`.
fn domain_config(cfg: &EngineConfig, interfaces: &[IpAddr], env: Option<&str>) -> Option<String> {
    let threads = !env.is_some_and(sets_receive_threads);
    if interfaces.is_empty() && cfg.peers.is_empty() && !threads {
        return None;
    }
    let mut fragment = String::new();
    if threads {
        fragment.push_str(RECEIVE_THREADS);
    }
    if !interfaces.is_empty() {
        fragment.push_str("<General><Interfaces>");
        for ip in interfaces {
            fragment.push_str(&format!("<NetworkInterface address=\"{}\"/>", xml_attr(&ip.to_string())));
        }
        fragment.push_str("</Interfaces></General>");
    }
    // Loopback has no multicast: a participant restricted to it finds the others on this
    // machine by unicast, at the well-known ports of their participant indices.
    let loopback = ["127.0.0.1".to_string()];
    let peers = if cfg.peers.is_empty() && !interfaces.is_empty() && interfaces.iter().all(IpAddr::is_loopback) {
        &loopback[..]
    } else {
        &cfg.peers[..]
    };
    if !peers.is_empty() {
        fragment.push_str("<Discovery><Peers>");
        for p in peers {
            fragment.push_str(&format!("<Peer address=\"{}\"/>", xml_attr(p)));
        }
        fragment.push_str(
            "</Peers><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>50</MaxAutoParticipantIndex>\
             </Discovery>",
        );
    }
    Some(match env {
        Some(e) => format!("{e},{fragment}"),
        None => fragment,
    })
}

/// One receive thread per socket, blocking in `recvmsg` (Cyclone 0.10's default, and what
/// `ddsperf` from Debian's cyclonedds-tools runs with), rather than Cyclone 11's one thread
/// multiplexing every socket with `epoll_wait` + `recvmsg`: one system call less per packet,
/// 0.6-0.8 µs of a one-core round trip (docs/benchmarks.md, "Where a one-core round trip
/// goes"). Cyclone wakes such threads at shutdown with a datagram to their own socket, which
/// a host firewall must let through; `CYCLONEDDS_URI` may set `MultipleReceiveThreads` itself.
const RECEIVE_THREADS: &str = "<Internal><MultipleReceiveThreads>true</MultipleReceiveThreads></Internal>";

/// Whether `CYCLONEDDS_URI` (inline XML and `file://` entries, comma-separated) sets
/// `MultipleReceiveThreads` itself: then it stands.
fn sets_receive_threads(env: &str) -> bool {
    env.split(',').any(|part| {
        let part = part.trim();
        match part.strip_prefix("file://") {
            Some(path) => std::fs::read_to_string(path).is_ok_and(|t| t.contains("MultipleReceiveThreads")),
            None => part.contains("MultipleReceiveThreads"),
        }
    })
}

/// A participant on domain `id` announcing `lease` (None: Cyclone's, `Discovery/LeaseDuration`,
/// 10 s by default): its handle or Cyclone's return code. The lease is the participant's
/// automatic liveliness, which Cyclone renews every 4/5 of it.
fn create_participant(id: u32, lease: Option<Duration>) -> dds_entity_t {
    let Some(lease) = lease else {
        // SAFETY: default QoS, no listener.
        return unsafe { dds_create_participant(id, ptr::null(), ptr::null()) };
    };
    // SAFETY: plain allocation; null on failure.
    let qos = unsafe { dds_create_qos() };
    if qos.is_null() {
        return DDS_RETCODE_OUT_OF_RESOURCES;
    }
    let qos = NativeQos(qos);
    let ns = i64::try_from(lease.as_nanos()).unwrap_or(i64::MAX);
    // SAFETY: `qos.0` is a valid QoS object; the setter stores the value, the participant
    // copies the QoS during the call; no listener.
    unsafe {
        dds_qset_liveliness(qos.0, dds_liveliness_kind_DDS_LIVELINESS_AUTOMATIC, ns);
        dds_create_participant(id, qos.0, ptr::null())
    }
}

/// Creates domain `id` with configuration `conf`: the handle or Cyclone's return code.
fn create_domain(id: u32, conf: &str) -> Result<dds_entity_t, GatewayError> {
    let cconf = c_string("Cyclone configuration", conf)?;
    // SAFETY: a NUL-terminated string that Cyclone parses during the call.
    Ok(unsafe { dds_create_domain(id, cconf.as_ptr()) })
}

/// A `dds_qos_t`, deleted on drop.
struct NativeQos(*mut dds_qos_t);

impl NativeQos {
    /// The QoS `q` of an endpoint of type `ty` (whose hash goes into its USER_DATA).
    fn new(q: &Qos, ty: &TopicType, batching: bool) -> Result<NativeQos, GatewayError> {
        // SAFETY: plain allocation; null on failure.
        let p = unsafe { dds_create_qos() };
        if p.is_null() {
            return Err(GatewayError::dds("a QoS", "out of memory"));
        }
        let qos = NativeQos(p);
        let depth = |n: u32| i32::try_from(n.max(1)).unwrap_or(i32::MAX);
        // SAFETY: `p` is a valid QoS object owned by `qos`; the setters only store values in it.
        unsafe {
            match q.reliability {
                Reliability::Reliable => {
                    dds_qset_reliability(p, dds_reliability_kind_DDS_RELIABILITY_RELIABLE, MAX_BLOCKING_NS)
                }
                Reliability::BestEffort => {
                    dds_qset_reliability(p, dds_reliability_kind_DDS_RELIABILITY_BEST_EFFORT, MAX_BLOCKING_NS)
                }
            }
            match q.history {
                History::KeepAll => dds_qset_history(p, dds_history_kind_DDS_HISTORY_KEEP_ALL, 0),
                History::KeepLast(n) => dds_qset_history(p, dds_history_kind_DDS_HISTORY_KEEP_LAST, depth(n)),
            }
            match q.durability {
                Durability::Volatile => dds_qset_durability(p, dds_durability_kind_DDS_DURABILITY_VOLATILE),
                Durability::TransientLocal { depth: d } => {
                    dds_qset_durability(p, dds_durability_kind_DDS_DURABILITY_TRANSIENT_LOCAL);
                    // What a late joiner gets: Cyclone keeps the writer's last `d` samples for it.
                    dds_qset_durability_service(p, 0, dds_history_kind_DDS_HISTORY_KEEP_LAST, depth(d), -1, -1, -1);
                }
            }
            match q.ownership {
                Ownership::Shared => dds_qset_ownership(p, dds_ownership_kind_DDS_OWNERSHIP_SHARED),
                Ownership::Exclusive { strength } => {
                    dds_qset_ownership(p, dds_ownership_kind_DDS_OWNERSHIP_EXCLUSIVE);
                    dds_qset_ownership_strength(p, strength);
                }
            }
            if batching {
                dds_qset_writer_batching(p, true);
            }
            if let Some(user_data) = ty.user_data() {
                // Cyclone copies the bytes.
                dds_qset_userdata(p, user_data.as_ptr().cast(), user_data.len());
            }
        }
        Ok(qos)
    }
}

impl Drop for NativeQos {
    fn drop(&mut self) {
        // SAFETY: created by dds_create_qos and deleted once, here.
        unsafe { dds_delete_qos(self.0) };
    }
}

/// The GUID of an entity.
fn entity_guid(e: dds_entity_t) -> Result<Guid, dds_return_t> {
    let mut g = dds_guid_t { v: [0; 16] };
    // SAFETY: `g` is a valid out-parameter.
    let r = unsafe { dds_get_guid(e, &mut g) };
    if r < 0 {
        Err(r)
    } else {
        Ok(Guid(g.v))
    }
}

fn delete_entity(e: dds_entity_t) {
    // SAFETY: deleting a handle is safe for any value: a stale or wrong one only returns an error.
    let r = unsafe { dds_delete(e) };
    if r < 0 {
        tracing::debug!("cyclone: deleting entity {e}: {}", retcode(r));
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Writes `pieces` (the encapsulation header first) as one serialized sample: one copy, into
/// the serdata. False when DDS refused it.
///
/// # Safety
/// `sertype` must be the sertype of `writer`'s topic, and `writer` must not have been deleted.
unsafe fn write_pieces(writer: dds_entity_t, sertype: *const ddsi_sertype, pieces: &[&[u8]]) -> bool {
    let mut iov = [ddsrt_iovec_t { iov_base: ptr::null_mut(), iov_len: 0 }; 2];
    debug_assert!(pieces.len() <= iov.len());
    let mut size = 0;
    for (v, p) in iov.iter_mut().zip(pieces) {
        // The blob sertype only reads from the iov (memcpy into its own buffer).
        *v = ddsrt_iovec_t { iov_base: p.as_ptr() as *mut c_void, iov_len: p.len() };
        size += p.len();
    }
    let n = pieces.len().min(iov.len());
    // SAFETY: `sertype` is live (caller), the iov entries point at `size` readable bytes in total.
    let sd = unsafe { ddsi_serdata_from_ser_iov(sertype, ddsi_serdata_kind_SDK_DATA, n, iov.as_ptr(), size) };
    if sd.is_null() {
        return false;
    }
    // SAFETY: `sd` is a fresh serdata of the writer's sertype; dds_writecdr consumes its reference once the
    // writer is locked, which cannot fail for a live writer (caller).
    let r = unsafe { dds_writecdr(writer, sd) };
    if r < 0 {
        tracing::debug!("cyclone: write on {writer}: {}", retcode(r));
    }
    r >= 0
}

/// A topic with the blob sertype, or the error of Cyclone.
fn blob_topic(participant: dds_entity_t, topic: &str, type_name: &str) -> Result<dds_entity_t, GatewayError> {
    let ctopic = c_string("topic name", topic)?;
    let ctype = c_string("type name", type_name)?;
    // SAFETY: both strings are NUL-terminated and outlive the call; the C side only reads them (it
    // duplicates the type name and copies the topic name). Keyless: ROS 2 types have no keys.
    let t = unsafe {
        cdds_create_blob_topic(participant, ctopic.as_ptr() as *mut c_char, ctype.as_ptr() as *mut c_char, true)
    };
    if t < 0 {
        return Err(GatewayError::dds(format!("topic {topic} ({type_name})"), retcode(t)));
    }
    Ok(t)
}

/// Per reader: the sink and the writers' GUIDs seen so far, by publication handle.
struct ReaderCtx {
    sink: Sink,
    writers: Mutex<HashMap<dds_instance_handle_t, Guid>>,
}

impl ReaderCtx {
    /// The GUID of the writer with publication handle `h`, looked up on its first sample.
    fn writer_guid(
        writers: &mut HashMap<dds_instance_handle_t, Guid>,
        reader: dds_entity_t,
        h: dds_instance_handle_t,
    ) -> Guid {
        if let Some(g) = writers.get(&h) {
            return *g;
        }
        // SAFETY: `reader` is the reader this listener belongs to; the result is null or a
        // malloc'ed endpoint that we free below.
        let ep = unsafe { dds_get_matched_publication_data(reader, h) };
        if ep.is_null() {
            // Gone already (or not matched any more): don't cache.
            return Guid::default();
        }
        // SAFETY: non-null, filled by Cyclone.
        let g = Guid(unsafe { (*ep).key.v });
        // SAFETY: returned by dds_get_matched_publication_data, freed once.
        unsafe { dds_builtintopic_free_endpoint(ep) };
        if writers.len() >= 4096 {
            writers.clear();
        }
        writers.insert(h, g);
        g
    }

    /// Takes everything the reader holds and hands each valid sample to the sink.
    fn drain(&self, reader: dds_entity_t) {
        let mut samples: [*mut ddsi_serdata; TAKE_BATCH] = [ptr::null_mut(); TAKE_BATCH];
        let mut infos: [MaybeUninit<dds_sample_info_t>; TAKE_BATCH] = [MaybeUninit::uninit(); TAKE_BATCH];
        let mut writers = lock(&self.writers);
        loop {
            // SAFETY: both buffers hold TAKE_BATCH entries; Cyclone fills the first n of each.
            let n = unsafe {
                dds_takecdr(reader, samples.as_mut_ptr(), TAKE_BATCH as u32, infos.as_mut_ptr().cast(), DDS_ANY_STATE)
            };
            if n <= 0 {
                break;
            }
            let n = n as usize;
            for (sd, info) in samples[..n].iter().zip(&infos[..n]) {
                // SAFETY: the first n infos were written by dds_takecdr.
                let info = unsafe { info.assume_init_ref() };
                if info.valid_data {
                    let guid = Self::writer_guid(&mut writers, reader, info.publication_handle);
                    self.deliver(*sd, guid);
                }
                // SAFETY: dds_takecdr handed us one reference to each sample.
                unsafe { ddsi_serdata_unref(*sd) };
            }
            if n < TAKE_BATCH {
                break;
            }
        }
    }

    /// One sample to the sink: its serialized form, encapsulation header included, borrowed.
    fn deliver(&self, sd: *mut ddsi_serdata, guid: Guid) {
        let mut iov = ddsrt_iovec_t { iov_base: ptr::null_mut(), iov_len: 0 };
        // SAFETY: `sd` is a live serdata (we hold a reference).
        let size = unsafe { ddsi_serdata_size(sd) } as usize;
        // SAFETY: as above; `iov` receives a pointer into the serdata, valid until the unref below.
        let r = unsafe { ddsi_serdata_to_ser_ref(sd, 0, size, &mut iov) };
        let bytes: &[u8] = if iov.iov_base.is_null() || iov.iov_len == 0 {
            &[]
        } else {
            // SAFETY: Cyclone's reference covers iov_len bytes at iov_base until ddsi_serdata_to_ser_unref.
            unsafe { std::slice::from_raw_parts(iov.iov_base as *const u8, iov.iov_len) }
        };
        // A panicking sink must not unwind into C (it would abort the process).
        if catch_unwind(AssertUnwindSafe(|| (self.sink)(guid, Data::Raw(bytes)))).is_err() {
            tracing::error!("cyclone: a reader's sink panicked; sample dropped");
        }
        if !r.is_null() {
            // SAFETY: releases the reference taken by ddsi_serdata_to_ser_ref, with its iov.
            unsafe { ddsi_serdata_to_ser_unref(r, &iov) };
        }
    }
}

/// The data-available listener of every reader; `arg` is its [`ReaderCtx`].
unsafe extern "C" fn on_data_available(reader: dds_entity_t, arg: *mut c_void) {
    // SAFETY: `arg` is `Arc::as_ptr` of a ReaderCtx that `Inner::contexts` keeps alive until after
    // the participant (and so this reader and its listener) is deleted.
    let ctx = unsafe { &*(arg as *const ReaderCtx) };
    ctx.drain(reader);
}

/// The entities this engine created, for `ros_discovery_info`.
#[derive(Default)]
struct Endpoints {
    readers: Vec<Guid>,
    writers: Vec<Guid>,
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

/// A discovered endpoint: its topic, GUID and announced QoS.
struct Discovered {
    topic: String,
    guid: Guid,
    qos: EndpointQos,
}

/// An incremental map of built-in topic instances, by instance handle.
struct Builtin {
    reader: dds_entity_t,
    /// Writers (DCPSPublication) or readers (DCPSSubscription): for the QoS defaults.
    writers: bool,
    known: HashMap<dds_instance_handle_t, Discovered>,
}

/// The terms of a discovered endpoint's QoS (`q` may be null); those it lacks have their
/// DDS defaults (RELIABLE for a writer, BEST_EFFORT for a reader, VOLATILE, SHARED).
fn endpoint_qos(q: *const dds_qos_t, writer: bool) -> EndpointQos {
    let mut qos = EndpointQos {
        reliability: if writer { Reliability::Reliable } else { Reliability::BestEffort },
        transient_local: false,
        ownership: Ownership::Shared,
    };
    if q.is_null() {
        return qos;
    }
    let (mut reliability, mut max_blocking, mut durability, mut ownership, mut strength) = (0, 0, 0, 0, 0);
    // SAFETY: `q` is a live QoS object (from a loaned built-in sample); the getters only write
    // the out-parameters, all valid, and return false when the policy is absent.
    unsafe {
        if dds_qget_reliability(q, &mut reliability, &mut max_blocking) {
            qos.reliability = if reliability == dds_reliability_kind_DDS_RELIABILITY_RELIABLE {
                Reliability::Reliable
            } else {
                Reliability::BestEffort
            };
        }
        if dds_qget_durability(q, &mut durability) {
            qos.transient_local = durability != dds_durability_kind_DDS_DURABILITY_VOLATILE;
        }
        if dds_qget_ownership(q, &mut ownership) && ownership == dds_ownership_kind_DDS_OWNERSHIP_EXCLUSIVE {
            if !dds_qget_ownership_strength(q, &mut strength) {
                strength = 0;
            }
            qos.ownership = Ownership::Exclusive { strength };
        }
    }
    qos
}

impl Builtin {
    fn new(participant: dds_entity_t, topic: dds_entity_t, what: &str, writers: bool) -> Result<Builtin, GatewayError> {
        // SAFETY: a built-in topic pseudo-handle, default QoS, no listener.
        let reader = unsafe { dds_create_reader(participant, topic, ptr::null(), ptr::null()) };
        if reader < 0 {
            return Err(GatewayError::dds(format!("the {what} reader"), retcode(reader)));
        }
        Ok(Builtin { reader, writers, known: HashMap::new() })
    }

    /// Takes what changed: alive instances added, disposed / unregistered ones removed; our
    /// own participant's endpoints left out.
    fn update(&mut self, own: &[u8; PREFIX_LEN]) {
        loop {
            let mut buf: [*mut c_void; BUILTIN_BATCH] = [ptr::null_mut(); BUILTIN_BATCH];
            let mut infos: [MaybeUninit<dds_sample_info_t>; BUILTIN_BATCH] = [MaybeUninit::uninit(); BUILTIN_BATCH];
            // SAFETY: buf[0] null: Cyclone loans the samples; both buffers hold BUILTIN_BATCH entries.
            let n = unsafe {
                dds_take(self.reader, buf.as_mut_ptr(), infos.as_mut_ptr().cast(), BUILTIN_BATCH, BUILTIN_BATCH as u32)
            };
            if n <= 0 {
                if n < 0 {
                    tracing::debug!("cyclone: taking discovery data: {}", retcode(n));
                }
                return;
            }
            for (p, info) in buf[..n as usize].iter().zip(&infos[..n as usize]) {
                // SAFETY: the first n infos were written by dds_take.
                let info = unsafe { info.assume_init_ref() };
                if info.instance_state != dds_instance_state_DDS_IST_ALIVE {
                    self.known.remove(&info.instance_handle);
                    continue;
                }
                if !info.valid_data || p.is_null() {
                    continue;
                }
                // SAFETY: a loaned, valid sample of a DCPSPublication/DCPSSubscription reader.
                let ep = unsafe { &*(*p as *const dds_builtintopic_endpoint_t) };
                if ep.participant_key.v[..PREFIX_LEN] == own[..] || ep.topic_name.is_null() {
                    continue;
                }
                // SAFETY: a NUL-terminated string inside the loaned sample.
                let topic = unsafe { CStr::from_ptr(ep.topic_name) }.to_string_lossy().into_owned();
                let qos = endpoint_qos(ep.qos, self.writers);
                self.known.insert(info.instance_handle, Discovered { topic, guid: Guid(ep.key.v), qos });
            }
            // SAFETY: returns the loan obtained by dds_take above.
            let r = unsafe { dds_return_loan(self.reader, buf.as_mut_ptr(), n) };
            if r < 0 {
                tracing::debug!("cyclone: returning a discovery loan: {}", retcode(r));
            }
            if (n as usize) < BUILTIN_BATCH {
                return;
            }
        }
    }
}

struct Discovery {
    publications: Builtin,
    subscriptions: Builtin,
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
    guid: Guid,
    node_name: String,
    node_namespace: String,
    discovery: Mutex<Discovery>,
    announcer: Mutex<Option<Announcer>>,
}

impl std::fmt::Debug for Cyclone {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cyclone")
            .field("domain_id", &self.domain_id)
            .field("participant", &self.inner.participant)
            .field("guid", &self.guid)
            .finish()
    }
}

impl Cyclone {
    /// Joins `cfg.domain_id`: the participant, its discovery readers.
    pub fn open(cfg: &EngineConfig) -> Result<Cyclone, GatewayError> {
        let domain_id = u32::from(cfg.domain_id);
        let mut domain = None;
        let env = std::env::var("CYCLONEDDS_URI").ok();
        let env = env.as_deref().map(str::trim).filter(|e| !e.is_empty());
        if let Some(conf) = domain_config(cfg, &cfg.interfaces, env) {
            let mut d = create_domain(domain_id, &conf)?;
            let mut conf = Some(conf);
            if d < 0 && d != DDS_RETCODE_PRECONDITION_NOT_MET && env.is_some() && !cfg.interfaces.is_empty() {
                // Interface lists add up, and Cyclone refuses an interface selected twice (one that
                // CYCLONEDDS_URI names already): keep the environment's interfaces then.
                tracing::warn!(
                    "cyclone: CYCLONEDDS_URI and the interfaces {:?} do not combine ({}); using the interfaces of \
                     CYCLONEDDS_URI",
                    cfg.interfaces,
                    retcode(d)
                );
                conf = domain_config(cfg, &[], env);
                d = match &conf {
                    Some(c) => create_domain(domain_id, c)?,
                    None => 0,
                };
            }
            if d == DDS_RETCODE_PRECONDITION_NOT_MET {
                // Another participant of this process made the domain already: its config stands.
                if cfg.interfaces.is_empty() && cfg.peers.is_empty() {
                    tracing::debug!("cyclone: domain {domain_id} already exists in this process; its config stands");
                } else {
                    tracing::warn!(
                        "cyclone: domain {domain_id} already exists in this process; interfaces/peers not applied"
                    );
                }
            } else if d < 0 {
                let conf = conf.unwrap_or_default();
                return Err(GatewayError::dds(format!("domain {domain_id} with config {conf}"), retcode(d)));
            } else if d > 0 {
                domain = Some(d);
            }
        }
        let participant = create_participant(domain_id, cfg.participant_lease);
        if participant < 0 {
            if let Some(d) = domain {
                delete_entity(d);
            }
            return Err(GatewayError::dds(format!("a participant on domain {domain_id}"), retcode(participant)));
        }
        // From here on, dropping `inner` cleans up.
        let inner = Arc::new(Inner {
            participant,
            domain,
            endpoints: Mutex::new(Endpoints::default()),
            contexts: Mutex::new(Vec::new()),
        });
        let guid = entity_guid(participant).map_err(|r| GatewayError::dds("the participant's GUID", retcode(r)))?;
        let discovery = Discovery {
            publications: Builtin::new(participant, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, "DCPSPublication", true)?,
            subscriptions: Builtin::new(participant, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, "DCPSSubscription", false)?,
        };
        tracing::debug!("cyclone: participant {guid:?} on domain {domain_id}");
        Ok(Cyclone {
            inner,
            domain_id: cfg.domain_id,
            guid,
            node_name: cfg.node_name.clone(),
            node_namespace: if cfg.node_namespace.is_empty() { "/".into() } else { cfg.node_namespace.clone() },
            discovery: Mutex::new(discovery),
            announcer: Mutex::new(None),
        })
    }

    /// A writer and its topic on our participant.
    fn create_writer(
        &self,
        topic: &str,
        ty: &TopicType,
        q: &Qos,
        batching: bool,
    ) -> Result<(dds_entity_t, dds_entity_t, *const ddsi_sertype), GatewayError> {
        let t = blob_topic(self.inner.participant, topic, &ty.name)?;
        let qos = NativeQos::new(q, ty, batching).inspect_err(|_| delete_entity(t))?;
        // SAFETY: live participant and topic, a valid QoS, no listener.
        let w = unsafe { dds_create_writer(self.inner.participant, t, qos.0, ptr::null()) };
        if w < 0 {
            delete_entity(t);
            return Err(GatewayError::dds(format!("a writer on {topic}"), retcode(w)));
        }
        let mut sertype: *const ddsi_sertype = ptr::null();
        // SAFETY: `sertype` is a valid out-parameter.
        let r = unsafe { dds_get_entity_sertype(w, &mut sertype) };
        if r < 0 || sertype.is_null() {
            delete_entity(w);
            delete_entity(t);
            return Err(GatewayError::dds(format!("a writer on {topic}"), retcode(r)));
        }
        Ok((t, w, sertype))
    }
}

impl Engine for Cyclone {
    fn kind(&self) -> EngineKind {
        EngineKind::Cyclone
    }

    fn arbitrates_ownership(&self) -> bool {
        true
    }

    fn domain_id(&self) -> u16 {
        self.domain_id
    }

    fn own_prefix(&self) -> [u8; PREFIX_LEN] {
        self.guid.prefix()
    }

    fn writer(&self, topic: &str, ty: &TopicType, q: &Qos) -> Result<Box<dyn Writer>, GatewayError> {
        let (t, w, sertype) = self.create_writer(topic, ty, q, true)?;
        let guid = match entity_guid(w) {
            Ok(g) => g,
            Err(r) => {
                delete_entity(w);
                delete_entity(t);
                return Err(GatewayError::dds(format!("a writer on {topic}"), retcode(r)));
            }
        };
        lock(&self.inner.endpoints).writers.push(guid);
        Ok(Box::new(CycloneWriter { inner: self.inner.clone(), topic: t, writer: w, sertype, guid }))
    }

    fn reader(&self, topic: &str, ty: &TopicType, q: &Qos, _decode: Decode, sink: Sink) -> Result<(), GatewayError> {
        let t = blob_topic(self.inner.participant, topic, &ty.name)?;
        let fail = |what: String, detail: String| {
            delete_entity(t);
            GatewayError::dds(what, detail)
        };
        let qos = NativeQos::new(q, ty, false).map_err(|e| fail(format!("a reader on {topic}"), e.to_string()))?;
        let ctx = Arc::new(ReaderCtx { sink, writers: Mutex::new(HashMap::new()) });
        // SAFETY: the argument stays valid for the reader's life (kept in `contexts` below).
        let listener = unsafe { dds_create_listener(Arc::as_ptr(&ctx) as *mut c_void) };
        if listener.is_null() {
            return Err(fail(format!("a listener on {topic}"), "out of memory".into()));
        }
        // SAFETY: a fresh listener; the callback matches dds_on_data_available_fn.
        unsafe { dds_lset_data_available(listener, Some(on_data_available)) };
        // Keep the state before the reader can call back.
        lock(&self.inner.contexts).push(ctx.clone());
        // SAFETY: live participant and topic, valid QoS and listener (copied by Cyclone).
        let r = unsafe { dds_create_reader(self.inner.participant, t, qos.0, listener) };
        // SAFETY: created above; the reader holds its own copy.
        unsafe { dds_delete_listener(listener) };
        if r < 0 {
            lock(&self.inner.contexts).retain(|c| !Arc::ptr_eq(c, &ctx));
            return Err(fail(format!("a reader on {topic}"), retcode(r)));
        }
        match entity_guid(r) {
            Ok(g) => lock(&self.inner.endpoints).readers.push(g),
            Err(e) => tracing::warn!("cyclone: GUID of the reader on {topic}: {}", retcode(e)),
        }
        Ok(())
    }

    fn remote(&self) -> Remote {
        let own = self.guid.prefix();
        let mut d = lock(&self.discovery);
        d.publications.update(&own);
        d.subscriptions.update(&own);
        let mut remote = Remote::default();
        for e in d.publications.known.values() {
            remote.writers.entry(e.topic.clone()).or_default().insert(e.guid);
            remote.qos.insert(e.guid, e.qos);
        }
        for e in d.subscriptions.known.values() {
            remote.readers.entry(e.topic.clone()).or_default().insert(e.guid);
            remote.qos.insert(e.guid, e.qos);
        }
        remote
    }

    fn announce(&self) -> Result<(), GatewayError> {
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
        if announcer.is_none() {
            let q = Qos {
                reliability: Reliability::Reliable,
                history: History::KeepLast(1),
                durability: Durability::TransientLocal { depth: 1 },
                ownership: Ownership::Shared,
            };
            let (_, writer, sertype) =
                self.create_writer(DISCOVERY_TOPIC, &TopicType::stock(DISCOVERY_TYPE), &q, false)?;
            *announcer = Some(Announcer { writer, sertype });
        }
        let a = announcer.as_ref().expect("created above");
        // SAFETY: the sertype of `a.writer`, alive as long as our participant.
        if !unsafe { write_pieces(a.writer, a.sertype, &[&HEADER_LE, &body]) } {
            return Err(GatewayError::dds("a ros_discovery_info sample", "write refused"));
        }
        // SAFETY: any handle is accepted.
        unsafe { dds_write_flush(a.writer) };
        Ok(())
    }
}

/// `rmw_dds_common::msg::ParticipantEntitiesInfo` with one node, as plain little-endian CDR
/// (no encapsulation header; alignment relative to the start of `out`).
fn encode_participant_info(
    out: &mut Vec<u8>,
    participant: &Guid,
    namespace: &str,
    name: &str,
    readers: &[Guid],
    writers: &[Guid],
) {
    fn align4(out: &mut Vec<u8>) {
        out.resize(out.len().next_multiple_of(4), 0);
    }
    fn u32_(out: &mut Vec<u8>, v: usize) {
        align4(out);
        out.extend_from_slice(&(v as u32).to_le_bytes());
    }
    fn string(out: &mut Vec<u8>, s: &str) {
        u32_(out, s.len() + 1);
        out.extend_from_slice(s.as_bytes());
        out.push(0);
    }
    fn gids(out: &mut Vec<u8>, gs: &[Guid]) {
        u32_(out, gs.len());
        for g in gs {
            out.extend_from_slice(&g.0);
        }
    }
    out.clear();
    out.extend_from_slice(&participant.0);
    u32_(out, 1);
    string(out, namespace);
    string(out, name);
    gids(out, readers);
    gids(out, writers);
}

/// A writer of pre-encoded samples; deletes its DDS writer when dropped.
struct CycloneWriter {
    inner: Arc<Inner>,
    topic: dds_entity_t,
    writer: dds_entity_t,
    sertype: *const ddsi_sertype,
    guid: Guid,
}

// SAFETY: the entities are integer handles; `sertype` is only read by Cyclone's thread-safe serdata
// code and stays valid while `writer` exists, which is until our Drop (the participant is kept alive by
// `inner`).
unsafe impl Send for CycloneWriter {}

impl Writer for CycloneWriter {
    fn write(&mut self, body: &[u8]) -> bool {
        // SAFETY: `sertype` belongs to `writer`, which lives until we drop.
        unsafe { write_pieces(self.writer, self.sertype, &[&HEADER_LE, body]) }
    }

    fn write_serialized(&mut self, raw: &[u8]) -> bool {
        // SAFETY: as above.
        unsafe { write_pieces(self.writer, self.sertype, &[raw]) }
    }

    fn flush(&mut self) {
        flush_writer(self.writer);
    }

    fn flusher(&self) -> Option<super::Flusher> {
        let writer = self.writer;
        Some(std::sync::Arc::new(move || flush_writer(writer)))
    }
}

/// `dds_write_flush`: thread-safe in Cyclone; a handle that is gone by now is refused with
/// an error code, nothing worse.
fn flush_writer(writer: dds_entity_t) {
    // SAFETY: any handle is accepted.
    let r = unsafe { dds_write_flush(writer) };
    if r < 0 {
        tracing::debug!("cyclone: flush of {writer}: {}", retcode(r));
    }
}

impl Drop for CycloneWriter {
    fn drop(&mut self) {
        self.flush();
        delete_entity(self.writer);
        delete_entity(self.topic);
        let mut eps = lock(&self.inner.endpoints);
        if let Some(i) = eps.writers.iter().position(|g| *g == self.guid) {
            eps.writers.swap_remove(i);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_fragment() {
        let mut cfg = EngineConfig::default();
        // One receive thread per socket, unless the environment's config says.
        assert_eq!(domain_config(&cfg, &[], Some("<x/>")).as_deref(), Some(&*format!("<x/>,{RECEIVE_THREADS}")));
        assert_eq!(domain_config(&cfg, &[], None).as_deref(), Some(RECEIVE_THREADS));
        let own = "<Internal><MultipleReceiveThreads>false</MultipleReceiveThreads></Internal>";
        assert_eq!(domain_config(&cfg, &[], Some(own)), None);
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("c.xml");
        std::fs::write(&file, format!("<CycloneDDS><Domain>{own}</Domain></CycloneDDS>")).unwrap();
        assert_eq!(domain_config(&cfg, &[], Some(&format!("<y/>, file://{}", file.display()))), None);
        cfg.interfaces = vec!["127.0.0.1".parse().unwrap()];
        cfg.peers = vec!["host\"a".into()];
        let c = domain_config(&cfg, &cfg.interfaces, Some("file:///etc/c.xml")).unwrap();
        assert!(c.starts_with(&format!(
            "file:///etc/c.xml,{RECEIVE_THREADS}<General><Interfaces><NetworkInterface address=\"127.0.0.1\"/>"
        )));
        assert!(c.contains("<Peer address=\"host&quot;a\"/>"));
        assert!(c.ends_with("<MaxAutoParticipantIndex>50</MaxAutoParticipantIndex></Discovery>"));
        assert!(!domain_config(&cfg, &cfg.interfaces, None).unwrap().contains(','));
        assert!(!domain_config(&cfg, &[], None).unwrap().contains("Interfaces"));
        // Loopback only and no peers: the other participants on loopback are the peers.
        cfg.peers.clear();
        assert!(domain_config(&cfg, &cfg.interfaces, None).unwrap().contains("<Peer address=\"127.0.0.1\"/>"));
        cfg.interfaces = vec!["192.0.2.1".parse().unwrap()];
        assert!(!domain_config(&cfg, &cfg.interfaces, None).unwrap().contains("Peer"));
    }

    #[test]
    fn participant_info_layout() {
        let mut out = Vec::new();
        let g = |b: u8| Guid([b; 16]);
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
