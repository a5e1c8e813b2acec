//! Writing the SUBSCRIBE set: staging items and committing what changed, or computing a
//! whole set in place, under the writers' lock; and the book-keeping of a commit.

use std::time::Instant;

use super::Participant;
use crate::ddf::{Leaf, Role};
use crate::shm::bucket::{copy_words, store_bytes, store_range, with_bytes_mut, Stamp};
use crate::shm::segment::{self, Segment, MAX_READ_TRIES};
use crate::shm::ShmError;
use crate::sync::{AtomicU64, Ordering};

impl Participant {
    /// Reads the PUBLISH set where it lies and commits a whole SUBSCRIBE set computed from
    /// it, with no copy on either side: `f(publish, out)` writes every byte of `out`, the
    /// shared memory of the next SUBSCRIBE value. This is `subscribe_lock`, `publish_lock`
    /// and `commit_all_with` in one, for components that turn their inputs into their
    /// outputs byte for byte (a relay, a converter, a serialiser). The read is checked after
    /// `f` returns: if the framework published meanwhile, `f` runs again on the newer value
    /// before anything is committed, so `f` may see a torn set first and must only compute
    /// from its bytes. In a synchronous domain it waits for the next step first and answers
    /// it. The snapshot buffer is left as it was. Returns the step (generation) read.
    pub fn answer_with(&mut self, mut f: impl FnMut(&[u8], &mut [u8])) -> Result<u64, ShmError> {
        self.begin_read()?;
        self.claim_writer()?;
        let lock = self.lock_writers()?;
        let seg = &self.seg;
        let (pub_size, sub_size) = (seg.info.publish.size as usize, seg.info.subscribe.size as usize);
        let publish = seg.bucket(Role::Publish);
        let mut read = None;
        // The answer is stamped with the step it answers: the one read.
        seg.bucket(Role::Subscribe).try_write_with(|_, next| {
            with_bytes_mut(next, |out| {
                let out = &mut out[..sub_size];
                read = publish.read_in_place(|bytes| f(bytes, out), pub_size, MAX_READ_TRIES);
            });
            read.map(|(_, stamp, ())| stamp)
        });
        drop(lock);
        let generation = read.ok_or_else(|| seg.never_settles(Role::Publish))?.0;
        let step = self.finish_read(generation);
        if self.seg.info.flags.synchronous {
            // The step answered is the one read; the commit's acknowledgement wakes the
            // framework for both.
            self.locked_step = step;
        }
        Self::committed(&self.seg, self.slot, self.locked_step);
        self.stale_staging = true;
        self.reset_after_commit();
        Ok(step)
    }

    /// The SUBSCRIBE values being staged.
    pub fn staging(&mut self) -> &[u8] {
        // A corrupted segment leaves the buffer as it was; `commit` reports the error.
        let _ = self.refresh_staging();
        &self.staging
    }

    /// Mutable staging buffer: whatever differs from the last commit is committed next.
    pub fn staging_mut(&mut self) -> &mut [u8] {
        let _ = self.refresh_staging();
        &mut self.staging
    }

    /// Stages one item of the SUBSCRIBE set (committed even if unchanged).
    pub fn stage(&mut self, path: &str, bytes: &[u8]) -> Result<(), ShmError> {
        let (index, _) = self.leaf(Role::Subscribe, path)?;
        self.stage_at(index, bytes)
    }

    /// Stages the SUBSCRIBE item with index `index` in its set (as [`leaf`](Self::leaf) gives
    /// it): [`stage`](Self::stage) without looking the
    /// path up, for a caller that resolved the item once.
    pub fn stage_at(&mut self, index: usize, bytes: &[u8]) -> Result<(), ShmError> {
        let Some(range) = self.seg.info.subscribe.leaves.get(index).map(Leaf::range) else {
            return Err(ShmError::UnknownItem {
                domain: self.seg.info.name.clone(),
                role: Role::Subscribe,
                item: format!("#{index}"),
            });
        };
        if bytes.len() != range.len() {
            return Err(ShmError::SizeMismatch {
                domain: self.seg.info.name.clone(),
                role: Role::Subscribe,
                expected: range.len(),
                got: bytes.len(),
            });
        }
        self.refresh_staging()?;
        self.staging[range].copy_from_slice(bytes);
        self.marked[index] = true;
        Ok(())
    }

