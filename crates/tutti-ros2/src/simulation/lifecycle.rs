//! The `simulation_interfaces` calls as the run's lifecycle (docs/ros2.md, "The calls and the
//! lifecycle"): each call is one or two requests of the run's control plane
//! ([`tutti_host::control`], what `tutti ctl` sends), and its answer is the standard's result
//! code with a message that says why.
//!
//! The standard's STOPPED is "paused and reset"; the run has no such state of its own, so the
//! gateway remembers that it stopped the run and says STOPPED while the run is still paused
//! at step 0; any other change (a step, a resume, `tutti ctl`) makes it PAUSED or PLAYING
//! again. The run's own `stopped` (it has ended) is QUITTING.

use std::time::Duration;

use tutti_host::control::{ControlClient, ControlError, Request, RunState, RunStatus};

use super::{feature, result, scope, state};
use crate::{Struct, Value};

/// A `simulation_interfaces/msg/Result`: a code of [`result`] and a message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outcome {
    pub code: u8,
    pub message: String,
}

impl Outcome {
    pub fn ok() -> Outcome {
        Outcome { code: result::OK, message: String::new() }
    }

    pub fn new(code: u8, message: impl Into<String>) -> Outcome {
        Outcome { code, message: message.into() }
    }

    /// As the message's value.
    pub fn value(&self) -> Value {
        Struct::new().with("result", self.code).with("error_message", self.message.as_str()).into()
    }
}

/// The run's control plane, as the calls use it (a trait so the mapping is tested without a run).
pub trait Control {
    fn call(&mut self, request: &Request) -> Result<RunStatus, ControlError>;
}

/// The control plane of the run of a namespace, reached as `tutti ctl` reaches it: a
/// connection per call, so a run that restarts is found again.
#[derive(Debug, Clone)]
pub struct RunControl {
    pub namespace: String,
    /// The longest wait for an answer (`step N` is answered after its N steps).
    pub timeout: Duration,
}

impl Control for RunControl {
    fn call(&mut self, request: &Request) -> Result<RunStatus, ControlError> {
        ControlClient::connect(&self.namespace, self.timeout)?.request(request)
    }
}

/// What the gateway knows of the run's lifecycle beyond the run's own state.
#[derive(Debug, Clone, Default)]
pub struct Lifecycle {
    /// Why stepping cannot apply to this run (None: it can): every domain is asynchronous.
    pub no_stepping: Option<String>,
    /// The gateway stopped the run (paused it and reset its time) and nothing moved it since.
    stopped: bool,
}

/// A control-plane failure as a result: the run refused (its reason), or could not be reached.
fn failed(what: &str, e: &ControlError) -> Outcome {
    Outcome::new(result::OPERATION_FAILED, format!("{what}: {e}"))
}

impl Lifecycle {
    pub fn new(no_stepping: Option<String>) -> Lifecycle {
        Lifecycle { no_stepping, stopped: false }
    }

    /// `GetSimulatorFeatures`: what this run supports (`state_reset`: the run holds its
    /// checkpoint of step 0, so SCOPE_STATE can go back to it).
    pub fn features(&self, action: bool, state_reset: bool) -> Vec<u16> {
        let mut f = vec![feature::SIMULATION_RESET, feature::SIMULATION_RESET_TIME];
        if state_reset {
            f.push(feature::SIMULATION_RESET_STATE);
        }
        f.extend([
            feature::SIMULATION_STATE_GETTING,
            feature::SIMULATION_STATE_SETTING,
            feature::SIMULATION_STATE_PAUSE,
        ]);
        if self.no_stepping.is_none() {
            f.extend([feature::STEP_SIMULATION_SINGLE, feature::STEP_SIMULATION_MULTIPLE]);
            if action {
                f.push(feature::STEP_SIMULATION_ACTION);
            }
        }
        f
    }

