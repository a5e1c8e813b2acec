//! An FMU as an external participant of a domain.
//!
//! * **Synchronous domain**: one `doStep` per framework step. At the step published at
//!   simulated time `s` with period `h` (both from the segment; see [`step_size`] for a
//!   framework whose simulated time runs faster than its period), the FMU reads its inputs
//!   from that step's PUBLISH set, advances from its time to `s + h` (normally `doStep(s, h)`)
//!   and commits its outputs as its answer to that step. The FMU is initialised at the time
//!   of the first step it reads. If the framework went on without it (a step timed out), the
//!   next `doStep` covers the gap (one longer step). A step that ends where the FMU already
//!   is (a repeated step, as the framework's `feedthrough` ordering publishes: docs/run.md)
//!   sets the inputs and commits the outputs again, with no `doStep`.
//! * **Asynchronous domain**: the FMU steps on its own clock, every `step` of wall time, from
//!   time 0 by `step`, with the latest inputs, and commits after each step.
//!
//! A failing FMU call ends this participant (an error with the FMU's log), never the
//! framework: the connection is released on return.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use tutti_core::ddf::{Domain, Value};
use tutti_core::shm::{ConnectOptions, Participant, ShmError};

use crate::fmu::{CallError, Instance};
use crate::mapping::Mapping;
use crate::model::{Causality, ModelDescription};

/// How the FMU steps (from the domain's `synchronous` flag).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepMode {
    /// One `doStep` per framework step.
    Synchronous,
    /// On its own clock, every `step`.
    Asynchronous { step: Duration },
}

/// Options of an FMU participant.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// How to connect (namespace, name shown in `tutti status`, timeouts).
    pub connect: ConnectOptions,
    /// The step of an asynchronous domain; in a synchronous one, the step used only when
    /// the framework has not published its period.
    pub step: Duration,
    /// Parameter values `(name, text)`, set before initialisation.
    pub params: Vec<(String, String)>,
    /// Stop after this many steps (`None`: until stopped).
    pub max_steps: Option<u64>,
}

/// Why an FMU participant stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error(transparent)]
    Call(#[from] CallError),
    /// The shared-memory error names the domain.
    #[error("{source}")]
    Domain { domain: String, source: ShmError },
    #[error("--param {name}: {why}")]
    Param { name: String, why: String },
}

impl RunError {
    /// Whether the user's input is at fault (a parameter), as opposed to the run.
    pub fn is_invalid_input(&self) -> bool {
        matches!(self, RunError::Param { .. })
    }
}

/// What a finished run did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSummary {
    pub steps: u64,
    /// The FMU's time at the end.
    pub time: f64,
    /// The run ended because the framework stopped.
    pub framework_stopped: bool,
}

/// An FMU connected to a domain.
#[derive(Debug)]
pub struct FmuParticipant {
    instance: Instance,
    participant: Option<Participant>,
    mapping: Mapping,
    domain: String,
    mode: StepMode,
    fallback_step: f64,
    /// The FMU's time once initialised.
    time: Option<f64>,
    steps: u64,
    max_steps: Option<u64>,
    framework_stopped: bool,
    /// The last framework step read and its simulated time.
    last_seen: Option<(u64, f64)>,
}

/// How long one wait for the framework's next step lasts before the run loop looks at its
/// stop flag again: a Ctrl-C or SIGTERM ends the run within this, not after the whole step
/// timeout, by which a supervisor's grace may be over (a component SIGKILLed at a launch
/// file's teardown left its FMU's unpacked directory behind).
const WAIT_SLICE: Duration = Duration::from_millis(200);

/// The step size of a synchronous step: the framework's period, unless its simulated time
/// advances by something else per step (a framework running faster or slower than real
/// time, such as `tutti-demo uav --speed`): then the simulated time per step, measured over
/// the steps since the last one read (steps this participant missed count). The period is
/// kept exactly when it agrees, so that `doStep` gets the framework's own number.
pub fn step_size(period: f64, last: Option<(u64, f64)>, now: (u64, f64)) -> f64 {
    match last {
        Some((k0, s0)) if now.0 > k0 && now.1 > s0 => {
            let per_step = (now.1 - s0) / (now.0 - k0) as f64;
            if (per_step - period).abs() <= 1e-9 * per_step.max(period) {
                period
            } else {
                per_step
            }
        }
        _ => period,
    }
}

/// Sets `--param` values on a freshly instantiated FMU.
pub fn set_params(md: &ModelDescription, instance: &mut Instance, params: &[(String, String)]) -> Result<(), RunError> {
    for (name, text) in params {
        let err = |why: String| RunError::Param { name: name.clone(), why };
        let var = md.variable(name).ok_or_else(|| err(format!("model '{}' has no such variable", md.model_name)))?;
        if !matches!(var.causality, Causality::Parameter | Causality::Input | Causality::StructuralParameter) {
            return Err(err(format!("the variable is {}, not a parameter or input", var.causality.as_str())));
        }
        if var.variability == "constant" {
            return Err(err("the variable is a constant".into()));
        }
        let ty = var
            .ty
            .ddf_type(md.fmi_version)
            .ok_or_else(|| err(format!("type {} cannot be set", var.ty.fmi_name(md.fmi_version))))?;
        let folded = match text.trim() {
            "true" => "1",
            "false" => "0",
            t => t,
        };
        let value = ty.parse_value(folded).ok_or_else(|| err(format!("'{text}' is not a {} value", ty.canonical())))?;
        instance.set(var, value)?;
    }
    Ok(())
}

