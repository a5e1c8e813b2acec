//! The route manager: bridges each domain once a framework hosts it (or all of them from
//! the start with `hosted_only` off, or as a mirror), building each route with its kind's
//! constructor in [`crate::routes`], then runs one `select!` loop that compares discovery
//! with the connections it holds, reports status and stops on request. Samples do not pass
//! through it: readers' sinks commit them (or hand them to a mirror's thread) on the
//! engine's receive path. The loop only hears of a DDS writer's sample while that writer has
//! no connection yet (it then gives it one), and of samples that could not be decoded.
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
use tutti_core::shm::observer::{Look, Observer};
use tutti_core::shm::{DomainHost, Framework, FrameworkOptions};

use crate::cdr::SetCodec;
use crate::config::{self, ConfigError, PlannedSet};
use crate::engine::{self, Decode, EndpointId, Engine, TopicType};
use crate::routes::from_dds::{self, Destination, Direct, RemoteWriter, Sample, Target};
use crate::routes::from_step::{self, StepRoute};
use crate::routes::mirror::{self, MirrorCounters};
use crate::routes::to_dds::{self, Activation, Outgoing, Polled, ServedBy};
use crate::routes::{clock, per_item, poses, Counters, Event, ShmConfig};
use crate::stats::{LogLimit, SetStats, Stats};
use crate::{foxglove, http, GatewayError, GatewayOptions, TypeMode};

/// A route as the manager sees it.
#[derive(Debug)]
enum Route {
    /// DDS -> shared memory; `set`: the planned set it belongs to; `direct`: the remote
    /// writers whose samples the reader's sink commits (None for a mirror, whose sink hands
    /// every sample to the mirror's thread: its writers get no connections).
    In { domain: usize, set: usize, topic: String, direct: Option<Direct> },
    /// Shared memory -> DDS; `set`: the planned set its topics are (None: `/clock`), whose
    /// readers the domain counts.
    Out { domain: usize, topics: Vec<String>, activation: Arc<Activation>, set: Option<usize> },
}

#[derive(Debug)]
struct DomainState {
    name: String,
    synchronous: bool,
    /// Steps of lookahead of its DDS writers' answers (docs/run.md, "Sites and lookahead").
    lookahead: u32,
    own_commits: Arc<AtomicU64>,
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
    opts: GatewayOptions,
    shutdown: Arc<AtomicBool>,
    status_every: Duration,
    on_status: &mut dyn FnMut(&str),
) -> Result<Arc<Stats>, GatewayError> {
    let (m, rt) = start(opts, Placement::Process)?;
    Ok(m.serve_until(rt, shutdown, status_every, on_status))
}

/// Where the frameworks whose domains the gateway bridges run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Placement {
    /// In other processes: their PUBLISH sets are followed in shared memory.
    Process,
    /// In this process, which hands each step's PUBLISH sets to the routes the manager
    /// leaves it ([`Manager::take_step_routes`]); every domain is bridged from the start.
    InProcess,
}

/// Checks `opts`, opens the engine and builds the routes of the domains to bridge now;
/// returns the manager and the runtime of its loop.
pub(crate) fn start(
    mut opts: GatewayOptions,
    placement: Placement,
) -> Result<(Manager, tokio::runtime::Runtime), GatewayError> {
    if opts.mirror && opts.types == TypeMode::PerItem {
        return Err(GatewayError::MirrorNeedsTyped);
    }
    // Canonical from here on (`sim1`, `a/b`, or empty), as the routes and the report use it.
    opts.ros_namespace = tutti_ros2::names::namespace(&opts.ros_namespace).map_err(ConfigError::from)?;
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
    let mut m = Manager::build(opts, plan, cfg, stats, placement)?;
    if let Some(addr) = m.opts.http {
        let (thread, bound, stop) = http::serve(addr, m.report_fn())?;
        info!("stats on http://{bound}/metrics (Prometheus) and http://{bound}/stats (JSON)");
        m.http = Some((thread, stop));
    }
    if let Some(addr) = m.opts.foxglove {
        let mut counters: Vec<Counters> = (0..m.plan.len()).map(|si| m.counters(si)).collect();
        // The entities' `/tf` channel counts in the totals only.
        counters.push(Counters { total: m.stats.clone(), set: Default::default() });
        // Its `time` follows `/clock`'s domain, else the first.
        let time_domain = m.clock_domain.or((!m.domains.is_empty()).then_some(0));
        let (thread, bound) = foxglove::serve(addr, &rt, &m.opts, &m.plan, counters, m.cfg.clone(), time_domain)?;
        info!("Foxglove WebSocket server on ws://{bound}/");
        m.threads.push(thread);
    }
    Ok((m, rt))
}

