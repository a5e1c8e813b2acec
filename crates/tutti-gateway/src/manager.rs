//! The route manager: builds every route of the model, then runs one `select!` loop that
//! takes DDS samples from the reader tasks, compares discovery with the connections it
//! holds, reports status and stops on request. Shared-memory work happens on the routes'
//! own threads; this loop only hands samples over and never blocks.

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc as std_mpsc;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tokio::sync::mpsc;
use tracing::{info, warn};
use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::{self, Endpoint, Qos};
use tutti_core::shm::{Framework, FrameworkOptions, Participant, ShmError};

use crate::cdr::{SetCodec, TypedSample};
use crate::engine::{self, Decode, Engine, Guid};
use crate::routes::clock::{self, ClockPump};
use crate::routes::from_dds::{self, Direct, RemoteWriter, Sample};
use crate::routes::per_item::{self, ItemWriters};
use crate::routes::to_dds::{self, Activation, Outbound, SetWriter, Watched};
use crate::routes::{mirror, Event, Payload, ShmConfig};
use crate::stats::{LogLimit, Stats};
use crate::{GatewayError, GatewayOptions, TypeMode};

/// A route as the manager sees it.
#[derive(Debug)]
enum Route {
    /// DDS -> shared memory (or -> the mirror's framework); `direct`: the writers whose
    /// samples the reader task commits itself (asynchronous domains).
    In { domain: usize, topic: String, direct: Direct },
    /// Shared memory -> DDS; `counts_readers`: its remote readers get connections.
    Out { domain: usize, topics: Vec<String>, activation: Arc<Activation>, counts_readers: bool },
}

#[derive(Debug)]
struct DomainState {
    name: String,
    synchronous: bool,
    own_commits: Arc<AtomicU64>,
    /// Connections standing for the remote readers of the PUBLISH set (None: connecting).
    readers: HashMap<Guid, Option<Participant>>,
    mirror: Option<std_mpsc::Sender<TypedSample>>,
}

#[derive(Debug)]
struct WriterEntry {
    writer: RemoteWriter,
    created: Instant,
}

/// Serves `opts` until `shutdown` is set; `on_status` is called every `status_every` with
/// a one-line summary (and once when the gateway is up).
pub fn run(
    opts: GatewayOptions,
    shutdown: Arc<AtomicBool>,
    status_every: Duration,
    on_status: &mut dyn FnMut(&str),
) -> Result<Arc<Stats>, GatewayError> {
    if opts.mirror && opts.types == TypeMode::PerItem {
        return Err(GatewayError::Invalid("--mirror needs --ros2-types typed: per-item samples carry no step".into()));
    }
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(GatewayError::Runtime)?;
    let stats = Arc::new(Stats::default());
    let cfg = ShmConfig {
        namespace: opts.namespace.clone(),
        timeout: opts.timeout,
        wait: opts.wait,
        poll: opts.poll,
        stop: Arc::new(AtomicBool::new(false)),
    };
    let mut m = Manager::build(&opts, cfg, stats.clone())?;
    on_status(&format!("up: {}", m.line()));
    rt.block_on(m.serve(&opts, shutdown, status_every, on_status));
    m.stop();
    drop(rt);
    Ok(stats)
}

struct Manager {
    dds: Box<dyn Engine>,
    cfg: ShmConfig,
    stats: Arc<Stats>,
    routes: Vec<Route>,
    domains: Vec<DomainState>,
    writers: HashMap<(usize, Guid), WriterEntry>,
    threads: Vec<JoinHandle<()>>,
    events: mpsc::UnboundedReceiver<Event>,
    connected_tx: mpsc::UnboundedSender<(usize, Guid, Result<Participant, ShmError>)>,
    connected: mpsc::UnboundedReceiver<(usize, Guid, Result<Participant, ShmError>)>,
    topics: usize,
    bad_log: LogLimit,
}

impl std::fmt::Debug for Manager {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Manager").field("routes", &self.routes.len()).finish()
    }
}

