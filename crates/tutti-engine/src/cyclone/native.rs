//! Cyclone's C API, wrapped once: return codes as text, QoS objects, GUIDs, entities, the
//! blob topics and the write of a pre-encoded sample.

use std::ffi::{c_char, c_void, CStr, CString};
use std::ptr;
use std::sync::{Mutex, MutexGuard, PoisonError};

use cyclors::{
    cdds_create_blob_topic, dds_create_qos, dds_delete, dds_delete_qos,
    dds_durability_kind_DDS_DURABILITY_TRANSIENT_LOCAL, dds_durability_kind_DDS_DURABILITY_VOLATILE, dds_entity_t,
    dds_get_guid, dds_guid_t, dds_history_kind_DDS_HISTORY_KEEP_ALL, dds_history_kind_DDS_HISTORY_KEEP_LAST,
    dds_ownership_kind_DDS_OWNERSHIP_EXCLUSIVE, dds_ownership_kind_DDS_OWNERSHIP_SHARED, dds_qos_t,
    dds_qset_durability, dds_qset_durability_service, dds_qset_history, dds_qset_lifespan, dds_qset_ownership,
    dds_qset_ownership_strength, dds_qset_reliability, dds_qset_userdata, dds_qset_writer_batching,
    dds_reliability_kind_DDS_RELIABILITY_BEST_EFFORT, dds_reliability_kind_DDS_RELIABILITY_RELIABLE, dds_return_t,
    dds_strretcode, dds_writecdr, ddsi_serdata_from_ser_iov, ddsi_serdata_kind_SDK_DATA, ddsi_sertype, ddsrt_iovec_t,
};
use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};

use crate::{EngineError, TopicType};

/// How long a reliable write may block on a full history (ns).
const MAX_BLOCKING_NS: i64 = 100_000_000;

/// Cyclone's text for a return code.
pub(super) fn retcode(ret: dds_return_t) -> String {
    // SAFETY: dds_strretcode accepts any value and returns a pointer to a static NUL-terminated string.
    let s = unsafe { dds_strretcode(ret) };
    if s.is_null() {
        return format!("return code {ret}");
    }
    // SAFETY: non-null and static (above).
    unsafe { CStr::from_ptr(s) }.to_string_lossy().into_owned()
}

/// The error of Cyclone's `ret` making `what`: [`EngineError::NotAllowed`] when DDS Security's
/// access control refused it.
pub(super) fn entity_error(what: String, ret: dds_return_t) -> EngineError {
    if ret == cyclors::DDS_RETCODE_NOT_ALLOWED_BY_SECURITY as dds_return_t {
        EngineError::NotAllowed { what }
    } else {
        EngineError::dds(what, retcode(ret))
    }
}

pub(super) fn c_string(what: &'static str, s: &str) -> Result<CString, EngineError> {
    CString::new(s).map_err(|_| EngineError::NulByte { what, value: s.escape_debug().to_string() })
}

/// A `dds_qos_t`, deleted on drop.
pub(super) struct NativeQos(pub(super) *mut dds_qos_t);

impl NativeQos {
    /// The QoS `q` of an endpoint of type `ty` (whose hash goes into its USER_DATA).
    pub(super) fn new(q: &Qos, ty: &TopicType, batching: bool) -> Result<NativeQos, EngineError> {
        // SAFETY: plain allocation; null on failure.
        let p = unsafe { dds_create_qos() };
        if p.is_null() {
            return Err(EngineError::dds("a QoS", "out of memory"));
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
            if let Some(lifespan) = q.lifespan {
                dds_qset_lifespan(p, i64::try_from(lifespan.as_nanos()).unwrap_or(i64::MAX));
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
pub(super) fn entity_guid(e: dds_entity_t) -> Result<[u8; 16], dds_return_t> {
    let mut g = dds_guid_t { v: [0; 16] };
    // SAFETY: `g` is a valid out-parameter.
    let r = unsafe { dds_get_guid(e, &mut g) };
    if r < 0 {
        Err(r)
    } else {
        Ok(g.v)
    }
}

pub(super) fn delete_entity(e: dds_entity_t) {
    // SAFETY: deleting a handle is safe for any value: a stale or wrong one only returns an error.
    let r = unsafe { dds_delete(e) };
    if r < 0 {
        tracing::debug!("cyclone: deleting entity {e}: {}", retcode(r));
    }
}

pub(super) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Writes `pieces` (the encapsulation header first) as one serialized sample: one copy, into
/// the serdata. False when DDS refused it.
///
/// # Safety
/// `sertype` must be the sertype of `writer`'s topic, and `writer` must not have been deleted.
pub(super) unsafe fn write_pieces(writer: dds_entity_t, sertype: *const ddsi_sertype, pieces: &[&[u8]]) -> bool {
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
pub(super) fn blob_topic(participant: dds_entity_t, topic: &str, type_name: &str) -> Result<dds_entity_t, EngineError> {
    let ctopic = c_string("topic name", topic)?;
    let ctype = c_string("type name", type_name)?;
    // SAFETY: both strings are NUL-terminated and outlive the call; the C side only reads them (it
    // duplicates the type name and copies the topic name). Keyless: ROS 2 types have no keys.
    let t = unsafe {
        cdds_create_blob_topic(participant, ctopic.as_ptr() as *mut c_char, ctype.as_ptr() as *mut c_char, true)
    };
    if t < 0 {
        return Err(entity_error(format!("topic {topic} ({type_name})"), t));
    }
    Ok(t)
}
