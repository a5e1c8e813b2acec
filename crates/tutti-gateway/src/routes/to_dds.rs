//! Shared memory -> DDS: each set's writer.
//!
//! Asynchronous sets (and the SUBSCRIBE set of every domain, whose shared-memory writers
//! DDS readers want to see) are watched by one poller thread: a set whose generation moved
//! is read (a consistent seqlock copy) and written to DDS, at most `max_rate` times a second
//! where the config file says so. A synchronous PUBLISH set is followed by a pump thread
//! that sleeps on the domain's step word and sends each step once, in order, tagged with its
//! step number. Both are passive observers: they hold no connection, so a DDS reader never
//! paces or stalls a domain and is not counted as a participant. A pump that the framework
//! outruns (more than the bucket's slots between two of its wake-ups) sends the newest step
//! and counts the ones it could not send (`skipped`). Routes work only while a remote reader
//! is matched ([`Activation`]).
//!
//! A step of a synchronous set that DDS refuses (the reliable, keep-all writer's history is
//! full until its readers acknowledge) is tried again for up to the step timeout
//! ([`Outbound::write_step`]): with `--every-step` the pump then holds its answer to the next
//! step, so the framework steps at the rate DDS takes them; a step still refused then is
//! counted `lost` and logged with its domain and topic, never dropped silently.

use std::collections::BTreeSet;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::Arc;
use std::thread::{self, JoinHandle, Thread};
use std::time::{Duration, Instant};

use tracing::{info, warn};
use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::ItemTopic;
use tutti_core::shm::observer::{Look, Observer};
use tutti_core::shm::segment::Segment;
use tutti_core::shm::{ConnKind, Participant, ShmError};

use super::per_item::ItemWriters;
use super::{Counters, Patience, ShmConfig};
use crate::cdr::SetCodec;
use crate::config::PlannedSet;
use crate::engine::{EndpointId, Engine, Writer};
use crate::stats::{LogLimit, SetStats, Stats};
use crate::GatewayError;

/// A shared-memory -> DDS route as its constructor hands it to the manager: its topics
/// (whose remote readers switch it on), its activation, and what serves it.
#[derive(Debug)]
pub struct Outgoing {
    pub topics: Vec<String>,
    pub activation: Arc<Activation>,
    pub served_by: ServedBy,
}

/// What serves an outgoing route.
#[derive(Debug)]
pub enum ServedBy {
    /// The poller thread, which looks at every watched set in turn.
    Poller(Box<dyn Polled>),
    /// A thread of its own (a synchronous PUBLISH set's pump).
    Thread(JoinHandle<()>),
    /// The framework's step, in the framework's own process (see [`super::from_step`]).
    Step(Box<super::from_step::StepRoute>),
}

/// The typed route of planned set `p` of domain `d` (shared memory -> DDS): a synchronous
/// PUBLISH set (a whole set: a per-item writer, which sends an item again when a reader
/// joins, is only ever watched by the poller) is followed by a pump thread (a lock-step reader named `every_step`, when
/// given), every other set is watched by the poller (`own_commits`: the gateway's own
/// commits to a SUBSCRIBE set, which are not sent back to DDS).
pub fn typed(
    dds: &dyn Engine,
    d: &Domain,
    p: &PlannedSet,
    cfg: &ShmConfig,
    counters: Counters,
    own_commits: Option<Arc<AtomicU64>>,
    every_step: Option<String>,
) -> Result<Outgoing, GatewayError> {
    let out = set_writer(dds, d, p)?;
    let activation = Arc::new(Activation::default());
    let served_by = if p.role == Role::Publish && d.flags.synchronous {
        let (name, cfg, a) = (d.name.clone(), cfg.clone(), activation.clone());
        let pump = match every_step {
            Some(reader) => spawn_lockstep_pump(name, out, a, cfg, counters, reader),
            None => spawn_sync_pump(name, out, a, cfg, counters),
        };
        ServedBy::Thread(pump.map_err(|e| GatewayError::Thread("a thread", e))?)
    } else {
        ServedBy::Poller(watched(&d.name, p, out, activation.clone(), counters.set, own_commits))
    };
    Ok(Outgoing { topics: vec![p.ros2_topic.clone()], activation, served_by })
}

