//! The framework role: creates the domains of a model, publishes the PUBLISH set, steps
//! synchronous domains in lock-step, reads the SUBSCRIBE set, and notices dead participants.

use std::time::{Duration, Instant};

use super::bucket::Stamp;
use super::handshake::{
    item_bit, load_mask, reads_any, CONN_EVENT, CONN_SYNC_READER, CONN_WAKE, CONN_WRITER, MASK_WORDS,
};
use super::segment::{
    self, namespace_from_env, DomainInfo, DomainStatus, Segment, WaitMode, Waited, Waiter, STATE_STOPPED,
};
use super::state::{self, StateAnswer, StateConnection, StateRequest};
use super::{os, ShmError};
use crate::ddf::{Model, Role};
use crate::sync::Ordering;

/// How the framework creates and steps its domains.
#[derive(Debug, Clone)]
pub struct FrameworkOptions {
    /// Namespace of the segments (default: `TUTTI_NAMESPACE`, else `tutti`).
    pub namespace: String,
    /// Longest wait for participants in one synchronous step, and for the seed.
    pub timeout: Duration,
    /// How the framework waits for participants.
    pub wait: WaitMode,
    /// Connection slots per domain.
    pub connections: u32,
    /// Permission bits of the segments (default 0600: the creating user only).
    pub mode: u32,
    /// Start with wait-to-go held: participants block in connect until `release`.
    pub hold: bool,
    /// How often dead participants are looked for.
    pub sweep_every: Duration,
}

impl Default for FrameworkOptions {
    fn default() -> Self {
        FrameworkOptions {
            namespace: namespace_from_env(),
            timeout: crate::defaults::STEP_TIMEOUT,
            wait: WaitMode::adaptive(),
            connections: segment::DEFAULT_CONNECTIONS,
            mode: 0o600,
            hold: false,
            sweep_every: Duration::from_millis(10),
        }
    }
}

/// The framework of a whole model: one [`DomainHost`] per domain.
#[derive(Debug)]
pub struct Framework {
    pub domains: Vec<DomainHost>,
}

impl Framework {
    /// Creates every domain of `model`. On error nothing is left behind.
    pub fn create(model: &Model, opts: &FrameworkOptions) -> Result<Framework, ShmError> {
        let mut domains = Vec::with_capacity(model.domains.len());
        for d in &model.domains {
            let seg = Segment::create(&opts.namespace, d, opts.connections, opts.mode, opts.hold)?;
            domains.push(DomainHost::new(seg, opts.clone()));
        }
        Ok(Framework { domains })
    }

