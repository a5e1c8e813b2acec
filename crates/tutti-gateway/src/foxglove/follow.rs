//! The Foxglove server's follower: a thread of its own (`tutti-fg-follow`) that follows the
//! domains from outside, as the gateway's poller does (an [`Observer`] each: no connection,
//! never waited for), and hands the WebSocket sessions what they send:
//!
//! * each subscribed set, when it changed, as a CDR message (the sample the gateway sends
//!   to DDS, stamped with its step's simulated time);
//! * the simulated time of the time domain (`/clock`'s domain, else the first domain);
//! * the connection graph: each domain's participants, as publishers and subscribers of its
//!   two topics.
//!
//! Only non-waiting reads of shared memory run here (a set is copied under its seqlock, or
//! looked at again at the next turn); the sessions, on the manager's runtime, never touch
//! shared memory to read.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use tokio::sync::{broadcast, watch};
use tutti_core::cdr::HEADER_LE;
use tutti_core::ddf::Role;
use tutti_core::shm::observer::{Look, Observer};
use tutti_core::shm::segment::Segment;

use super::protocol::sim_ns;
use super::{Shared, Source};
use crate::entities::{DomainEntities, NewPoses};
use tutti_ros2::simulation::entities::{self as ent, Entities};

/// What the follower hands the sessions.
#[derive(Debug, Clone)]
pub(crate) enum Out {
    /// A new value of channel `channel`: its CDR message and its simulated time.
    Message { channel: u32, time_ns: u64, data: Arc<[u8]> },
    /// The simulated time now.
    Time(u64),
}

/// The connection graph: topic -> ids of its publishers, topic -> ids of its subscribers.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Graph {
    pub published: BTreeMap<String, BTreeSet<String>>,
    pub subscribed: BTreeMap<String, BTreeSet<String>>,
}

/// How often the graph is looked at.
const GRAPH_EVERY: Duration = Duration::from_millis(250);
/// At most one `Time` message in this long.
const TIME_EVERY: Duration = Duration::from_millis(10);
/// The pause between two turns while a client subscribes to something, and while none does.
const BUSY_TURN: Duration = Duration::from_millis(1);
const IDLE_TURN: Duration = Duration::from_millis(20);

/// One channel as the follower reads it.
struct Followed {
    channel: u32,
    role: Role,
    codec: Arc<tutti_core::cdr::SetCodec>,
    /// The set's generation last sent (None: nothing sent since the segment was opened, or
    /// since a new subscription).
    last: Option<u64>,
    /// The channel's subscription epoch when last looked at.
    epoch: u64,
    buf: Vec<u8>,
    body: Vec<u8>,
}

/// Starts the follower; it ends when the gateway stops (`shared.cfg.stop`).
pub(crate) fn spawn(
    shared: Arc<Shared>,
    out: broadcast::Sender<Out>,
    graph: watch::Sender<Graph>,
    time_domain: Option<usize>,
) -> std::io::Result<JoinHandle<()>> {
    thread::Builder::new().name("tutti-fg-follow".into()).spawn(move || run(&shared, &out, &graph, time_domain))
}

fn run(sh: &Shared, out: &broadcast::Sender<Out>, graph: &watch::Sender<Graph>, time_domain: Option<usize>) {
    let mut observers: Vec<Observer> = sh.domains.iter().map(|d| Observer::new(d.name.clone())).collect();
    let mut followed: Vec<Vec<Followed>> = sh.domains.iter().map(|_| Vec::new()).collect();
    let mut poses = None;
    for ch in &sh.channels {
        match &ch.source {
            Source::Set { domain, role, codec } => followed[*domain].push(Followed {
                channel: ch.id,
                role: *role,
                codec: codec.clone(),
                last: None,
                epoch: 0,
                buf: vec![0; codec.shm_size()],
                body: Vec::new(),
            }),
            Source::Poses => poses = Some(PoseFollow::new(sh, ch.id)),
        }
    }
    let (mut last_time, mut time_at) = (None::<u64>, Instant::now());
    let mut graph_at = Instant::now();
    while !sh.cfg.stop.load(Ordering::Acquire) {
        let busy = sh.channels.iter().any(|c| c.subscribers.load(Ordering::Acquire) > 0);
        let look_graph = graph_at.elapsed() >= GRAPH_EVERY;
        let mut g = Graph::default();
        for (di, obs) in observers.iter_mut().enumerate() {
            let seg = match obs.look(&sh.cfg.namespace) {
                Look::Fresh => {
                    followed[di].iter_mut().for_each(|f| f.last = None);
                    obs.segment()
                }
                Look::Same => obs.segment(),
                _ => None,
            };
            let Some(seg) = seg else { continue };
            if time_domain == Some(di) {
                let now = sim_ns(seg.sim_time());
                if last_time != Some(now) && time_at.elapsed() >= TIME_EVERY {
                    (last_time, time_at) = (Some(now), Instant::now());
                    let _ = out.send(Out::Time(now));
                }
            }
            for f in &mut followed[di] {
                let ch = &sh.channels[f.channel as usize - 1];
                let epoch = ch.epoch.load(Ordering::Acquire);
                if epoch != f.epoch {
                    (f.epoch, f.last) = (epoch, None);
                }
                if ch.subscribers.load(Ordering::Acquire) > 0 {
                    if let Some(msg) = f.read(seg) {
                        // No session listening is no error: it subscribed and left.
                        let _ = out.send(msg);
                    }
                }
            }
            if look_graph {
                add_domain(&mut g, sh, di, seg);
            }
        }
        if let Some(p) = &mut poses {
            if let Some(msg) = p.read(sh, &observers) {
                let _ = out.send(msg);
            }
        }
        if look_graph {
            graph_at = Instant::now();
            graph.send_if_modified(|old| {
                let changed = *old != g;
                *old = g;
                changed
            });
        }
        thread::sleep(if busy { BUSY_TURN } else { IDLE_TURN });
    }
}