impl FmuParticipant {
    /// Sets the parameters of `instance` and connects it to `domain` with `mapping`.
    pub fn connect(
        md: &ModelDescription,
        mut instance: Instance,
        domain: &Domain,
        mapping: Mapping,
        opts: RunOptions,
    ) -> Result<FmuParticipant, RunError> {
        set_params(md, &mut instance, &opts.params)?;
        let name = domain.name.clone();
        let participant = Participant::connect_checked(domain, opts.connect)
            .map_err(|source| RunError::Domain { domain: name.clone(), source })?;
        let mode =
            if domain.flags.synchronous { StepMode::Synchronous } else { StepMode::Asynchronous { step: opts.step } };
        Ok(FmuParticipant {
            instance,
            participant: Some(participant),
            mapping,
            domain: name,
            mode,
            fallback_step: opts.step.as_secs_f64(),
            time: None,
            steps: 0,
            max_steps: opts.max_steps,
            framework_stopped: false,
            last_seen: None,
        })
    }

    pub fn mode(&self) -> StepMode {
        self.mode
    }

    /// The FMU's time (`None` before the first step).
    pub fn time(&self) -> Option<f64> {
        self.time
    }

    fn shm(&self, source: ShmError) -> RunError {
        RunError::Domain { domain: self.domain.clone(), source }
    }

    fn participant(&mut self) -> &mut Participant {
        // Present from `connect` until `finish`, which consumes self.
        self.participant.as_mut().expect("connected")
    }

    /// Copies the inputs from the last PUBLISH snapshot into the FMU.
    fn set_inputs(&mut self) -> Result<(), RunError> {
        let inputs = std::mem::take(&mut self.mapping.inputs);
        let mut result = Ok(());
        for pair in &inputs {
            let value: Value = {
                let snap = self.participant().snapshot();
                pair.leaf.ty.decode(&snap[pair.leaf.range()])
            };
            if let Err(e) = self.instance.set(&pair.var, value) {
                result = Err(e.into());
                break;
            }
        }
        self.mapping.inputs = inputs;
        result
    }

    /// Reads the outputs from the FMU, stages and commits them.
    fn commit_outputs(&mut self) -> Result<(), RunError> {
        if !self.mapping.outputs.is_empty() {
            // Synchronous: this commit answers the step just read.
            self.participant().publish_lock().map_err(|e| self.shm(e))?;
        }
        let outputs = std::mem::take(&mut self.mapping.outputs);
        let mut result = Ok(());
        let mut buf = [0u8; 8];
        for pair in &outputs {
            match self.instance.get(&pair.var) {
                Ok(v) => {
                    let n = pair.leaf.ty.size() as usize;
                    pair.leaf.ty.encode(v, &mut buf[..n]);
                    if let Err(e) = self.participant().stage(&pair.leaf.path, &buf[..n]) {
                        result = Err(self.shm(e));
                        break;
                    }
                }
                Err(e) => {
                    result = Err(e.into());
                    break;
                }
            }
        }
        self.mapping.outputs = outputs;
        result?;
        if self.mapping.outputs.is_empty() {
            // Nothing to write: the FMU only reads, and the framework does not wait for it.
            return Ok(());
        }
        self.participant().commit().map_err(|e| self.shm(e))
    }

    /// Initialises the FMU at `start` with the current inputs.
    fn initialise(&mut self, start: f64) -> Result<(), RunError> {
        self.instance.enter_initialization(start)?;
        self.set_inputs()?;
        self.instance.exit_initialization()?;
        self.time = Some(start);
        Ok(())
    }

