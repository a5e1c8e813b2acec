//! Reading the PUBLISH set: a snapshot of it into the connection's own buffer, and in a
//! synchronous domain the wait for the next step and the acknowledgement of its read.

use super::gate::{GateFor, StepGate};
use super::Participant;
use crate::ddf::Role;
use crate::shm::handshake::{CONN_SYNC_READER, CONN_WRITER};
use crate::shm::segment;
use crate::shm::ShmError;
use crate::sync::Ordering;

impl Participant {
    /// Takes a consistent snapshot of the PUBLISH set into this connection's own buffer. In
    /// a synchronous domain, waits for the next step (each step is read exactly once) and
    /// acknowledges it. Returns the step read (asynchronous: the framework's latest).
    pub fn subscribe_lock(&mut self) -> Result<u64, ShmError> {
        self.begin_read()?;
        let generation = self.seg.read_set(Role::Publish, &mut self.snapshot)?;
        let step = self.finish_read(generation);
        if self.seg.info.flags.synchronous {
            let h = self.seg.header();
            segment::wake(&h.ack_seq, &h.ack_waiters);
        }
        Ok(step)
    }

    /// The start of every read: the connection is checked and, in a synchronous domain,
    /// declared a lock-step reader and made to wait for the next step.
    pub(super) fn begin_read(&mut self) -> Result<(), ShmError> {
        self.check()?;
        // A step boundary: a state request that came meanwhile is answered first.
        self.serve_state();
        if self.seg.info.flags.synchronous {
            self.set_flag(CONN_SYNC_READER);
            if self.event_driven() {
                let answered = self.ask_next();
                self.waiting(GateFor::DueAfter(answered)).wait(&self.seg)?;
                return self.check();
            }
            self.forfeit_owed_answer();
            self.wait_next_step()?;
        }
        Ok(())
    }

    /// A writer that asks for the next step before it has answered the step it read (a
    /// client that reads in one thread and writes in another, each call under its own lock,
    /// as VILLASnode does) gives up its answer to that step: the framework goes on with the
    /// SUBSCRIBE values as they stand instead of waiting for an answer that cannot come while
    /// this read waits, and the connection's next commit answers the step it reads next. A
    /// client that reads, then writes, then reads (one thread) never gets here.
    fn forfeit_owed_answer(&mut self) {
        let k = self.last_read;
        if !self.has_read || k <= self.last_commit {
            return;
        }
        let seg = &self.seg;
        let writer = seg.conn(self.slot).is_some_and(|c| c.flags.load(Ordering::Acquire) & CONN_WRITER != 0);
        if !writer {
            return;
        }
        if let Some(conn) = seg.conn_ctl(self.slot) {
            seg.step_ctl().ack_commit(&conn, k);
        }
        let h = seg.header();
        segment::wake(&h.ack_seq, &h.ack_waiters);
        self.last_commit = k;
    }

    /// The end of every read of PUBLISH generation `generation`: returns the step read and,
    /// in a synchronous domain, acknowledges it (the caller wakes the framework).
    pub(super) fn finish_read(&mut self, generation: u64) -> u64 {
        let event = self.event_driven();
        let seg = &self.seg;
        // The PUBLISH generation counts the framework's publishes, i.e. its steps; an
        // event-driven connection reads the due step the framework stays at (it may have
        // left steps out).
        let step = if event {
            seg.conn(self.slot).map_or_else(|| seg.step(), |c| c.due_at.load(Ordering::Acquire))
        } else if seg.info.flags.synchronous {
            generation.max(self.last_read + 1)
        } else {
            generation
        };
        // The framework is still at that step: it waits for this connection's answer.
        self.read_sim = seg.sim_time();
        self.read_index = seg.header().pub_index.load(Ordering::Acquire);
        self.last_read = step;
        self.has_read = true;
        if let Some(c) = seg.conn(self.slot) {
            c.reads.fetch_add(1, Ordering::Relaxed);
        }
        if seg.info.flags.synchronous {
            if let Some(conn) = seg.conn_ctl(self.slot) {
                seg.step_ctl().ack_read(&conn, step);
            }
        }
        step
    }

    /// Synchronous domains: waits (at most the timeout) until the framework has published a
    /// step after the last one this connection read.
    fn wait_next_step(&self) -> Result<(), ShmError> {
        self.waiting(GateFor::ReadAfter(self.last_read)).wait(&self.seg)?;
        self.check()
    }

    /// The part of [`subscribe_lock`](Self::subscribe_lock) that waits, apart: in a
    /// synchronous domain, declares the connection a lock-step reader (giving up an answer it
    /// owes, as `subscribe_lock` does) and returns a [`StepGate`] that waits for the next
    /// step without borrowing the participant. A caller that serialises its calls with a
    /// lock (the RTAPI) waits on the gate with that lock released, then calls
    /// `subscribe_lock`, which finds the step there. `None`: `subscribe_lock` would not wait.
    pub fn read_gate(&mut self) -> Result<Option<StepGate>, ShmError> {
        if !self.seg.info.flags.synchronous {
            return Ok(None);
        }
        self.check()?;
        self.set_flag(CONN_SYNC_READER);
        if self.event_driven() {
            let answered = self.ask_next();
            return Ok(Some(self.gate(GateFor::DueAfter(answered))));
        }
        self.forfeit_owed_answer();
        Ok(Some(self.gate(GateFor::ReadAfter(self.last_read))))
    }

    /// The PUBLISH set as of the last `subscribe_lock`.
    pub fn snapshot(&self) -> &[u8] {
        &self.snapshot
    }

    /// Mutable access to the snapshot buffer (the RTAPI hands out pointers into it).
    pub fn snapshot_mut(&mut self) -> &mut [u8] {
        &mut self.snapshot
    }

    /// The bytes of PUBLISH item `index` (its index in the set) in the last snapshot.
    pub fn snapshot_item(&self, index: usize) -> Option<&[u8]> {
        self.seg.info.publish.leaves.get(index).map(|l| &self.snapshot[l.range()])
    }
}