    /// After [`commit_all_with`](Self::commit_all_with): staging and the record of the last
    /// commit become the SUBSCRIBE set as it is now (the values committed, unless another
    /// writer has changed some since, in which case those are the newer values, and the next
    /// commit leaves them alone as before).
    pub(super) fn refresh_staging(&mut self) -> Result<(), ShmError> {
        if self.stale_staging {
            self.seg.read_set(Role::Subscribe, &mut self.staging)?;
            self.shadow.copy_from_slice(&self.staging);
            self.stale_staging = false;
        }
        Ok(())
    }

    /// The leaf `path` of set `role`, with its index in that set.
    pub fn leaf(&self, role: Role, path: &str) -> Result<(usize, &Leaf), ShmError> {
        self.seg
            .info
            .set(role)
            .leaves
            .iter()
            .enumerate()
            .find(|(_, l)| l.path == path)
            .ok_or_else(|| ShmError::UnknownItem { domain: self.seg.info.name.clone(), role, item: path.to_string() })
    }

    /// Commits the staged SUBSCRIBE values atomically: the leaves staged or changed since the
    /// last commit replace the current values; other writers' items are kept. In a
    /// synchronous domain this is the connection's contribution to the locked step.
    pub fn commit(&mut self) -> Result<(), ShmError> {
        self.check()?;
        self.claim_writer()?;
        self.refresh_staging()?;
        // The scratch list is taken out for the commit and put back, whatever the outcome.
        let mut changed = std::mem::take(&mut self.changed);
        changed.clear();
        changed.extend(
            self.seg
                .info
                .subscribe
                .leaves
                .iter()
                .enumerate()
                .filter(|(i, l)| self.marked[*i] || self.staging[l.range()] != self.shadow[l.range()])
                .map(|(_, l)| (l.offset as usize, l.size as usize)),
        );
        let written = self.write_changed(&changed);
        if written.is_ok() {
            for &(off, len) in &changed {
                self.shadow[off..off + len].copy_from_slice(&self.staging[off..off + len]);
            }
        }
        self.changed = changed;
        written
    }

    /// The write of [`commit`](Self::commit): the byte ranges `changed` of staging replace
    /// those of the SUBSCRIBE set, the rest is carried over.
    fn write_changed(&mut self, changed: &[(usize, usize)]) -> Result<(), ShmError> {
        let stamp = self.commit_stamp();
        let lock = self.lock_writers()?;
        let seg = &self.seg;
        let staging = &self.staging;
        let whole = changed.len() == seg.info.subscribe.leaves.len();
        seg.bucket(Role::Subscribe).write_with(stamp, |prev, next| {
            if whole {
                // Every item changes: no need to carry the previous value over.
                store_bytes(next, staging);
                return;
            }
            copy_words(next, prev);
            for &(off, len) in changed {
                store_range(next, off, &staging[off..off + len]);
            }
        });
        drop(lock);
        // Written into pages another process cut away: nobody will read it.
        seg.intact()?;
        Self::committed(seg, self.slot, self.locked_step);
        self.reset_after_commit();
        self.answer_if_on_commit();
        Ok(())
    }