/// The per-item route of planned set `p` of domain `d` (shared memory -> DDS): a writer for
/// each of `items`, watched by the poller (`own_commits`: the gateway's own commits to a
/// SUBSCRIBE set, not sent back to DDS), counted in `set`.
pub fn items(
    dds: &dyn Engine,
    d: &Domain,
    p: &PlannedSet,
    items: &[ItemTopic],
    set: Arc<SetStats>,
    own_commits: Option<Arc<AtomicU64>>,
) -> Result<Outgoing, GatewayError> {
    let out = Outbound::Items(ItemWriters::create(dds, items, &d.set(p.role).layout, &p.writer_qos)?);
    let activation = Arc::new(Activation::default());
    let poll = watched(&d.name, p, out, activation.clone(), set, own_commits);
    let topics = items.iter().map(|t| t.topic.clone()).collect();
    Ok(Outgoing { topics, activation, served_by: ServedBy::Poller(poll) })
}

/// The typed DDS writer of planned set `p` of domain `d`.
pub fn set_writer(dds: &dyn Engine, d: &Domain, p: &PlannedSet) -> Result<Outbound, GatewayError> {
    let codec = Arc::new(SetCodec::new(&d.set(p.role).layout));
    let writer = dds.writer(&p.ros2_topic, &p.topic_type(), &p.writer_qos)?;
    Ok(Outbound::Set(Box::new(SetWriter::new(codec, writer).named(&d.name, &p.topic))))
}

/// Planned set `p` of `domain` watched by the poller: `out` carries the set's changes
/// (`own_commits`: the gateway's own commits, not sent back to DDS), at most at the set's
/// `max_rate`, counted in `set`.
pub fn watched(
    domain: &str,
    p: &PlannedSet,
    out: Outbound,
    activation: Arc<Activation>,
    set: Arc<SetStats>,
    own_commits: Option<Arc<AtomicU64>>,
) -> Box<dyn Polled> {
    let w = Watched::new(domain.to_string(), p.role, out, activation, own_commits);
    Box::new(w.with_max_rate(p.max_rate).counted(set))
}

/// The typed writer of one set.
pub struct SetWriter {
    codec: Arc<SetCodec>,
    writer: Box<dyn Writer>,
    body: Vec<u8>,
    /// The domain and the DDS topic, for the log of a lost step.
    domain: String,
    topic: String,
    lost_log: LogLimit,
}

impl std::fmt::Debug for SetWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SetWriter").field("codec", &self.codec).field("topic", &self.topic).finish()
    }
}

/// The pause between two tries of a write that DDS refused at once (an engine that waits for
/// room before refusing, as both do for a reliable writer, is tried again at once).
const RETRY_PAUSE: Duration = Duration::from_micros(200);

impl SetWriter {
    pub fn new(codec: Arc<SetCodec>, writer: Box<dyn Writer>) -> Self {
        SetWriter {
            codec,
            writer,
            body: Vec::new(),
            domain: String::new(),
            topic: String::new(),
            lost_log: LogLimit::new(Duration::from_secs(5)),
        }
    }

    /// Names the domain and topic it writes, for its log.
    pub fn named(mut self, domain: &str, topic: &str) -> Self {
        self.domain = domain.to_string();
        self.topic = topic.to_string();
        self
    }

    /// Encodes and writes one sample (held by a batching engine until [`SetWriter::flush`]);
    /// false when DDS refused it.
    pub fn send(&mut self, step: u64, sim_time: f64, shm: &[u8]) -> bool {
        self.codec.encode(step, sim_time, shm, &mut self.body);
        self.writer.write(&self.body)
    }

