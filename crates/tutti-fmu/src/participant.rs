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
//!
//! **Checkpoints** (docs/fmu.md): an FMU that can get, set and serialize its state keeps it
//! for the framework's checkpoints. Its connection says so from the start (a
//! [`StateHandler`] in [`ConnectOptions::state`]); the framework's requests are answered from
//! inside the connection's waits, in the run loop's thread. The handler reaches the FMU
//! through the core it shares with the run loop, which never holds it across a call into
//! the participant.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use tutti_core::ddf::{Domain, Value};
use tutti_core::shm::{ConnectOptions, Participant, SharedState, ShmError, StateError, StateHandler};

use crate::fmu::{CallError, Instance};
use crate::mapping::{Mapping, Pair};
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
    /// How to connect (namespace, name shown in `tutti status`, timeouts). Its `state` is the
    /// participant's own: [`FmuParticipant::connect`] sets it (the FMU's state handler, or
    /// none for an FMU that cannot save its state).
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

/// What the run loop and the FMU's state handler share: the FMU and the participant's
/// bookkeeping of it, which a checkpoint saves and restores together.
#[derive(Debug)]
struct Core {
    instance: Instance,
    /// The FMU's time once initialised.
    time: Option<f64>,
    steps: u64,
    /// The last framework step read and its simulated time.
    last_seen: Option<(u64, f64)>,
}

/// The lock on `core`; a panic while it was held leaves it usable (the FMU's own state is
/// what it is either way).
fn lock(core: &Mutex<Core>) -> MutexGuard<'_, Core> {
    core.lock().unwrap_or_else(PoisonError::into_inner)
}

/// An FMU connected to a domain.
#[derive(Debug)]
pub struct FmuParticipant {
    /// The FMU and its bookkeeping, shared with the state handler, which the connection calls
    /// from inside its waits: locked through [`core`](Self::core) only, whose guard borrows
    /// `self`, so no call into `participant` (they take `&mut self`) can be made with it held.
    core: Arc<Mutex<Core>>,
    participant: Option<Participant>,
    mapping: Mapping,
    domain: String,
    mode: StepMode,
    fallback_step: f64,
    max_steps: Option<u64>,
    framework_stopped: bool,
    /// The connection keeps the FMU's state for checkpoints.
    keeps_state: bool,
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

impl Core {
    /// Initialises the FMU at `start` with `inputs` (values of `pairs`).
    fn initialise(&mut self, start: f64, pairs: &[Pair], inputs: Vec<Value>) -> Result<(), CallError> {
        self.instance.enter_initialization(start)?;
        self.set_inputs(pairs, inputs)?;
        self.instance.exit_initialization()?;
        self.time = Some(start);
        Ok(())
    }

    /// Sets the FMU's inputs: `values` of `pairs`.
    fn set_inputs(&mut self, pairs: &[Pair], values: Vec<Value>) -> Result<(), CallError> {
        pairs.iter().zip(values).try_for_each(|(pair, value)| self.instance.set(&pair.var, value))
    }

    /// The FMU's outputs: the values of `pairs`.
    fn outputs(&mut self, pairs: &[Pair]) -> Result<Vec<Value>, CallError> {
        pairs.iter().map(|pair| self.instance.get(&pair.var)).collect()
    }

    /// Brings the FMU to `start + h` with `inputs`: initialised at `start` first if it is not
    /// yet, normally one `doStep(start, h)`; a gap (a step the framework made without this
    /// FMU's answer: it timed out) is one longer step from the FMU's own time; a step that
    /// ends where the FMU already is makes none (a repeated step: the framework's feedthrough
    /// ordering evaluates the outputs again with new inputs; or the first step read raced
    /// with the framework's next one).
    fn advance(&mut self, start: f64, h: f64, pairs: &[Pair], inputs: Vec<Value>) -> Result<(), CallError> {
        match self.time {
            None => self.initialise(start, pairs, inputs)?,
            Some(_) => self.set_inputs(pairs, inputs)?,
        }
        let now = self.time.unwrap_or(start);
        let target = start + h;
        if now == start {
            // The usual case: exactly the framework's time and period.
            self.instance.do_step(start, h)?;
        } else if target > now {
            self.instance.do_step(now, target - now)?;
        } else {
            return Ok(());
        }
        self.time = Some(target);
        self.steps += 1;
        Ok(())
    }

