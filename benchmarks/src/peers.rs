//! DDS peers for benchmarks, each a separate DDS participant (normally another process) on
//! the engine of `opts.engine`: the echo ([`run`]) reads the typed PUBLISH samples of a
//! domain and writes each back, unchanged, as a SUBSCRIBE sample (the two sets must have the
//! same layout); the sink ([`sink`]) counts the samples it receives on one of the two
//! topics, and can check that steps arrive once and in order; the source ([`source`])
//! writes SUBSCRIBE samples as fast as it can; the ping ([`ping`], and
//! [`ping_in_listener`] answered on the receive thread as ddsperf's) measures round trips
//! through the echo without the gateway.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::{self, Endpoint, History, Reliability};

use tutti_gateway::cdr::{SetCodec, TypedSample};
use tutti_gateway::config::PlannedSet;
use tutti_gateway::engine::{self, Data, Decode, EndpointId, Engine, Sink, TopicType, Writer};
use tutti_gateway::{GatewayError, GatewayOptions};

/// Why a DDS peer of the benchmark failed.
#[derive(Debug, thiserror::Error)]
pub enum PeerError {
    /// The echo writes back what it reads: its domain's two sets must have one layout.
    #[error("domain '{domain}': the echo needs equal PUBLISH and SUBSCRIBE layouts")]
    EchoLayouts { domain: String },
    /// The gateway's options leave the set out.
    #[error("domain '{domain}': its {role} set is not bridged")]
    NotBridged { domain: String, role: Role },
    /// A ping got no answer from the echo.
    #[error("no echo (is the loopback interface up?)")]
    NoEcho,
    /// The gateway's options cannot be served.
    #[error(transparent)]
    Gateway(#[from] GatewayError),
    /// The engine refused a participant, a reader or a writer.
    #[error(transparent)]
    Engine(#[from] tutti_gateway::engine::EngineError),
}

/// A sink that decodes typed samples (of other participants: the engine drops its own) and
/// hands them to `f`.
fn typed_sink(codec: Arc<SetCodec>, f: impl Fn(TypedSample) + Send + Sync + 'static) -> Sink {
    Arc::new(move |_: EndpointId, data: Data<'_>| {
        let s = match data {
            Data::Raw(raw) => codec.decode(raw),
            Data::Decoded(r) => r.and_then(|p| match p {
                tutti_gateway::cdr::Payload::Set(s) => Ok(s),
                tutti_gateway::cdr::Payload::Item { .. } => Err(tutti_gateway::cdr::CdrError::Unexpected("not a set")),
            }),
        };
        if let Ok(s) = s {
            f(s);
        }
    })
}

/// The sets the gateway bridges for `opts` (its plan).
fn plan_of(opts: &GatewayOptions) -> Result<Vec<PlannedSet>, PeerError> {
    Ok(tutti_gateway::config::plan(opts).map_err(GatewayError::from)?)
}

/// The ROS 2 topic and the type of `role`'s set of `domain` in the gateway's `plan`: the type
/// with the hash its endpoints announce. On Zenoh the hash is part of every key, so a peer
/// without it would never meet the gateway.
fn set_topic(
    plan: &[PlannedSet],
    opts: &GatewayOptions,
    domain: &Domain,
    role: Role,
) -> Result<(String, TopicType), PeerError> {
    let set = plan.iter().find(|s| s.role == role && opts.model.domains[s.domain].name == domain.name);
    let set = set.ok_or_else(|| PeerError::NotBridged { domain: domain.name.clone(), role })?;
    Ok((set.ros2_topic.clone(), set.topic_type()))
}

/// Echoes domain `domain` of `opts.model` until `stop`; returns the samples echoed.
pub fn run(opts: &GatewayOptions, domain: &Domain, stop: Arc<AtomicBool>) -> Result<u64, PeerError> {
    if domain.publish.layout != domain.subscribe.layout {
        return Err(PeerError::EchoLayouts { domain: domain.name.clone() });
    }
    let ep = Endpoints::open(opts, domain, Role::Publish)?;
    let n = Arc::new(AtomicU64::new(0));
    let (codec, writer, count) = (ep.codec.clone(), Mutex::new(ep.writer), n.clone());
    let body = Mutex::new(Vec::new());
    let sink = typed_sink(ep.codec.clone(), move |s| {
        let mut body = body.lock().unwrap_or_else(PoisonError::into_inner);
        codec.encode(s.step, s.sim_time, &s.data, &mut body);
        let mut w = writer.lock().unwrap_or_else(PoisonError::into_inner);
        if w.write(&body) {
            count.fetch_add(1, Ordering::Relaxed);
        }
        w.flush();
    });
    ep.dds.reader(&ep.reads.0, &ep.reads.1, &ep.rq, Decode::Set(ep.codec.clone()), sink)?;
    while !stop.load(Ordering::Acquire) {
        std::thread::sleep(Duration::from_millis(50));
    }
    drop(ep.dds);
    Ok(n.load(Ordering::Relaxed))
}

/// How long after its first sample an ordered sink's reader may still be joining. A volatile
/// reader that matches a writer stepping flat out gets the samples written once the writer
/// knows it; its stream starts when the writer's first heartbeat reaches it, which may skip
/// samples it already saw being sent: one gap, the start of its stream. So the first gap
/// within this time counts as skipped while joining, and any other gap as lost. Measured on
/// rustdds' writer: one gap of 16-78 steps, 0.16-1.5 ms after the first sample on an idle
/// machine, later under CPU stress, and none after (docs/benchmarks.md).
pub const JOINING: Duration = Duration::from_secs(1);

/// What a [`sink`] received in its window.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Received {
    /// Samples counted (those after the first, within the window).
    pub samples: u64,
    /// Seconds they were counted over: the window, or less if the sink gave up earlier.
    pub secs: f64,
    /// Ordered sinks: steps missing between two received ones, except the gap where the
    /// reader's stream started ([`JOINING`]).
    pub lost: u64,
    /// Ordered sinks: the steps of the first gap, if it came within [`JOINING`] of the first
    /// sample (the start of a volatile reader's stream).
    pub skipped_joining: u64,
    /// Ordered sinks: samples whose step was not after the previous one (duplicated or
    /// reordered).
    pub misordered: u64,
}