    /// Waits, under one deadline (the timeout), for the seed of every synchronous domain
    /// with `states=yes`, so that a host of many domains does not wait for them one after
    /// the other in their first steps. Returns how many are still unseeded.
    pub fn wait_for_seeds(&mut self) -> usize {
        let pending = |d: &DomainHost| {
            let f = d.info().flags;
            f.synchronous && f.states && !d.seed_waited && !d.seeded()
        };
        let deadline = self.domains.first().map(|d| Instant::now() + d.opts.timeout);
        while let Some(deadline) = deadline {
            if !self.domains.iter().any(pending) || Instant::now() >= deadline {
                break;
            }
            for d in &mut self.domains {
                d.maybe_sweep();
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        let unseeded = self.domains.iter().filter(|d| pending(d)).count();
        for d in &mut self.domains {
            if pending(d) {
                d.seg.header().timeouts.fetch_add(1, Ordering::Relaxed);
            }
            d.seed_waited = true;
        }
        unseeded
    }

    pub fn domain(&mut self, name: &str) -> Option<&mut DomainHost> {
        self.domains.iter_mut().find(|d| d.info().name == name)
    }

    /// Asks connections of every domain at once to save or restore their state (docs/run.md,
    /// "Checkpoints") and collects their answers, waiting at most `timeout`: `asked[d]` lists
    /// domain `d`'s connections, each with the bytes to take back for a restore. Call it at a
    /// step boundary. The answers come in the same order.
    pub fn exchange_states(
        &self,
        kind: StateRequest,
        asked: &[Vec<(&StateConnection, &[u8])>],
        timeout: Duration,
    ) -> Result<Vec<Vec<StateAnswer>>, ShmError> {
        let deadline = Instant::now() + timeout;
        let mut requests = Vec::new();
        for (d, conns) in self.domains.iter().zip(asked) {
            if conns.is_empty() {
                requests.push((&d.seg, 0, Vec::new()));
                continue;
            }
            let files: Vec<(usize, &[u8])> = conns.iter().map(|(c, b)| (c.slot, *b)).collect();
            let seq = d.seg.request_state(kind, &files)?;
            requests.push((&d.seg, seq, conns.iter().map(|(c, _)| (c.slot, c.pid)).collect()));
        }
        Ok(state::collect_answers(&requests, kind, deadline))
    }
}

/// What one step did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepReport {
    /// The step number published (1, 2, …).
    pub step: u64,
    /// Connections that owed a read or a commit when the timeout expired (synchronous only).
    pub timed_out: usize,
    /// Dead connections removed during the step.
    pub removed: usize,
}

/// The framework side of one domain.
#[derive(Debug)]
pub struct DomainHost {
    seg: Segment,
    opts: FrameworkOptions,
    step: u64,
    subscribe: Vec<u8>,
    last_sweep: Instant,
    /// The connections the last timed-out step waited for (see `timed_out_on`).
    waited_for: Vec<String>,
    seed_waited: bool,
    /// The PUBLISH set of the last step (event-driven domains: to tell a changed step).
    last_publish: Option<Vec<u8>>,
}

impl DomainHost {
    fn new(seg: Segment, opts: FrameworkOptions) -> Self {
        let subscribe = seg.info.subscribe.default_bytes();
        DomainHost {
            seg,
            opts,
            step: 0,
            subscribe,
            last_sweep: Instant::now(),
            seed_waited: false,
            waited_for: Vec::new(),
            last_publish: None,
        }
    }

    pub fn info(&self) -> &DomainInfo {
        &self.seg.info
    }

    pub fn segment(&self) -> &Segment {
        &self.seg
    }

    /// The last step published.
    pub fn current_step(&self) -> u64 {
        self.step
    }

    /// The SUBSCRIBE set as read by the last step (defaults until an external writer seeds).
    pub fn subscribe(&self) -> &[u8] {
        &self.subscribe
    }

    /// Whether an external writer has published at least once.
    pub fn seeded(&self) -> bool {
        self.seg.seeded()
    }

    pub fn connection_count(&self) -> u32 {
        self.seg.connection_count()
    }

    /// The participants' connections now, as a checkpoint sees them.
    pub fn state_connections(&self) -> Vec<StateConnection> {
        self.seg.state_connections()
    }

    /// The lookahead (steps) of a remote writer joined to this domain across a link to
    /// another site, if one is (docs/run.md, "Sites and lookahead").
    pub fn lookahead(&self) -> Option<u64> {
        (0..self.seg.scan_len())
            .filter_map(|i| self.seg.conn(i))
            .filter(|c| c.active.load(Ordering::Acquire) != 0)
            .map(|c| c.link[0].load(Ordering::Relaxed))
            .find(|&k| k > 0)
    }

    /// Event-driven: connection `slot` is next due from index `index` (a checkpoint's).
    pub fn set_due_index(&self, slot: usize, index: u64) {
        if let Some(conn) = self.seg.conn_ctl(slot) {
            conn.due_index.store(index, Ordering::Release);
        }
    }

    /// The PUBLISH set of the last step (event-driven domains keep it to tell what changed).
    pub fn last_publish(&self) -> Option<&[u8]> {
        self.last_publish.as_deref()
    }

    /// Puts back the sets of a checkpoint at a step boundary: the SUBSCRIBE set (written into
    /// the segment as the framework's own commit, so that participants and the next step read
    /// it), the PUBLISH set of the last step (what an event-driven domain compares the next
    /// with) and whether the domain was seeded.
    pub fn restore_sets(
        &mut self,
        subscribe: &[u8],
        last_publish: Option<&[u8]>,
        seeded: bool,
    ) -> Result<(), ShmError> {
        self.check_size(Role::Subscribe, subscribe.len())?;
        let info = &self.seg.info;
        let sim_time = self.seg.sim_time();
        self.seg.bucket(Role::Subscribe).write(subscribe, Stamp { step: self.step, sim_time });
        self.subscribe.copy_from_slice(subscribe);
        self.last_publish = last_publish.filter(|p| p.len() == info.publish.size as usize).map(<[u8]>::to_vec);
        self.seg.header().seeded.store(u32::from(seeded), Ordering::Release);
        self.seed_waited = true;
        Ok(())
    }