    /// The state a checkpoint keeps: a header of this participant's bookkeeping, then the
    /// FMU's serialized state.
    fn save(&mut self) -> Result<Vec<u8>, CallError> {
        let fmu = self.instance.save_state()?;
        Ok(Bookkeeping { time: self.time, steps: self.steps }.encode(&fmu))
    }

    /// Takes back a state [`save`](Self::save) gave. The next step's size is the period, as
    /// for a steady step: the framework's last step seen is forgotten.
    fn restore(&mut self, state: &[u8]) -> Result<(), RestoreError> {
        let (kept, fmu) = Bookkeeping::decode(state)
            .map_err(|why| RestoreError::Foreign { model: self.instance.model_name().to_string(), why })?;
        self.instance.restore_state(fmu)?;
        self.time = kept.time;
        self.steps = kept.steps;
        self.last_seen = None;
        Ok(())
    }
}

/// The participant's own part of a saved state, in a header before the FMU's:
///
/// | bytes | what |
/// |---|---|
/// | 0..8 | [`STATE_MAGIC`] |
/// | 8..12 | [`STATE_VERSION`], little-endian |
/// | 12..16 | flags, little-endian: bit 0, the FMU has a time (it was initialised) |
/// | 16..24 | the FMU's time, an `f64`'s bits, little-endian (0 without one) |
/// | 24..32 | the steps made, little-endian |
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bookkeeping {
    time: Option<f64>,
    steps: u64,
}

/// The first bytes of a state an FMU participant saved.
const STATE_MAGIC: [u8; 8] = *b"tuttiFMU";
/// The layout of [`Bookkeeping`]'s header.
const STATE_VERSION: u32 = 1;
const HEADER_LEN: usize = 32;
const HAS_TIME: u32 = 1;

impl Bookkeeping {
    /// The header, followed by `fmu` (the FMU's serialized state).
    fn encode(self, fmu: &[u8]) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER_LEN + fmu.len());
        out.extend_from_slice(&STATE_MAGIC);
        out.extend_from_slice(&STATE_VERSION.to_le_bytes());
        out.extend_from_slice(&(if self.time.is_some() { HAS_TIME } else { 0 }).to_le_bytes());
        out.extend_from_slice(&self.time.unwrap_or(0.0).to_bits().to_le_bytes());
        out.extend_from_slice(&self.steps.to_le_bytes());
        out.extend_from_slice(fmu);
        out
    }

    /// The bookkeeping and the FMU's serialized state of `bytes`, or why they are not a state
    /// [`encode`](Self::encode) made.
    fn decode(bytes: &[u8]) -> Result<(Bookkeeping, &[u8]), ForeignState> {
        let (header, fmu) = bytes.split_at_checked(HEADER_LEN).ok_or(ForeignState::Short(bytes.len()))?;
        let word = |at: usize| u32::from_le_bytes(header[at..at + 4].try_into().expect("4 bytes of the header"));
        let long = |at: usize| u64::from_le_bytes(header[at..at + 8].try_into().expect("8 bytes of the header"));
        if header[..8] != STATE_MAGIC {
            return Err(ForeignState::NoMark);
        }
        match (word(8), word(12)) {
            (STATE_VERSION, flags) if flags & !HAS_TIME == 0 => {
                let time = (flags & HAS_TIME != 0).then(|| f64::from_bits(long(16)));
                Ok((Bookkeeping { time, steps: long(24) }, fmu))
            }
            (STATE_VERSION, flags) => Err(ForeignState::Flags(flags)),
            (version, _) => Err(ForeignState::Version(version)),
        }
    }
}

/// Why bytes to restore are not a state an FMU participant saved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
enum ForeignState {
    #[error("{0} bytes, fewer than its {HEADER_LEN}-byte header")]
    Short(usize),
    #[error("it does not begin with the mark of an FMU participant's state")]
    NoMark,
    #[error("its header is of version {0}; this tutti reads version {STATE_VERSION}")]
    Version(u32),
    #[error("unknown flags {0:#x} in its header")]
    Flags(u32),
}