    /// Encodes and writes step `step` of a synchronous set, trying again while DDS refuses it
    /// (see [`Patience`]); false when it was still refused after `patience.timeout`, which is
    /// logged here, naming the domain and the topic (at most once every 5 s).
    pub fn send_step(&mut self, step: u64, sim_time: f64, shm: &[u8], patience: &Patience) -> bool {
        self.codec.encode(step, sim_time, shm, &mut self.body);
        let deadline = Instant::now() + patience.timeout;
        let mut tries = 0u64;
        loop {
            let t = Instant::now();
            if self.writer.write(&self.body) {
                return true;
            }
            tries += 1;
            // What a batching engine holds goes out, so that its readers can acknowledge it.
            self.writer.flush();
            if Instant::now() >= deadline || patience.stop.load(Ordering::Acquire) {
                break;
            }
            if t.elapsed() < RETRY_PAUSE {
                thread::sleep(RETRY_PAUSE);
            }
        }
        if let Some(held) = self.lost_log.allow() {
            warn!(
                domain = %self.domain,
                topic = %self.topic,
                "step {step} of domain '{}' was not written to DDS topic '{}': its DDS writer refused it {tries} time(s) for {:?}, the step timeout (its reliable readers did not acknowledge the earlier steps: a reader killed without leaving holds it back until its participant's lease runs out); counted as lost ({held} more lost since the last report)",
                self.domain,
                self.topic,
                patience.timeout
            );
        }
        false
    }

    pub fn flush(&mut self) {
        self.writer.flush();
    }

    /// Its writer's flush for another thread ([`crate::engine::Writer::flusher`]).
    pub fn flusher(&self) -> Option<crate::engine::Flusher> {
        self.writer.flusher()
    }
}

/// A DDS side of a set: typed or per item.
#[derive(Debug)]
pub enum Outbound {
    Set(Box<SetWriter>),
    Items(ItemWriters),
}

impl Outbound {
    /// Writes the set `shm` and sends it at once; returns the samples written.
    pub fn send(&mut self, step: u64, sim_time: f64, shm: &[u8], stats: &Stats, set: Option<&SetStats>) -> u64 {
        let n = self.write(step, sim_time, shm, stats, set);
        self.flush();
        n
    }

    /// The flush of a typed set's writer for another thread (None for per-item writers and
    /// engines that do not batch).
    pub fn flusher(&self) -> Option<crate::engine::Flusher> {
        match self {
            Outbound::Set(w) => w.flusher(),
            Outbound::Items(_) => None,
        }
    }

    /// Sends what [`Outbound::write`] left in the writers' batches.
    pub fn flush(&mut self) {
        match self {
            Outbound::Set(w) => w.flush(),
            Outbound::Items(w) => w.flush(),
        }
    }

    /// Writes the set `shm`, leaving it in the writers' batches where the engine batches;
    /// returns the samples written, counted in the gateway's totals and in `set`'s counters.
    pub fn write(&mut self, step: u64, sim_time: f64, shm: &[u8], stats: &Stats, set: Option<&SetStats>) -> u64 {
        let (sent, failed) = match self {
            Outbound::Set(w) => {
                if w.send(step, sim_time, shm) {
                    (1, 0)
                } else {
                    (0, 1)
                }
            }
            Outbound::Items(w) => w.send(shm),
        };
        SetStats::add(set, |s| &s.samples_out, &stats.to_dds, sent);
        Stats::add(&stats.errors, failed);
        sent
    }

    /// Writes step `step` of a synchronous set, `shm`, waiting while DDS refuses it (see
    /// [`Patience`]); returns the samples written, counted as [`Outbound::write`] counts
    /// them. A step still refused after the step timeout is counted `lost` (and `dropped` in
    /// `set`), and logged. Per-item writers (no step travels with them) write as
    /// [`Outbound::write`] does: an item refused goes out again with the next step.
    pub fn write_step(
        &mut self,
        step: u64,
        sim_time: f64,
        shm: &[u8],
        stats: &Stats,
        set: Option<&SetStats>,
        patience: &Patience,
    ) -> u64 {
        match self {
            Outbound::Set(w) => {
                if w.send_step(step, sim_time, shm, patience) {
                    SetStats::add(set, |s| &s.samples_out, &stats.to_dds, 1);
                    1
                } else {
                    SetStats::add(set, |s| &s.dropped, &stats.lost, 1);
                    0
                }
            }
            Outbound::Items(_) => self.write(step, sim_time, shm, stats, set),
        }
    }

