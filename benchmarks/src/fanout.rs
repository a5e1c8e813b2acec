//! The fan-out shape of `tutti-bench scale`: one writer, R readers, next to iceoryx2's
//! publish-subscribe with as many subscribers, in the same run.
//!
//! tutti: the framework publishes one 8-byte item of an asynchronous domain's PUBLISH set
//! (`DomainHost::publish_step`) with R participants connected. iceoryx2: a publisher sends
//! one 8-byte sample (loan, write, send) to R subscribers of one service (history 0, a
//! buffer of 2 per subscriber). Both in one thread of this process: after each write, every
//! reader takes the value (outside the timed call) and it is checked, so that no reader
//! falls behind and every write reaches every reader. The figure is the writer's call: what
//! publishing costs as readers grow.

use std::time::{Duration, Instant};

use anyhow::{bail, Context as _};
use iceoryx2::prelude::*;
use tutti_core::ddf;
use tutti_core::shm::{ConnectOptions, Framework, FrameworkOptions, Participant, WaitMode};

use crate::iceoryx;
use crate::nearest_rank;

/// One fan-out run's figures.
#[derive(Debug, Clone)]
pub struct FanOut {
    pub system: &'static str,
    pub readers: usize,
    pub writes: usize,
    pub p50_ns: f64,
    pub p99_ns: f64,
}

impl FanOut {
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "system": self.system, "shape": "fan-out", "readers": self.readers, "writes": self.writes,
            "publish_ns": { "p50": self.p50_ns, "p99": self.p99_ns },
        })
    }
}

fn figures(system: &'static str, readers: usize, mut times: Vec<Duration>) -> FanOut {
    times.sort();
    let ns = |q| nearest_rank(&times, q).as_nanos() as f64;
    FanOut { system, readers, writes: times.len(), p50_ns: ns(0.5), p99_ns: ns(0.99) }
}

/// tutti: the framework's publish with `readers` participants reading every value.
pub fn tutti(namespace: &str, readers: usize, writes: usize) -> anyhow::Result<FanOut> {
    let text = r#"<orchestra><domain name="fan"><synchronous>no</synchronous><states>no</states>
        <set name="PUBLISH"><item name="x"><type>uint64</type></item></set>
        <set name="SUBSCRIBE"><item name="y"><type>uint64</type></item></set></domain></orchestra>"#;
    let model = ddf::parse_str(text, "fan-out.ddf").context("the fan-out DDF")?;
    let opts =
        FrameworkOptions { namespace: namespace.to_string(), connections: readers as u32 + 1, ..Default::default() };
    let mut fw = Framework::create(&model, &opts).context("creating the fan-out domain")?;
    let mut conns = (0..readers)
        .map(|i| {
            let o = ConnectOptions {
                namespace: namespace.to_string(),
                name: format!("r{i}"),
                wait: WaitMode::Spin,
                connect_timeout: Duration::from_secs(10),
                ..Default::default()
            };
            Participant::connect("fan", o).with_context(|| format!("reader {i}"))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let x = match conns.first() {
        Some(p) => p.leaf(ddf::Role::Publish, "x")?.0,
        None => 0,
    };
    let domain = &mut fw.domains[0];
    let mut times = Vec::with_capacity(writes);
    let warm = crate::warmup(writes);
    for k in 0..(warm + writes) as u64 {
        let bytes = k.to_ne_bytes();
        let t0 = Instant::now();
        domain.publish_step(&bytes, k as f64).context("publishing")?;
        let dt = t0.elapsed();
        for (i, p) in conns.iter_mut().enumerate() {
            p.subscribe_lock()?;
            let got = p.snapshot_item(x).and_then(|b| b.try_into().ok()).map(u64::from_ne_bytes);
            if got != Some(k) {
                bail!("tutti fan-out: reader {i} read {got:?} after write {k}");
            }
        }
        if k >= warm as u64 {
            times.push(dt);
        }
    }
    drop(conns);
    Ok(figures("tutti", readers, times))
}

/// iceoryx2: a publisher's send with `readers` subscribers receiving every sample.
pub fn iceoryx2(readers: usize, writes: usize) -> anyhow::Result<FanOut> {
    let (tag, _guard) = iceoryx::run_tag();
    let run = || -> Result<FanOut, Box<dyn std::error::Error>> {
        let node = iceoryx::node(&tag)?;
        let svc = node
            .service_builder(&ServiceName::new(&format!("iox2fan/{tag}"))?)
            .publish_subscribe::<u64>()
            .max_publishers(1)
            .max_subscribers(readers.max(1))
            .history_size(0)
            .subscriber_max_buffer_size(2)
            .create()?;
        let publisher = svc.publisher_builder().create()?;
        let subs = (0..readers).map(|_| svc.subscriber_builder().create()).collect::<Result<Vec<_>, _>>()?;
        let mut times = Vec::with_capacity(writes);
        let warm = crate::warmup(writes);
        for k in 0..(warm + writes) as u64 {
            let t0 = Instant::now();
            publisher.loan_uninit()?.write_payload(k).send()?;
            let dt = t0.elapsed();
            for (i, s) in subs.iter().enumerate() {
                let got = s.receive()?.map(|s| *s.payload());
                if got != Some(k) {
                    return Err(format!("iceoryx2 fan-out: subscriber {i} received {got:?} after send {k}").into());
                }
            }
            if k >= warm as u64 {
                times.push(dt);
            }
        }
        Ok(figures("iceoryx2", readers, times))
    };
    run().map_err(|e| anyhow::anyhow!("iceoryx2 fan-out with {readers} subscribers: {e}"))
}
