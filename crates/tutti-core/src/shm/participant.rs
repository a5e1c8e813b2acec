//! The external participant role: connect to a domain by name, snapshot the PUBLISH set,
//! stage and commit the SUBSCRIBE set. The RTAPI (C and Python) is a thin layer over this.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::bucket::{copy_words, store_bytes, store_range, with_bytes_mut, Stamp};
use super::handshake::{item_bit, CONN_EVENT, CONN_SYNC_READER, CONN_WAKE, CONN_WRITER, MASK_WORDS};
use super::segment::{
    self, namespace_from_env, ConnKind, DomainInfo, Segment, WaitMode, Waited, Waiter, MAX_READ_TRIES, STATE_RUNNING,
};
use super::{os, ShmError};
use crate::ddf::{Domain, Leaf, Role};
use crate::sync::{AtomicU64, Ordering};

/// How a participant connects and waits.
#[derive(Debug, Clone)]
pub struct ConnectOptions {
    /// Namespace of the segments (default: `TUTTI_NAMESPACE`, else `tutti`).
    pub namespace: String,
    /// Shown in `tutti status` (default: the program name).
    pub name: String,
    /// How long `connect` waits for the domain to appear and for wait-to-go.
    pub connect_timeout: Duration,
    /// How long a lock waits for the framework's next step.
    pub timeout: Duration,
    /// Spin, poll every N µs ("flag delay"), or block.
    pub wait: WaitMode,
    /// Do not wait for the framework's wait-to-go signal in `connect`.
    pub skip_wait_to_go: bool,
    /// What the connection stands for: a component (the default), a DDS writer (set by the
    /// gateway) or an observer, not counted as a participant (the gateway's lock-step reader
    /// with `--every-step`, which the framework still waits for once it reads).
    pub kind: ConnKind,
}

impl Default for ConnectOptions {
    fn default() -> Self {
        let name = std::env::args().next().map(|a| a.rsplit('/').next().unwrap_or(&a).to_string()).unwrap_or_default();
        ConnectOptions {
            namespace: namespace_from_env(),
            name,
            connect_timeout: Duration::from_secs(5),
            timeout: Duration::from_secs(5),
            wait: WaitMode::Block,
            skip_wait_to_go: false,
            kind: ConnKind::Participant,
        }
    }
}

/// A connection to one domain.
#[derive(Debug)]
pub struct Participant {
    seg: Arc<Segment>,
    slot: usize,
    id: u64,
    me: os::ProcessId,
    opts: ConnectOptions,
    /// Own copy of the PUBLISH set, refreshed by `subscribe_lock`.
    snapshot: Vec<u8>,
    /// SUBSCRIBE values being staged; committed by `commit`.
    staging: Vec<u8>,
    /// The SUBSCRIBE values as this connection last committed them (to find changes).
    shadow: Vec<u8>,
    /// Leaves staged explicitly (committed even when unchanged).
    marked: Vec<bool>,
    /// The byte ranges a commit writes, (offset, length): kept between commits so that a
    /// commit allocates nothing.
    changed: Vec<(usize, usize)>,
    last_read: u64,
    last_commit: u64,
    locked_step: u64,
    /// Whether the connection ever read (it then reads before it answers).
    has_read: bool,
    /// Staging and shadow are out of date after `commit_all_with`; the next use refreshes
    /// them from the SUBSCRIBE set (off the commit's path).
    stale_staging: bool,
    /// When the framework's process was last found alive (checked at most every 50 ms).
    framework_seen: std::cell::Cell<Instant>,
    /// The simulated time of the step last read, and its index (simulated time over step).
    read_sim: f64,
    read_index: u64,
    /// When this connection is due, in an event-driven domain (`docs/timing.md`).
    due: Due,
}