    /// [`Outbound::write_step`], then sent at once.
    pub fn send_step(
        &mut self,
        step: u64,
        sim_time: f64,
        shm: &[u8],
        stats: &Stats,
        set: Option<&SetStats>,
        patience: &Patience,
    ) -> u64 {
        let n = self.write_step(step, sim_time, shm, stats, set, patience);
        self.flush();
        n
    }

    /// Forget what was sent (per-item writers then send every item again).
    pub fn reset(&mut self) {
        if let Outbound::Items(w) = self {
            w.reset();
        }
    }
}

/// The shortest time between two samples at most `rate` a second (zero: no limit); shared
/// by the rate-limited sets and `/clock`.
pub fn min_interval(rate: Option<f64>) -> Duration {
    rate.filter(|r| *r > 0.0).map_or(Duration::ZERO, |r| Duration::from_secs_f64(1.0 / r))
}

/// Discovery passes after a reader joined in which per-item writers send every item again.
const REJOIN_PASSES: u32 = 3;

/// The remote readers of a route, and the passes left in which a join counts again.
#[derive(Debug, Default)]
struct KnownReaders {
    readers: BTreeSet<EndpointId>,
    rejoins: u32,
}

/// Whether a route has a remote reader to work for; wakes the thread that serves it.
#[derive(Debug, Default)]
pub struct Activation {
    active: AtomicBool,
    /// Counts the times a reader joined the route's topics: per-item writers send only the
    /// items that changed, so a reader joining one item's topic late must be sent every item
    /// again (an item whose value never changes would never reach it otherwise).
    joined: AtomicU64,
    known: std::sync::Mutex<KnownReaders>,
    thread: std::sync::OnceLock<Thread>,
}

impl Activation {
    /// The remote readers now on the route's topics (from discovery).
    ///
    /// A join also counts at the next three discovery passes (`REJOIN_PASSES`): the gateway learns of a
    /// reader from discovery before that reader has necessarily learnt of the gateway's
    /// writer, and a volatile reader drops what arrives before it has, so the items sent
    /// once at the join may never reach it (seen on a loaded machine).
    pub fn set_readers(&self, readers: &BTreeSet<EndpointId>) {
        let counts = {
            let mut known = self.known.lock().unwrap_or_else(|e| e.into_inner());
            let counts = if readers.difference(&known.readers).next().is_some() {
                known.rejoins = REJOIN_PASSES;
                true
            } else {
                let again = known.rejoins > 0;
                known.rejoins = known.rejoins.saturating_sub(1);
                again
            };
            known.readers.clone_from(readers);
            counts
        };
        if counts {
            self.joined.fetch_add(1, Ordering::AcqRel);
        }
        self.set(!readers.is_empty());
    }

    /// How many times a reader has joined (see `set_readers`).
    pub fn joined(&self) -> u64 {
        self.joined.load(Ordering::Acquire)
    }

    pub fn set(&self, on: bool) {
        if self.active.swap(on, Ordering::AcqRel) != on {
            self.wake();
        }
    }

    pub fn is_active(&self) -> bool {
        self.active.load(Ordering::Acquire)
    }

    pub fn wake(&self) {
        if let Some(t) = self.thread.get() {
            t.unpark();
        }
    }
}

/// The observer's look as a route uses it: the segment, or None (logged when the
/// framework stopped or the segment is refused).
pub fn look<'a>(obs: &'a mut Observer, namespace: &str) -> Option<(&'a Segment, bool)> {
    let fresh = match obs.look(namespace) {
        Look::Fresh => true,
        Look::Same => false,
        Look::Gone => return None,
        Look::Stopped => {
            info!(domain = %obs.domain, "framework stopped; waiting for it to come back");
            return None;
        }
        Look::Refused(e) => {
            warn!(domain = %obs.domain, "cannot open the domain: {e}");
            return None;
        }
    };
    obs.segment().map(|seg| (seg, fresh))
}

