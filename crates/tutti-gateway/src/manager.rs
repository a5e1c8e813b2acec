//! The route manager: bridges each domain once a framework hosts it (or all of them from
//! the start with `hosted_only` off, or as a mirror), then runs one `select!` loop that
//! takes DDS samples from the reader tasks, compares discovery with the connections it
//! holds, reports status and stops on request. Shared-memory work happens on the routes'
//! own threads; this loop only hands samples over and never blocks.
//!
//! DDS readers are passive: they get no shared-memory connection, so they never pace a
//! domain and are not counted as participants; the gateway's presence in each domain it
//! bridges (an observer connection) carries their count for `tutti status`. Each DDS writer
//! gets a connection (counted apart from the participants), released as soon as discovery
//! says it left, or after the lease when it owes a synchronous step's answer and is silent.

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc as std_mpsc;
use std::sync::Arc;
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

use tokio::sync::mpsc;
use tracing::{info, warn};
use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::Qos;
use tutti_core::shm::observer::{Look, Observer};
use tutti_core::shm::{Framework, FrameworkOptions};

use crate::cdr::{SetCodec, TypedSample};
use crate::config::{self, PlannedSet};
use crate::engine::{self, Decode, Engine, Guid};
use crate::routes::clock::{self, ClockPump};
use crate::routes::from_dds::{self, Direct, RemoteWriter, Sample};
use crate::routes::per_item::{self, ItemWriters};
use crate::routes::to_dds::{self, Activation, Outbound, Polled, SetWriter, Watched};
use crate::routes::{mirror, Event, Payload, ShmConfig};
use crate::stats::{LogLimit, SetStats, Stats};
use crate::{http, GatewayError, GatewayOptions, TypeMode};

/// A route as the manager sees it.
#[derive(Debug)]
enum Route {
    /// DDS -> shared memory (or -> the mirror's framework); `direct`: the writers whose
    /// samples the reader task commits itself (asynchronous domains).
    /// `set`: the planned set it belongs to.
    In { domain: usize, set: usize, topic: String, direct: Direct },
    /// Shared memory -> DDS; `set`: the planned set its topics are (None: `/clock`), whose
    /// readers the domain counts.
    Out { domain: usize, topics: Vec<String>, activation: Arc<Activation>, set: Option<usize> },
}

#[derive(Debug)]
struct DomainState {
    name: String,
    synchronous: bool,
    own_commits: Arc<AtomicU64>,
    mirror: Option<std_mpsc::Sender<TypedSample>>,
    /// Its routes exist.
    bridged: bool,
    /// The gateway's presence in the domain (None for a mirror, which hosts it): tells
    /// whether a framework hosts it, and shows its DDS readers in `tutti status`.
    presence: Option<Observer>,
    /// DDS readers of its sets (each set's readers once).
    dds_readers: usize,
}

#[derive(Debug)]
struct WriterEntry {
    writer: RemoteWriter,
    created: Instant,
    /// Discovery has listed it at least once (a writer known only from its first sample
    /// gets a grace period before discovery catches up; one that discovery listed and no
    /// longer lists has left).
    listed: bool,
}

/// Serves `opts` until `shutdown` is set; `on_status` is called every `status_every` with
/// a one-line summary (and once when the gateway is up).
pub fn run(
    mut opts: GatewayOptions,
    shutdown: Arc<AtomicBool>,
    status_every: Duration,
    on_status: &mut dyn FnMut(&str),
) -> Result<Arc<Stats>, GatewayError> {
    if opts.mirror && opts.types == TypeMode::PerItem {
        return Err(GatewayError::Invalid("--mirror needs --ros2-types typed: per-item samples carry no step".into()));
    }
    // Canonical from here on (`sim1`, `a/b`, or empty), as the routes and the report use it.
    opts.ros_namespace = config::ros_namespace(&opts.ros_namespace)?;
    let plan = config::plan(&opts)?;
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(GatewayError::Runtime)?;
    let stats = Arc::new(Stats::default());
    let cfg = ShmConfig {
        namespace: opts.namespace.clone(),
        timeout: opts.timeout,
        wait: opts.wait,
        poll: opts.poll,
        lease: opts.lease,
        stop: Arc::new(AtomicBool::new(false)),
    };
    let mut m = Manager::build(opts, plan, cfg, stats.clone())?;
    let http = match m.opts.http {
        Some(addr) => {
            let (thread, bound, stop) = http::serve(addr, m.report_fn())?;
            info!("stats on http://{bound}/metrics (Prometheus) and http://{bound}/stats (JSON)");
            Some((thread, stop))
        }
        None => None,
    };
    on_status(&format!("up: {}", m.line()));
    m.warn_unhosted();
    rt.block_on(m.serve(shutdown, status_every, on_status));
    m.stop();
    if let Some((thread, stop)) = http {
        stop.stop();
        let _ = thread.join();
    }
    drop(rt);
    Ok(stats)
}

