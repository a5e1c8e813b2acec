//! The gateway inside the framework's process (`tutti host --gateway`, and `tutti run`):
//! the same plan, config, discovery and routes as `tutti gateway`, in threads of the process
//! that runs the framework, except that the framework's own PUBLISH sets reach DDS from the
//! framework's step instead of through shared memory.
//!
//! [`start`] opens the DDS participant, bridges every domain of the model and returns two
//! things: a [`GatewaySink`], which the caller adds to its `tutti_host::Host` (it writes
//! each step's PUBLISH sets to DDS as soon as the step is published, on the framework's
//! thread: [`crate::routes::from_step`]), and an [`InProcess`] handle that stops the
//! gateway and gives its counters. Everything else runs as in a separate gateway: DDS
//! samples for the SUBSCRIBE sets are committed on the engine's receive thread through
//! each DDS writer's own connection, the SUBSCRIBE sets that external components write are
//! watched by the poller thread, `/clock` too, and the manager's loop (its own thread here,
//! `tutti-gw-manager`) follows discovery and prints status.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::Duration;

use tutti_core::shm::Framework;
use tutti_host::{Published, StepDone, StepSink};

use crate::manager::{self, Placement};
use crate::routes::from_step::{self, StepRoute};
use crate::{GatewayError, GatewayOptions, Stats};

/// What [`start`] reports on: called on the manager's thread with the status line (every
/// `status_every`, and once when the gateway is up).
pub type OnStatus = Box<dyn FnMut(&str) + Send>;

/// A gateway running in this process; stopped by [`InProcess::stop`], or when dropped, or
/// when its [`GatewaySink`] finishes.
#[derive(Debug)]
pub struct InProcess {
    shared: Arc<Shared>,
}

#[derive(Debug)]
struct Shared {
    stop: Arc<AtomicBool>,
    thread: Mutex<Option<JoinHandle<()>>>,
    /// The flush thread of the batched asynchronous sets ([`crate::routes::from_step::Held`]).
    flusher: Mutex<Option<JoinHandle<()>>>,
    stats: Arc<Stats>,
}

impl Shared {
    /// Stops the manager and every thread of the gateway, once.
    fn stop(&self) {
        self.stop.store(true, Ordering::Release);
        for slot in [&self.thread, &self.flusher] {
            let thread = slot.lock().unwrap_or_else(PoisonError::into_inner).take();
            if let Some(t) = thread {
                t.thread().unpark();
                let _ = t.join();
            }
        }
    }
}

impl InProcess {
    /// The gateway's counters, as they stand.
    pub fn stats(&self) -> Arc<Stats> {
        self.shared.stats.clone()
    }

    /// Stops the gateway (if its sink has not already) and returns its counters.
    pub fn stop(self) -> Arc<Stats> {
        self.shared.stop();
        self.shared.stats.clone()
    }
}

impl Drop for InProcess {
    fn drop(&mut self) {
        self.shared.stop();
    }
}

/// The step sink of a gateway in the framework's process: writes each domain's PUBLISH set
/// to DDS when the step is published (`StepSink::published`). Finishing it (the end of the
/// host's run) sends what is batched and stops the gateway, before the framework removes its
/// domains.
#[derive(Debug)]
pub struct GatewaySink {
    /// Per domain of the model, its PUBLISH set's route (None: not bridged).
    routes: Vec<Option<Box<StepRoute>>>,
    shared: Arc<Shared>,
}

impl GatewaySink {
    /// Writes step `step` of domain `domain` (its index in the model), PUBLISH set `set`,
    /// to DDS if a reader wants it; what [`StepSink::published`] does for every domain, for a
    /// framework that steps its domains itself. `more`: another step follows at once (an
    /// asynchronous set may then wait in a batch, at most [`crate::routes::from_step::HOLD_AT_MOST`]).
    /// Returns whether it was written.
    pub fn send(&mut self, domain: usize, step: u64, sim: f64, set: &[u8], more: bool) -> bool {
        match self.routes.get_mut(domain) {
            Some(Some(r)) => r.send(step, sim, set, more),
            _ => false,
        }
    }

    /// Sends what asynchronous sets stepped back to back left in the writers' batches.
    pub fn flush(&mut self) {
        self.routes.iter_mut().flatten().for_each(|r| r.flush());
    }
}

impl StepSink for GatewaySink {
    fn published(
        &mut self,
        fw: &Framework,
        step: &Published<'_>,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        for ((route, host), set) in self.routes.iter_mut().zip(&fw.domains).zip(step.publish) {
            if let Some(r) = route {
                r.send(host.current_step(), step.sim, set, step.more);
            }
        }
        Ok(())
    }

    fn step(&mut self, _: &Framework, _: &StepDone<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.flush();
        self.shared.stop();
        Ok(())
    }
}

impl Drop for GatewaySink {
    fn drop(&mut self) {
        self.flush();
    }
}

/// Starts the gateway `opts` describes for the framework of this process, whose segments are
/// in shared-memory namespace `namespace` and already exist (a `tutti_host::Host` made
/// them): every domain is bridged at once. Returns once the routes exist (or with the reason
/// they cannot), with the handle and the sink to add to the host. `opts.every_step` changes
/// nothing here (every step of a synchronous set goes to DDS anyway) and a mirror is refused.
pub fn start(
    mut opts: GatewayOptions,
    namespace: &str,
    status_every: Duration,
    mut on_status: OnStatus,
) -> Result<(InProcess, GatewaySink), GatewayError> {
    if opts.mirror {
        return Err(GatewayError::InProcessMirror);
    }
    opts.namespace = namespace.to_string();
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    let shutdown = stop.clone();
    let thread = thread::Builder::new()
        .name("tutti-gw-manager".into())
        .spawn(move || {
            let (mut m, rt) = match manager::start(opts, Placement::InProcess) {
                Ok(started) => started,
                Err(e) => {
                    let _ = tx.send(Err(e));
                    return;
                }
            };
            if tx.send(Ok((m.take_step_routes(), m.stats()))).is_err() {
                return;
            }
            m.serve_until(rt, shutdown, status_every, &mut *on_status);
        })
        .map_err(|e| GatewayError::Thread("a thread", e))?;
    let started = rx.recv();
    match started {
        Ok(Ok((routes, stats))) => {
            let held: Vec<_> = routes.iter().flatten().filter_map(|r| r.held()).collect();
            let flusher = match from_step::spawn_flusher(held.clone(), stop.clone()) {
                Ok(f) => f,
                Err(e) => {
                    stop.store(true, Ordering::Release);
                    let _ = thread.join();
                    return Err(GatewayError::Thread("a thread", e));
                }
            };
            if let Some(f) = &flusher {
                held.iter().for_each(|h| h.watched_by(f.thread().clone()));
            }
            let shared =
                Arc::new(Shared { stop, thread: Mutex::new(Some(thread)), flusher: Mutex::new(flusher), stats });
            Ok((InProcess { shared: shared.clone() }, GatewaySink { routes, shared }))
        }
        Ok(Err(e)) => {
            let _ = thread.join();
            Err(e)
        }
        Err(_) => {
            let _ = thread.join();
            Err(GatewayError::Thread("the gateway", std::io::Error::other("its thread ended before it was up")))
        }
    }
}