impl Followed {
    /// The set's value if it changed since the last one sent, with its step and simulated
    /// time; None if it did not, or if it never held still while it was read (it is read
    /// again at the next turn).
    fn read(&mut self, seg: &Segment) -> Option<Out> {
        let generation = seg.generation(self.role);
        if self.last == Some(generation) {
            return None;
        }
        // Labelled with the step the value belongs to, read with it (a SUBSCRIBE set: the
        // step its commit answered).
        let (got, stamp) = seg.try_read_set_stamped(self.role, &mut self.buf, 1 << 10)?;
        let (step, sim) = (stamp.step, stamp.sim_time);
        self.last = Some(got);
        self.codec.encode(step, sim, &self.buf, &mut self.body);
        let mut data = Vec::with_capacity(HEADER_LE.len() + self.body.len());
        data.extend_from_slice(&HEADER_LE);
        data.extend_from_slice(&self.body);
        Some(Out::Message { channel: self.channel, time_ns: sim_ns(sim), data: data.into() })
    }
}

/// The `/tf` channel: the entities' poses, read (as the gateway's `/tf` route reads them) when
/// a step of one of their domains is new, or a client subscribed anew.
struct PoseFollow {
    channel: u32,
    source: DomainEntities,
    /// The entities' domains (indexes of the followed domains).
    domains: Vec<usize>,
    new: NewPoses,
    epoch: u64,
}

impl PoseFollow {
    fn new(sh: &Shared, channel: u32) -> PoseFollow {
        let opts = &sh.entities;
        let mut domains: Vec<usize> =
            opts.iter().filter_map(|e| sh.domains.iter().position(|d| d.name == e.domain)).collect();
        domains.sort_unstable();
        domains.dedup();
        let source = DomainEntities::new(opts, &sh.model, &sh.cfg.namespace, sh.cfg.timeout);
        PoseFollow { channel, source, domains, new: NewPoses::default(), epoch: 0 }
    }

    /// The poses as a `TFMessage`, if a client listens and something moved.
    fn read(&mut self, sh: &Shared, observers: &[Observer]) -> Option<Out> {
        let ch = &sh.channels[self.channel as usize - 1];
        if ch.subscribers.load(Ordering::Acquire) == 0 {
            return None;
        }
        let epoch = ch.epoch.load(Ordering::Acquire);
        let force = std::mem::replace(&mut self.epoch, epoch) != epoch;
        let marks =
            self.domains.iter().map(|&di| observers[di].segment().map(|s| (s.step(), s.time_resets()))).collect();
        let bodies = self.new.take(marks, force, &mut self.source)?;
        let time = bodies.iter().map(|b| b.sim_time).fold(0.0, f64::max);
        let value = ent::tf_value(self.source.list().iter().zip(&bodies));
        let body = ent::tf_message().encode(&value).ok()?;
        let mut data = Vec::with_capacity(HEADER_LE.len() + body.len());
        data.extend_from_slice(&HEADER_LE);
        data.extend_from_slice(&body);
        Some(Out::Message { channel: self.channel, time_ns: sim_ns(time), data: data.into() })
    }
}

/// Domain `di`'s participants in the graph: the framework publishes the PUBLISH topic and
/// subscribes the SUBSCRIBE topic; each participant subscribes the PUBLISH topic, and
/// publishes the SUBSCRIBE topic once it has written it (DDS writers and Foxglove clients,
/// through the gateway, are writers too).
fn add_domain(g: &mut Graph, sh: &Shared, di: usize, seg: &Segment) {
    let status = seg.status();
    let topic = |role: Role| {
        let of = |c: &&super::ChannelInfo| matches!(c.source, Source::Set { domain, role: r, .. } if domain == di && r == role);
        sh.channels.iter().find(of).map(|c| c.topic.clone())
    };
    let framework = format!("framework of {} (pid {})", status.domain, status.framework_pid);
    let (publish, subscribe) = (topic(Role::Publish), topic(Role::Subscribe));
    if let Some(t) = &publish {
        g.published.entry(t.clone()).or_default().insert(framework.clone());
    }
    if let Some(t) = &subscribe {
        g.subscribed.entry(t.clone()).or_default().insert(framework);
    }
    for c in status.connections.iter().filter(|c| !c.observer) {
        let id = format!("{} (pid {})", c.name, c.pid);
        if let (Some(t), false) = (&publish, c.remote) {
            g.subscribed.entry(t.clone()).or_default().insert(id.clone());
        }
        if let (Some(t), true) = (&subscribe, c.writer || c.remote) {
            g.published.entry(t.clone()).or_default().insert(id);
        }
    }
}