/// Counts the typed samples of `role`'s topic of `domain` that arrive in `window`, from
/// the first one (gives up after `patience` without any).
///
/// Unordered, the reader keeps every sample (best effort, deep history), so what is counted
/// is what reached this participant, not what a KEEP_LAST 1 reader happened to see.
/// `ordered`, the reader has the QoS the domain's flags call for (RELIABLE, KEEP_ALL in a
/// synchronous domain) and the steps are checked: each must be the one after the previous.
pub fn sink(
    opts: &GatewayOptions,
    domain: &Domain,
    role: Role,
    window: Duration,
    patience: Duration,
    ordered: bool,
) -> Result<Received, PeerError> {
    let dds = engine::open(opts.engine, &opts.engine_config())?;
    let (topic, ty) = set_topic(&plan_of(opts)?, opts, domain, role)?;
    let mut rq = mapping::qos(domain.flags, opts.profile, Endpoint::Reader, 0);
    if !ordered {
        rq.reliability = Reliability::BestEffort;
        rq.history = History::KeepLast(1 << 16);
    }
    let codec = Arc::new(SetCodec::new(&domain.set(role).layout));
    // First sample's time, the result so far, the last step seen, whether the stream has started
    // (its first gap, while joining, was seen).
    let state = Arc::new(Mutex::new((None::<Instant>, Received::default(), None::<u64>, false)));
    let st = state.clone();
    let counter = typed_sink(codec.clone(), move |s| {
        let mut guard = st.lock().unwrap_or_else(PoisonError::into_inner);
        let (first, got, last, started) = &mut *guard;
        match *first {
            None => *first = Some(Instant::now()),
            Some(t) if t.elapsed() < window => got.samples += 1,
            Some(_) => return,
        }
        if ordered {
            match *last {
                Some(prev) if s.step <= prev => got.misordered += 1,
                Some(prev) if s.step > prev + 1 && !*started && first.is_some_and(|t| t.elapsed() < JOINING) => {
                    *started = true;
                    got.skipped_joining += s.step - prev - 1
                }
                Some(prev) => got.lost += s.step - prev - 1,
                None => {}
            }
            *last = Some(last.map_or(s.step, |prev| prev.max(s.step)));
        }
    });
    dds.reader(&topic, &ty, &rq, Decode::Set(codec), counter)?;
    let start = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(20));
        let first = state.lock().unwrap_or_else(PoisonError::into_inner).0;
        match first {
            Some(t) if t.elapsed() >= window => break,
            None if start.elapsed() >= patience => break,
            _ => {}
        }
    }
    drop(dds);
    let (first, mut got, _, _) = *state.lock().unwrap_or_else(PoisonError::into_inner);
    got.secs = first.map_or(0.0, |t| t.elapsed().min(window).as_secs_f64());
    Ok(got)
}