/// One set watched by the poller.
#[derive(Debug)]
pub struct Watched {
    pub role: Role,
    pub out: Outbound,
    pub activation: Arc<Activation>,
    /// SUBSCRIBE: commits made by the gateway itself (not sent back to DDS).
    pub own_commits: Option<Arc<AtomicU64>>,
    live: Observer,
    last_gen: Option<u64>,
    base: Baseline,
    last_local: u64,
    buf: Vec<u8>,
    /// `activation.joined()` as last acted on.
    joined: u64,
    /// A reader joined a per-item PUBLISH set: every item goes out again at the next look,
    /// changed or not (an item whose value never changes would never reach that reader).
    resend: bool,
    /// Whether the last look wrote a sample, and the samples written but not yet flushed.
    hot: bool,
    unflushed: u32,
    /// Shortest time between two samples (zero: no limit), and when the next may go.
    min_interval: Duration,
    next_allowed: Instant,
    /// The set's own counters (the stats endpoint).
    set: Option<Arc<SetStats>>,
}

/// Where a watched SUBSCRIBE set's count of local commits starts: its generation and the
/// gateway's own commits when it was first seen (commits since then, less the gateway's,
/// are those of local writers).
#[derive(Debug, Clone, Copy, Default)]
struct Baseline {
    generation: u64,
    own: u64,
}

/// Samples of a set changing flat out that go out in one batch at most.
const FLUSH_EVERY: u32 = 32;

impl Watched {
    pub fn new(
        domain: String,
        role: Role,
        out: Outbound,
        activation: Arc<Activation>,
        own_commits: Option<Arc<AtomicU64>>,
    ) -> Self {
        Watched {
            role,
            out,
            activation,
            own_commits,
            live: Observer::new(domain),
            last_gen: None,
            base: Baseline::default(),
            last_local: 0,
            buf: Vec::new(),
            joined: 0,
            resend: false,
            hot: false,
            unflushed: 0,
            min_interval: Duration::ZERO,
            next_allowed: Instant::now(),
            set: None,
        }
    }

    /// Counts what it sends in `set` too.
    pub fn counted(mut self, set: Arc<SetStats>) -> Self {
        self.set = Some(set);
        self
    }

    /// At most `rate` samples a second (None: every change): a set changing faster goes out
    /// downsampled, always with its newest value.
    pub fn with_max_rate(mut self, rate: Option<f64>) -> Self {
        self.min_interval = min_interval(rate);
        self
    }

    /// Looks at the set once; returns true when something was written.
    fn poll_once(&mut self, cfg: &ShmConfig, stats: &Stats) -> bool {
        if !self.activation.is_active() {
            self.live.close();
            self.last_gen = None;
            return false;
        }
        let joined = self.activation.joined();
        if joined != self.joined {
            self.joined = joined;
            self.out.reset();
            // A SUBSCRIBE set's items go out again with its next local commit (the gateway's
            // own commits are never echoed back to DDS).
            self.resend = matches!(self.out, Outbound::Items(_)) && self.own_commits.is_none();
        }
        let Some((seg, fresh)) = look(&mut self.live, &cfg.namespace) else {
            self.last_gen = None;
            return false;
        };
        if fresh {
            self.buf = vec![0; seg.info.set(self.role).size as usize];
            self.out.reset();
            self.last_gen = None;
        }
        let gen = seg.generation(self.role);
        if self.last_gen == Some(gen) && !self.resend {
            return false;
        }
        // Rate-limited: the change waits (and is read, newest, when the limit allows).
        if !self.min_interval.is_zero() {
            let now = Instant::now();
            if now < self.next_allowed {
                return false;
            }
            self.next_allowed = now + self.min_interval;
        }
        let first = self.last_gen.is_none();
        self.last_gen = Some(gen);
        if let Some(own) = &self.own_commits {
            // Commits the gateway made for DDS writers are not echoed back to DDS.
            let own = own.load(Ordering::Acquire);
            if first {
                self.base = Baseline { generation: gen, own };
                self.last_local = 0;
                if !seg.seeded() {
                    return false;
                }
            } else {
                let local = gen.wrapping_sub(self.base.generation).saturating_sub(own.wrapping_sub(self.base.own));
                if local <= self.last_local {
                    return false;
                }
                self.last_local = local;
            }
        }
        // Labelled with the step the value belongs to (the one a commit answered), read with
        // it: the framework may have moved on since.
        let Some((_, stamp)) = seg.try_read_set_stamped(self.role, &mut self.buf, 1 << 16) else {
            return false;
        };
        let sent = self.out.write(stamp.step, stamp.sim_time, &self.buf, stats, self.set.as_deref()) > 0;
        self.resend &= !sent;
        sent
    }
}