    pub fn status(&self) -> DomainStatus {
        self.seg.status()
    }

    /// One step: publish `publish` (the whole PUBLISH set) as step `current_step() + 1`; in
    /// a synchronous domain wait (at most the timeout) until every participant has read it
    /// and every writer has committed for it; then read the SUBSCRIBE set. In a synchronous
    /// domain with `states=yes` the first step first waits for the seed.
    pub fn step(&mut self, publish: &[u8], sim_time: f64) -> Result<StepReport, ShmError> {
        let removed = self.publish_step(publish, sim_time)?;
        let mut report = self.complete_step()?;
        report.removed += removed;
        Ok(report)
    }

    /// First half of [`step`](Self::step): publish the next step (after the seed, if one is
    /// due). A host with many domains publishes to all, then completes all, so that their
    /// participants work in parallel. Returns how many dead connections were removed.
    pub fn publish_step(&mut self, publish: &[u8], sim_time: f64) -> Result<usize, ShmError> {
        self.seg.intact()?;
        self.check_size(Role::Publish, publish.len())?;
        let info = &self.seg.info;
        let (sync, states) = (info.flags.synchronous, info.flags.states);
        let mut removed = self.maybe_sweep();
        if sync && states && !self.seed_waited {
            self.seed_waited = true;
            let (waited, r) = self.wait_acks(Segment::seeded)?;
            removed += r;
            if waited == Waited::TimedOut {
                self.seg.header().timeouts.fetch_add(1, Ordering::Relaxed);
            }
        }
        let changed = self.note_publish(publish);
        let h = self.seg.header();
        let k = self.step + 1;
        self.seg.bucket(Role::Publish).write(publish, Stamp { step: k, sim_time });
        h.sim_time_bits.store(sim_time.to_bits(), Ordering::Relaxed);
        h.heartbeat_ns.store(os::now_ns(), Ordering::Relaxed);
        h.steps.fetch_add(1, Ordering::Relaxed);
        self.seg.step_ctl().publish(k, self.index_of(sim_time, k), &changed);
        self.step = k;
        if self.seg.info.flags.event {
            // Tells the event-driven participants due at `k`, woken below.
            tell_due(&self.seg, k);
        }
        segment::wake(&h.step_seq, &h.step_waiters);
        Ok(removed)
    }

    /// Whether `got` bytes are a whole set `role` of this domain.
    fn check_size(&self, role: Role, got: usize) -> Result<(), ShmError> {
        let info = &self.seg.info;
        let expected = info.set(role).size as usize;
        if got == expected {
            return Ok(());
        }
        Err(ShmError::SizeMismatch { domain: info.name.clone(), role, expected, got })
    }

    /// Event-driven domains: the items of `publish` that differ from the last step's PUBLISH
    /// set (every item at the first step), a bit per item ([`item_bit`]); `publish` is kept
    /// for the next step.
    fn note_publish(&mut self, publish: &[u8]) -> [u64; MASK_WORDS] {
        if !self.seg.info.flags.event {
            return [0; MASK_WORDS];
        }
        let changed = self.changed_items(publish);
        match &mut self.last_publish {
            Some(last) => last.copy_from_slice(publish),
            None => self.last_publish = Some(publish.to_vec()),
        }
        changed
    }

    /// The items of `publish` that differ from the last step's PUBLISH set ([`item_bit`]).
    fn changed_items(&self, publish: &[u8]) -> [u64; MASK_WORDS] {
        let mut mask = [0; MASK_WORDS];
        let last = self.last_publish.as_deref();
        if last == Some(publish) {
            return mask;
        }
        for (i, leaf) in self.seg.info.publish.leaves.iter().enumerate() {
            let r = leaf.range();
            if last.map_or(true, |last| last.get(r.clone()) != publish.get(r)) {
                let (w, bit) = item_bit(i);
                mask[w] |= bit;
            }
        }
        mask
    }

