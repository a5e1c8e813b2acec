//! DDS peers for benchmarks, each a separate DDS participant (normally another process):
//! the echo ([`run`]) reads the typed PUBLISH samples of a domain and writes each back,
//! unchanged, as a SUBSCRIBE sample (the two sets must have the same layout); the sink
//! ([`sink`]) counts the samples it receives on one of the two topics; the source
//! ([`source`]) writes SUBSCRIBE samples as fast as it can.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use futures::StreamExt;
use ros2_client::dds::{Publisher, Subscription};
use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::{self, Endpoint, History, Reliability};

use crate::cdr::{PreEncoded, SetCodec, SetSeed, TypedSample};
use crate::node::{prefix, Dds};
use crate::{GatewayError, GatewayOptions};

/// Echoes domain `domain` of `opts.model` until `stop`; returns the samples echoed.
pub fn run(opts: &GatewayOptions, domain: &Domain, stop: Arc<AtomicBool>) -> Result<u64, GatewayError> {
    if domain.publish.layout != domain.subscribe.layout {
        return Err(GatewayError::Invalid(format!(
            "domain '{}': the echo needs equal PUBLISH and SUBSCRIBE layouts",
            domain.name
        )));
    }
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(GatewayError::Runtime)?;
    let Endpoints { dds, codec, sub, publ } = Endpoints::open(opts, domain, Role::Publish)?;
    let own = dds.own_prefix;
    let echoed = rt.block_on(async {
        let stream = sub.async_stream_seed(SetSeed(codec.clone()));
        futures::pin_mut!(stream);
        let mut tick = tokio::time::interval(Duration::from_millis(50));
        let mut n = 0u64;
        let mut body = Vec::new();
        loop {
            tokio::select! {
                Some(r) = stream.next() => {
                    let Ok((s, info)) = r else { continue };
                    if prefix(&info.publisher_gid()) == own {
                        continue;
                    }
                    codec.encode(s.step, s.sim_time, &s.data, &mut body);
                    if publ.publish(PreEncoded(std::mem::take(&mut body))).is_ok() {
                        n += 1;
                    }
                }
                _ = tick.tick() => if stop.load(Ordering::Acquire) { break n },
            }
        }
    });
    drop(dds);
    Ok(echoed)
}

/// Counts the typed samples of `role`'s topic of `domain` that arrive in `window`, from
/// the first one (gives up after `patience` without any); returns (samples, seconds).
/// The reader keeps every sample (best effort, deep history), so what is counted is what
/// reached this participant, not what a KEEP_LAST 1 reader happened to see.
pub fn sink(
    opts: &GatewayOptions,
    domain: &Domain,
    role: Role,
    window: Duration,
    patience: Duration,
) -> Result<(u64, f64), GatewayError> {
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(GatewayError::Runtime)?;
    let mut dds = Dds::open(opts)?;
    let pkg = mapping::package_name(&opts.ddf_path);
    let names = mapping::set_names(&pkg, &domain.name, role);
    let mut rq = mapping::qos(domain.flags, opts.profile, Endpoint::Reader, 0);
    rq.reliability = Reliability::BestEffort;
    rq.history = History::KeepLast(1 << 16);
    let codec = Arc::new(SetCodec::new(&domain.set(role).layout));
    let sub = dds.subscription::<TypedSample>(&names.topic, &names.dds_type, &rq)?;
    let own = dds.own_prefix;
    let counted = rt.block_on(async {
        let stream = sub.async_stream_seed(SetSeed(codec));
        futures::pin_mut!(stream);
        let mut first: Option<Instant> = None;
        let mut n = 0u64;
        let start = Instant::now();
        loop {
            let limit = match first {
                Some(t) => (t + window).saturating_duration_since(Instant::now()),
                None => (start + patience).saturating_duration_since(Instant::now()),
            };
            match tokio::time::timeout(limit, stream.next()).await {
                Ok(Some(Ok((_, info)))) if prefix(&info.publisher_gid()) != own => {
                    if first.is_none() {
                        first = Some(Instant::now());
                    } else {
                        n += 1;
                    }
                }
                Ok(Some(_)) => {}
                Ok(None) | Err(_) => break (n, first.map_or(0.0, |t| t.elapsed().as_secs_f64())),
            }
        }
    });
    drop(dds);
    Ok(counted)
}

