//! Writers of pre-encoded samples: a write stays in the writer's packing buffer until
//! [`Writer::flush`] (`dds_write_flush`) or until the buffer fills; every writer of the gateway
//! flushes when nothing more is waiting (and on drop). A writer deletes its DDS writer when
//! dropped and keeps the participant alive until then.

use std::sync::Arc;

use cyclors::{dds_entity_t, dds_write_flush, ddsi_sertype};
use tutti_core::cdr::HEADER_LE;

use super::native::{delete_entity, lock, retcode, write_pieces};
use super::Inner;
use crate::dds::rpc::ReplyWriter;
use crate::{Flusher, Writer};

/// A writer of pre-encoded samples; deletes its DDS writer when dropped.
pub(super) struct CycloneWriter {
    pub(super) inner: Arc<Inner>,
    pub(super) topic: dds_entity_t,
    pub(super) writer: dds_entity_t,
    pub(super) sertype: *const ddsi_sertype,
    pub(super) guid: [u8; 16],
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

    fn flusher(&self) -> Option<Flusher> {
        let writer = self.writer;
        Some(Arc::new(move || flush_writer(writer)))
    }
}

/// A service's reply writer: Cyclone writes no related sample identity and counts no matches
/// (discovery decides whether a reply reaches its client).
impl ReplyWriter for CycloneWriter {
    fn write(&mut self, body: &[u8]) -> bool {
        Writer::write(self, body)
    }

    fn flush(&mut self) {
        Writer::flush(self);
    }
}

/// `dds_write_flush`: thread-safe in Cyclone; a handle that is gone by now is refused with
/// an error code, nothing worse.
pub(super) fn flush_writer(writer: dds_entity_t) {
    // SAFETY: any handle is accepted.
    let r = unsafe { dds_write_flush(writer) };
    if r < 0 {
        tracing::debug!("cyclone: flush of {writer}: {}", retcode(r));
    }
}

impl Drop for CycloneWriter {
    fn drop(&mut self) {
        Writer::flush(self);
        delete_entity(self.writer);
        delete_entity(self.topic);
        let mut eps = lock(&self.inner.endpoints);
        if let Some(i) = eps.writers.iter().position(|g| *g == self.guid) {
            eps.writers.swap_remove(i);
        }
    }
}