pub(crate) struct Manager {
    opts: GatewayOptions,
    placement: Placement,
    /// Per domain, its PUBLISH set's route written from the framework's step (in-process),
    /// until [`Manager::take_step_routes`] hands them over.
    step_routes: Vec<Option<Box<StepRoute>>>,
    /// The stats endpoint's thread and its stop, when served.
    http: Option<(JoinHandle<()>, http::Shutdown)>,
    plan: Vec<PlannedSet>,
    /// The counters of each planned set (same order).
    set_stats: Vec<Arc<SetStats>>,
    clock_domain: Option<usize>,
    dds: Arc<dyn Engine>,
    cfg: ShmConfig,
    stats: Arc<Stats>,
    routes: Vec<Route>,
    domains: Vec<DomainState>,
    writers: HashMap<(usize, EndpointId), WriterEntry>,
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
        placement: Placement,
    ) -> Result<Manager, GatewayError> {
        if opts.mirror && placement == Placement::InProcess {
            return Err(GatewayError::InProcessMirror);
        }
        let clock_domain = opts.clock_domain()?;
        let dds: Arc<dyn Engine> = Arc::from(engine::open(opts.engine, &opts.engine_config())?);
        let (events_tx, events) = mpsc::unbounded_channel();
        let (poller, added) = std_mpsc::channel();
        let poll_thread =
            to_dds::spawn_poller(added, cfg.clone(), stats.clone()).map_err(|e| GatewayError::Thread("a thread", e))?;
        let poller_thread = poll_thread.thread().clone();
        let mut hosts = mirror_hosts(&opts, &plan)?;
        let domains = opts
            .model
            .domains
            .iter()
            .map(|d| DomainState {
                name: d.name.clone(),
                synchronous: d.flags.synchronous,
                lookahead: opts.lookahead.of(&d.name),
                own_commits: Arc::new(AtomicU64::new(0)),
                bridged: false,
                presence: (!opts.mirror).then(|| Observer::with_presence(d.name.clone(), &opts.node_name)),
                dds_readers: 0,
            })
            .collect();
        let set_stats = plan.iter().map(|_| Arc::new(SetStats::default())).collect();
        let step_routes = opts.model.domains.iter().map(|_| None).collect();
        let mut m = Manager {
            opts,
            placement,
            step_routes,
            http: None,
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
        // In-process, the framework of every domain is this process's, there already.
        let bridge_all = m.opts.mirror || !m.opts.hosted_only || placement == Placement::InProcess;
        for di in 0..m.domains.len() {
            let host = hosts.get_mut(di).and_then(Option::take);
            if m.opts.mirror && host.is_none() {
                info!(domain = %m.domains[di].name, "not mirrored: `allow` / `deny` leave out both its sets");
                continue;
            }
            if bridge_all || m.hosted(di) {
                m.bridge(di, host)?;
            }
        }
        m.offer_services()?;
        m.dds.announce()?;
        Ok(m)
    }

    /// The `simulation_interfaces` services (docs/ros2.md), unless the gateway is a mirror
    /// (the framework it would control is its own, fed from DDS) or passive.
    fn offer_services(&mut self) -> Result<(), GatewayError> {
        if self.opts.mirror || self.opts.passive {
            return Ok(());
        }
        let entities = crate::entities::DomainEntities::new(
            &self.opts.entities,
            &self.opts.model,
            &self.cfg.namespace,
            self.opts.timeout,
        );
        let thread = crate::services::start(
            self.dds.clone(),
            &self.opts.ros_namespace,
            &self.cfg.namespace,
            &self.opts.model,
            Box::new(entities),
            self.cfg.stop.clone(),
        );
        if let Some(thread) = self.permitted("*", "the simulation_interfaces services", thread)? {
            self.threads.push(thread);
        }
        Ok(())
    }

    /// `r`, or None where DDS Security's access control refused an entity of it: the
    /// enclave's permissions do not allow `topic` (in that direction), which is then left
    /// out, with a warning, and counted in `denied` (docs/security.md, "What the network
    /// can do"). Every other error stands.
    fn permitted<T>(&self, domain: &str, topic: &str, r: Result<T, GatewayError>) -> Result<Option<T>, GatewayError> {
        match r {
            Err(GatewayError::Engine(engine::EngineError::NotAllowed { what })) => {
                warn!(domain, "{topic} left out: the enclave's permissions do not allow {what}");
                Stats::add(&self.stats.denied, 1);
                Ok(None)
            }
            r => r.map(Some),
        }
    }

    /// The routes of the framework's own PUBLISH sets (per domain; None: not bridged), for
    /// the in-process sink; empty afterwards.
    pub(crate) fn take_step_routes(&mut self) -> Vec<Option<Box<StepRoute>>> {
        std::mem::take(&mut self.step_routes)
    }

    /// The gateway's counters.
    pub(crate) fn stats(&self) -> Arc<Stats> {
        self.stats.clone()
    }

    /// Serves (the stats endpoint too, if asked for) until `shutdown` is set, then stops
    /// every route's thread; returns the counters.
    pub(crate) fn serve_until(
        mut self,
        rt: tokio::runtime::Runtime,
        shutdown: Arc<AtomicBool>,
        status_every: Duration,
        on_status: &mut dyn FnMut(&str),
    ) -> Arc<Stats> {
        on_status(&format!("up: {}", self.line()));
        self.warn_unhosted();
        rt.block_on(self.serve(shutdown, status_every, on_status));
        self.stop();
        if let Some((thread, stop)) = self.http.take() {
            stop.stop();
            let _ = thread.join();
        }
        drop(rt);
        self.stats.clone()
    }

    /// What the stats endpoint serves: the totals and each planned set's counters, read from
    /// the same atomics the routes count in (no call into the manager).
    fn report_fn(&self) -> http::ReportFn {
        let ns = self.opts.ros_namespace.clone();
        let gateway = http::GatewayReport {
            engine: self.dds.kind().name().to_string(),
            dds_domain: self.dds.domain_id(),
            node: tutti_ros2::names::under(&ns, &self.opts.node_name),
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
            Look::Gone => false,
            Look::Stopped => {
                info!(domain = %self.domains[di].name, "its framework stopped: the presence connection is released");
                false
            }
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

    /// Creates the routes of domain `di` (`host`: its framework, for a mirror), each with its
    /// kind's constructor, and `/clock` if it comes from this domain.
    fn bridge(&mut self, di: usize, host: Option<DomainHost>) -> Result<(), GatewayError> {
        let d = self.opts.model.domains[di].clone();
        if self.opts.mirror {
            let host = host.ok_or_else(|| GatewayError::NotCreated { domain: d.name.clone() })?;
            self.mirror(di, &d, host)?;
        } else {
            let sets: Vec<usize> = (0..self.plan.len()).filter(|&si| self.plan[si].domain == di).collect();
            for si in sets {
                match self.opts.types {
                    TypeMode::Typed => self.typed(di, &d, si)?,
                    TypeMode::PerItem => self.per_item(di, &d, si)?,
                }
            }
        }
        if self.clock_domain == Some(di) {
            let out = clock::route(&*self.dds, &d.name, &self.opts.ros_namespace, self.opts.clock_rate);
            if let Some(out) = self.permitted(&d.name, "/clock", out)? {
                info!(domain = %d.name, "{}: the simulated time of {}", out.topics[0], d.name);
                self.outgoing(di, None, out);
            }
        }
        // The entities' poses, once, with the first entity's domain (a mirror's home serves them).
        if !self.opts.mirror && self.opts.entities.first().is_some_and(|e| e.domain == d.name) {
            let (o, cfg) = (&self.opts, &self.cfg);
            let out = poses::route(&*self.dds, &o.entities, &o.model, cfg, &o.ros_namespace, o.pose_rate);
            if let Some(out) = self.permitted(&d.name, "/tf", out)? {
                info!("{} and {} pose topics: the entities' poses", out.topics[0], out.topics.len() - 1);
                self.outgoing(di, None, out);
            }
        }
        self.poller_thread.unpark();
        self.domains[di].bridged = true;
        Ok(())
    }

    /// The planned set of domain `di` in `role`, if the gateway bridges it.
    fn planned(&self, di: usize, role: Role) -> Option<usize> {
        self.plan.iter().position(|p| p.domain == di && p.role == role)
    }

    fn counters(&self, si: usize) -> Counters {
        Counters { total: self.stats.clone(), set: self.set_stats[si].clone() }
    }

    /// Whether a set in `role` goes to DDS from the framework's step rather than from shared
    /// memory: the framework's own PUBLISH set, when the framework is this process.
    fn written_from_step(&self, role: Role) -> bool {
        self.placement == Placement::InProcess && role == Role::Publish
    }

    /// Typed set `si`: a PUBLISH set goes to DDS; a SUBSCRIBE set comes from DDS, and its
    /// shared-memory writers go to DDS too.
    fn typed(&mut self, di: usize, d: &Domain, si: usize) -> Result<(), GatewayError> {
        let p = self.plan[si].clone();
        self.topics += 1;
        let own_commits = match p.role {
            Role::Publish => None,
            Role::Subscribe => {
                let decode = Decode::Set(Arc::new(SetCodec::new(&d.subscribe.layout)));
                let r = self.inbound(di, si, &p.ros2_topic, &p.topic_type(), decode, None);
                self.permitted(&d.name, &p.ros2_topic, r)?;
                Some(self.domains[di].own_commits.clone())
            }
        };
        let out = if self.written_from_step(p.role) {
            from_step::typed(&*self.dds, d, &p, self.counters(si), self.cfg.patience())
        } else {
            // With a lookahead, the other site answers every step, so it must be sent every step.
            let every_step = (self.opts.every_step || self.domains[di].lookahead > 0)
                .then(|| format!("{} every-step reader", self.opts.node_name));
            to_dds::typed(&*self.dds, d, &p, &self.cfg, self.counters(si), own_commits, every_step)
        };
        if let Some(out) = self.permitted(&d.name, &p.ros2_topic, out)? {
            self.outgoing(di, Some(si), out);
        }
        Ok(())
    }

    /// Per-item set `si`: a topic per item, as [`Manager::typed`] does for the whole set.
    fn per_item(&mut self, di: usize, d: &Domain, si: usize) -> Result<(), GatewayError> {
        let p = self.plan[si].clone();
        let items = config::item_ros2_topics(&self.opts, &p);
        self.topics += items.len();
        let own_commits = match p.role {
            Role::Publish => None,
            Role::Subscribe => {
                for t in &items {
                    let Some(leaf) = d.subscribe.layout.leaf(&t.path) else { continue };
                    let r =
                        self.inbound(di, si, &t.topic, &TopicType::stock(&t.dds_type), per_item::decoder(leaf), None);
                    self.permitted(&d.name, &t.topic, r)?;
                }
                Some(self.domains[di].own_commits.clone())
            }
        };
        let out = if self.written_from_step(p.role) {
            from_step::items(&*self.dds, d, &p, &items, self.counters(si), self.cfg.patience())
        } else {
            to_dds::items(&*self.dds, d, &p, &items, self.set_stats[si].clone(), own_commits)
        };
        if let Some(out) = self.permitted(&d.name, &p.ros2_topic, out)? {
            self.outgoing(di, Some(si), out);
        }
        Ok(())
    }

    /// A mirrored domain: its framework's thread, fed by the PUBLISH reader's sink, sends
    /// the local SUBSCRIBE set. The counters of a set the config leaves out count what
    /// nobody reads.
    fn mirror(&mut self, di: usize, d: &Domain, host: DomainHost) -> Result<(), GatewayError> {
        let (publish, subscribe) = (self.planned(di, Role::Publish), self.planned(di, Role::Subscribe));
        let set = |si: Option<usize>| si.map_or_else(|| Arc::new(SetStats::default()), |si| self.set_stats[si].clone());
        let counters = MirrorCounters { total: self.stats.clone(), publish: set(publish), subscribe: set(subscribe) };
        let out = match subscribe {
            Some(si) => {
                self.topics += 1;
                let w = to_dds::set_writer(&*self.dds, d, &self.plan[si]);
                self.permitted(&d.name, &self.plan[si].ros2_topic, w)?
            }
            None => None,
        };
        let (tx, rx) = std_mpsc::channel();
        let thread = mirror::spawn(host, rx, out, self.cfg.clone(), counters, self.domains[di].lookahead);
        self.threads.push(thread.map_err(|e| GatewayError::Thread("a thread", e))?);
        if let Some(si) = publish {
            self.topics += 1;
            let p = self.plan[si].clone();
            let decode = Decode::Set(Arc::new(SetCodec::new(&d.publish.layout)));
            let r = self.inbound(di, si, &p.ros2_topic, &p.topic_type(), decode, Some(tx));
            self.permitted(&d.name, &p.ros2_topic, r)?;
        }
        Ok(())
    }

    /// Registers a shared-memory -> DDS route of domain `di` (`set`: its planned set; None:
    /// `/clock`) and hands it to what serves it.
    fn outgoing(&mut self, di: usize, set: Option<usize>, out: Outgoing) {
        let Outgoing { topics, activation, served_by } = out;
        self.routes.push(Route::Out { domain: di, topics, activation, set });
        match served_by {
            // The poller only ends with the gateway.
            ServedBy::Poller(p) => {
                let _ = self.poller.send(p);
            }
            ServedBy::Thread(t) => self.threads.push(t),
            ServedBy::Step(r) => {
                if let Some(slot) = self.step_routes.get_mut(di) {
                    *slot = Some(r);
                }
            }
        }
    }

    /// A DDS -> shared-memory route of planned set `set` over `topic` (of type `ty`,
    /// samples read by `decode`): its reader, whose sink decodes and commits the samples on
    /// the engine's receive path (or, with `mirror`, hands them to the mirror's thread).
    fn inbound(
        &mut self,
        domain: usize,
        set: usize,
        topic: &str,
        ty: &TopicType,
        decode: Decode,
        mirror: Option<std_mpsc::Sender<crate::cdr::TypedSample>>,
    ) -> Result<(), GatewayError> {
        let (direct, target) = match mirror {
            Some(tx) => (None, Target::Mirror(tx)),
            None => {
                let direct = Direct::default();
                (Some(direct.clone()), Target::Writers(direct))
            }
        };
        let route = self.routes.len();
        self.routes.push(Route::In { domain, set, topic: topic.to_string(), direct });
        let to = Destination { route, events: self.events_tx.clone(), target };
        let rq = self.plan[set].reader_qos;
        let r = from_dds::reader(&*self.dds, topic, ty, &rq, decode, to);
        if r.is_err() {
            // No reader: the route has nothing to route.
            self.routes.pop();
        }
        r
    }

    /// DDS readers, over all domains (each set's once).
    fn dds_readers(&self) -> usize {
        self.domains.iter().map(|d| d.dds_readers).sum()
    }

    fn line(&self) -> String {
        let bridged = self.domains.iter().filter(|d| d.bridged).count();
        let net = self.dds.kind().network();
        format!(
            "{bridged} of {} domains bridged, {} topics, {} ({}), {net} writers {}, {net} readers {} | {}",
            self.domains.len(),
            self.topics,
            self.dds.location(),
            self.dds.kind(),
            self.writers.len(),
            self.dds_readers(),
            self.stats
        )
    }

    async fn serve(&mut self, shutdown: Arc<AtomicBool>, status_every: Duration, on_status: &mut dyn FnMut(&str)) {
        let mut discovery = tokio::time::interval(self.opts.discovery_every);
        discovery.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        // The CLI and the config file refuse a zero or overlong period; a caller of the library
        // that passes one gets the nearest one tokio takes (it panics on zero, and the first
        // tick's instant overflows on a huge one).
        let status_every = status_every.clamp(Duration::from_millis(1), crate::config::MAX_DURATION);
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
    /// the route's sink where it needs no wait); false if it cannot be started.
    fn add_writer(&mut self, key: (usize, EndpointId)) -> bool {
        let Some(Route::In { domain, set, direct: Some(direct), .. }) = self.routes.get(key.0) else { return false };
        let d = &self.domains[*domain];
        let gid = key.1;
        let spawned = RemoteWriter::spawn(
            d.name.clone(),
            writer_name(&gid, d.lookahead),
            d.synchronous,
            d.lookahead,
            self.cfg.clone(),
            Counters { total: self.stats.clone(), set: self.set_stats[*set].clone() },
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

    /// The writers committed by inbound route `route`'s sink.
    fn direct(&self, route: usize) -> Option<&Direct> {
        match self.routes.get(route) {
            Some(Route::In { direct, .. }) => direct.as_ref(),
            _ => None,
        }
    }

    /// Bridges the domains whose framework has appeared since the last look.
    fn bridge_hosted(&mut self) {
        for di in 0..self.domains.len() {
            // Looked at every time: it keeps the presence connection across framework restarts.
            let hosted = self.hosted(di);
            if hosted && !self.domains[di].bridged {
                match self.bridge(di, None).and_then(|()| Ok(self.dds.announce()?)) {
                    Ok(()) => {
                        info!(domain = %self.domains[di].name, "hosted in namespace '{}': bridged", self.cfg.namespace)
                    }
                    Err(e) => warn!(domain = %self.domains[di].name, "cannot bridge the domain: {e}"),
                }
            }
        }
    }

    /// Bridges the domains whose framework has appeared, then compares discovery with the
    /// routes: (de)activates writers, gives new remote writers connections, releases those
    /// that left, and counts each domain's DDS readers.
    fn rediscover(&mut self) {
        self.bridge_hosted();
        let remote = self.dds.remote();
        let mut readers = vec![0usize; self.domains.len()];
        let mut matched_writers: BTreeSet<(usize, EndpointId)> = BTreeSet::new();
        let mut set_writers: Vec<BTreeSet<EndpointId>> = vec![BTreeSet::new(); self.plan.len()];
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
                Route::In { set, topic, direct, .. } => {
                    set_writers[*set].extend(remote.writers_on(topic));
                    if direct.is_some() {
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
                if let Some(Route::In { direct: Some(direct), .. }) = routes.get(key.0) {
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
        // Our own samples the engine dropped (echo suppression is the engine's).
        self.stats.own_samples.store(self.dds.own_samples(), Ordering::Relaxed);
        self.stats.bad_input.store(self.dds.bad_input(), Ordering::Relaxed);
        self.stats.remote_readers.store(self.dds_readers() as u64, Ordering::Relaxed);
    }

    fn stop(&mut self) {
        self.cfg.stop.store(true, Ordering::Release);
        self.writers.clear();
        for r in &self.routes {
            if let Route::In { direct: Some(direct), .. } = r {
                direct.clear();
            }
        }
        for d in &mut self.domains {
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

/// A mirror's local frameworks, by the DDF's domain index (none when not a mirror): one for
/// each domain with a set bridged. A domain whose sets `allow` / `deny` leave out gets no
/// copy, so that a site mirroring some of a DDF's domains may host the others itself.
fn mirror_hosts(opts: &GatewayOptions, plan: &[PlannedSet]) -> Result<Vec<Option<DomainHost>>, GatewayError> {
    if !opts.mirror {
        return Ok(Vec::new());
    }
    let fo = FrameworkOptions {
        namespace: opts.namespace.clone(),
        timeout: opts.timeout,
        wait: opts.wait,
        ..Default::default()
    };
    let bridged = |di: usize| plan.iter().any(|p| p.domain == di);
    let domains = opts.model.domains.iter().enumerate().filter(|(di, _)| bridged(*di)).map(|(_, d)| d.clone());
    let model = tutti_core::ddf::Model { source: opts.model.source.clone(), domains: domains.collect() };
    let mut hosts: Vec<Option<DomainHost>> = opts.model.domains.iter().map(|_| None).collect();
    for host in Framework::create(&model, &fo)?.domains {
        if let Some(di) = opts.model.domains.iter().position(|d| d.name == host.info().name) {
            hosts[di] = Some(host);
        }
    }
    Ok(hosts)
}

/// The name of a remote writer's connection, as `tutti status` and the framework's reports
/// show it: `dds-writer GID`; with a lookahead, the writer's participant (the other site's
/// gateway: the first 12 bytes of its GID) and K, within the 48 bytes a name has.
fn writer_name(gid: &EndpointId, lookahead: u32) -> String {
    let id = gid.short();
    if lookahead == 0 {
        return format!("dds-writer {id}");
    }
    format!("dds-writer {} lookahead {lookahead}", &id[..id.len().min(24)])
}