    /// The index of a step at simulated time `sim_time`: its time over the step the
    /// framework said ([`set_sim_step`](Self::set_sim_step)), else the step number `k`.
    fn index_of(&self, sim_time: f64, k: u64) -> u64 {
        match self.seg.sim_step() {
            Some(dt) if sim_time.is_finite() && sim_time >= 0.0 => (sim_time / dt).round() as u64,
            _ => k,
        }
    }

    /// Event-driven domains: how many steps from index `next` (the next step's simulated
    /// time over the step) nobody would be due at if they were published with `publish`, so
    /// that a framework not paced by the wall clock may leave them out and make the step of
    /// index `next + n` next. 0 when someone is due at the next step (always in a lock-step
    /// domain with participants), `None` when nobody will be due unless an input changes
    /// (the framework then steps as usual).
    pub fn idle_steps(&self, publish: &[u8], next: u64) -> Option<u64> {
        let k = self.step + 1;
        let seg = &self.seg;
        if !seg.info.flags.synchronous {
            return None;
        }
        let ctl = seg.step_ctl();
        if ctl.all_due_step.load(Ordering::Acquire) == k {
            return Some(0);
        }
        let changed = self.changed_items(publish);
        let mut first: Option<u64> = None;
        for i in 0..seg.scan_len() {
            let Some(conn) = seg.conn_ctl(i) else { break };
            let flags = conn.flags.load(Ordering::Acquire);
            // Only connections that take part and read in lock-step or write.
            if !conn.takes_part(k) || flags & (CONN_SYNC_READER | CONN_WRITER) == 0 {
                continue;
            }
            let woken = reads_any(&load_mask(conn.read_items), &changed);
            if flags & CONN_EVENT == 0 || (flags & CONN_WAKE != 0 && woken) {
                return Some(0);
            }
            let due = conn.due_index.load(Ordering::Acquire).max(next);
            first = Some(first.map_or(due, |n| n.min(due)));
        }
        first.filter(|&due| due != u64::MAX).map(|due| due - next)
    }

    /// Event-driven domains: every participant is due at the next step (after a reset of
    /// simulated time, so that each says anew when it is next due).
    pub fn all_due_next(&self) {
        self.seg.header().all_due_step.store(self.step + 1, Ordering::Release);
    }

    /// Sets the domain's simulated time back to `sim_time` (seconds) between two steps: the
    /// run was reset or restored. Readers of [`Segment::time_resets`] see it at once.
    pub fn reset_time(&self, sim_time: f64) {
        let h = self.seg.header();
        h.sim_time_bits.store(sim_time.to_bits(), Ordering::Release);
        h.time_resets.fetch_add(1, Ordering::AcqRel);
    }

    /// Says the simulated time of one step (seconds): the steps' indexes are their simulated
    /// times over it, and an event-driven participant turns a time it asks for into a step
    /// with it.
    pub fn set_sim_step(&self, seconds: f64) {
        self.seg.header().sim_step_bits.store(seconds.to_bits(), Ordering::Release);
    }

    /// Second half of [`step`](Self::step): in a synchronous domain wait for the
    /// participants of the published step; then read the SUBSCRIBE set.
    pub fn complete_step(&mut self) -> Result<StepReport, ShmError> {
        let report = self.await_step()?;
        self.read_subscribe()?;
        Ok(report)
    }

    /// [`complete_step`](Self::complete_step) without reading the SUBSCRIBE set, for a
    /// framework that wants a few items of a large set: it reads them with
    /// [`read_subscribe_at`](Self::read_subscribe_at).
    pub fn await_step(&mut self) -> Result<StepReport, ShmError> {
        let k = self.step;
        let mut timed_out = 0;
        let mut removed = 0;
        if self.seg.info.flags.synchronous {
            let event = self.seg.info.flags.event;
            let (waited, r) = self.wait_acks(move |seg| {
                // A participant may have become event-driven, or joined, since the publish.
                if event {
                    tell_due(seg, k);
                }
                let step = seg.step_ctl();
                !(0..seg.scan_len()).any(|i| seg.conn_ctl(i).is_some_and(|c| c.owes(&step, k)))
            })?;
            removed += r;
            if waited == Waited::TimedOut {
                self.waited_for.clear();
                let step = self.seg.step_ctl();
                for i in 0..self.seg.scan_len() {
                    if let (Some(ctl), Some(slot)) = (self.seg.conn_ctl(i), self.seg.conn(i)) {
                        if ctl.owes(&step, k) {
                            slot.missed.fetch_add(1, Ordering::Relaxed);
                            timed_out += 1;
                            self.waited_for.push(self.seg.describe_conn(i));
                        }
                    }
                }
                self.seg.header().timeouts.fetch_add(1, Ordering::Relaxed);
            }
        }
        self.seg.intact()?;
        Ok(StepReport { step: k, timed_out, removed })
    }