/// Writes typed SUBSCRIBE samples of `domain` as fast as the writer takes them until
/// `stop` (after `settle`, for discovery); each carries its sequence number as `step` and
/// in every item. Returns the samples written.
pub fn source(
    opts: &GatewayOptions,
    domain: &Domain,
    settle: Duration,
    stop: Arc<AtomicBool>,
) -> Result<u64, GatewayError> {
    let mut dds = Dds::open(opts)?;
    let pkg = mapping::package_name(&opts.ddf_path);
    let names = mapping::set_names(&pkg, &domain.name, Role::Subscribe);
    let wq = mapping::qos(domain.flags, opts.profile, Endpoint::Writer, 0);
    let layout = &domain.subscribe.layout;
    let codec = SetCodec::new(layout);
    let publ = dds.publisher::<PreEncoded>(&names.topic, &names.dds_type, &wq)?;
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
        if publ.publish(PreEncoded(std::mem::take(&mut body))).is_err() {
            n -= 1;
        }
    }
    drop(dds);
    Ok(n)
}

/// A rustdds ping for the echo, without the gateway: writes typed PUBLISH samples of
/// `domain` and waits (spinning, yielding the core between looks, as the benchmark's
/// framework does) for each to come back on SUBSCRIBE. Returns the round trips (µs) of
/// `samples` pings, after the path works once (gives up after `patience`).
pub fn ping(
    opts: &GatewayOptions,
    domain: &Domain,
    samples: u32,
    patience: Duration,
) -> Result<Vec<f64>, GatewayError> {
    let Endpoints { dds, codec, sub, publ } = Endpoints::open(opts, domain, Role::Subscribe)?;
    let shm = vec![0u8; codec.shm_size()];
    let mut body = Vec::new();
    let mut once = |step: u64, limit: Duration| -> Option<f64> {
        codec.encode(step, 0.0, &shm, &mut body);
        let t = Instant::now();
        publ.publish(PreEncoded(body.clone())).ok()?;
        let mut spins = 0u32;
        while t.elapsed() < limit {
            if let Ok(Some((s, _))) = sub.take_seed(SetSeed(codec.clone())) {
                if s.step == step {
                    return Some(t.elapsed().as_secs_f64() * 1e6);
                }
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
            return Err(GatewayError::Invalid("no echo (is the loopback interface up?)".into()));
        }
    }
    let mut times = Vec::with_capacity(samples as usize);
    for _ in 0..samples {
        step += 1;
        if let Some(t) = once(step, Duration::from_secs(1)) {
            times.push(t);
        }
    }
    drop(dds);
    Ok(times)
}

/// The DDS side of the echo and of its ping: one participant, a typed reader of one set's
/// topic and a writer of the other's (the two sets have one layout, so one codec serves both).
struct Endpoints {
    dds: Dds,
    codec: Arc<SetCodec>,
    sub: Subscription<TypedSample>,
    publ: Publisher<PreEncoded>,
}

impl Endpoints {
    /// `reads`: the set whose topic is read (the echo reads PUBLISH, the ping SUBSCRIBE).
    fn open(opts: &GatewayOptions, domain: &Domain, reads: Role) -> Result<Endpoints, GatewayError> {
        let mut dds = Dds::open(opts)?;
        let pkg = mapping::package_name(&opts.ddf_path);
        let writes = match reads {
            Role::Publish => Role::Subscribe,
            Role::Subscribe => Role::Publish,
        };
        let (rn, wn) = (mapping::set_names(&pkg, &domain.name, reads), mapping::set_names(&pkg, &domain.name, writes));
        let rq = mapping::qos(domain.flags, opts.profile, Endpoint::Reader, 0);
        let wq = mapping::qos(domain.flags, opts.profile, Endpoint::Writer, 0);
        let codec = Arc::new(SetCodec::new(&domain.publish.layout));
        let sub = dds.subscription::<TypedSample>(&rn.topic, &rn.dds_type, &rq)?;
        let publ = dds.publisher::<PreEncoded>(&wn.topic, &wn.dds_type, &wq)?;
        Ok(Endpoints { dds, codec, sub, publ })
    }
}
