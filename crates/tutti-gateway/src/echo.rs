//! A DDS echo peer for benchmarks: reads the typed PUBLISH samples of a domain and writes
//! each back, unchanged, as a SUBSCRIBE sample (the two sets must have the same layout).
//! It is a separate DDS participant, normally in another process.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use futures::StreamExt;
use tutti_core::ddf::{Domain, Role};
use tutti_core::mapping::{self, Endpoint};

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
    let mut dds = Dds::open(opts)?;
    let pkg = mapping::package_name(&opts.ddf_path);
    let (pubn, subn) = (
        mapping::set_names(&pkg, &domain.name, Role::Publish),
        mapping::set_names(&pkg, &domain.name, Role::Subscribe),
    );
    let rq = mapping::qos(domain.flags, opts.profile, Endpoint::Reader, 0);
    let wq = mapping::qos(domain.flags, opts.profile, Endpoint::Writer, 0);
    let codec = Arc::new(SetCodec::new(&domain.publish.layout));
    let sub = dds.subscription::<TypedSample>(&pubn.topic, &pubn.dds_type, &rq)?;
    let publ = dds.publisher::<PreEncoded>(&subn.topic, &subn.dds_type, &wq)?;
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