struct Manager {
    opts: GatewayOptions,
    plan: Vec<PlannedSet>,
    /// The counters of each planned set (same order).
    set_stats: Vec<Arc<SetStats>>,
    clock_domain: Option<usize>,
    dds: Box<dyn Engine>,
    cfg: ShmConfig,
    stats: Arc<Stats>,
    routes: Vec<Route>,
    domains: Vec<DomainState>,
    writers: HashMap<(usize, Guid), WriterEntry>,
    threads: Vec<JoinHandle<()>>,
    /// Routes for the poller thread, and the thread (woken when one is sent).
    poller: std_mpsc::Sender<Box<dyn Polled>>,
    poller_thread: Thread,
    events_tx: mpsc::UnboundedSender<Event>,
    events: mpsc::UnboundedReceiver<Event>,
    topics: usize,
    bad_log: LogLimit,
}

impl std::fmt::Debug for Manager {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Manager").field("routes", &self.routes.len()).finish()
    }
}

impl Manager {
    fn build(
        opts: GatewayOptions,
        plan: Vec<PlannedSet>,
        cfg: ShmConfig,
        stats: Arc<Stats>,
    ) -> Result<Manager, GatewayError> {
        let clock_domain = opts.clock_domain()?;
        let dds = engine::open(opts.engine, &opts.engine_config())?;
        let (events_tx, events) = mpsc::unbounded_channel();
        let (poller, added) = std_mpsc::channel();
        let poll_thread =
            to_dds::spawn_poller(added, cfg.clone(), stats.clone()).map_err(|e| GatewayError::dds("a thread", e))?;
        let poller_thread = poll_thread.thread().clone();
        let mut hosts: Vec<Option<_>> = if opts.mirror {
            let fo = FrameworkOptions {
                namespace: opts.namespace.clone(),
                timeout: opts.timeout,
                wait: opts.wait,
                ..Default::default()
            };
            Framework::create(&opts.model, &fo)?.domains.into_iter().map(Some).collect()
        } else {
            Vec::new()
        };
        let domains = opts
            .model
            .domains
            .iter()
            .map(|d| DomainState {
                name: d.name.clone(),
                synchronous: d.flags.synchronous,
                own_commits: Arc::new(AtomicU64::new(0)),
                mirror: None,
                bridged: false,
                presence: (!opts.mirror).then(|| Observer::with_presence(d.name.clone(), &opts.node_name)),
                dds_readers: 0,
            })
            .collect();
        let set_stats = plan.iter().map(|_| Arc::new(SetStats::default())).collect();
        let mut m = Manager {
            opts,
            plan,
            set_stats,
            clock_domain,
            dds,
            cfg,
            stats,
            routes: Vec::new(),
            domains,
            writers: HashMap::new(),
            threads: vec![poll_thread],
            poller,
            poller_thread,
            events_tx,
            events,
            topics: 0,
            bad_log: LogLimit::new(Duration::from_secs(5)),
        };
        let bridge_all = m.opts.mirror || !m.opts.hosted_only;
        for di in 0..m.domains.len() {
            let host = hosts.get_mut(di).and_then(Option::take);
            if bridge_all || m.hosted(di) {
                m.bridge(di, host)?;
            }
        }
        m.dds.announce()?;
        Ok(m)
    }

