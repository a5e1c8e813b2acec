//! The gateway of a launch file (`gateway:` key), run in the framework's process.
//!
//! The key is read and checked with the rest of the file ([`crate::file::Gateway`]: the
//! gateway config file's own keys and checks, against the DDF). [`start`] runs it with
//! `tutti_gateway::in_process`, as `tutti host --gateway` does: the framework's own PUBLISH
//! sets go to DDS from each step (the gateway is one of the host's step sinks), DDS samples
//! for its SUBSCRIBE sets are committed on the engine's receive thread, and sets that the
//! components write are followed by the gateway's poller.

use std::time::Duration;

use tutti_host::Host;

use crate::file::Gateway;
use crate::supervisor::{Event, OnEvent};
use crate::RunError;

/// The gateway's status line, when its config file does not say how often.
const STATUS_EVERY: Duration = Duration::from_secs(60);

/// A gateway started for a run; stopped, its manager thread joined, when dropped (so that
/// the framework, dropped next, removes domains nobody bridges any more).
#[derive(Debug)]
pub struct GatewayRun {
    _gateway: tutti_gateway::in_process::InProcess,
}

/// Starts the gateway `gateway` over the domains `host` has created, once they exist and
/// before the components start; its step sink is added to `host`. It runs until the returned
/// value is dropped (after the components are torn down, before the framework).
pub fn start(gateway: &Gateway, host: &mut Host, on_event: &OnEvent) -> Result<Option<GatewayRun>, RunError> {
    let ev = on_event.clone();
    let on_status = Box::new(move |line: &str| ev(Event::Notice(format!("gateway: {line}"))));
    let every = gateway.keys.gateway.status_every.unwrap_or(STATUS_EVERY);
    let (running, sink) =
        tutti_gateway::in_process::start((*gateway.options).clone(), host.namespace(), every, on_status)
            .map_err(RunError::Gateway)?;
    host.add_sink(Box::new(sink));
    let from = gateway.config.as_ref().map_or_else(|| "its inline keys".to_string(), |p| p.display().to_string());
    on_event(Event::Notice(format!("gateway: running in the framework's process ({from})")));
    Ok(Some(GatewayRun { _gateway: running }))
}
