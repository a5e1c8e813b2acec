//! A whole run of a launch file ([`run`]): the framework of the DDF's domains (a
//! [`Host`]), its recordings, the gateway, and the components under a [`Supervisor`].
//!
//! In order: the framework creates the domains (holding their participants with `hold`),
//! the recordings and the gateway start, then the components in file order. With `hold` the
//! framework starts stepping once every component has connected, releasing them all at
//! once; without, it steps from the start and the components join as they come. The run
//! ends at `duration` or `steps`, at the interrupt (Ctrl-C), when every component has ended
//! by itself, or when the components could not all be started. Then the components are
//! torn down in reverse order while the framework still exists, the recordings finish, the
//! gateway stops and the framework removes its domains, last.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use tutti_host::control::{self, ComponentAction, Components, Refusal};
use tutti_host::{Host, HostOptions, Summary};

use crate::supervisor::{ComponentStatus, Event, OnEvent, Supervisor, SupervisorOptions};
use crate::{Launch, RunError, SupervisorError};

/// What a run needs besides its launch file.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Where the components' `NAME.log` files go.
    pub log_dir: PathBuf,
    /// The `tutti` executable, for FMU components.
    pub tutti_exe: PathBuf,
    /// The namespace of the segments (None: `TUTTI_NAMESPACE`, else the default).
    pub namespace: Option<String>,
    /// How long a component has to exit after SIGTERM before SIGKILL.
    pub grace: Duration,
    /// Real-time scheduling for the stepping thread (`tutti run --realtime`), applied once
    /// the components have started, as `tutti host --realtime` applies it.
    pub realtime: Option<tutti_host::RealtimeRequest>,
    /// Start from this checkpoint (`tutti run --restore`), put back before the first step.
    pub restore: Option<Box<tutti_host::checkpoint::Checkpoint>>,
}

/// How a run ended.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Every component, in file order, as it ended.
    pub components: Vec<ComponentStatus>,
    /// Why the components could not all be started, if they could not.
    pub start_error: Option<SupervisorError>,
    /// The framework's summary, if it ran.
    pub summary: Option<Summary>,
}

impl Outcome {
    /// Whether every component ended well ([`ComponentStatus::ended_well`]) and all could
    /// be started (an interrupted start is no failure).
    pub fn all_well(&self) -> bool {
        let started = matches!(self.start_error, None | Some(SupervisorError::Stopping));
        started && self.components.iter().all(ComponentStatus::ended_well)
    }
}

/// Runs `launch` until it ends (see the module); `interrupt` (Ctrl-C) tears it down.
/// `on_supervisor` is given the supervisor once the components are starting: what a control
/// plane keeps to restart, stop and start them.
pub fn run(
    launch: &Launch,
    opts: RunOptions,
    interrupt: Arc<AtomicBool>,
    on_event: OnEvent,
    on_supervisor: impl FnOnce(&Supervisor),
) -> Result<Outcome, RunError> {
    let fw = &launch.framework;
    let host_opts = HostOptions {
        step: fw.step,
        speed: fw.speed,
        duration: fw.duration,
        steps: fw.steps,
        catch_up: fw.catch_up,
        timeout: fw.timeout,
        wait: fw.wait,
        namespace: opts.namespace.clone(),
        sets: fw.set.clone(),
        hold: None,
        wait_for: fw.wait_for.clone(),
        hold_until_start: fw.hold,
        connections: launch.connections.clone(),
        ordering: fw.ordering,
        ddf_name: launch.ddf.display().to_string(),
        stateless: launch.components.iter().filter(|c| c.stateless).map(|c| c.name.clone()).collect(),
        checkpoint: fw.checkpoint.clone(),
        restore: opts.restore.clone(),
        // Room in every domain for each component, with some to spare for recorders,
        // gateways and tools (`tutti status`, a monitor): a large launch file just works.
        slots: (launch.components.len() as u32 + 16).clamp(tutti_core::shm::DEFAULT_CONNECTIONS, 4096),
    };
    let mut host = Host::new(&launch.model, host_opts)?;
    for path in &fw.record {
        let recorder = tutti_record::create(path, &launch.model, &launch.ddf)
            .map_err(|source| RunError::Record { path: path.clone(), source: Box::new(source) })?;
        host.add_sink(Box::new(tutti_record::RecordingSink(recorder)));
    }
    let namespace = host.namespace().to_string();
    let gateway = match &launch.gateway {
        Some(g) => crate::gateway::start(g, &mut host, &on_event)?,
        None => None,
    };
    let finished = Arc::new(AtomicBool::new(false));
    let mut sup_opts = SupervisorOptions::new(namespace, opts.log_dir.clone(), launch.ddf.clone(), opts.tutti_exe);
    sup_opts.grace = opts.grace;
    let sup_interrupt = interrupt.clone();
    sup_opts.interrupt = interrupt;
    sup_opts.finished = finished.clone();
    let supervisor = Supervisor::start(launch.components.clone(), sup_opts, on_event.clone())
        .map_err(|source| RunError::LogDir { dir: opts.log_dir.clone(), source })?;
    on_supervisor(&supervisor);
    // `tutti ctl`: the lifecycle of the framework, and the components through the
    // supervisor; a stop raises the interrupt, which tears the run down in order.
    if let Err(e) = host.serve_control(sup_interrupt, Some(Arc::new(Controlled(supervisor.clone())))) {
        supervisor.shutdown();
        return Err(e.into());
    }
    // With `hold`, the framework steps once all have connected (or not at all).
    let go = !fw.hold || supervisor.wait_started().is_ok();
    let mut stepped = Ok(None);
    if go && !finished.load(Ordering::SeqCst) {
        if let Some(req) = &opts.realtime {
            let got = tutti_host::enter_realtime(req);
            for line in got.applied.iter().map(|a| format!("real-time: {a}")) {
                on_event(Event::Notice(line));
            }
            for line in got.warnings.iter().map(|r| format!("real-time: not applied: {r}")) {
                on_event(Event::Notice(line));
            }
        }
        stepped = host.run_and_keep(&finished, |r| on_event(Event::Host(r))).map(Some);
    }
    // Components first (reverse order), while their domains still exist; then the
    // gateway; the framework removes the domains last.
    let f = supervisor.shutdown();
    drop(gateway);
    drop(host);
    let summary = stepped?;
    Ok(Outcome { components: f.components, start_error: f.start_error, summary })
}

/// The components of a launched run, as the control plane reaches them.
struct Controlled(Supervisor);

impl Components for Controlled {
    fn act(&self, action: ComponentAction, name: &str) -> Result<(), Refusal> {
        let done = match action {
            ComponentAction::Restart => self.0.restart(name).map(|_| ()),
            ComponentAction::Stop => self.0.stop_component(name),
            ComponentAction::Start => self.0.start_component(name).map(|_| ()),
        };
        done.map_err(|e| Refusal(e.to_string()))
    }

    fn signal(&self, name: &str, signal: i32) -> Result<(), Refusal> {
        self.0.signal(name, signal).map_err(|e| Refusal(e.to_string()))
    }

    fn status(&self) -> Vec<control::ComponentStatus> {
        let status = |c: ComponentStatus| control::ComponentStatus {
            name: c.name,
            state: c.state.name(),
            pid: c.pid,
            restarts: c.restarts,
        };
        self.0.status().into_iter().map(status).collect()
    }
}