    /// The standard's state of a run in `status`.
    fn standard_state(&mut self, status: &RunStatus) -> u8 {
        if !(status.state == RunState::Paused && status.step == 0) {
            self.stopped = false;
        }
        match status.state {
            RunState::Ready => state::STOPPED,
            RunState::Playing => state::PLAYING,
            RunState::Paused if self.stopped => state::STOPPED,
            RunState::Paused => state::PAUSED,
            RunState::Stopped => state::QUITTING,
        }
    }

    /// `GetSimulationState`: the state and the result.
    pub fn get_state(&mut self, ctl: &mut dyn Control) -> (u8, Outcome) {
        match ctl.call(&Request::State) {
            Ok(s) => (self.standard_state(&s), Outcome::ok()),
            Err(e) => (state::NO_WORLD, failed("the run's state", &e)),
        }
    }

    /// `SetSimulationState` to `target`.
    pub fn set_state(&mut self, ctl: &mut dyn Control, target: u8) -> Outcome {
        if !matches!(target, state::STOPPED | state::PLAYING | state::PAUSED | state::QUITTING) {
            let why = match target {
                state::NO_WORLD | state::LOADING_WORLD => "a tutti run has no worlds to unload or load",
                _ => "it is no SimulationState",
            };
            return Outcome::new(result::FEATURE_UNSUPPORTED, format!("state {target}: {why}"));
        }
        let status = match ctl.call(&Request::State) {
            Ok(s) => s,
            Err(e) => return failed("the run's state", &e),
        };
        let now = self.standard_state(&status);
        if now == target && status.state != RunState::Ready {
            return Outcome::new(result::ALREADY_IN_TARGET_STATE, format!("already {}", name(target)));
        }
        if status.state == RunState::Ready {
            return match target {
                state::STOPPED => {
                    Outcome::new(result::ALREADY_IN_TARGET_STATE, "already stopped: the run has not started")
                }
                state::QUITTING => self.quit(ctl),
                _ => Outcome::new(
                    result::STATE_TRANSITION_ERROR,
                    "the run has not started: it waits for its participants, and plays once they are there",
                ),
            };
        }
        if now == state::QUITTING {
            return Outcome::new(result::INCORRECT_TRANSITION, "the run has ended");
        }
        match target {
            state::PLAYING => match ctl.call(&Request::Resume) {
                Ok(_) => {
                    self.stopped = false;
                    Outcome::ok()
                }
                Err(e) => failed("resume", &e),
            },
            state::PAUSED if now == state::STOPPED => Outcome::new(
                result::INCORRECT_TRANSITION,
                "the run is stopped (paused at time 0): set PLAYING, or step it",
            ),
            state::PAUSED => match ctl.call(&Request::Pause) {
                Ok(_) => Outcome::ok(),
                Err(e) => failed("pause", &e),
            },
            state::STOPPED => {
                if now == state::PLAYING {
                    if let Err(e) = ctl.call(&Request::Pause) {
                        return failed("pause", &e);
                    }
                }
                match ctl.call(&Request::Reset) {
                    Ok(_) => {
                        self.stopped = true;
                        Outcome::ok()
                    }
                    Err(e) => failed("reset", &e),
                }
            }
            _ => self.quit(ctl),
        }
    }

    fn quit(&mut self, ctl: &mut dyn Control) -> Outcome {
        match ctl.call(&Request::Stop) {
            Ok(_) => Outcome::ok(),
            Err(e) => failed("stop", &e),
        }
    }

    /// Whether `steps` steps can be made now: Ok, or the result that refuses them.
    pub fn can_step(&mut self, ctl: &mut dyn Control, steps: u64) -> Result<(), Outcome> {
        if let Some(why) = &self.no_stepping {
            return Err(Outcome::new(result::FEATURE_UNSUPPORTED, why.clone()));
        }
        if steps == 0 {
            return Err(Outcome::new(result::OPERATION_FAILED, "steps must be 1 or more"));
        }
        let status = ctl.call(&Request::State).map_err(|e| failed("the run's state", &e))?;
        match self.standard_state(&status) {
            state::PAUSED | state::STOPPED if status.state == RunState::Paused => Ok(()),
            s => Err(Outcome::new(
                result::OPERATION_FAILED,
                format!("the simulation is {}: steps are made only while it is paused", name(s)),
            )),
        }
    }