    /// One step. Synchronous: waits for the framework's next step (at most `WAIT_SLICE`, 200 ms: a
    /// `Timeout` means none came yet, wait again) and answers it. Asynchronous: reads the
    /// latest inputs, advances the FMU by the step and commits (the caller paces).
    pub fn step(&mut self) -> Result<(), RunError> {
        let sync = self.mode == StepMode::Synchronous;
        let p = self.participant();
        // The connection's timeout (commits, locks); a wait for a step is sliced.
        let timeout = p.wait_timeout();
        if sync {
            // A timed-out slice is waited again by the run loop, unless it is told to stop.
            p.set_timeout(WAIT_SLICE.min(timeout));
        }
        let read = p.subscribe_lock();
        p.set_timeout(timeout);
        let step = read.map_err(|e| self.shm(e))?;
        let (start, h) = match self.mode {
            StepMode::Synchronous => {
                let p = self.participant();
                let sim = p.sim_time();
                let period = p.period().map_or(self.fallback_step, |d| d.as_nanos() as f64 * 1e-9);
                let h = step_size(period, self.last_seen, (step, sim));
                self.last_seen = Some((step, sim));
                (sim, h)
            }
            StepMode::Asynchronous { step } => {
                // Time k·h rather than a running sum: no drift over long runs.
                let h = step.as_secs_f64();
                (self.steps as f64 * h, h)
            }
        };
        match self.time {
            None => self.initialise(start)?,
            Some(_) => self.set_inputs()?,
        }
        let now = self.time.unwrap_or(start);
        let target = start + h;
        if now == start {
            // The usual case: exactly the framework's time and period.
            self.instance.do_step(start, h)?;
        } else if target > now {
            // A gap left by a step the framework made without this FMU's answer (it timed
            // out): one longer step from the FMU's own time.
            self.instance.do_step(now, target - now)?;
        } else {
            // Already there: a repeated step (the framework's feedthrough ordering evaluates
            // the outputs again with new inputs), or the first step read raced with the
            // framework's next one.
            return self.commit_outputs();
        }
        self.time = Some(target);
        self.steps += 1;
        self.commit_outputs()
    }

    /// Steps until `stop` is set, the step limit is reached or an error; then terminates the
    /// FMU and disconnects. In an asynchronous domain each step starts `step` after the last.
    pub fn run(mut self, stop: &AtomicBool) -> Result<RunSummary, RunError> {
        let result = self.run_loop(stop);
        self.finish();
        result.map(|()| RunSummary {
            steps: self.steps,
            time: self.time.unwrap_or(0.0),
            framework_stopped: self.framework_stopped,
        })
    }

    /// In a synchronous domain with `states` that the framework has not stepped yet (and
    /// nobody has seeded): initialises the FMU at the domain's time, with its start values
    /// and parameters, and commits its initial outputs as the domain's seed. The framework
    /// waits for that seed before its first step, so the FMU answers every step from the
    /// first, and the framework's initial exchange (docs/run.md, Connections) hands these
    /// outputs to the connected inputs of the first step. Elsewhere, nothing.
    pub fn seed(&mut self) -> Result<bool, RunError> {
        if self.time.is_some() || self.mapping.outputs.is_empty() {
            return Ok(false);
        }
        let p = self.participant();
        let flags = p.info().flags;
        let fresh = p.segment().step() == 0 && !p.segment().seeded();
        if !(flags.synchronous && flags.states && fresh) {
            return Ok(false);
        }
        let start = p.sim_time();
        self.instance.enter_initialization(start)?;
        self.instance.exit_initialization()?;
        self.time = Some(start);
        self.commit_outputs()?;
        Ok(true)
    }

    fn run_loop(&mut self, stop: &AtomicBool) -> Result<(), RunError> {
        if self.mode == StepMode::Synchronous {
            match self.seed() {
                Ok(_) => {}
                Err(RunError::Domain { source: ShmError::FrameworkStopped { .. }, .. }) => {
                    self.framework_stopped = true;
                    return Ok(());
                }
                Err(e) => return Err(e),
            }
        }
        let begin = Instant::now();
        let mut k: u32 = 0;
        while !stop.load(Ordering::Acquire) && self.max_steps.map_or(true, |m| self.steps < m) {
            match self.step() {
                Ok(()) => {}
                // A synchronous step that does not come within the timeout: the framework
                // may be paused; keep waiting unless told to stop.
                Err(RunError::Domain { source: ShmError::Timeout { .. }, .. })
                    if self.mode == StepMode::Synchronous =>
                {
                    continue
                }
                // The framework ending is the end of the run, not a failure of the FMU.
                Err(RunError::Domain { source: ShmError::FrameworkStopped { .. }, .. }) => {
                    self.framework_stopped = true;
                    return Ok(());
                }
                Err(e) => return Err(e),
            }
            if let StepMode::Asynchronous { step } = self.mode {
                k += 1;
                let next = begin + step * k;
                let now = Instant::now();
                if next > now {
                    std::thread::sleep(next - now);
                }
            }
        }
        Ok(())
    }

    /// Terminates the FMU and releases the connection.
    fn finish(&mut self) {
        if let Some(p) = self.participant.take() {
            p.disconnect();
        }
        self.instance.terminate();
    }
}

impl Drop for FmuParticipant {
    fn drop(&mut self) {
        if let Some(p) = self.participant.take() {
            p.disconnect();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::step_size;

    #[test]
    fn the_step_is_the_period_unless_simulated_time_says_otherwise() {
        assert_eq!(step_size(0.01, None, (1, 0.0)), 0.01);
        // 0.07 - 0.06 is not 0.01 in floating point: the period itself is used.
        assert_eq!(step_size(0.01, Some((6, 0.06)), (7, 0.07)), 0.01);
        // Two steps missed: still one period per step.
        assert_eq!(step_size(0.01, Some((6, 0.06)), (9, 0.09)), 0.01);
        // Simulated time runs 8 times faster than the wall-clock period.
        assert!((step_size(0.00625, Some((1, 0.0)), (2, 0.05)) - 0.05).abs() < 1e-15);
    }
}