/// Writes typed SUBSCRIBE samples of `domain` as fast as the writer takes them until
/// `stop` (after `settle`, for discovery); each carries its sequence number as `step` and
/// in every item. Returns the samples written.
pub fn source(
    opts: &GatewayOptions,
    domain: &Domain,
    settle: Duration,
    stop: Arc<AtomicBool>,
) -> Result<u64, PeerError> {
    let dds = engine::open(opts.engine, &opts.engine_config())?;
    let (topic, ty) = set_topic(&plan_of(opts)?, opts, domain, Role::Subscribe)?;
    let wq = mapping::qos(domain.flags, opts.profile, Endpoint::Writer, 0);
    let layout = &domain.subscribe.layout;
    let codec = SetCodec::new(layout);
    let mut w = dds.writer(&topic, &ty, &wq)?;
    std::thread::sleep(settle);
    let mut shm = vec![0u8; layout.size as usize];
    let mut body = Vec::new();
    let mut n = 0u64;
    while !stop.load(Ordering::Relaxed) {
        n += 1;
        for leaf in &layout.leaves {
            if let Some(dst) = shm.get_mut(leaf.range()) {
                leaf.ty.encode(tutti_core::ddf::Value::Float(n as f64), &mut dst[..leaf.ty.size() as usize]);
            }
        }
        codec.encode(n, n as f64, &shm, &mut body);
        if !w.write(&body) {
            n -= 1;
        }
        if n % 32 == 0 {
            w.flush();
        }
    }
    w.flush();
    drop(w);
    drop(dds);
    Ok(n)
}