    /// What the stats endpoint serves: the totals and each planned set's counters, read from
    /// the same atomics the routes count in (no call into the manager).
    fn report_fn(&self) -> http::ReportFn {
        let ns = self.opts.ros_namespace.clone();
        let gateway = http::GatewayReport {
            engine: self.dds.kind().name().to_string(),
            dds_domain: self.dds.domain_id(),
            node: config::node_full_name(&ns, &self.opts.node_name),
            ros_namespace: ns,
            ..Default::default()
        };
        let mirror = self.opts.mirror;
        let topics: Vec<(http::TopicReport, Arc<SetStats>)> = self
            .plan
            .iter()
            .zip(&self.set_stats)
            .map(|(p, s)| {
                let direction = match (p.role, mirror) {
                    (Role::Publish, false) => http::Direction::Out,
                    (Role::Publish, true) => http::Direction::In,
                    (Role::Subscribe, false) => http::Direction::Both,
                    (Role::Subscribe, true) => http::Direction::Out,
                };
                (http::TopicReport::new(p, &self.domains[p.domain].name, direction), s.clone())
            })
            .collect();
        let (stats, start) = (self.stats.clone(), Instant::now());
        Arc::new(move || http::Report {
            gateway: http::GatewayReport {
                uptime_s: start.elapsed().as_secs_f64(),
                totals: http::GatewayReport::totals(&stats),
                ..gateway.clone()
            },
            topics: topics.iter().map(|(t, s)| t.clone().with_counts(s)).collect(),
        })
    }

    /// Whether a framework hosts domain `di` now (looked at through its presence).
    fn hosted(&mut self, di: usize) -> bool {
        let ns = self.cfg.namespace.clone();
        let Some(obs) = self.domains[di].presence.as_mut() else { return true };
        match obs.look(&ns) {
            Look::Fresh | Look::Same => true,
            Look::Gone | Look::Stopped => false,
            Look::Refused(e) => {
                warn!(domain = %self.domains[di].name, "cannot open the domain: {e}");
                false
            }
        }
    }

    fn warn_unhosted(&self) {
        let waiting: Vec<&str> = self.domains.iter().filter(|d| !d.bridged).map(|d| d.name.as_str()).collect();
        if !waiting.is_empty() {
            warn!(
                "not bridged until a framework hosts them in namespace '{}' (TUTTI_NAMESPACE): {} (--all-domains bridges every domain at once)",
                self.cfg.namespace,
                waiting.join(", ")
            );
        }
    }

