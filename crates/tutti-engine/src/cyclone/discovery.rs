//! Discovery: the DCPSPublication / DCPSSubscription built-in readers, drained into
//! incremental maps whenever the engine is asked what is out there; and the node's
//! announcement on `ros_discovery_info`.

use std::collections::HashMap;
use std::ffi::{c_void, CStr};
use std::mem::MaybeUninit;
use std::ptr;

use cyclors::{
    dds_builtintopic_endpoint_t, dds_create_reader, dds_durability_kind_DDS_DURABILITY_VOLATILE, dds_entity_t,
    dds_instance_handle_t, dds_instance_state_DDS_IST_ALIVE, dds_ownership_kind_DDS_OWNERSHIP_EXCLUSIVE,
    dds_qget_durability, dds_qget_ownership, dds_qget_ownership_strength, dds_qget_reliability, dds_qos_t,
    dds_reliability_kind_DDS_RELIABILITY_RELIABLE, dds_return_loan, dds_sample_info_t, dds_take,
    DDS_BUILTIN_TOPIC_DCPSPUBLICATION, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION,
};
use tutti_core::mapping::{Ownership, Reliability};

use super::native::retcode;
use crate::dds::{endpoint, PREFIX_LEN};
use crate::{EndpointId, EndpointQos, EngineError, Remote};

/// Samples taken per `dds_take` on a built-in topic.
const BUILTIN_BATCH: usize = 32;

/// A discovered endpoint: its topic, GUID and announced QoS.
pub(super) struct Discovered {
    topic: String,
    id: EndpointId,
    qos: EndpointQos,
}

/// An incremental map of built-in topic instances, by instance handle.
pub(super) struct Builtin {
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
    fn new(participant: dds_entity_t, topic: dds_entity_t, what: &str, writers: bool) -> Result<Builtin, EngineError> {
        // SAFETY: a built-in topic pseudo-handle, default QoS, no listener.
        let reader = unsafe { dds_create_reader(participant, topic, ptr::null(), ptr::null()) };
        if reader < 0 {
            return Err(EngineError::dds(format!("the {what} reader"), retcode(reader)));
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
                self.known.insert(info.instance_handle, Discovered { topic, id: endpoint(ep.key.v), qos });
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

/// Both built-in readers.
pub(super) struct Discovery {
    publications: Builtin,
    subscriptions: Builtin,
}

impl Discovery {
    pub(super) fn new(participant: dds_entity_t) -> Result<Discovery, EngineError> {
        Ok(Discovery {
            publications: Builtin::new(participant, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, "DCPSPublication", true)?,
            subscriptions: Builtin::new(participant, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, "DCPSSubscription", false)?,
        })
    }

    /// Every remote endpoint by its DDS topic (our own participant `own`'s left out).
    pub(super) fn remote(&mut self, own: &[u8; PREFIX_LEN]) -> Remote {
        self.publications.update(own);
        self.subscriptions.update(own);
        let mut remote = Remote::default();
        for e in self.publications.known.values() {
            remote.writers.entry(e.topic.clone()).or_default().insert(e.id);
            remote.qos.insert(e.id, e.qos);
        }
        for e in self.subscriptions.known.values() {
            remote.readers.entry(e.topic.clone()).or_default().insert(e.id);
            remote.qos.insert(e.id, e.qos);
        }
        remote
    }
}