    /// The connections the last step that timed out waited for, as `'NAME' (pid N)`
    /// (`, a DDS writer` for one standing for DDS), so that a host can say who held it up.
    pub fn timed_out_on(&self) -> &[String] {
        &self.waited_for
    }

    /// Reads the latest SUBSCRIBE set without stepping (asynchronous domains, or between steps).
    pub fn read_subscribe(&mut self) -> Result<&[u8], ShmError> {
        self.seg.read_set(Role::Subscribe, &mut self.subscribe)?;
        Ok(&self.subscribe)
    }

    /// Reads `out.len()` bytes of the latest SUBSCRIBE set from byte `offset` (one item, say,
    /// without copying a large set), consistently; returns the set's generation. The buffer
    /// of [`subscribe`](Self::subscribe) is left as it was.
    pub fn read_subscribe_at(&self, offset: usize, out: &mut [u8]) -> Result<u64, ShmError> {
        let size = self.seg.info.subscribe.size as usize;
        let end = offset.saturating_add(out.len());
        if end > size {
            return Err(ShmError::OutOfRange {
                domain: self.seg.info.name.clone(),
                role: Role::Subscribe,
                offset,
                end,
                size,
            });
        }
        self.seg.read_set_at(Role::Subscribe, offset, out)
    }

    /// Waits until `done` holds, sweeping dead connections meanwhile; gives up at the timeout.
    fn wait_acks(&mut self, done: impl Fn(&Segment) -> bool) -> Result<(Waited, usize), ShmError> {
        let h = self.seg.header();
        let waiter = Waiter {
            mode: self.opts.wait,
            futex: &h.ack_seq,
            waiters: &h.ack_waiters,
            check_every: self.opts.sweep_every.min(Duration::from_millis(2)),
        };
        let deadline = Instant::now() + self.opts.timeout;
        let mut removed = 0;
        let seg = &self.seg;
        let waited = waiter.wait::<ShmError>(
            deadline,
            || Ok(done(seg)),
            || {
                removed += sweep(seg);
                Ok(())
            },
        )?;
        if removed > 0 {
            self.last_sweep = Instant::now();
        }
        Ok((waited, removed))
    }

    fn maybe_sweep(&mut self) -> usize {
        if self.last_sweep.elapsed() >= self.opts.sweep_every {
            self.last_sweep = Instant::now();
            sweep(&self.seg)
        } else {
            0
        }
    }

    /// Removes the connections of dead processes now; returns how many.
    pub fn sweep(&mut self) -> usize {
        self.last_sweep = Instant::now();
        sweep(&self.seg)
    }

    /// Removes connection slot `slot` as the framework removes a connection it judges dead,
    /// whether or not its process lives: the participant's next call fails with
    /// [`ShmError::ConnectionLost`]. Returns whether a connection was removed.
    pub fn remove_connection(&self, slot: usize) -> bool {
        let pid = self.seg.conn(slot).map_or(0, |c| c.active.load(Ordering::Acquire));
        self.seg.release_slot(slot, pid)
    }

    /// Holds (`true`) or releases (`false`) the wait-to-go signal.
    /// Pauses or resumes the domain between two steps: while paused, a participant waiting
    /// for the next step waits as long as the pause lasts, without a timeout, and gets a
    /// whole timeout from the resume on.
    pub fn set_paused(&self, paused: bool) {
        let h = self.seg.header();
        if !paused {
            h.resumed_ns.store(os::now_ns(), Ordering::Release);
        }
        h.paused.store(if paused { segment::PAUSED } else { 0 }, Ordering::Release);
    }