    /// Commits a whole SUBSCRIBE set computed from the last snapshot of the PUBLISH set:
    /// `f(snapshot, out)` writes every byte of `out`, which is the shared memory of the next
    /// value itself, so the set reaches the other side without a staging copy (the path for
    /// a component that computes all its outputs at once; `out` starts with unspecified
    /// bytes). Whatever `f` leaves in `out` is committed. The staging buffer is not copied
    /// on the way: its next use reads it back from the SUBSCRIBE set.
    pub fn commit_all_with(&mut self, f: impl FnOnce(&[u8], &mut [u8])) -> Result<(), ShmError> {
        self.check()?;
        self.claim_writer()?;
        let stamp = self.commit_stamp();
        let lock = self.lock_writers()?;
        let seg = &self.seg;
        let size = seg.info.subscribe.size as usize;
        let snapshot = &self.snapshot;
        seg.bucket(Role::Subscribe)
            .write_with(stamp, |_, next| with_bytes_mut(next, |out| f(snapshot, &mut out[..size])));
        drop(lock);
        // Written into pages another process cut away: nobody will read it.
        seg.intact()?;
        Self::committed(seg, self.slot, self.locked_step);
        self.stale_staging = true;
        self.reset_after_commit();
        self.answer_if_on_commit();
        Ok(())
    }

    /// The [`Stamp`] of this connection's next commit: in a synchronous domain the step it
    /// answers, at the simulated time of that step; in an asynchronous one the step the
    /// framework published last (a commit there answers no step).
    fn commit_stamp(&self) -> Stamp {
        if self.seg.info.flags.synchronous {
            Stamp { step: self.locked_step, sim_time: self.read_sim }
        } else {
            self.seg.stamp(Role::Publish, MAX_READ_TRIES).unwrap_or_default()
        }
    }

    /// Takes the lock of SUBSCRIBE writers (one commit at a time; a holder that dies is
    /// cleared by the framework), waiting at most the timeout. The lock is released when
    /// the guard drops, also when a closure of the caller's panics meanwhile (the slot it was
    /// filling is not current and its sequence number tells the next writer so).
    fn lock_writers(&self) -> Result<WriterLock<'_>, ShmError> {
        let h = self.seg.header();
        let deadline = Instant::now() + self.opts.timeout;
        let mut turns = 0u32;
        while h.writer_lock.compare_exchange(0, self.id, Ordering::AcqRel, Ordering::Relaxed).is_err() {
            turns += 1;
            if turns % 64 == 0 {
                if Instant::now() >= deadline {
                    return Err(self.timeout("another writer's commit", self.opts.timeout));
                }
                self.check_alive()?;
                std::thread::yield_now();
            }
            std::hint::spin_loop();
        }
        Ok(WriterLock(&h.writer_lock))
    }

    /// Book-keeping of a commit that has reached the segment: counters, the seed, and in a
    /// synchronous domain the acknowledgement of the locked step `k`.
    fn committed(seg: &Segment, slot: usize, k: u64) {
        let h = seg.header();
        h.sets[Role::Subscribe as usize].commits.fetch_add(1, Ordering::Relaxed);
        // Written once: a store on every commit would take the line from its readers.
        if h.seeded.load(Ordering::Relaxed) == 0 {
            h.seeded.store(1, Ordering::Release);
        }
        if let Some(c) = seg.conn(slot) {
            c.commits.fetch_add(1, Ordering::Relaxed);
        }
        if seg.info.flags.synchronous {
            if let Some(conn) = seg.conn_ctl(slot) {
                seg.step_ctl().ack_commit(&conn, k);
            }
            segment::wake(&h.ack_seq, &h.ack_waiters);
        }
    }

    /// After a commit: nothing staged any more, and the step answered.
    fn reset_after_commit(&mut self) {
        self.marked.iter_mut().for_each(|m| *m = false);
        if self.seg.info.flags.synchronous {
            self.last_commit = self.locked_step;
        }
    }
}

/// The SUBSCRIBE writers' lock, held until dropped.
struct WriterLock<'a>(&'a AtomicU64);

impl Drop for WriterLock<'_> {
    fn drop(&mut self) {
        self.0.store(0, Ordering::Release);
    }
}