/// What an event-driven participant said about when it is due (`docs/timing.md`).
#[derive(Debug, Clone, Copy, Default)]
struct Due {
    /// It said something: it takes part only in the steps it is due at.
    said: bool,
    /// Due at the first step at or after this simulated time (once).
    request: Option<f64>,
    /// Due every this many steps (at steps whose simulated time is a multiple of it).
    period_steps: Option<u64>,
    /// Also due at any step whose PUBLISH set changed.
    wake: bool,
    /// Its commit answers the step (a DDS writer: it never asks for a step itself).
    answer_on_commit: bool,
    /// The PUBLISH items it reads ([`item_bit`]; none: all), for waking on change.
    reads: [u64; MASK_WORDS],
    /// The step it last answered by asking for its next, while nothing it said has changed
    /// since: asking again (the RTAPI's gate, then its lock) answers nothing new.
    asked: Option<u64>,
}

/// A time within this fraction of a step of a step's time counts as that step.
const STEP_TOLERANCE: f64 = 1e-6;

impl Participant {
    /// Connects to domain `domain`: waits (up to `connect_timeout`) for its framework, then
    /// for wait-to-go unless skipped.
    pub fn connect(domain: &str, opts: ConnectOptions) -> Result<Participant, ShmError> {
        let deadline = Instant::now() + opts.connect_timeout;
        let seg = loop {
            let err = match Segment::open(&opts.namespace, domain) {
                Ok(seg) if seg.framework_alive() => break seg,
                Ok(_) => ShmError::FrameworkStopped { domain: domain.to_string() },
                Err(e @ (ShmError::NoSuchDomain { .. } | ShmError::NotReady { .. })) => e,
                Err(e) => return Err(e),
            };
            if Instant::now() >= deadline {
                return Err(err);
            }
            std::thread::sleep(Duration::from_millis(5));
        };
        let me = os::current_process();
        let slot = seg.claim_slot(me, &opts.name, opts.kind)?;
        let id = seg.conn_id(slot);
        let (pub_size, sub_size) = (seg.info.publish.size as usize, seg.info.subscribe.size as usize);
        let mut p = Participant {
            snapshot: vec![0; pub_size],
            staging: vec![0; sub_size],
            shadow: vec![0; sub_size],
            marked: vec![false; seg.info.subscribe.leaves.len()],
            changed: Vec::with_capacity(seg.info.subscribe.leaves.len()),
            last_read: 0,
            last_commit: 0,
            locked_step: 0,
            has_read: false,
            // Start from the SUBSCRIBE values as they are: a commit changes only what we change.
            stale_staging: true,
            framework_seen: std::cell::Cell::new(Instant::now()),
            read_sim: 0.0,
            read_index: 0,
            due: Due::default(),
            seg: Arc::new(seg),
            slot,
            id,
            me,
            opts,
        };
        if let Some(c) = p.seg.conn(slot) {
            p.last_read = c.last_read.load(Ordering::Relaxed);
            p.last_commit = p.last_read;
        }
        p.refresh_staging()?;
        p.seg.read_set(Role::Publish, &mut p.snapshot)?;
        if !p.opts.skip_wait_to_go {
            p.wait_ready_to_go_until(deadline)?;
        }
        p.join_lock_step();
        Ok(p)
    }

    /// A connection claimed while the framework held wait-to-go (its first step deferred, see
    /// `Segment::claim_slot`) takes part in lock-step from the framework's next step on.
    fn join_lock_step(&mut self) {
        let Some(c) = self.seg.conn(self.slot) else { return };
        if c.first_step.load(Ordering::Acquire) == u64::MAX {
            let k = self.seg.step();
            c.last_read.store(k, Ordering::Relaxed);
            c.last_commit.store(k, Ordering::Relaxed);
            c.answered.store(k, Ordering::Relaxed);
            // The framework's release (`DomainHost::set_hold`) may set it first.
            let _ = c.first_step.compare_exchange(u64::MAX, k + 1, Ordering::AcqRel, Ordering::Acquire);
        }
        (self.last_read, self.last_commit) =
            (c.last_read.load(Ordering::Acquire), c.last_commit.load(Ordering::Acquire));
    }