    pub fn set_hold(&self, hold: bool) {
        let h = self.seg.header();
        if !hold {
            // Every connection held so far takes part from the next step, whenever its
            // process gets round to running again after the release.
            let k = self.step;
            for i in 0..self.seg.scan_len() {
                let Some(c) = self.seg.conn(i) else { break };
                if c.active.load(Ordering::Acquire) != 0 && c.first_step.load(Ordering::Acquire) == u64::MAX {
                    c.last_read.store(k, Ordering::Relaxed);
                    c.last_commit.store(k, Ordering::Relaxed);
                    c.answered.store(k, Ordering::Relaxed);
                    let _ = c.first_step.compare_exchange(u64::MAX, k + 1, Ordering::AcqRel, Ordering::Acquire);
                }
            }
        }
        h.hold.store(u32::from(hold), Ordering::Release);
        if !hold {
            os::futex_wake_all(&h.hold);
        }
    }

    /// Waits until at least `n` connections have declared themselves writers, or the
    /// timeout. Returns the number of writers seen.
    pub fn wait_for_writers(&mut self, n: usize, timeout: Duration) -> Result<usize, ShmError> {
        let deadline = Instant::now() + timeout;
        loop {
            self.sweep();
            let writers = (0..self.seg.scan_len())
                .filter_map(|i| self.seg.conn(i))
                .filter(|c| c.active.load(Ordering::Acquire) != 0 && c.flags.load(Ordering::Acquire) & CONN_WRITER != 0)
                .count();
            if writers >= n || Instant::now() >= deadline {
                return Ok(writers);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Publishes the step period, so that participants know the step they are answering
    /// (an FMU's `doStep` size) from the first step on; call before the first
    /// [`publish_step`](Self::publish_step). [`record_timing`](Self::record_timing) keeps it
    /// up to date afterwards.
    pub fn set_period(&self, period: Duration) {
        self.seg.header().period_ns.store(period.as_nanos() as u64, Ordering::Relaxed);
    }

    /// Records timing of the real-time loop, shown by `tutti status`.
    pub fn record_timing(&self, period: Duration, late: Duration, overrun: bool) {
        let h = self.seg.header();
        h.period_ns.store(period.as_nanos() as u64, Ordering::Relaxed);
        let late = late.as_nanos() as u64;
        h.last_late_ns.store(late, Ordering::Relaxed);
        h.max_late_ns.fetch_max(late, Ordering::Relaxed);
        if overrun {
            h.overruns.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Event-driven domains, at step `k`: tells every connection due at `k` that has not been
/// told (`StepCtl::mark_due`), and wakes it; the others sleep on.
fn tell_due(seg: &Segment, k: u64) {
    let step = seg.step_ctl();
    for i in 0..seg.scan_len() {
        if let (Some(ctl), Some(slot)) = (seg.conn_ctl(i), seg.conn(i)) {
            if step.mark_due(&ctl, k) {
                segment::wake(&slot.due_seq, &slot.due_waiters);
            }
        }
    }
}

/// Removes every connection whose process is gone; returns how many.
fn sweep(seg: &Segment) -> usize {
    let mut removed = 0;
    for i in 0..seg.scan_len() {
        let Some(c) = seg.conn(i) else { break };
        if seg.release_if_dead(i, c.active.load(Ordering::Acquire)) {
            removed += 1;
        }
    }
    removed
}

impl Drop for DomainHost {
    fn drop(&mut self) {
        let h = self.seg.header();
        h.state.store(STATE_STOPPED, Ordering::Release);
        h.step_seq.fetch_add(1, Ordering::Release);
        h.ack_seq.fetch_add(1, Ordering::Release);
        h.hold.store(0, Ordering::Release);
        os::futex_wake_all(&h.step_seq);
        os::futex_wake_all(&h.ack_seq);
        os::futex_wake_all(&h.hold);
        // Event-driven connections wait on words of their own.
        for i in 0..self.seg.scan_len() {
            if let Some(c) = self.seg.conn(i) {
                c.due_seq.fetch_add(1, Ordering::Release);
                os::futex_wake_all(&c.due_seq);
            }
        }
        let _ = os::shm_unlink(&self.seg.shm_name);
    }
}