impl Manager {
    fn build(opts: &GatewayOptions, cfg: ShmConfig, stats: Arc<Stats>) -> Result<Manager, GatewayError> {
        let engine = engine::open(opts.engine, &opts.engine_config())?;
        let dds: &dyn Engine = &*engine;
        let (tx, events) = mpsc::unbounded_channel();
        let (connected_tx, connected) = mpsc::unbounded_channel();
        let pkg = mapping::package_name(&opts.ddf_path);
        let mut hosts = if opts.mirror {
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
        let mut routes = Vec::new();
        let mut domains = Vec::new();
        let mut watched: Vec<Box<dyn to_dds::Polled>> = Vec::new();
        let mut threads = Vec::new();
        let mut topics = 0usize;
        for (di, d) in opts.model.domains.iter().enumerate() {
            let wq = mapping::qos(d.flags, opts.profile, Endpoint::Writer, opts.strength);
            let rq = mapping::qos(d.flags, opts.profile, Endpoint::Reader, opts.strength);
            let own_commits = Arc::new(AtomicU64::new(0));
            let mut state = DomainState {
                name: d.name.clone(),
                synchronous: d.flags.synchronous,
                own_commits: own_commits.clone(),
                readers: HashMap::new(),
                mirror: None,
            };
            match (opts.types, opts.mirror) {
                (TypeMode::Typed, false) => {
                    topics += 2;
                    let (pubn, subn) = (
                        mapping::set_names(&pkg, &d.name, Role::Publish),
                        mapping::set_names(&pkg, &d.name, Role::Subscribe),
                    );
                    // PUBLISH: shared memory -> DDS.
                    let out = set_writer(dds, d, Role::Publish, &pubn, &wq)?;
                    let activation = route_out(&mut routes, di, vec![pubn.topic.clone()], true);
                    if d.flags.synchronous {
                        let name = format!("{} sync reader", opts.node_name);
                        threads.push(
                            to_dds::spawn_sync_pump(d.name.clone(), out, activation, cfg.clone(), stats.clone(), name)
                                .map_err(|e| GatewayError::dds("a thread", e))?,
                        );
                    } else {
                        watched.push(Box::new(Watched::new(d.name.clone(), Role::Publish, out, activation, None)));
                    }
                    // SUBSCRIBE: DDS -> shared memory, and shared-memory writers -> DDS.
                    let decode = Decode::Set(Arc::new(SetCodec::new(&d.subscribe.layout)));
                    inbound(dds, &mut routes, &tx, &stats, di, &subn.topic, &subn.dds_type, decode, &rq)?;
                    let out = set_writer(dds, d, Role::Subscribe, &subn, &wq)?;
                    let activation = route_out(&mut routes, di, vec![subn.topic], false);
                    watched.push(Box::new(Watched::new(
                        d.name.clone(),
                        Role::Subscribe,
                        out,
                        activation,
                        Some(own_commits),
                    )));
                }
                (TypeMode::Typed, true) => {
                    topics += 2;
                    let (pubn, subn) = (
                        mapping::set_names(&pkg, &d.name, Role::Publish),
                        mapping::set_names(&pkg, &d.name, Role::Subscribe),
                    );
                    let decode = Decode::Set(Arc::new(SetCodec::new(&d.publish.layout)));
                    inbound(dds, &mut routes, &tx, &stats, di, &pubn.topic, &pubn.dds_type, decode, &rq)?;
                    let out = set_writer(dds, d, Role::Subscribe, &subn, &wq)?;
                    let (mtx, mrx) = std_mpsc::channel();
                    let host = hosts
                        .get_mut(di)
                        .and_then(Option::take)
                        .ok_or_else(|| GatewayError::Invalid(format!("domain '{}' was not created", d.name)))?;
                    threads.push(
                        mirror::spawn(host, mrx, out, cfg.clone(), stats.clone())
                            .map_err(|e| GatewayError::dds("a thread", e))?,
                    );
                    state.mirror = Some(mtx);
                }
                (TypeMode::PerItem, _) => {
                    let pub_topics = mapping::item_topics(d, Role::Publish);
                    let sub_topics = mapping::item_topics(d, Role::Subscribe);
                    topics += pub_topics.len() + sub_topics.len();
                    let out = Outbound::Items(ItemWriters::create(dds, &pub_topics, &d.publish.layout, &wq)?);
                    let topics = pub_topics.iter().map(|t| t.topic.clone()).collect();
                    let activation = route_out(&mut routes, di, topics, true);
                    watched.push(Box::new(Watched::new(d.name.clone(), Role::Publish, out, activation, None)));
                    for t in &sub_topics {
                        let Some(leaf) = d.subscribe.layout.leaf(&t.path) else { continue };
                        let decode = per_item::decoder(leaf);
                        inbound(dds, &mut routes, &tx, &stats, di, &t.topic, &t.dds_type, decode, &rq)?;
                    }
                    let out = Outbound::Items(ItemWriters::create(dds, &sub_topics, &d.subscribe.layout, &wq)?);
                    let topics = sub_topics.iter().map(|t| t.topic.clone()).collect();
                    let activation = route_out(&mut routes, di, topics, false);
                    watched.push(Box::new(Watched::new(
                        d.name.clone(),
                        Role::Subscribe,
                        out,
                        activation,
                        Some(own_commits),
                    )));
                }
            }
            domains.push(state);
        }
        if let Some(di) = opts.clock_domain()? {
            let d = &opts.model.domains[di];
            let writer = dds.writer(clock::TOPIC, clock::TYPE, &clock::qos())?;
            let activation = route_out(&mut routes, di, vec![clock::TOPIC.to_string()], false);
            watched.push(Box::new(ClockPump::new(d.name.clone(), writer, activation, opts.clock_rate)));
            topics += 1;
            info!(domain = %d.name, "/clock: the simulated time of {}", d.name);
        }
        if !watched.is_empty() {
            threads.push(
                to_dds::spawn_poller(watched, cfg.clone(), stats.clone())
                    .map_err(|e| GatewayError::dds("a thread", e))?,
            );
        }
        dds.announce()?;
        Ok(Manager {
            dds: engine,
            cfg,
            stats,
            routes,
            domains,
            writers: HashMap::new(),
            threads,
            events,
            connected_tx,
            connected,
            topics,
            bad_log: LogLimit::new(Duration::from_secs(5)),
        })
    }

    /// Connections standing for remote readers, over all domains.
    fn remote_readers(&self) -> usize {
        self.domains.iter().map(|d| d.readers.len()).sum()
    }

    fn line(&self) -> String {
        format!(
            "{} domains, {} topics, DDS domain {} ({}), remote writers {}, remote readers {} | {}",
            self.domains.len(),
            self.topics,
            self.dds.domain_id(),
            self.dds.kind(),
            self.writers.len(),
            self.remote_readers(),
            self.stats
        )
    }

    async fn serve(
        &mut self,
        opts: &GatewayOptions,
        shutdown: Arc<AtomicBool>,
        status_every: Duration,
        on_status: &mut dyn FnMut(&str),
    ) {
        let mut discovery = tokio::time::interval(opts.discovery_every);
        discovery.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        let mut status = tokio::time::interval_at(tokio::time::Instant::now() + status_every, status_every);
        let mut check = tokio::time::interval(Duration::from_millis(50));
        loop {
            tokio::select! {
                Some(ev) = self.events.recv() => self.on_event(ev),
                Some((di, gid, r)) = self.connected.recv() => self.on_connected(di, gid, r),
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
                Stats::add(&self.stats.bad_samples, 1);
                let topic = match self.routes.get(route) {
                    Some(Route::In { topic, .. }) => topic.as_str(),
                    _ => "?",
                };
                if let Some(held) = self.bad_log.allow() {
                    warn!(topic, "sample dropped ({held} more since the last report): {error}");
                }
            }
        }
    }

    /// Gives remote writer `key.1` of inbound route `key.0` its connection (committed by
    /// the route's reader task where the domain allows); false if it cannot be started.
    fn add_writer(&mut self, key: (usize, Guid)) -> bool {
        let Some(Route::In { domain, direct, .. }) = self.routes.get(key.0) else { return false };
        let d = &self.domains[*domain];
        let gid = key.1;
        let spawned = RemoteWriter::spawn(
            d.name.clone(),
            gid,
            d.synchronous,
            self.cfg.clone(),
            self.stats.clone(),
            d.own_commits.clone(),
        );
        match spawned {
            Ok(writer) => {
                info!(domain = %d.name, "DDS writer {} joined", gid.short());
                direct.insert(gid, writer.clone());
                self.writers.insert(key, WriterEntry { writer, created: Instant::now() });
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

    fn on_connected(&mut self, di: usize, gid: Guid, r: Result<Participant, ShmError>) {
        let Some(d) = self.domains.get_mut(di) else { return };
        match (d.readers.get_mut(&gid), r) {
            (Some(slot @ None), Ok(p)) => *slot = Some(p),
            // Not wanted any more, or failed: dropped now; retried at the next discovery.
            (Some(None), Err(_)) => {
                d.readers.remove(&gid);
            }
            _ => {}
        }
    }

    /// Compares discovery with the routes: (de)activates writers, gives new remote writers
    /// and PUBLISH readers connections, releases those that left.
    fn rediscover(&mut self) {
        let remote = self.dds.remote();
        let mut wanted_readers: Vec<BTreeSet<Guid>> = vec![BTreeSet::new(); self.domains.len()];
        let mut matched_writers: BTreeSet<(usize, Guid)> = BTreeSet::new();
        for (ri, route) in self.routes.iter().enumerate() {
            match route {
                Route::Out { domain, topics, activation, counts_readers } => {
                    let readers = remote.readers_on(topics);
                    activation.set_readers(&readers);
                    if *counts_readers {
                        wanted_readers[*domain].extend(readers);
                    }
                }
                Route::In { domain, topic, .. } => {
                    if self.domains[*domain].mirror.is_none() {
                        matched_writers.extend(remote.writers_on(topic).map(|g| (ri, g)));
                    }
                }
            }
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
            let keep = matched_writers.contains(key) || w.created.elapsed() < grace;
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
        // Remote readers of the PUBLISH set: a connection each.
        for (di, wanted) in wanted_readers.into_iter().enumerate() {
            let d = &mut self.domains[di];
            d.readers.retain(|g, _| wanted.contains(g));
            for gid in wanted {
                if d.readers.contains_key(&gid) {
                    continue;
                }
                d.readers.insert(gid, None);
                let opts = self.cfg.connect_options(format!("dds-reader {}", gid.short()), Duration::from_millis(100));
                let (name, tx) = (d.name.clone(), self.connected_tx.clone());
                tokio::task::spawn_blocking(move || {
                    let _ = tx.send((di, gid, Participant::connect(&name, opts)));
                });
            }
        }
        self.stats.remote_writers.store(self.writers.len() as u64, Ordering::Relaxed);
        self.stats.remote_readers.store(self.remote_readers() as u64, Ordering::Relaxed);
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
            d.readers.clear();
            d.mirror = None;
        }
        for r in &self.routes {
            if let Route::Out { activation, .. } = r {
                activation.wake();
            }
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// A DDS -> shared-memory route over `topic` (DDS type `dds_type`, samples read by
/// `decode`): its reader, whose sink decodes (and, in asynchronous domains, commits) its
/// samples on the engine's receive path, and the route entry the sink reports under.
#[allow(clippy::too_many_arguments)]
fn inbound(
    dds: &dyn Engine,
    routes: &mut Vec<Route>,
    tx: &mpsc::UnboundedSender<Event>,
    stats: &Arc<Stats>,
    domain: usize,
    topic: &str,
    dds_type: &str,
    decode: Decode,
    rq: &Qos,
) -> Result<(), GatewayError> {
    let direct = Direct::default();
    routes.push(Route::In { domain, topic: topic.to_string(), direct: direct.clone() });
    let to = (routes.len() - 1, tx.clone(), direct);
    let sink = from_dds::sink(decode.clone(), to, stats.clone(), dds.own_prefix());
    dds.reader(topic, dds_type, rq, decode, sink)
}

/// The typed shared-memory -> DDS writer of one set.
fn set_writer(
    dds: &dyn Engine,
    d: &Domain,
    role: Role,
    names: &mapping::SetNames,
    q: &Qos,
) -> Result<Outbound, GatewayError> {
    let codec = Arc::new(SetCodec::new(&d.set(role).layout));
    let writer = dds.writer(&names.topic, &names.dds_type, q)?;
    Ok(Outbound::Set(Box::new(SetWriter::new(codec, writer))))
}

/// A shared-memory -> DDS route over `topics`: registered in `routes`, and its activation
/// (on while the topics have remote readers) returned for the thread that serves it.
fn route_out(routes: &mut Vec<Route>, domain: usize, topics: Vec<String>, counts_readers: bool) -> Arc<Activation> {
    let activation = Arc::new(Activation::default());
    routes.push(Route::Out { domain, topics, activation: activation.clone(), counts_readers });
    activation
}