    /// Creates the routes of domain `di` (`host`: its framework, for a mirror).
    fn bridge(&mut self, di: usize, host: Option<tutti_core::shm::DomainHost>) -> Result<(), GatewayError> {
        let d = self.opts.model.domains[di].clone();
        let sets: Vec<(usize, PlannedSet)> =
            self.plan.iter().enumerate().filter(|(_, p)| p.domain == di).map(|(i, p)| (i, p.clone())).collect();
        let planned = |role: Role| sets.iter().find(|(_, p)| p.role == role).map(|(i, p)| (*i, p));
        let own_commits = self.domains[di].own_commits.clone();
        let dds: &dyn Engine = &*self.dds;
        let mut watched: Vec<Box<dyn Polled>> = Vec::new();
        match (self.opts.types, self.opts.mirror) {
            (TypeMode::Typed, false) => {
                // PUBLISH: shared memory -> DDS.
                if let Some((si, p)) = planned(Role::Publish) {
                    self.topics += 1;
                    let out = set_writer(dds, &d, p)?;
                    let activation = route_out(&mut self.routes, di, vec![p.topic.clone()], Some(si));
                    let counters = (self.stats.clone(), self.set_stats[si].clone());
                    if d.flags.synchronous {
                        let (name, cfg) = (d.name.clone(), self.cfg.clone());
                        let pump = if self.opts.every_step {
                            let reader = format!("{} every-step reader", self.opts.node_name);
                            to_dds::spawn_lockstep_pump(name, out, activation, cfg, counters, reader)
                        } else {
                            to_dds::spawn_sync_pump(name, out, activation, cfg, counters)
                        };
                        self.threads.push(pump.map_err(|e| GatewayError::dds("a thread", e))?);
                    } else {
                        watched.push(self.watched(&d.name, si, out, activation, None));
                    }
                }
                // SUBSCRIBE: DDS -> shared memory, and shared-memory writers -> DDS.
                if let Some((si, p)) = planned(Role::Subscribe) {
                    self.topics += 1;
                    let decode = Decode::Set(Arc::new(SetCodec::new(&d.subscribe.layout)));
                    self.inbound(di, si, &p.topic, &p.dds_type, decode, &p.reader_qos)?;
                    let out = set_writer(&*self.dds, &d, p)?;
                    let activation = route_out(&mut self.routes, di, vec![p.topic.clone()], Some(si));
                    watched.push(self.watched(&d.name, si, out, activation, Some(own_commits)));
                }
            }
            (TypeMode::Typed, true) => {
                // The counters of a set the config leaves out count what nobody reads.
                let unused = || Arc::new(SetStats::default());
                let mut set_in = unused();
                if let Some((si, p)) = planned(Role::Publish) {
                    self.topics += 1;
                    let decode = Decode::Set(Arc::new(SetCodec::new(&d.publish.layout)));
                    self.inbound(di, si, &p.topic, &p.dds_type, decode, &p.reader_qos)?;
                    set_in = self.set_stats[si].clone();
                }
                let mut set_out = unused();
                let out = match planned(Role::Subscribe) {
                    Some((si, p)) => {
                        self.topics += 1;
                        set_out = self.set_stats[si].clone();
                        Some(set_writer(&*self.dds, &d, p)?)
                    }
                    None => None,
                };
                let (mtx, mrx) = std_mpsc::channel();
                let host = host.ok_or_else(|| GatewayError::Invalid(format!("domain '{}' was not created", d.name)))?;
                self.threads.push(
                    mirror::spawn(host, mrx, out, self.cfg.clone(), self.stats.clone(), (set_in, set_out))
                        .map_err(|e| GatewayError::dds("a thread", e))?,
                );
                self.domains[di].mirror = Some(mtx);
            }
            (TypeMode::PerItem, _) => {
                if let Some((si, p)) = planned(Role::Publish) {
                    let pub_topics = config::item_topics(&self.opts, p);
                    self.topics += pub_topics.len();
                    let out = Outbound::Items(ItemWriters::create(dds, &pub_topics, &d.publish.layout, &p.writer_qos)?);
                    let topics = pub_topics.iter().map(|t| t.topic.clone()).collect();
                    let activation = route_out(&mut self.routes, di, topics, Some(si));
                    watched.push(self.watched(&d.name, si, out, activation, None));
                }
                if let Some((si, p)) = planned(Role::Subscribe) {
                    let sub_topics = config::item_topics(&self.opts, p);
                    self.topics += sub_topics.len();
                    for t in &sub_topics {
                        let Some(leaf) = d.subscribe.layout.leaf(&t.path) else { continue };
                        let decode = per_item::decoder(leaf);
                        self.inbound(di, si, &t.topic, &t.dds_type, decode, &p.reader_qos)?;
                    }
                    let out = Outbound::Items(ItemWriters::create(
                        &*self.dds,
                        &sub_topics,
                        &d.subscribe.layout,
                        &p.writer_qos,
                    )?);
                    let topics = sub_topics.iter().map(|t| t.topic.clone()).collect();
                    let activation = route_out(&mut self.routes, di, topics, Some(si));
                    watched.push(self.watched(&d.name, si, out, activation, Some(own_commits)));
                }
            }
        }
        if self.clock_domain == Some(di) {
            let topic = config::dds_topic(&self.opts.ros_namespace, "clock");
            let writer = self.dds.writer(&topic, clock::TYPE, &clock::qos())?;
            let activation = route_out(&mut self.routes, di, vec![topic.clone()], None);
            watched.push(Box::new(ClockPump::new(d.name.clone(), writer, activation, self.opts.clock_rate)));
            self.topics += 1;
            info!(domain = %d.name, "/{}: the simulated time of {}", topic.trim_start_matches("rt/"), d.name);
        }
        let any = !watched.is_empty();
        for w in watched {
            // The poller only ends with the gateway.
            let _ = self.poller.send(w);
        }
        if any {
            self.poller_thread.unpark();
        }
        self.domains[di].bridged = true;
        Ok(())
    }

    /// A shared-memory -> DDS route of planned set `si` that the poller serves: `out` carries
    /// the set's changes (`own_commits`: the gateway's own commits, not sent back to DDS), at
    /// most at the set's `max_rate`, counted in the set's counters.
    fn watched(
        &self,
        domain: &str,
        si: usize,
        out: Outbound,
        activation: Arc<Activation>,
        own_commits: Option<Arc<AtomicU64>>,
    ) -> Box<dyn Polled> {
        let p = &self.plan[si];
        let w = Watched::new(domain.to_string(), p.role, out, activation, own_commits);
        Box::new(w.with_max_rate(p.max_rate).counted(self.set_stats[si].clone()))
    }