    /// Connects and checks that `domain` (from a DDF) describes the running domain: the same
    /// flags and, in each set, the same items (paths, types, lengths). The items may be listed
    /// in another order (the product's tools do not agree on one): every access goes through
    /// the running domain's layout, by path or item key.
    pub fn connect_checked(domain: &Domain, opts: ConnectOptions) -> Result<Participant, ShmError> {
        let p = Participant::connect(&domain.name, opts)?;
        if p.seg.info.layout_hash != domain.layout_hash {
            if let Some(difference) = describe_difference(domain, &p.seg.info) {
                return Err(ShmError::LayoutMismatch {
                    domain: domain.name.clone(),
                    expected: domain.layout_hash,
                    found: p.seg.info.layout_hash,
                    difference,
                });
            }
        }
        Ok(p)
    }

    /// The domain as the segment describes it.
    pub fn info(&self) -> &DomainInfo {
        &self.seg.info
    }

    pub fn segment(&self) -> &Segment {
        &self.seg
    }

    pub fn set_wait_mode(&mut self, mode: WaitMode) {
        self.opts.wait = mode;
    }

    pub fn set_timeout(&mut self, timeout: Duration) {
        self.opts.timeout = timeout;
    }

    /// The longest wait of this connection (for a step, a commit's step, a lock): what
    /// [`set_timeout`](Self::set_timeout) set.
    pub fn wait_timeout(&self) -> Duration {
        self.opts.timeout
    }

    /// A pointer to the framework's state word (0 while it initialises, 1 running, 2
    /// stopped): the live status the RTAPI hands to C. Valid while this participant lives;
    /// another process writes it, so read it as `volatile`.
    pub fn state_word_ptr(&self) -> *mut u32 {
        self.seg.header().state.as_ptr()
    }

    /// Connections now in the domain (this one included).
    pub fn connection_count(&self) -> u32 {
        self.seg.connection_count()
    }

    /// The step of the last snapshot (0 before any), and the framework's simulated time.
    pub fn last_step(&self) -> u64 {
        self.last_read
    }

    /// The simulated time (seconds) of the framework's latest step.
    pub fn sim_time(&self) -> f64 {
        self.seg.sim_time()
    }

    /// The framework's step period, when it steps at a fixed rate (see [`Segment::period`]).
    pub fn period(&self) -> Option<Duration> {
        self.seg.period()
    }

    /// Whether the connection is still in place (the framework removes connections it
    /// judges dead) and the framework runs.
    pub fn check(&self) -> Result<(), ShmError> {
        // A framework killed outright cannot mark its segment stopped: look at its process
        // now and then (a /proc read costs microseconds; every call would be too many).
        let look = self.framework_seen.get().elapsed() >= Duration::from_millis(50);
        let r = self.waiting(GateFor::Nothing).check(&self.seg, look);
        if look && r.is_ok() {
            self.framework_seen.set(Instant::now());
        }
        r
    }

    /// [`check`](Self::check), looking at the framework's process every time (a wait's
    /// periodic check).
    fn check_alive(&self) -> Result<(), ShmError> {
        self.waiting(GateFor::Nothing).check(&self.seg, true)
    }

    fn timeout(&self, what: &'static str, after: Duration) -> ShmError {
        ShmError::Timeout { domain: self.seg.info.name.clone(), what, ms: after.as_millis() as u64 }
    }

