//! The external participant role: connect to a domain by name, snapshot the PUBLISH set,
//! stage and commit the SUBSCRIBE set. The RTAPI (C and Python) is a thin layer over this.
//!
//! `connect` joins a domain (and leaves it), `subscribe` reads the PUBLISH set, `publish`
//! locks a step to answer and claims the right to write, `commit` writes the SUBSCRIBE set,
//! `due` says when an event-driven connection takes part, and `gate` is the wait for the
//! framework, in place or apart from the participant.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::os;
use super::segment::{namespace_from_env, ConnKind, DomainInfo, Segment, WaitMode};
use super::state::{SharedState, StateHandler};
use crate::sync::Ordering;

mod commit;
mod connect;
mod due;
mod gate;
mod publish;
mod subscribe;

use due::Due;
pub use gate::StepGate;

/// How a participant connects and waits.
#[derive(Debug, Clone)]
pub struct ConnectOptions {
    /// Namespace of the segments (default: `TUTTI_NAMESPACE`, else `tutti`).
    pub namespace: String,
    /// Shown in `tutti status` (default: the program name).
    pub name: String,
    /// How long `connect` waits for the domain to appear and for wait-to-go.
    pub connect_timeout: Duration,
    /// How long a lock waits for the framework's next step.
    pub timeout: Duration,
    /// Spin, poll every N µs ("flag delay"), or block.
    pub wait: WaitMode,
    /// Do not wait for the framework's wait-to-go signal in `connect`.
    pub skip_wait_to_go: bool,
    /// What the connection stands for: a component (the default), a DDS writer (set by the
    /// gateway) or an observer, not counted as a participant (the gateway's lock-step reader
    /// with `--every-step`, which the framework still waits for once it reads).
    pub kind: ConnKind,
    /// The component keeps a state that a checkpoint saves and restores: said from the
    /// connection on, so that the run's first checkpoint (at step 0) has it (docs/run.md,
    /// "Checkpoints").
    pub state: Option<SharedState>,
}

/// The environment variable a launcher names each component with (the default connection
/// name): a checkpoint finds a component's state again by its domain and this name.
pub const COMPONENT_ENV: &str = "TUTTI_COMPONENT";

impl Default for ConnectOptions {
    fn default() -> Self {
        let program =
            || std::env::args().next().map(|a| a.rsplit('/').next().unwrap_or(&a).to_string()).unwrap_or_default();
        let name = std::env::var(COMPONENT_ENV).ok().filter(|n| !n.is_empty()).unwrap_or_else(program);
        ConnectOptions {
            namespace: namespace_from_env(),
            name,
            connect_timeout: Duration::from_secs(5),
            timeout: Duration::from_secs(5),
            wait: WaitMode::adaptive(),
            skip_wait_to_go: false,
            kind: ConnKind::Participant,
            state: None,
        }
    }
}

/// A connection to one domain.
#[derive(Debug)]
pub struct Participant {
    seg: Arc<Segment>,
    slot: usize,
    id: u64,
    me: os::ProcessId,
    opts: ConnectOptions,
    /// Own copy of the PUBLISH set, refreshed by `subscribe_lock`.
    snapshot: Vec<u8>,
    /// SUBSCRIBE values being staged; committed by `commit`.
    staging: Vec<u8>,
    /// The SUBSCRIBE values as this connection last committed them (to find changes).
    shadow: Vec<u8>,
    /// Leaves staged explicitly (committed even when unchanged).
    marked: Vec<bool>,
    /// The byte ranges a commit writes, (offset, length): kept between commits so that a
    /// commit allocates nothing.
    changed: Vec<(usize, usize)>,
    last_read: u64,
    last_commit: u64,
    locked_step: u64,
    /// Whether the connection ever read (it then reads before it answers).
    has_read: bool,
    /// Staging and shadow are out of date after `commit_all_with`; the next use refreshes
    /// them from the SUBSCRIBE set (off the commit's path).
    stale_staging: bool,
    /// When the framework's process was last found alive (checked at most every 50 ms).
    framework_seen: std::cell::Cell<Instant>,
    /// The simulated time of the step last read, and its index (simulated time over step).
    read_sim: f64,
    read_index: u64,
    /// When this connection is due, in an event-driven domain (`docs/timing.md`).
    due: Due,
}

impl Participant {
    /// From now on this connection keeps a state that `handler` saves and restores at the
    /// framework's request (docs/run.md, "Checkpoints"); the requests are answered while the
    /// connection waits for a step and at the start of each read.
    pub fn set_state_handler(&mut self, handler: Box<dyn StateHandler>) {
        self.opts.state = Some(SharedState::new(handler));
        self.seg.set_keeps_state(self.slot, true);
    }

    /// Answers a state request of the framework now if one waits (a connection that reads
    /// rarely, or never waits, calls it at its own step boundary); returns whether it did.
    pub fn serve_state(&self) -> bool {
        self.opts.state.as_ref().is_some_and(|h| self.seg.serve_state(self.slot, h))
    }

    /// The domain as the segment describes it.
    pub fn info(&self) -> &DomainInfo {
        &self.seg.info
    }

    pub fn segment(&self) -> &Segment {
        &self.seg
    }

    pub fn set_wait_mode(&mut self, mode: WaitMode) {
        self.opts.wait = mode;
    }

    pub fn set_timeout(&mut self, timeout: Duration) {
        self.opts.timeout = timeout;
    }

    /// The longest wait of this connection (for a step, a commit's step, a lock): what
    /// [`set_timeout`](Self::set_timeout) set.
    pub fn wait_timeout(&self) -> Duration {
        self.opts.timeout
    }

    /// A pointer to the framework's state word (0 while it initialises, 1 running, 2
    /// stopped): the live status the RTAPI hands to C. Valid while this participant lives;
    /// another process writes it, so read it as `volatile`.
    pub fn state_word_ptr(&self) -> *mut u32 {
        self.seg.header().state.as_ptr()
    }

    /// Connections now in the domain (this one included).
    pub fn connection_count(&self) -> u32 {
        self.seg.connection_count()
    }

    /// The step of the last snapshot (0 before any), and the framework's simulated time.
    pub fn last_step(&self) -> u64 {
        self.last_read
    }

    /// The simulated time (seconds) of the framework's latest step.
    pub fn sim_time(&self) -> f64 {
        self.seg.sim_time()
    }

    /// The framework's step period, when it steps at a fixed rate (see [`Segment::period`]).
    pub fn period(&self) -> Option<Duration> {
        self.seg.period()
    }

    /// The simulated time of the step this connection is at (the one it read last; in an
    /// asynchronous domain the framework's latest).
    pub fn simulation_time(&self) -> f64 {
        if self.seg.info.flags.synchronous && (self.has_read || self.locked_step > 0) {
            self.read_sim
        } else {
            self.seg.sim_time()
        }
    }

    /// Shows this connection's link to another site (a remote writer with a lookahead, the
    /// gateway's) in `tutti status`.
    pub fn set_link(&self, link: &crate::shm::segment::LinkInfo) {
        self.seg.set_link(self.slot, link);
    }

    /// Sets a bit of this connection's flags (written only when missing: the framework
    /// polls the line they are on).
    fn set_flag(&self, bit: u32) {
        if let Some(c) = self.seg.conn(self.slot) {
            if c.flags.load(Ordering::Acquire) & bit == 0 {
                c.flags.fetch_or(bit, Ordering::AcqRel);
            }
        }
    }
}