    /// A DDS -> shared-memory route over `topic` (DDS type `dds_type`, samples read by
    /// `decode`): its reader, whose sink decodes (and, in asynchronous domains, commits) its
    /// samples on the engine's receive path, and the route entry the sink reports under.
    fn inbound(
        &mut self,
        domain: usize,
        set: usize,
        topic: &str,
        dds_type: &str,
        decode: Decode,
        rq: &Qos,
    ) -> Result<(), GatewayError> {
        let direct = Direct::default();
        self.routes.push(Route::In { domain, set, topic: topic.to_string(), direct: direct.clone() });
        let to = (self.routes.len() - 1, self.events_tx.clone(), direct);
        let sink = from_dds::sink(decode.clone(), to, self.stats.clone(), self.dds.own_prefix());
        self.dds.reader(topic, dds_type, rq, decode, sink)
    }

    /// DDS readers, over all domains (each set's once).
    fn dds_readers(&self) -> usize {
        self.domains.iter().map(|d| d.dds_readers).sum()
    }

    fn line(&self) -> String {
        let bridged = self.domains.iter().filter(|d| d.bridged).count();
        format!(
            "{bridged} of {} domains bridged, {} topics, DDS domain {} ({}), DDS writers {}, DDS readers {} | {}",
            self.domains.len(),
            self.topics,
            self.dds.domain_id(),
            self.dds.kind(),
            self.writers.len(),
            self.dds_readers(),
            self.stats
        )
    }

    async fn serve(&mut self, shutdown: Arc<AtomicBool>, status_every: Duration, on_status: &mut dyn FnMut(&str)) {
        let mut discovery = tokio::time::interval(self.opts.discovery_every);
        discovery.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        let mut status = tokio::time::interval_at(tokio::time::Instant::now() + status_every, status_every);
        let mut check = tokio::time::interval(Duration::from_millis(50));
        loop {
            tokio::select! {
                Some(ev) = self.events.recv() => self.on_event(ev),
                _ = discovery.tick() => self.rediscover(),
                _ = status.tick() => on_status(&self.line()),
                _ = check.tick() => if shutdown.load(Ordering::Acquire) { break },
            }
        }
    }

    fn on_event(&mut self, ev: Event) {
        match ev {
            Event::Sample(inb) => {
                let Some(Route::In { domain, .. }) = self.routes.get(inb.route) else { return };
                if let Some(mtx) = &self.domains[*domain].mirror {
                    if let Payload::Set(s) = inb.payload {
                        let _ = mtx.send(s);
                    }
                    return;
                }
                let key = (inb.route, inb.writer);
                // A writer whose connection thread has gone is started again, once.
                for _ in 0..2 {
                    if !self.writers.contains_key(&key) && !self.add_writer(key) {
                        return;
                    }
                    if self.writers.get(&key).is_some_and(|w| w.writer.send(Sample::Owned(inb.payload.clone())).is_ok())
                    {
                        return;
                    }
                    self.writers.remove(&key);
                    if let Some(direct) = self.direct(key.0) {
                        direct.remove(&key.1);
                    }
                }
            }
            Event::Bad { route, error } => {
                let (topic, set) = match self.routes.get(route) {
                    Some(Route::In { topic, set, .. }) => (topic.as_str(), self.set_stats.get(*set).map(|s| &**s)),
                    _ => ("?", None),
                };
                SetStats::add(set, |s| &s.bad_input, &self.stats.bad_samples, 1);
                if let Some(held) = self.bad_log.allow() {
                    warn!(topic, "sample dropped ({held} more since the last report): {error}");
                }
            }
        }
    }

    /// Gives remote writer `key.1` of inbound route `key.0` its connection (committed by
    /// the route's reader task where the domain allows); false if it cannot be started.
    fn add_writer(&mut self, key: (usize, Guid)) -> bool {
        let Some(Route::In { domain, set, direct, .. }) = self.routes.get(key.0) else { return false };
        let d = &self.domains[*domain];
        let gid = key.1;
        let spawned = RemoteWriter::spawn(
            d.name.clone(),
            gid,
            d.synchronous,
            self.cfg.clone(),
            (self.stats.clone(), self.set_stats[*set].clone()),
            d.own_commits.clone(),
        );
        match spawned {
            Ok(writer) => {
                info!(domain = %d.name, "DDS writer {} joined", gid.short());
                direct.insert(gid, writer.clone());
                self.writers.insert(key, WriterEntry { writer, created: Instant::now(), listed: false });
                true
            }
            Err(e) => {
                warn!("cannot start a thread: {e}");
                false
            }
        }
    }

    /// The writers committed by inbound route `route`'s reader task.
    fn direct(&self, route: usize) -> Option<&Direct> {
        match self.routes.get(route) {
            Some(Route::In { direct, .. }) => Some(direct),
            _ => None,
        }
    }