/// Why a state could not be taken back. The cause of `Foreign` is in the message, not a
/// `source` (as for `LoadError`).
#[derive(Debug, thiserror::Error)]
enum RestoreError {
    #[error("FMU '{model}': the state to restore is not one an FMU participant saved: {why}")]
    Foreign { model: String, why: ForeignState },
    #[error(transparent)]
    Call(#[from] CallError),
}

/// The FMU participant's [`StateHandler`]: [`Core::save`] and [`Core::restore`].
struct Checkpoints(Arc<Mutex<Core>>);

// SAFETY: an FMU instance is not `Send` (it stays on the thread that created it), and neither
// is `FmuParticipant`, which holds the other reference to the core. This handler is reachable
// only through the `SharedState` given to that participant's connection, which the
// `FmuParticipant` owns and never hands out (nor a `StepGate` of it); the connection calls a
// handler only from inside its own waits and reads, in the thread that makes them
// (`StateHandler`), which is the `FmuParticipant`'s. So the core is only ever used on that
// thread, and the mutex keeps the handler and the run loop apart.
unsafe impl Send for Checkpoints {}

impl StateHandler for Checkpoints {
    fn save(&mut self) -> Result<Vec<u8>, StateError> {
        Ok(lock(&self.0).save()?)
    }

    fn restore(&mut self, state: &[u8]) -> Result<(), StateError> {
        Ok(lock(&self.0).restore(state)?)
    }
}

impl FmuParticipant {
    /// Sets the parameters of `instance` and connects it to `domain` with `mapping`. An FMU
    /// that can save and restore its state ([`Instance::can_save_state`]) keeps it for the
    /// framework's checkpoints from the connection on; another is a component that keeps no
    /// state (docs/fmu.md, "Checkpoints").
    pub fn connect(
        md: &ModelDescription,
        mut instance: Instance,
        domain: &Domain,
        mapping: Mapping,
        opts: RunOptions,
    ) -> Result<FmuParticipant, RunError> {
        set_params(md, &mut instance, &opts.params)?;
        let keeps_state = instance.can_save_state();
        // Neither `Send` nor `Sync` (the instance is not): the core stays on this thread, the
        // `Arc` and the mutex share it with the state handler there (see `Checkpoints`).
        #[allow(clippy::arc_with_non_send_sync)]
        let core = Arc::new(Mutex::new(Core { instance, time: None, steps: 0, last_seen: None }));
        let state = keeps_state.then(|| SharedState::new(Box::new(Checkpoints(Arc::clone(&core)))));
        let name = domain.name.clone();
        let participant = Participant::connect_checked(domain, ConnectOptions { state, ..opts.connect })
            .map_err(|source| RunError::Domain { domain: name.clone(), source })?;
        let mode =
            if domain.flags.synchronous { StepMode::Synchronous } else { StepMode::Asynchronous { step: opts.step } };
        Ok(FmuParticipant {
            core,
            participant: Some(participant),
            mapping,
            domain: name,
            mode,
            fallback_step: opts.step.as_secs_f64(),
            max_steps: opts.max_steps,
            framework_stopped: false,
            keeps_state,
        })
    }

    pub fn mode(&self) -> StepMode {
        self.mode
    }

    /// Whether the connection keeps the FMU's state for the framework's checkpoints.
    pub fn keeps_state(&self) -> bool {
        self.keeps_state
    }

    /// The FMU's time (`None` before the first step).
    pub fn time(&self) -> Option<f64> {
        self.core().time
    }

    /// The FMU and its bookkeeping, locked. Never held across a call into the participant.
    fn core(&self) -> MutexGuard<'_, Core> {
        lock(&self.core)
    }

    fn shm(&self, source: ShmError) -> RunError {
        RunError::Domain { domain: self.domain.clone(), source }
    }

    fn participant(&mut self) -> &mut Participant {
        // Present from `connect` until `finish`, which consumes self.
        self.participant.as_mut().expect("connected")
    }

    /// The inputs' values in the last PUBLISH snapshot.
    fn inputs(&self) -> Vec<Value> {
        let snap = self.participant.as_ref().expect("connected").snapshot();
        self.mapping.inputs.iter().map(|pair| pair.leaf.ty.decode(&snap[pair.leaf.range()])).collect()
    }

