//! Defaults that several layers share, each in one place with the text a command line's
//! `default_value` takes (the same duration, written as `tutti_core::parse` reads it).
//!
//! The step timeout is the framework's longest wait for the participants of a synchronous
//! step, and for a seed ([`crate::shm::FrameworkOptions::timeout`]). `tutti host --timeout`,
//! the runner's `HostOptions`, a launch file's `framework.timeout` and the framework itself
//! default to [`STEP_TIMEOUT`]; `tutti ssp ddf` and `tutti run SYSTEM.ssp` to
//! [`SSP_STEP_TIMEOUT`].

use std::time::Duration;

/// The step timeout (docs/run.md, `framework.timeout`): long beside the steps of a
/// real-time run (milliseconds), short enough that a participant that hangs holds its
/// domain up for a moment only.
pub const STEP_TIMEOUT: Duration = Duration::from_secs(1);
/// [`STEP_TIMEOUT`] as a command line writes it.
pub const STEP_TIMEOUT_TEXT: &str = "1s";

/// The step timeout of an SSP system's run (docs/ssp.md). An SSP system is a co-simulation
/// of FMUs that should give the system's results however loaded the machine is: when the
/// framework moves on without an FMU's answer, that FMU's next `doStep` covers the missed
/// step too (docs/fmu.md), and the results change. An FMU's `doStep` and its initialisation
/// (the seed) have no real-time bound, so an SSP run waits ten times [`STEP_TIMEOUT`] before
/// it gives up on one.
pub const SSP_STEP_TIMEOUT: Duration = Duration::from_secs(10);
/// [`SSP_STEP_TIMEOUT`] as a command line writes it.
pub const SSP_STEP_TIMEOUT_TEXT: &str = "10s";

#[cfg(all(test, not(tutti_loom)))]
mod tests {
    use super::*;
    use crate::parse::parse_duration;

    #[test]
    fn each_text_is_its_duration() {
        assert_eq!(parse_duration(STEP_TIMEOUT_TEXT), Ok(STEP_TIMEOUT));
        assert_eq!(parse_duration(SSP_STEP_TIMEOUT_TEXT), Ok(SSP_STEP_TIMEOUT));
    }
}