    /// `StepSimulation`: `steps` steps of a paused run, then paused again.
    pub fn step(&mut self, ctl: &mut dyn Control, steps: u64) -> Outcome {
        if let Err(refused) = self.can_step(ctl, steps) {
            return refused;
        }
        self.stopped = false;
        match ctl.call(&Request::Step { n: steps }) {
            Ok(_) => Outcome::ok(),
            Err(e) => failed("step", &e),
        }
    }

    /// `ResetSimulation` with `scope`: DEFAULT and TIME take the run's time back to 0 (its
    /// components keep their state, as `tutti ctl reset` does); STATE, and ALL, go back to the
    /// run's checkpoint of step 0, every value and component's state included (`tutti ctl
    /// reset state`); SPAWNED alone is not supported (a run spawns nothing).
    pub fn reset(&mut self, ctl: &mut dyn Control, s: u8) -> Outcome {
        let request = if s == scope::DEFAULT || s == scope::TIME {
            Request::Reset
        } else if s & scope::STATE != 0 {
            Request::ResetState
        } else {
            return Outcome::new(
                result::FEATURE_UNSUPPORTED,
                format!("scope {s}: SCOPE_DEFAULT, SCOPE_TIME, SCOPE_STATE and SCOPE_ALL are supported (a run spawns nothing)"),
            );
        };
        self.stopped = false;
        match ctl.call(&request) {
            Ok(_) => Outcome::ok(),
            Err(e) => failed("reset", &e),
        }
    }
}