    /// Bridges the domains whose framework has appeared, then compares discovery with the
    /// routes: (de)activates writers, gives new remote writers connections, releases those
    /// that left, and counts each domain's DDS readers.
    fn rediscover(&mut self) {
        for di in 0..self.domains.len() {
            // Looked at every time: it keeps the presence connection across framework restarts.
            let hosted = self.hosted(di);
            if hosted && !self.domains[di].bridged {
                match self.bridge(di, None).and_then(|()| self.dds.announce()) {
                    Ok(()) => {
                        info!(domain = %self.domains[di].name, "hosted in namespace '{}': bridged", self.cfg.namespace)
                    }
                    Err(e) => warn!(domain = %self.domains[di].name, "cannot bridge the domain: {e}"),
                }
            }
        }
        let remote = self.dds.remote();
        let mut readers = vec![0usize; self.domains.len()];
        let mut matched_writers: BTreeSet<(usize, Guid)> = BTreeSet::new();
        let mut set_writers: Vec<BTreeSet<Guid>> = vec![BTreeSet::new(); self.plan.len()];
        for (ri, route) in self.routes.iter().enumerate() {
            match route {
                Route::Out { domain, topics, activation, set } => {
                    let on = remote.readers_on(topics);
                    activation.set_readers(&on);
                    if let Some(si) = set {
                        readers[*domain] += on.len();
                        self.set_stats[*si].readers.store(on.len() as u64, Ordering::Relaxed);
                    }
                }
                Route::In { domain, set, topic, .. } => {
                    set_writers[*set].extend(remote.writers_on(topic));
                    if self.domains[*domain].mirror.is_none() {
                        matched_writers.extend(remote.writers_on(topic).map(|g| (ri, g)));
                    }
                }
            }
        }
        for (s, w) in self.set_stats.iter().zip(&set_writers) {
            s.writers.store(w.len() as u64, Ordering::Relaxed);
        }
        // Remote writers: a connection each, from the moment they match.
        for &key in &matched_writers {
            if !self.writers.contains_key(&key) {
                self.add_writer(key);
            }
        }
        let grace = Duration::from_secs(2);
        let routes = &self.routes;
        self.writers.retain(|key, w| {
            let listed = matched_writers.contains(key);
            w.listed |= listed;
            // Known from a sample only: discovery may not list it yet.
            let keep = listed || (!w.listed && w.created.elapsed() < grace);
            if keep {
                w.writer.tick();
            } else {
                info!("DDS writer {} left: its connection is released", key.1.short());
                if let Some(Route::In { direct, .. }) = routes.get(key.0) {
                    direct.remove(&key.1);
                }
            }
            keep
        });
        for (d, n) in self.domains.iter_mut().zip(readers) {
            d.dds_readers = n;
            if let Some(p) = &d.presence {
                p.set_dds_readers(n as u64);
            }
        }
        self.stats.remote_writers.store(self.writers.len() as u64, Ordering::Relaxed);
        self.stats.remote_readers.store(self.dds_readers() as u64, Ordering::Relaxed);
    }

    fn stop(&mut self) {
        self.cfg.stop.store(true, Ordering::Release);
        self.writers.clear();
        for r in &self.routes {
            if let Route::In { direct, .. } = r {
                direct.clear();
            }
        }
        for d in &mut self.domains {
            d.mirror = None;
            d.presence = None;
        }
        for r in &self.routes {
            if let Route::Out { activation, .. } = r {
                activation.wake();
            }
        }
        self.poller_thread.unpark();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// The typed shared-memory -> DDS writer of a planned set.
fn set_writer(dds: &dyn Engine, d: &Domain, p: &PlannedSet) -> Result<Outbound, GatewayError> {
    let codec = Arc::new(SetCodec::new(&d.set(p.role).layout));
    let writer = dds.writer(&p.topic, &p.dds_type, &p.writer_qos)?;
    Ok(Outbound::Set(Box::new(SetWriter::new(codec, writer))))
}

/// A shared-memory -> DDS route over `topics`: registered in `routes`, and its activation
/// (on while the topics have remote readers) returned for the thread that serves it.
fn route_out(routes: &mut Vec<Route>, domain: usize, topics: Vec<String>, set: Option<usize>) -> Arc<Activation> {
    let activation = Arc::new(Activation::default());
    routes.push(Route::Out { domain, topics, activation: activation.clone(), set });
    activation
}
