//! Readers: a data-available listener takes up to [`TAKE_BATCH`] samples per `dds_takecdr` and
//! hands each, with its writer's id, to the reader's sink, or, for a service's request reader,
//! to the services' request sink. Samples of our own participant's writers are dropped here
//! and counted (echo suppression is the engine's).

use std::collections::HashMap;
use std::ffi::c_void;
use std::mem::MaybeUninit;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use cyclors::{
    dds_builtintopic_free_endpoint, dds_create_listener, dds_create_reader, dds_delete_listener, dds_entity_t,
    dds_get_matched_publication_data, dds_instance_handle_t, dds_lset_data_available, dds_sample_info_t, dds_takecdr,
    ddsi_serdata, ddsi_serdata_size, ddsi_serdata_to_ser_ref, ddsi_serdata_to_ser_unref, ddsi_serdata_unref,
    ddsrt_iovec_t, DDS_ANY_STATE,
};
use tutti_core::mapping::Qos;

use super::native::{blob_topic, delete_entity, entity_error, entity_guid, lock, retcode, NativeQos};
use super::Inner;
use crate::dds::{endpoint, peer_of, rpc};
use crate::{Data, EngineError, PeerId, RequestSink, Sink, TopicType};

/// Samples taken per `dds_takecdr` in a reader's listener.
const TAKE_BATCH: usize = 64;

/// Where a reader's samples go.
pub(super) enum Deliver {
    /// A topic's reader: to its sink.
    Data(Sink),
    /// A service's request reader: to the services' sink, as requests.
    Requests(RequestSink),
}

/// Per reader: where its samples go, the writers' GUIDs seen so far (by publication handle),
/// and our own peer, whose samples are dropped and counted.
pub(super) struct ReaderCtx {
    deliver: Deliver,
    writers: Mutex<HashMap<dds_instance_handle_t, [u8; 16]>>,
    own: PeerId,
    own_samples: Arc<AtomicU64>,
}

impl ReaderCtx {
    /// The GUID of the writer with publication handle `h`, looked up on its first sample.
    fn writer_guid(
        writers: &mut HashMap<dds_instance_handle_t, [u8; 16]>,
        reader: dds_entity_t,
        h: dds_instance_handle_t,
    ) -> [u8; 16] {
        if let Some(g) = writers.get(&h) {
            return *g;
        }
        // SAFETY: `reader` is the reader this listener belongs to; the result is null or a
        // malloc'ed endpoint that we free below.
        let ep = unsafe { dds_get_matched_publication_data(reader, h) };
        if ep.is_null() {
            // Gone already (or not matched any more): don't cache.
            return [0; 16];
        }
        // SAFETY: non-null, filled by Cyclone.
        let g = unsafe { (*ep).key.v };
        // SAFETY: returned by dds_get_matched_publication_data, freed once.
        unsafe { dds_builtintopic_free_endpoint(ep) };
        if writers.len() >= 4096 {
            writers.clear();
        }
        writers.insert(h, g);
        g
    }

    /// Takes everything the reader holds and hands each valid sample on.
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
                    if peer_of(&guid) == self.own {
                        self.own_samples.fetch_add(1, Ordering::Relaxed);
                    } else {
                        self.deliver(*sd, guid);
                    }
                }
                // SAFETY: dds_takecdr handed us one reference to each sample.
                unsafe { ddsi_serdata_unref(*sd) };
            }
            if n < TAKE_BATCH {
                break;
            }
        }
    }

    /// One sample on: its serialized form, encapsulation header included, borrowed.
    fn deliver(&self, sd: *mut ddsi_serdata, guid: [u8; 16]) {
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
        let hand_on = || match &self.deliver {
            Deliver::Data(sink) => sink(endpoint(guid), Data::Raw(bytes)),
            // Cyclone reads no sample identity: rmw_cyclonedds's form only.
            Deliver::Requests(sink) => {
                rpc::deliver(rpc::Incoming { writer: guid, sequence: None, related: None, raw: bytes }, sink)
            }
        };
        if catch_unwind(AssertUnwindSafe(hand_on)).is_err() {
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

/// A reader on DDS topic `topic` (type `ty`, QoS `q`) of `inner`'s participant, whose samples
/// go where `deliver` says, our own peer's (`own`) dropped and counted in `own_samples`.
pub(super) fn create(
    inner: &Inner,
    topic: &str,
    ty: &TopicType,
    q: &Qos,
    deliver: Deliver,
    own: (PeerId, Arc<AtomicU64>),
) -> Result<(), EngineError> {
    let t = blob_topic(inner.participant, topic, &ty.name)?;
    let fail = |what: String, detail: String| {
        delete_entity(t);
        EngineError::dds(what, detail)
    };
    let refused = |what: String, ret| {
        delete_entity(t);
        entity_error(what, ret)
    };
    let qos = NativeQos::new(q, ty, false).map_err(|e| fail(format!("a reader on {topic}"), e.to_string()))?;
    let ctx = Arc::new(ReaderCtx { deliver, writers: Mutex::new(HashMap::new()), own: own.0, own_samples: own.1 });
    // SAFETY: the argument stays valid for the reader's life (kept in `contexts` below).
    let listener = unsafe { dds_create_listener(Arc::as_ptr(&ctx) as *mut c_void) };
    if listener.is_null() {
        return Err(fail(format!("a listener on {topic}"), "out of memory".into()));
    }
    // SAFETY: a fresh listener; the callback matches dds_on_data_available_fn.
    unsafe { dds_lset_data_available(listener, Some(on_data_available)) };
    // Keep the state before the reader can call back.
    lock(&inner.contexts).push(ctx.clone());
    // SAFETY: live participant and topic, valid QoS and listener (copied by Cyclone).
    let r = unsafe { dds_create_reader(inner.participant, t, qos.0, listener) };
    // SAFETY: created above; the reader holds its own copy.
    unsafe { dds_delete_listener(listener) };
    if r < 0 {
        lock(&inner.contexts).retain(|c| !Arc::ptr_eq(c, &ctx));
        return Err(refused(format!("a reader on {topic}"), r));
    }
    match entity_guid(r) {
        Ok(g) => lock(&inner.endpoints).readers.push(g),
        Err(e) => tracing::warn!("cyclone: GUID of the reader on {topic}: {}", retcode(e)),
    }
    Ok(())
}