/// The state's name in messages.
pub fn name(s: u8) -> &'static str {
    match s {
        state::STOPPED => "stopped",
        state::PLAYING => "playing",
        state::PAUSED => "paused",
        state::QUITTING => "quitting",
        state::NO_WORLD => "without a world",
        _ => "loading a world",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tutti_host::control::Refusal;

    /// A run as the control plane shows it: its state and step, and the requests it got.
    struct FakeRun {
        state: RunState,
        step: u64,
        got: Vec<Request>,
    }

    impl FakeRun {
        fn new(state: RunState) -> FakeRun {
            FakeRun { state, step: 5, got: Vec::new() }
        }
    }

    impl Control for FakeRun {
        fn call(&mut self, r: &Request) -> Result<RunStatus, ControlError> {
            self.got.push(r.clone());
            match r {
                Request::Pause => self.state = RunState::Paused,
                Request::Resume => self.state = RunState::Playing,
                Request::Reset => self.step = 0,
                Request::Step { n } if self.state == RunState::Paused => self.step += n,
                Request::Step { .. } => return Err(ControlError::Refused(Refusal("playing".into()))),
                Request::Stop => self.state = RunState::Stopped,
                _ => {}
            }
            Ok(RunStatus {
                state: self.state,
                step: self.step,
                sim_time: 0.0,
                namespace: "t".into(),
                pid: 1,
                components: Vec::new(),
                state_reset: false,
                speed: 1.0,
                end_time: None,
                seekable: false,
            })
        }
    }

    fn code(o: Outcome) -> u8 {
        o.code
    }

    #[test]
    fn pause_play_and_the_same_state_twice() {
        let (mut l, mut run) = (Lifecycle::new(None), FakeRun::new(RunState::Playing));
        assert_eq!(code(l.set_state(&mut run, state::PLAYING)), result::ALREADY_IN_TARGET_STATE);
        assert_eq!(code(l.set_state(&mut run, state::PAUSED)), result::OK);
        assert_eq!(l.get_state(&mut run).0, state::PAUSED);
        let again = l.set_state(&mut run, state::PAUSED);
        assert_eq!((again.code, again.message.as_str()), (result::ALREADY_IN_TARGET_STATE, "already paused"));
        assert_eq!(code(l.set_state(&mut run, state::PLAYING)), result::OK);
        assert_eq!(run.state, RunState::Playing);
    }

    #[test]
    fn stopped_is_paused_at_time_zero_until_something_moves_the_run() {
        let (mut l, mut run) = (Lifecycle::new(None), FakeRun::new(RunState::Playing));
        assert_eq!(code(l.set_state(&mut run, state::STOPPED)), result::OK);
        assert_eq!((run.state, run.step), (RunState::Paused, 0));
        assert_eq!(l.get_state(&mut run).0, state::STOPPED);
        assert_eq!(code(l.set_state(&mut run, state::STOPPED)), result::ALREADY_IN_TARGET_STATE);
        assert_eq!(code(l.set_state(&mut run, state::PAUSED)), result::INCORRECT_TRANSITION);
        assert_eq!(code(l.step(&mut run, 2)), result::OK);
        assert_eq!(l.get_state(&mut run).0, state::PAUSED);
        assert_eq!(code(l.set_state(&mut run, state::QUITTING)), result::OK);
        assert_eq!(l.get_state(&mut run).0, state::QUITTING);
        assert_eq!(code(l.set_state(&mut run, state::PLAYING)), result::INCORRECT_TRANSITION);
    }

    #[test]
    fn steps_only_while_paused_and_never_in_an_asynchronous_run() {
        let (mut l, mut run) = (Lifecycle::new(None), FakeRun::new(RunState::Playing));
        let o = l.step(&mut run, 3);
        assert_eq!(o.code, result::OPERATION_FAILED, "{o:?}");
        assert!(o.message.contains("playing"), "{o:?}");
        assert!(!run.got.iter().any(|r| matches!(r, Request::Step { .. })));
        run.state = RunState::Paused;
        assert_eq!(code(l.step(&mut run, 3)), result::OK);
        assert_eq!(run.step, 8);
        assert_eq!(code(l.step(&mut run, 0)), result::OPERATION_FAILED);
        let mut a = Lifecycle::new(Some("every domain is asynchronous".into()));
        let o = a.step(&mut run, 1);
        assert_eq!((o.code, o.message.as_str()), (result::FEATURE_UNSUPPORTED, "every domain is asynchronous"));
        assert!(!a.features(true, false).contains(&feature::STEP_SIMULATION_SINGLE));
        assert!(l.features(true, false).contains(&feature::STEP_SIMULATION_ACTION));
        assert!(!l.features(false, false).contains(&feature::STEP_SIMULATION_ACTION));
    }

    #[test]
    fn reset_scopes() {
        let (mut l, mut run) = (Lifecycle::new(None), FakeRun::new(RunState::Playing));
        assert_eq!(code(l.reset(&mut run, scope::TIME)), result::OK);
        assert_eq!(run.step, 0);
        assert_eq!(code(l.reset(&mut run, scope::DEFAULT)), result::OK);
        let o = l.reset(&mut run, scope::SPAWNED);
        assert_eq!(o.code, result::FEATURE_UNSUPPORTED, "{o:?}");
        assert!(o.message.contains("SCOPE_STATE"), "{o:?}");
        for s in [scope::STATE, scope::ALL, scope::TIME | scope::STATE] {
            assert_eq!(code(l.reset(&mut run, s)), result::OK, "{s}");
        }
        assert_eq!(run.got.iter().filter(|r| **r == Request::Reset).count(), 2);
        assert_eq!(run.got.iter().filter(|r| **r == Request::ResetState).count(), 3);
        assert!(l.features(true, true).contains(&feature::SIMULATION_RESET_STATE));
        assert!(!l.features(true, false).contains(&feature::SIMULATION_RESET_STATE));
    }

    #[test]
    fn states_without_a_world_are_not_targets() {
        let (mut l, mut run) = (Lifecycle::new(None), FakeRun::new(RunState::Playing));
        assert_eq!(code(l.set_state(&mut run, state::NO_WORLD)), result::FEATURE_UNSUPPORTED);
        assert_eq!(code(l.set_state(&mut run, 9)), result::FEATURE_UNSUPPORTED);
        assert!(run.got.is_empty());
    }
}
