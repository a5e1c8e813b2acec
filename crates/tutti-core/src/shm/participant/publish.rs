//! Locking a step to answer: the right to write the SUBSCRIBE set (exclusive where the
//! domain allows one writer), and in a synchronous domain the step the next commit answers.

use super::gate::{GateFor, StepGate};
use super::Participant;
use crate::shm::handshake::CONN_WRITER;
use crate::shm::segment::{self, Segment};
use crate::shm::ShmError;
use crate::sync::Ordering;

impl Participant {
    /// As [`read_gate`](Self::read_gate), for [`publish_lock`](Self::publish_lock): a gate
    /// when it would wait for a step to answer (a synchronous domain, a connection that
    /// does not read).
    pub fn publish_gate(&mut self) -> Result<Option<StepGate>, ShmError> {
        if !self.seg.info.flags.synchronous || self.has_read {
            return Ok(None);
        }
        self.check()?;
        // A writer before it waits, as in `publish_lock`: a framework waiting for writers
        // (`tutti host --wait-for`) counts it, and steps.
        self.claim_writer()?;
        if self.event_driven() && !self.due.answer_on_commit {
            let answered = self.ask_next();
            return Ok(Some(self.gate(GateFor::DueAfter(answered))));
        }
        let states = self.seg.info.flags.states;
        Ok(Some(self.gate(GateFor::PublishAfter { last: self.last_commit, states })))
    }

    /// The step the framework is waiting for this connection to answer, if it is: a
    /// synchronous writer that has not committed for the latest step. Lets the gateway
    /// notice a DDS writer that went silent while the domain waits for it.
    pub fn owed_step(&self) -> Option<u64> {
        let seg = &self.seg;
        let k = seg.step();
        seg.conn_ctl(self.slot).filter(|c| c.owes(&seg.step_ctl(), k)).map(|_| k)
    }

    /// Whether [`Participant::publish_lock`] would return at once, without waiting for a
    /// step: always in an asynchronous domain; in a synchronous one when the framework has
    /// published a step this connection has not answered yet (or awaits a seed). Lets a
    /// caller that must not block (a DDS receive thread) commit in place when it can.
    pub fn publish_ready(&self) -> bool {
        let seg = &self.seg;
        if !seg.info.flags.synchronous || (self.has_read && self.last_read > self.last_commit) {
            return true;
        }
        let h = seg.header();
        let k = h.pub_step.load(Ordering::Acquire);
        k > self.last_commit || (seg.info.flags.states && k == 0 && h.seeded.load(Ordering::Acquire) == 0)
    }

    /// Starts a SUBSCRIBE write: declares this connection a writer, claims exclusive
    /// ownership where the domain allows one writer, and in a synchronous domain waits for
    /// the step this commit answers (the seed needs no step). Returns the step locked: in a
    /// synchronous domain the step the next commit answers (for a connection that reads and
    /// has answered what it read, its last answer: the commit answers no new step), in an
    /// asynchronous one the framework's latest step.
    pub fn publish_lock(&mut self) -> Result<u64, ShmError> {
        self.check()?;
        self.claim_writer()?;
        if self.due.answer_on_commit && self.event_driven() {
            self.join_on_change();
        }
        let seg = &self.seg;
        let h = seg.header();
        if seg.info.flags.synchronous {
            if self.has_read && self.last_read > self.last_commit {
                // Answer the step this connection read and has not answered yet.
                self.locked_step = self.last_read;
                return Ok(self.locked_step);
            }
            if self.has_read {
                // A connection that reads has answered the step it read (or given up its
                // answer, see `forfeit_owed_answer`): this commit updates the values at once
                // and answers no step. Waiting for the next step here would count it as read
                // for the reader, which would then skip it.
                self.locked_step = self.last_commit;
                return Ok(self.locked_step);
            }
            if self.event_driven() && !self.due.answer_on_commit {
                // An event-driven writer that does not read: this asks for its next due step.
                let answered = self.ask_next();
                self.waiting(GateFor::DueAfter(answered)).wait(&self.seg)?;
                let seg = &self.seg;
                let k = seg.conn(self.slot).map_or_else(|| seg.step(), |c| c.due_at.load(Ordering::Acquire));
                self.read_sim = seg.sim_time();
                self.read_index = seg.header().pub_index.load(Ordering::Acquire);
                self.locked_step = k;
                self.last_read = self.last_read.max(k);
                return Ok(k);
            }
            let states = seg.info.flags.states;
            self.waiting(GateFor::PublishAfter { last: self.last_commit, states }).wait(seg)?;
            let k = h.pub_step.load(Ordering::Acquire);
            self.read_sim = seg.sim_time();
            self.read_index = h.pub_index.load(Ordering::Acquire);
            self.locked_step = k;
            // Waiting for step k counts as having seen it: a connection that writes before
            // it reads (or never reads) must not stall the framework for a read it never makes.
            if self.last_read < k {
                self.last_read = k;
                if let Some(conn) = seg.conn_ctl(self.slot) {
                    seg.step_ctl().ack_read(&conn, k);
                }
                segment::wake(&h.ack_seq, &h.ack_waiters);
            }
            return Ok(k);
        }
        Ok(seg.step())
    }

    pub(super) fn claim_writer(&self) -> Result<(), ShmError> {
        let seg = &self.seg;
        let h = seg.header();
        // The owner already (the usual case, on every commit): no write to the shared line.
        if !seg.info.flags.multiple_publish_allowed && h.owner_conn.load(Ordering::Acquire) != self.id {
            loop {
                match h.owner_conn.compare_exchange(0, self.id, Ordering::AcqRel, Ordering::Acquire) {
                    Ok(_) => break,
                    Err(owner) if owner == self.id => break,
                    Err(owner) => {
                        let slot = Segment::slot_of(owner);
                        let owner_pid = seg.conn(slot).map_or(0, |c| c.active.load(Ordering::Acquire));
                        // An owner being released right now: its ownership goes next.
                        if owner_pid == segment::RELEASING {
                            std::thread::yield_now();
                            continue;
                        }
                        // An owner that died is released here rather than after the
                        // framework's next sweep; then the claim is tried again.
                        if seg.release_if_dead(slot, owner_pid) {
                            continue;
                        }
                        if h.owner_conn.load(Ordering::Acquire) != owner {
                            continue;
                        }
                        h.rejected.fetch_add(1, Ordering::Relaxed);
                        return Err(ShmError::NotOwner { domain: seg.info.name.clone(), owner_pid });
                    }
                }
            }
        }
        // Flagged a writer only once allowed to write: a refused writer must not make the
        // framework wait for commits that will never come.
        self.set_flag(CONN_WRITER);
        Ok(())
    }
}