    /// Reads the outputs from the FMU, stages and commits them.
    fn commit_outputs(&mut self) -> Result<(), RunError> {
        if self.mapping.outputs.is_empty() {
            // Nothing to write: the FMU only reads, and the framework does not wait for it.
            return Ok(());
        }
        // Synchronous: this commit answers the step just read.
        self.participant().publish_lock().map_err(|e| self.shm(e))?;
        let values = self.core().outputs(&self.mapping.outputs)?;
        let p = self.participant.as_mut().expect("connected");
        let mut buf = [0u8; 8];
        let staged = self.mapping.outputs.iter().zip(values).try_for_each(|(pair, v)| {
            let n = pair.leaf.ty.size() as usize;
            pair.leaf.ty.encode(v, &mut buf[..n]);
            p.stage(&pair.leaf.path, &buf[..n])
        });
        staged.and_then(|()| p.commit()).map_err(|e| self.shm(e))
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
        let inputs = self.inputs();
        let (start, h) = match self.mode {
            StepMode::Synchronous => {
                let p = self.participant();
                let sim = p.sim_time();
                // The simulated time of a step, as the framework says it; a framework paced
                // faster or slower than the wall clock tells a period that is not it.
                let seg = p.segment();
                let period = seg
                    .sim_step()
                    .or_else(|| p.period().map(|d| d.as_nanos() as f64 * 1e-9))
                    .unwrap_or(self.fallback_step);
                let mut core = self.core();
                let h = step_size(period, core.last_seen, (step, sim));
                core.last_seen = Some((step, sim));
                (sim, h)
            }
            StepMode::Asynchronous { step } => {
                // Time k·h rather than a running sum: no drift over long runs.
                let h = step.as_secs_f64();
                (self.core().steps as f64 * h, h)
            }
        };
        self.core().advance(start, h, &self.mapping.inputs, inputs)?;
        self.commit_outputs()
    }

    /// Steps until `stop` is set, the step limit is reached or an error; then terminates the
    /// FMU and disconnects. In an asynchronous domain each step starts `step` after the last.
    pub fn run(mut self, stop: &AtomicBool) -> Result<RunSummary, RunError> {
        let result = self.run_loop(stop);
        self.finish();
        let core = self.core();
        result.map(|()| RunSummary {
            steps: core.steps,
            time: core.time.unwrap_or(0.0),
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
        if self.core().time.is_some() || self.mapping.outputs.is_empty() {
            return Ok(false);
        }
        let p = self.participant();
        let flags = p.info().flags;
        let fresh = p.segment().step() == 0 && !p.segment().seeded();
        if !(flags.synchronous && flags.states && fresh) {
            return Ok(false);
        }
        let start = p.sim_time();
        self.core().initialise(start, &[], Vec::new())?;
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
        while !stop.load(Ordering::Acquire) && self.max_steps.map_or(true, |m| self.core().steps < m) {
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
        self.core().instance.terminate();
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
    use super::{step_size, Bookkeeping, ForeignState, HEADER_LEN, STATE_VERSION};

    #[test]
    fn the_bookkeeping_header_round_trips_and_refuses_what_it_did_not_write() {
        for kept in [Bookkeeping { time: Some(0.07), steps: 7 }, Bookkeeping { time: None, steps: 0 }] {
            let bytes = kept.encode(b"fmu state");
            assert_eq!(bytes.len(), HEADER_LEN + 9);
            assert_eq!(Bookkeeping::decode(&bytes), Ok((kept, &b"fmu state"[..])));
        }
        let good = Bookkeeping { time: Some(-0.0), steps: u64::MAX }.encode(&[]);
        let (kept, fmu) = Bookkeeping::decode(&good).unwrap();
        assert_eq!((kept.time.map(f64::to_bits), kept.steps, fmu), (Some((-0.0f64).to_bits()), u64::MAX, &[][..]));
        assert_eq!(Bookkeeping::decode(&good[..HEADER_LEN - 1]), Err(ForeignState::Short(HEADER_LEN - 1)));
        assert_eq!(Bookkeeping::decode(&[b'x'; HEADER_LEN]), Err(ForeignState::NoMark));
        let mut newer = good.clone();
        newer[8..12].copy_from_slice(&(STATE_VERSION + 1).to_le_bytes());
        let e = Bookkeeping::decode(&newer).unwrap_err();
        assert_eq!(e.to_string(), "its header is of version 2; this tutti reads version 1");
        let mut flagged = good;
        flagged[12] |= 2;
        assert_eq!(Bookkeeping::decode(&flagged), Err(ForeignState::Flags(3)));
    }

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