/// What the poller thread looks at, one turn after the other.
pub trait Polled: Send + std::fmt::Debug {
    /// Whether a remote reader wants what it sends (the poller parks while none does).
    fn activation(&self) -> &Activation;
    /// Looks once; true when something was sent.
    fn poll(&mut self, cfg: &ShmConfig, stats: &Stats) -> bool;
}

impl Polled for Watched {
    fn activation(&self) -> &Activation {
        &self.activation
    }

    /// Looks at the set once (see `poll_once`) and sends what it wrote: at once when the set
    /// had been idle (no latency added to occasional changes), else every `FLUSH_EVERY` (32)
    /// samples and whenever the set goes idle, so that a set changing flat out goes out in
    /// batches (one datagram for many samples on a batching engine).
    fn poll(&mut self, cfg: &ShmConfig, stats: &Stats) -> bool {
        let was_hot = self.hot;
        let sent = self.poll_once(cfg, stats);
        self.hot = sent;
        if sent {
            self.unflushed += 1;
        }
        if self.unflushed > 0 && (!sent || !was_hot || self.unflushed >= FLUSH_EVERY) {
            self.out.flush();
            self.unflushed = 0;
        }
        sent
    }
}

/// Starts the poller thread; it looks after every route it is sent on `added` (as domains
/// come to be bridged), waking up for them when unparked.
pub fn spawn_poller(
    added: Receiver<Box<dyn Polled>>,
    cfg: ShmConfig,
    stats: Arc<Stats>,
) -> std::io::Result<JoinHandle<()>> {
    thread::Builder::new().name("tutti-gw-poll".into()).spawn(move || {
        let me = thread::current();
        let mut routes: Vec<Box<dyn Polled>> = Vec::new();
        let mut idle_turns = 0u32;
        while !cfg.stop.load(Ordering::Acquire) {
            while let Ok(r) = added.try_recv() {
                let _ = r.activation().thread.set(me.clone());
                routes.push(r);
            }
            let mut busy = false;
            let mut any_active = false;
            for r in routes.iter_mut() {
                any_active |= r.activation().is_active();
                busy |= r.poll(&cfg, &stats);
            }
            if !any_active {
                thread::park_timeout(Duration::from_millis(200));
                continue;
            }
            // Stay hot for a while after traffic; then sleep the poll interval.
            if busy {
                idle_turns = 0;
            } else {
                idle_turns = idle_turns.saturating_add(1);
            }
            if cfg.poll.is_zero() || idle_turns < 64 {
                thread::yield_now();
            } else {
                thread::sleep(cfg.poll);
            }
        }
    })
}

