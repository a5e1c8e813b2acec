//! The gateway of a launch file (`gateway:` key), started beside the framework.
//!
//! The key is read and checked with the rest of the file ([`crate::file::Gateway`]: the
//! gateway config file's own keys and checks, against the DDF). Running the gateway
//! in-process is not built yet: [`start`] is the one place where it will be.

use crate::file::Gateway;
use crate::supervisor::{Event, OnEvent};
use crate::RunError;

/// A gateway started for a run; stopped when dropped.
#[derive(Debug)]
pub struct GatewayRun {
    _private: (),
}

/// Starts the gateway `gateway` over the domains of namespace `namespace`, once the
/// framework has created them and before the components start; it runs until the
/// returned value is dropped (after the components are torn down, before the framework).
///
/// TODO(in-process gateway): run `tutti_gateway` here with `gateway.options` (already
/// checked against the DDF) and `namespace`, on a thread of its own, and return a
/// [`GatewayRun`] that stops it when dropped. Until then the key is checked but not run,
/// and the run says so.
pub fn start(gateway: &Gateway, namespace: &str, on_event: &OnEvent) -> Result<Option<GatewayRun>, RunError> {
    let from = gateway.config.as_ref().map_or_else(|| "its inline keys".to_string(), |p| p.display().to_string());
    on_event(Event::Notice(format!(
        "gateway: configured ({from}) but not started in namespace {namespace}: running the gateway from a \
         launch file is not built yet; run `tutti gateway` beside it"
    )));
    Ok(None)
}

impl Drop for GatewayRun {
    fn drop(&mut self) {
        // TODO(in-process gateway): stop the gateway and wait for its thread, so that the
        // framework, dropped next, removes domains nobody bridges any more.
    }
}
