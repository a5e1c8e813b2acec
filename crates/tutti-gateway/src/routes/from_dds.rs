//! DDS -> shared memory.
//!
//! A reader task per topic decodes samples and drops the gateway's own; the manager hands
//! each sample to the [`RemoteWriter`] of the DDS writer that sent it. A remote writer is a
//! shared-memory connection (marked remote) with its own thread: it commits the samples of
//! its DDS writer, so the core's rules apply unchanged — the first writer to publish owns
//! an exclusive set until its connection goes, a synchronous domain waits for its commit of
//! each step (`publish_lock` waits for the step the sample answers), and its first commit
//! seeds a `states=yes` domain.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use futures::StreamExt;
use ros2_client::dds::Subscription;
use ros2_client::Gid;
use tokio::sync::mpsc::UnboundedSender;
use tracing::{debug, info, warn};
use tutti_core::shm::{Participant, ShmError};

use super::{Event, Inbound, Payload, ShmConfig};
use crate::cdr::{SetSeed, TypedSample};
use crate::node::{prefix, short, PREFIX_LEN};
use crate::stats::{LogLimit, Stats};

/// Forwards the samples of a typed subscription as route `route`.
pub async fn forward_typed(
    sub: Subscription<TypedSample>,
    seed: SetSeed,
    route: usize,
    tx: UnboundedSender<Event>,
    stats: Arc<Stats>,
    own: [u8; PREFIX_LEN],
) {
    let stream = sub.async_stream_seed(seed);
    futures::pin_mut!(stream);
    while let Some(r) = stream.next().await {
        let ev = match r {
            Ok((sample, info)) => {
                let writer = info.publisher_gid();
                if prefix(&writer) == own {
                    Stats::add(&stats.own_samples, 1);
                    continue;
                }
                Event::Sample(Inbound { route, writer, payload: Payload::Set(sample) })
            }
            Err(e) => Event::Bad { route, error: format!("{e:?}") },
        };
        if tx.send(ev).is_err() {
            break;
        }
    }
}

/// The shared-memory connection of one remote DDS writer.
#[derive(Debug)]
pub struct RemoteWriter {
    tx: Sender<Payload>,
}

impl RemoteWriter {
    /// Connects (in its own thread) to `domain` on behalf of DDS writer `writer`.
    pub fn spawn(
        domain: String,
        writer: Gid,
        cfg: ShmConfig,
        stats: Arc<Stats>,
        own_commits: Arc<AtomicU64>,
    ) -> std::io::Result<Self> {
        let (tx, rx) = mpsc::channel();
        let name = format!("dds-writer {}", short(&writer));
        thread::Builder::new()
            .name("tutti-gw-writer".into())
            .stack_size(256 << 10)
            .spawn(move || run(domain, name, rx, cfg, stats, own_commits))?;
        Ok(RemoteWriter { tx })
    }

    /// Hands a sample to the connection; false when its thread has gone.
    pub fn send(&self, p: Payload) -> bool {
        self.tx.send(p).is_ok()
    }
}

fn run(
    domain: String,
    name: String,
    rx: Receiver<Payload>,
    cfg: ShmConfig,
    stats: Arc<Stats>,
    own_commits: Arc<AtomicU64>,
) {
    let connect = || Participant::connect(&domain, cfg.connect_options(name.clone(), Duration::from_millis(100)));
    let mut p = connect().ok();
    let mut refused_log = LogLimit::new(Duration::from_secs(5));
    let mut error_log = LogLimit::new(Duration::from_secs(5));
    loop {
        let msg = if p.is_some() {
            rx.recv().map_err(|_| RecvTimeoutError::Disconnected)
        } else {
            rx.recv_timeout(Duration::from_millis(500))
        };
        let payload = match msg {
            Ok(m) => m,
            Err(RecvTimeoutError::Timeout) => {
                p = connect().ok();
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => break,
        };
        if p.is_none() {
            p = connect().ok();
        }
        let Some(part) = p.as_mut() else {
            Stats::add(&stats.errors, 1);
            if error_log.allow().is_some() {
                warn!(domain = %domain, "{name}: sample dropped: the domain is not running");
            }
            continue;
        };
        match commit(part, payload, &own_commits) {
            Ok(Committed::Yes) => Stats::add(&stats.from_dds, 1),
            Ok(Committed::Late) => Stats::add(&stats.late, 1),
            Err(e @ ShmError::NotOwner { .. }) => {
                Stats::add(&stats.refused, 1);
                if let Some(held) = refused_log.allow() {
                    warn!(domain = %domain, "{name}: sample refused ({held} more since the last report): {e}");
                }
                // A refused connection is flagged as a writer; in a synchronous domain the
                // framework would wait for its commits. Leave, and come back with the next sample.
                if part.info().flags.synchronous {
                    p = None;
                }
            }
            Err(e @ (ShmError::ConnectionLost { .. } | ShmError::FrameworkStopped { .. })) => {
                Stats::add(&stats.errors, 1);
                info!(domain = %domain, "{name}: {e}; reconnecting");
                p = None;
            }
            Err(e) => {
                Stats::add(&stats.errors, 1);
                if let Some(held) = error_log.allow() {
                    debug!(domain = %domain, "{name}: sample dropped ({held} more): {e}");
                }
            }
        }
    }
}

/// What became of a sample.
enum Committed {
    Yes,
    /// It answers a step the framework has already left (it timed out waiting).
    Late,
}

fn commit(p: &mut Participant, payload: Payload, own_commits: &AtomicU64) -> Result<Committed, ShmError> {
    if p.info().flags.synchronous {
        // Waits for the step this sample answers (a seed needs none). A sample answering an
        // earlier step is not committed for the current one, or every later step would
        // get its predecessor's answer; the lock alone makes the connection a writer, so
        // the framework waits for the next answer.
        p.publish_lock()?;
        let locked = p.segment().header().pub_step.load(Ordering::Acquire);
        if let Payload::Set(s) = &payload {
            if s.step != 0 && s.step < locked {
                return Ok(Committed::Late);
            }
        }
    }
    match payload {
        Payload::Set(s) => {
            let staging = p.staging_mut();
            if staging.len() == s.data.len() {
                staging.copy_from_slice(&s.data);
            }
        }
        Payload::Item { path, bytes } => p.stage(&path, &bytes)?,
    }
    own_commits.fetch_add(1, Ordering::AcqRel);
    let r = p.commit();
    if r.is_err() {
        own_commits.fetch_sub(1, Ordering::AcqRel);
    }
    r.map(|()| Committed::Yes)
}