/// Starts the pump of a synchronous PUBLISH set: a passive observer that sleeps on the
/// domain's step word and sends every step it sees, once and in order.
pub fn spawn_sync_pump(
    domain: String,
    mut out: Outbound,
    activation: Arc<Activation>,
    cfg: ShmConfig,
    Counters { total: stats, set }: Counters,
) -> std::io::Result<JoinHandle<()>> {
    thread::Builder::new()
        .name(format!("tutti-gw-sync-{}", domain.chars().take(10).collect::<String>()))
        .stack_size(256 << 10)
        .spawn(move || {
            let _ = activation.thread.set(thread::current());
            let patience = cfg.patience();
            let mut live = Observer::new(domain.clone());
            let mut buf = Vec::new();
            let mut last = 0u64;
            let mut skip_log = LogLimit::new(Duration::from_secs(5));
            while !cfg.stop.load(Ordering::Acquire) {
                if !activation.is_active() {
                    live.close();
                    thread::park_timeout(Duration::from_millis(200));
                    continue;
                }
                let Some((seg, fresh)) = look(&mut live, &cfg.namespace) else {
                    thread::sleep(Duration::from_millis(50));
                    continue;
                };
                if fresh {
                    buf = vec![0; seg.info.publish.size as usize];
                    // From the next step on, as a lock-step reader joining now would.
                    last = seg.step();
                }
                if seg.wait_step_after(last, Duration::from_millis(200)) <= last {
                    continue;
                }
                // The PUBLISH generation counts the framework's steps.
                let Some((step, stamp)) = seg.try_read_set_stamped(Role::Publish, &mut buf, 1 << 16) else { continue };
                if step <= last {
                    continue;
                }
                let missed = step - last - 1;
                if missed > 0 && last > 0 {
                    SetStats::add(Some(&set), |s| &s.dropped, &stats.skipped, missed);
                    if let Some(held) = skip_log.allow() {
                        warn!(
                            domain = %domain,
                            "{missed} step(s) before step {step} went by before DDS could be sent them ({held} more such gaps since the last report): the gateway never holds a domain back for its DDS readers"
                        );
                    }
                }
                last = step;
                out.send_step(step, stamp.sim_time, &buf, &stats, Some(&set), &patience);
            }
        })
}

/// Starts the pump of a synchronous PUBLISH set for `--every-step`: a lock-step reader
/// (an observer connection, not a participant, that the framework waits for), so that every
/// step reaches DDS, at the cost of a copy and a DDS write in each step.
pub fn spawn_lockstep_pump(
    domain: String,
    mut out: Outbound,
    activation: Arc<Activation>,
    cfg: ShmConfig,
    Counters { total: stats, set }: Counters,
    name: String,
) -> std::io::Result<JoinHandle<()>> {
    thread::Builder::new()
        .name(format!("tutti-gw-step-{}", domain.chars().take(10).collect::<String>()))
        .stack_size(256 << 10)
        .spawn(move || {
            let _ = activation.thread.set(thread::current());
            let patience = cfg.patience();
            let mut p: Option<Participant> = None;
            while !cfg.stop.load(Ordering::Acquire) {
                if !activation.is_active() {
                    p = None;
                    thread::park_timeout(Duration::from_millis(200));
                    continue;
                }
                let part = match &mut p {
                    Some(part) => part,
                    None => {
                        let mut opts = cfg.connect_options(name.clone(), Duration::from_millis(200));
                        opts.kind = ConnKind::Observer;
                        match Participant::connect(&domain, opts) {
                            Ok(mut part) => {
                                part.set_timeout(Duration::from_millis(200).min(cfg.timeout));
                                p.insert(part)
                            }
                            Err(_) => {
                                thread::sleep(Duration::from_millis(200));
                                continue;
                            }
                        }
                    }
                };
                match part.subscribe_lock() {
                    // The step is acknowledged once copied; a write that waits for DDS keeps
                    // this reader from acknowledging the next one, which holds the framework.
                    Ok(step) => {
                        out.send_step(step, part.simulation_time(), part.snapshot(), &stats, Some(&set), &patience);
                    }
                    Err(ShmError::Timeout { .. }) => {}
                    Err(e) => {
                        info!(domain = %domain, "lock-step reader lost: {e}");
                        p = None;
                    }
                }
            }
        })
}