/// A ping for the echo, without the gateway: writes typed PUBLISH samples of `domain` and
/// waits (spinning, yielding the core between looks, as the benchmark's framework does)
/// for each to come back on SUBSCRIBE. Returns the round trips (µs) of `samples` pings,
/// after the path works once (gives up after `patience`).
pub fn ping(opts: &GatewayOptions, domain: &Domain, samples: u32, patience: Duration) -> Result<Vec<f64>, PeerError> {
    let mut ep = Endpoints::open(opts, domain, Role::Subscribe)?;
    let back = Arc::new(AtomicU64::new(0));
    let b = back.clone();
    let sink = typed_sink(ep.codec.clone(), move |s| b.store(s.step, Ordering::Release));
    ep.dds.reader(&ep.reads.0, &ep.reads.1, &ep.rq, Decode::Set(ep.codec.clone()), sink)?;
    let shm = vec![0u8; ep.codec.shm_size()];
    let mut body = Vec::new();
    let mut once = |step: u64, limit: Duration| -> Option<f64> {
        ep.codec.encode(step, 0.0, &shm, &mut body);
        let t = Instant::now();
        if !ep.writer.write(&body) {
            return None;
        }
        ep.writer.flush();
        let mut spins = 0u32;
        while t.elapsed() < limit {
            if back.load(Ordering::Acquire) == step {
                return Some(t.elapsed().as_secs_f64() * 1e6);
            }
            spins += 1;
            if spins < 16 {
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
        None
    };
    let end = Instant::now() + patience;
    let mut step = 0u64;
    loop {
        step += 1;
        if once(step, Duration::from_millis(100)).is_some() {
            break;
        }
        if Instant::now() > end {
            return Err(PeerError::NoEcho);
        }
    }
    let mut times = Vec::with_capacity(samples as usize);
    for _ in 0..samples {
        step += 1;
        if let Some(t) = once(step, Duration::from_secs(1)) {
            times.push(t);
        }
    }
    drop(ep);
    Ok(times)
}

/// The same pings as [`ping`], each written on the engine's receive thread as the answer to
/// the last one arrives, as ddsperf's ping does: no other thread waits for an answer, so each
/// round trip has one thread switch fewer than [`ping`]'s (and than any round trip whose answer
/// is awaited by a thread of its own, as a framework's is). Returns the round trips (µs) of
/// `samples` pings after the first answer; a ping lost on the way (best effort) is sent again
/// from this thread after 100 ms and not counted. Gives up after `patience` without an answer.
pub fn ping_in_listener(
    opts: &GatewayOptions,
    domain: &Domain,
    samples: u32,
    patience: Duration,
) -> Result<Vec<f64>, PeerError> {
    struct Chain {
        writer: Box<dyn Writer>,
        body: Vec<u8>,
        shm: Vec<u8>,
        /// The ping in flight and when it was written; None once `samples` came back.
        sent: Option<(u64, Instant)>,
        times: Vec<f64>,
    }
    impl Chain {
        fn send(&mut self, codec: &SetCodec, step: u64) {
            codec.encode(step, 0.0, &self.shm, &mut self.body);
            self.sent = Some((step, Instant::now()));
            if self.writer.write(&self.body) {
                self.writer.flush();
            }
        }
    }
    let Endpoints { writer, dds, codec, reads, rq } = Endpoints::open(opts, domain, Role::Subscribe)?;
    let want = samples as usize + 1;
    let chain = Arc::new(Mutex::new(Chain {
        writer,
        body: Vec::new(),
        shm: vec![0u8; codec.shm_size()],
        sent: None,
        times: Vec::with_capacity(want),
    }));
    let (c, cd) = (chain.clone(), codec.clone());
    let sink = typed_sink(codec.clone(), move |s| {
        let mut ch = c.lock().unwrap_or_else(PoisonError::into_inner);
        let Some((step, t)) = ch.sent else { return };
        if s.step != step {
            return;
        }
        let us = t.elapsed().as_secs_f64() * 1e6;
        ch.times.push(us);
        if ch.times.len() >= want {
            ch.sent = None;
        } else {
            ch.send(&cd, step + 1);
        }
    });
    dds.reader(&reads.0, &reads.1, &rq, Decode::Set(codec.clone()), sink)?;
    let end = Instant::now() + patience;
    let mut last = (0usize, Instant::now());
    loop {
        std::thread::sleep(Duration::from_millis(20));
        let mut ch = chain.lock().unwrap_or_else(PoisonError::into_inner);
        let n = ch.times.len();
        if n >= want {
            break;
        }
        if n == 0 && Instant::now() > end {
            return Err(PeerError::NoEcho);
        }
        if n != last.0 {
            last = (n, Instant::now());
        } else if last.1.elapsed() >= Duration::from_millis(100) || ch.sent.is_none() {
            // Not started, or a ping (or its answer) was lost: the chain starts again.
            let step = ch.sent.map_or(1, |(k, _)| k + 1_000_000);
            ch.send(&codec, step);
            last.1 = Instant::now();
        }
    }
    let mut times = std::mem::take(&mut chain.lock().unwrap_or_else(PoisonError::into_inner).times);
    drop(dds);
    // The first answer waited for discovery.
    times.remove(0);
    Ok(times)
}

/// The DDS side of the echo and of its ping: one participant, the names and QoS of the
/// topic read, and a writer of the other set's topic (the two sets have one layout, so one
/// codec serves both).
struct Endpoints {
    writer: Box<dyn Writer>,
    dds: Box<dyn Engine>,
    codec: Arc<SetCodec>,
    /// The topic read and its type.
    reads: (String, TopicType),
    rq: mapping::Qos,
}

impl Endpoints {
    /// `reads`: the set whose topic is read (the echo reads PUBLISH, the ping SUBSCRIBE).
    fn open(opts: &GatewayOptions, domain: &Domain, reads: Role) -> Result<Endpoints, PeerError> {
        let dds = engine::open(opts.engine, &opts.engine_config())?;
        let writes = match reads {
            Role::Publish => Role::Subscribe,
            Role::Subscribe => Role::Publish,
        };
        let plan = plan_of(opts)?;
        let (rn, wn) = (set_topic(&plan, opts, domain, reads)?, set_topic(&plan, opts, domain, writes)?);
        let rq = mapping::qos(domain.flags, opts.profile, Endpoint::Reader, 0);
        let wq = mapping::qos(domain.flags, opts.profile, Endpoint::Writer, 0);
        let codec = Arc::new(SetCodec::new(&domain.publish.layout));
        let writer = dds.writer(&wn.0, &wn.1, &wq)?;
        Ok(Endpoints { writer, dds, codec, reads: rn, rq })
    }
}