    fn waiter(&self, futex: &'static str) -> Waiter<'_> {
        let h = self.seg.header();
        let (futex, waiters) = match futex {
            "hold" => (&h.hold, &h.go_waiters),
            _ => (&h.step_seq, &h.step_waiters),
        };
        Waiter { mode: self.opts.wait, futex, waiters, check_every: Duration::from_millis(20) }
    }

    /// Blocks while the framework holds its wait-to-go signal (at most the connect timeout).
    pub fn wait_ready_to_go(&self) -> Result<(), ShmError> {
        self.wait_ready_to_go_until(Instant::now() + self.opts.connect_timeout)
    }

    fn wait_ready_to_go_until(&self, deadline: Instant) -> Result<(), ShmError> {
        let h = self.seg.header();
        let w = self.waiter("hold");
        match w.wait(deadline, || Ok(h.hold.load(Ordering::Acquire) == 0), || self.check_alive())? {
            Waited::Ready => Ok(()),
            Waited::TimedOut => Err(self.timeout("wait-to-go", self.opts.connect_timeout)),
        }
    }

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
    fn begin_read(&mut self) -> Result<(), ShmError> {
        self.check()?;
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

    /// Whether this connection takes part only in the steps it is due at: it said when it
    /// is due, in an event-driven domain.
    fn event_driven(&self) -> bool {
        self.due.said && self.seg.info.flags.event
    }

    /// Event-driven: answers the step this connection is at (what it committed for it is in)
    /// and says when it is next due, from what it asked for during the step. Returns the
    /// step answered; the connection's next step is the first due one after it.
    fn ask_next(&mut self) -> u64 {
        let s = self.last_read.max(self.locked_step);
        if self.due.asked == Some(s) {
            return s;
        }
        self.due.asked = Some(s);
        let next = if self.has_read || self.locked_step > 0 { self.next_due_after() } else { 0 };
        self.due.request = None;
        self.answer_as(s, next);
        s
    }

    /// Event-driven: tells the framework that this connection has answered step `s` and is
    /// next due from step `next`, or before it where an item it reads changes if it wakes on
    /// change.
    fn answer_as(&self, s: u64, next: u64) {
        let seg = &self.seg;
        if let (Some(c), Some(conn)) = (seg.conn(self.slot), seg.conn_ctl(self.slot)) {
            seg.step_ctl().answer(&conn, s, next, &self.due.reads);
            // The kind of due-ness after the answer: the framework reads the flags first.
            if self.due.wake {
                c.flags.fetch_or(CONN_WAKE, Ordering::AcqRel);
            } else {
                c.flags.fetch_and(!CONN_WAKE, Ordering::AcqRel);
            }
            if c.flags.load(Ordering::Acquire) & CONN_EVENT == 0 {
                c.flags.fetch_or(CONN_EVENT, Ordering::AcqRel);
            }
        }
        let h = seg.header();
        segment::wake(&h.ack_seq, &h.ack_waiters);
    }

    /// A wake-on-change writer's first lock ([`Participant::wake_on_change_writer`]): from the
    /// step the framework is at on, it takes part as an event-driven connection, due where the
    /// PUBLISH set changed. The lock flags it a writer; until its first commit it would
    /// otherwise be a lock-step writer owing every step, and that commit may be long in coming:
    /// a DDS node's first sample can answer a step the framework has left (the gateway drops
    /// it, docs/gateway.md) and the node then sends nothing until the set changes again.
    fn join_on_change(&self) {
        let seg = &self.seg;
        if seg.conn(self.slot).is_some_and(|c| c.flags.load(Ordering::Acquire) & CONN_EVENT == 0) {
            let k = seg.header().pub_step.load(Ordering::Acquire);
            // Due at step k itself only if its set changed: the node answers that change.
            self.answer_as(k.saturating_sub(1), u64::MAX);
        }
    }

    /// The index of the first step after the one this connection is at (index `read_index`,
    /// simulated time `read_sim`) that it is due at: the step of the time it asked for, the
    /// next multiple of its period, whichever comes first; with neither, the next step unless
    /// it waits for changes only. Indexes count the framework's steps of simulated time, so
    /// they stay right when the framework leaves steps out.
    fn next_due_after(&self) -> u64 {
        let n = self.read_index;
        let step = self.seg.sim_step();
        let mut next = u64::MAX;
        if let Some(t) = self.due.request {
            let ahead = match step {
                Some(dt) => ((t - self.read_sim) / dt - STEP_TOLERANCE).ceil(),
                None => 1.0,
            };
            // At least the next step; far-off times saturate.
            next = next.min(n.saturating_add(if ahead >= 1.0 { ahead as u64 } else { 1 }));
        }
        if let Some(p) = self.due.period_steps {
            next = next.min((n / p).saturating_add(1).saturating_mul(p));
        }
        if next == u64::MAX && !self.due.wake {
            next = n + 1;
        }
        next
    }

    /// Asks to be due next at the first step at or after simulated time `t` (seconds): a
    /// time within a millionth of a step of a step's time counts as that step. Once: the
    /// request is used up at that step. Takes effect when this connection asks for its next
    /// step. In a domain that is not event-driven it changes nothing (the participant is due
    /// at every step there).
    pub fn request_time(&mut self, t: f64) -> Result<(), ShmError> {
        if !t.is_finite() {
            return Err(self.invalid_timing("a requested time", t, "not a finite number".into()));
        }
        self.due.said = true;
        self.due.asked = None;
        self.due.request = Some(self.due.request.map_or(t, |r| r.min(t)));
        Ok(())
    }

    /// Also due at any step whose PUBLISH set differs from the step before (`on`), or not.
    pub fn set_wake_on_change(&mut self, on: bool) {
        self.due.said = true;
        self.due.asked = None;
        self.due.wake = on;
    }

    /// Due every `seconds` of simulated time (a whole multiple of the framework's step), at
    /// the steps whose time is a multiple of it; 0 turns the period off.
    pub fn set_period(&mut self, seconds: f64) -> Result<(), ShmError> {
        self.due.asked = None;
        if seconds == 0.0 {
            self.due.said = true;
            self.due.period_steps = None;
            return Ok(());
        }
        if !seconds.is_finite() || seconds < 0.0 {
            return Err(self.invalid_timing("a period of", seconds, "must be a positive number of seconds".into()));
        }
        let Some(dt) = self.seg.sim_step() else {
            return Err(self.invalid_timing(
                "a period of",
                seconds,
                "the framework has not said its step yet (it says it when it creates the domain)".into(),
            ));
        };
        let n = seconds / dt;
        if n.round() < 1.0 || (n - n.round()).abs() > STEP_TOLERANCE * n.max(1.0) {
            return Err(self.invalid_timing(
                "a period of",
                seconds,
                format!("must be a whole multiple of the framework's step ({dt} s)"),
            ));
        }
        self.due.said = true;
        self.due.period_steps = Some(n.round() as u64);
        Ok(())
    }

    /// A DDS writer through the gateway, in an event-driven domain: due at the steps whose
    /// PUBLISH set changed, each answered by its commit (it never asks for a step itself).
    pub fn wake_on_change_writer(&mut self) {
        self.due = Due { said: true, wake: true, answer_on_commit: true, ..Due::default() };
    }

    /// Notes that this connection reads PUBLISH item `index` (its index in the set): woken on
    /// change, it is due where one of the items it reads changed (none noted: any item). The
    /// RTAPI notes the items of RTSubscribe and of RTGetBuffer.
    pub fn reads_item(&mut self, index: usize) {
        let (w, bit) = item_bit(index);
        if self.due.reads[w] & bit == 0 {
            self.due.reads[w] |= bit;
            self.due.asked = None;
        }
    }

    /// The simulated time of the step this connection is at (the one it read last; in an
    /// asynchronous domain the framework's latest).
    pub fn simulation_time(&self) -> f64 {
        if self.seg.info.flags.synchronous && (self.has_read || self.locked_step > 0) {
            self.read_sim
        } else {
            self.seg.sim_time()
        }
    }

    fn invalid_timing(&self, what: &'static str, value: f64, reason: String) -> ShmError {
        ShmError::InvalidTiming { domain: self.seg.info.name.clone(), what, value, reason }
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
    fn finish_read(&mut self, generation: u64) -> u64 {
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

    /// Sets a bit of this connection's flags (written only when missing: the framework
    /// polls the line they are on).
    fn set_flag(&self, bit: u32) {
        if let Some(c) = self.seg.conn(self.slot) {
            if c.flags.load(Ordering::Acquire) & bit == 0 {
                c.flags.fetch_or(bit, Ordering::AcqRel);
            }
        }
    }

    /// Synchronous domains: waits (at most the timeout) until the framework has published a
    /// step after the last one this connection read.
    fn wait_next_step(&self) -> Result<(), ShmError> {
        self.waiting(GateFor::ReadAfter(self.last_read)).wait(&self.seg)?;
        self.check()
    }

    /// This connection's wait for `until` (see [`Waiting`]).
    fn waiting(&self, until: GateFor) -> Waiting {
        Waiting {
            slot: self.slot,
            id: self.id,
            pid: self.me.pid,
            wait: self.opts.wait,
            timeout: self.opts.timeout,
            until,
        }
    }

    fn gate(&self, until: GateFor) -> StepGate {
        StepGate { seg: self.seg.clone(), waiting: self.waiting(until) }
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

    /// The PUBLISH set as of the last `subscribe_lock`.
    pub fn snapshot(&self) -> &[u8] {
        &self.snapshot
    }

    /// Mutable access to the snapshot buffer (the RTAPI hands out pointers into it).
    pub fn snapshot_mut(&mut self) -> &mut [u8] {
        &mut self.snapshot
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

    fn claim_writer(&self) -> Result<(), ShmError> {
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

    /// The bytes of PUBLISH item `index` (its index in the set) in the last snapshot.
    pub fn snapshot_item(&self, index: usize) -> Option<&[u8]> {
        self.seg.info.publish.leaves.get(index).map(|l| &self.snapshot[l.range()])
    }

    /// After [`commit_all_with`](Self::commit_all_with): staging and the record of the last
    /// commit become the SUBSCRIBE set as it is now (the values committed, unless another
    /// writer has changed some since, in which case those are the newer values, and the next
    /// commit leaves them alone as before).
    fn refresh_staging(&mut self) -> Result<(), ShmError> {
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

    /// An event-driven connection whose commit answers its step ([`Participant::wake_on_change_writer`]).
    fn answer_if_on_commit(&mut self) {
        if self.due.answer_on_commit && self.event_driven() {
            self.ask_next();
        }
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

    /// Leaves the domain: releases the slot, ownership and pending handshakes.
    pub fn disconnect(mut self) {
        self.release();
    }

    /// Releases the slot unless it is no longer this connection's (released already, or
    /// removed by the framework: either bumps the slot's generation, so the id differs).
    fn release(&mut self) {
        if self.seg.conn_id(self.slot) == self.id {
            self.seg.release_slot(self.slot, self.me.pid);
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

/// What a participant's wait waits for.
#[derive(Debug, Clone, Copy)]
enum GateFor {
    /// A step after this one (the connection's last read).
    ReadAfter(u64),
    /// A step to answer after the last commit (or the seed, with `states`).
    PublishAfter { last: u64, states: bool },
    /// Event-driven: a step after this one (the last answered) that the connection is due at.
    DueAfter(u64),
    /// Nothing: only the connection's checks (see [`Waiting::check`]).
    Nothing,
}

/// A connection's wait for the framework, by value: the participant waits with it on its
/// own segment, a [`StepGate`] on a segment it shares, with no borrow of the participant.
#[derive(Debug, Clone, Copy)]
struct Waiting {
    slot: usize,
    id: u64,
    pid: u32,
    wait: WaitMode,
    timeout: Duration,
    until: GateFor,
}

impl Waiting {
    /// Whether the connection is still in place and its framework runs (looking at the
    /// framework's process too with `look_at_process`). A segment shrunk under us reads as
    /// zeros (a stopped framework, a lost connection): that is said instead.
    fn check(&self, seg: &Segment, look_at_process: bool) -> Result<(), ShmError> {
        let domain = || seg.info.name.clone();
        let r = if seg.header().state.load(Ordering::Acquire) != STATE_RUNNING {
            Err(ShmError::FrameworkStopped { domain: domain() })
        } else {
            match seg.conn(self.slot) {
                Some(c) if c.active.load(Ordering::Acquire) == self.pid && seg.conn_id(self.slot) == self.id => {
                    if look_at_process && !os::is_alive(seg.framework_id()) {
                        Err(ShmError::FrameworkStopped { domain: domain() })
                    } else {
                        Ok(())
                    }
                }
                _ => Err(ShmError::ConnectionLost { domain: domain() }),
            }
        };
        if r.is_err() {
            seg.intact_checked()?;
        }
        seg.intact()?;
        r
    }

    /// Waits until `until`, at most the timeout, except that a paused framework costs no
    /// timeout (the wait goes on for as long as the pause lasts, and a whole timeout after
    /// it); the connection is checked now and then, and ends the wait with its error.
    fn wait(&self, seg: &Segment) -> Result<(), ShmError> {
        let h = seg.header();
        let ctl = seg.step_ctl();
        let until = self.until;
        let mut ready = move || {
            Ok(match until {
                GateFor::ReadAfter(last) => ctl.next_step(last).is_some(),
                GateFor::PublishAfter { last, states } => {
                    let k = h.pub_step.load(Ordering::Acquire);
                    k > last || (states && k == 0 && h.seeded.load(Ordering::Acquire) == 0)
                }
                GateFor::DueAfter(answered) => {
                    seg.conn_ctl(self.slot).is_some_and(|conn| ctl.next_due(&conn, answered).is_some())
                }
                GateFor::Nothing => true,
            })
        };
        let what = match until {
            GateFor::PublishAfter { .. } => "a step to publish for",
            _ => "the framework's next step",
        };
        // An event-driven connection waits on its own word, which the framework bumps when it
        // is due, so the steps it is not due at do not wake it.
        let slot = seg.conn(self.slot).filter(|_| matches!(until, GateFor::DueAfter(_)));
        let (futex, waiters) = match slot {
            Some(c) => (&c.due_seq, &c.due_waiters),
            None => (&h.step_seq, &h.step_waiters),
        };
        let waiter = Waiter { mode: self.wait, futex, waiters, check_every: Duration::from_millis(20) };
        loop {
            let deadline = Instant::now() + self.timeout;
            let step_before = h.pub_step.load(Ordering::Acquire);
            match waiter.wait(deadline, &mut ready, || self.check(seg, true))? {
                Waited::Ready => return Ok(()),
                Waited::TimedOut if !seg.step_wait_may_time_out(self.timeout) => {}
                // Not due yet while the framework goes on stepping: nothing is late.
                Waited::TimedOut
                    if matches!(until, GateFor::DueAfter(_)) && h.pub_step.load(Ordering::Acquire) != step_before => {}
                Waited::TimedOut => {
                    let ms = self.timeout.as_millis() as u64;
                    return Err(ShmError::Timeout { domain: seg.info.name.clone(), what, ms });
                }
            }
        }
    }
}

/// A participant's wait for the framework, apart from the participant (see
/// [`Participant::read_gate`]): it holds the segment, not the connection, so another
/// thread may use the connection meanwhile. It ends as the participant's own wait does:
/// ready, timed out (never while the framework is paused), or with the error of a framework
/// that stopped, a connection that was removed or a segment that was shrunk.
#[derive(Debug)]
pub struct StepGate {
    seg: Arc<Segment>,
    waiting: Waiting,
}

impl StepGate {
    pub fn wait(&self) -> Result<(), ShmError> {
        self.waiting.wait(&self.seg)
    }
}

impl Drop for Participant {
    fn drop(&mut self) {
        self.release();
    }
}

/// The first way `domain` (from a DDF) differs from the running domain `live`, ignoring the
/// order of the items; `None` when they have the same flags and items.
pub fn describe_difference(domain: &Domain, live: &DomainInfo) -> Option<String> {
    let yn = |b: bool| if b { "yes" } else { "no" };
    for (name, ddf, running) in [
        ("synchronous", domain.flags.synchronous, live.flags.synchronous),
        ("multiplePublishAllowed", domain.flags.multiple_publish_allowed, live.flags.multiple_publish_allowed),
        ("states", domain.flags.states, live.flags.states),
    ] {
        if ddf != running {
            return Some(format!("<{name}> is {} in the DDF, {} in the running domain", yn(ddf), yn(running)));
        }
    }
    for role in Role::ALL {
        let ddf = &domain.set(role).layout.leaves;
        let running = &live.set(role).leaves;
        let describe = |l: &Leaf| format!("{} {}[{}]", l.path, l.ty.canonical(), l.length);
        for l in ddf {
            match running.iter().find(|r| r.path == l.path) {
                None => return Some(format!("{role} item '{}' is not in the running domain", l.path)),
                Some(r) if r.ty != l.ty || r.length != l.length => {
                    return Some(format!(
                        "{role} item: the DDF has {}, the running domain {}",
                        describe(l),
                        describe(r)
                    ))
                }
                Some(_) => {}
            }
        }
        if let Some(r) = running.iter().find(|r| !ddf.iter().any(|l| l.path == r.path)) {
            return Some(format!("{role} item '{}' of the running domain is not in the DDF", r.path));
        }
    }
    None
}
