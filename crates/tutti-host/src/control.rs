//! The run's control plane: its lifecycle ([`RunState`]) and the commands that move it
//! ([`Request`]), served to other processes of the same user on a Unix socket beside the
//! namespace's segments, `/dev/shm/tutti-ctl.<namespace>` ([`socket_path`]), as one JSON
//! object a line each way. `tutti ctl`, the Python module (`tutti_ctl`) and [`ControlClient`]
//! speak it; docs/run.md describes it.
//!
//! Only the owner may use it, as with the segments: the socket is the owner's alone (mode
//! 0600) and a connection from another user is closed unanswered (its peer's credentials are
//! checked). Nothing leaves the machine.
//!
//! The server thread answers `state` itself; every other command goes to the run's loop,
//! which carries it out between two steps and answers when it is done (`step N`: after the
//! N steps).

use std::io::{BufRead, BufReader, Write};
use std::os::unix::fs::PermissionsExt;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::Duration;

use serde::{Deserialize, Serialize};

/// Where the control socket of namespace `ns` is.
pub fn socket_path(ns: &str) -> PathBuf {
    PathBuf::from(tutti_core::shm::os::SHM_DIR).join(format!("tutti-ctl.{ns}"))
}

/// Where a run is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunState {
    /// Domains created; participants held in wait-to-go until the run starts.
    Ready,
    Playing,
    /// Held at a step boundary: no step is made, and no participant times out.
    Paused,
    Stopped,
}

impl RunState {
    fn from_u8(v: u8) -> RunState {
        match v {
            1 => RunState::Playing,
            2 => RunState::Paused,
            3 => RunState::Stopped,
            _ => RunState::Ready,
        }
    }

    /// The name `tutti ctl state` prints.
    pub fn name(self) -> &'static str {
        match self {
            RunState::Ready => "ready",
            RunState::Playing => "playing",
            RunState::Paused => "paused",
            RunState::Stopped => "stopped",
        }
    }
}

/// What can be done to a component of a launched run (`tutti run`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ComponentAction {
    Restart,
    Stop,
    Start,
}

/// A command, as it travels on the socket: `{"op": "step", "n": 7}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case", deny_unknown_fields)]
pub enum Request {
    /// The run's state; changes nothing.
    State,
    /// Hold every domain at the next step boundary.
    Pause,
    /// Step on from a pause.
    Resume,
    /// While paused: make exactly `n` steps, then pause again.
    Step { n: u64 },
    /// Step count and simulated time back to zero.
    Reset,
    /// Step at `factor` times real time from now on (a run paced by the wall clock; `tutti
    /// ctl speed 2`, Foxglove's playback speed).
    Speed { factor: f64 },
    /// A replay: go on from the recorded step at `time` (simulated seconds; the first step at
    /// or after it). A live run refuses it: it has no other time to go to.
    Seek { time: f64 },
    /// Back to the run's first step boundary, every value and component's state included: the
    /// checkpoint taken at step 0 (docs/run.md, "Checkpoints").
    ResetState,
    /// Write a checkpoint of the run to `path` (a path the run's process can reach; `tutti
    /// ctl` sends it absolute) at the next step boundary; with `skip_stateless`, components
    /// that keep no state are left out (and named in the file) instead of failing the save.
    Save {
        path: String,
        #[serde(default)]
        skip_stateless: bool,
    },
    /// Put back the checkpoint at `path` at the next step boundary; the run goes on (or stays
    /// paused) from there.
    Restore { path: String },
    /// End the run (a launched run tears its components down).
    Stop,
    /// Restart, stop or start one component of a launched run.
    Component { action: ComponentAction, name: String },
    /// Send a signal (`USR1`, `SIGUSR2`, …: [`SIGNALS`]) to the process of one running
    /// component of a launched run.
    Signal { name: String, signal: String },
}

/// The signals `tutti ctl signal` sends, by name (with or without `SIG`, any case).
pub const SIGNALS: &[(&str, i32)] = &[
    ("HUP", 1),
    ("INT", 2),
    ("QUIT", 3),
    ("KILL", 9),
    ("USR1", 10),
    ("USR2", 12),
    ("ALRM", 14),
    ("TERM", 15),
    ("CONT", 18),
    ("STOP", 19),
];

/// The number of signal `name` (`USR1`, `sigusr1`, `SIGTERM`, …), or why it is refused.
pub fn parse_signal(name: &str) -> Result<i32, Refusal> {
    let upper = name.trim().to_ascii_uppercase();
    let bare = upper.strip_prefix("SIG").unwrap_or(&upper);
    SIGNALS.iter().find(|(n, _)| *n == bare).map(|(_, v)| *v).ok_or_else(|| {
        let known: Vec<&str> = SIGNALS.iter().map(|(n, _)| *n).collect();
        Refusal(format!("unknown signal '{name}': expected one of {}", known.join(", ")))
    })
}

/// One component of a launched run, as `tutti ctl state` shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ComponentStatus {
    pub name: String,
    /// `starting`, `running`, `stopped`, `exited`, `failed`, …
    pub state: String,
    pub pid: Option<u32>,
    pub restarts: u32,
}

/// The state of a run, in every answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunStatus {
    pub state: RunState,
    /// Steps since the start (or the last reset).
    pub step: u64,
    /// Simulated time of the last step, seconds.
    pub sim_time: f64,
    pub namespace: String,
    /// The framework's process.
    pub pid: u32,
    /// The components of a launched run (none for `tutti host`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub components: Vec<ComponentStatus>,
    /// The run holds a checkpoint of its step 0, so `reset_state` can go back to it.
    #[serde(default)]
    pub state_reset: bool,
    /// Simulated time over wall time (infinite: not paced by the wall clock).
    #[serde(default = "one", with = "speed_text")]
    pub speed: f64,
    /// The simulated time the run ends at, when it has an end (`steps`, or `duration` of a
    /// run paced by the wall clock).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_time: Option<f64>,
    /// The run can go to another time (`seek`): a replay of a recording.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub seekable: bool,
}

fn one() -> f64 {
    1.0
}

/// A speed as JSON has it: a number, or `"inf"` (JSON has no infinity).
mod speed_text {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_str("inf")
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Speed {
            Number(f64),
            Text(String),
        }
        match Speed::deserialize(d)? {
            Speed::Number(v) => Ok(v),
            Speed::Text(t) if t == "inf" => Ok(f64::INFINITY),
            Speed::Text(t) => Err(serde::de::Error::custom(format!("'{t}' is not a speed"))),
        }
    }
}

/// An answer on the socket: `{"ok": true, "status": {…}}` or `{"ok": false, "error": "…"}`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Answer {
    ok: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    error: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    status: Option<RunStatus>,
}

/// A command the run could not carry out, with the reason a user reads.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Refusal(pub String);

/// What goes wrong talking to a run.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// No run serves namespace `namespace`.
    #[error(
        "no run in namespace '{namespace}' (no control socket {path}): is a `tutti host` or `tutti run` running there?"
    )]
    NoRun { namespace: String, path: String },
    /// The namespace's control socket is served by a process of another user.
    #[error("the control socket {path} of namespace '{namespace}' is served by another user (uid {uid}), not by a run of yours")]
    NotOurs { namespace: String, path: String, uid: u32 },
    /// Another run already serves the namespace.
    #[error("namespace '{namespace}' already has a running framework (its control socket {path} answers)")]
    Taken { namespace: String, path: String },
    #[error("{what} {path}: {source}")]
    Io {
        what: &'static str,
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The run answered something that is not a reply.
    #[error("the run's answer is not understood: {0}")]
    Protocol(String),
    /// The run refused the command.
    #[error("{0}")]
    Refused(Refusal),
    /// No answer within the time asked for.
    #[error("no answer from the run within {0:?}")]
    NoAnswer(Duration),
}

/// The components of a launched run, as the control plane reaches them.
pub trait Components: Send + Sync {
    /// Restarts, stops or starts component `name`.
    fn act(&self, action: ComponentAction, name: &str) -> Result<(), Refusal>;
    /// Sends signal number `signal` to the process of component `name`, which must run.
    fn signal(&self, name: &str, signal: i32) -> Result<(), Refusal>;
    /// Every component's state.
    fn status(&self) -> Vec<ComponentStatus>;
}

/// The state the server thread answers from, written by the run's loop.
#[derive(Debug)]
pub(crate) struct Shared {
    state: AtomicU8,
    step: AtomicU64,
    sim_bits: AtomicU64,
    namespace: String,
    /// Whether the run holds its step-0 checkpoint.
    pub(crate) state_reset: AtomicBool,
    /// The run's speed (f64 bits).
    speed_bits: AtomicU64,
    /// The simulated time it ends at (f64 bits; NaN: none).
    end_bits: AtomicU64,
    /// A replay, which can seek.
    pub(crate) seekable: AtomicBool,
}

impl Shared {
    pub(crate) fn set(&self, state: RunState, step: u64, sim: f64) {
        self.step.store(step, Ordering::Relaxed);
        self.sim_bits.store(sim.to_bits(), Ordering::Relaxed);
        self.state.store(state as u8, Ordering::Release);
    }

    pub(crate) fn set_speed(&self, speed: f64, end_time: Option<f64>) {
        self.speed_bits.store(speed.to_bits(), Ordering::Relaxed);
        self.end_bits.store(end_time.unwrap_or(f64::NAN).to_bits(), Ordering::Relaxed);
    }

    pub(crate) fn state(&self) -> RunState {
        RunState::from_u8(self.state.load(Ordering::Acquire))
    }

    fn status(&self, components: Option<&dyn Components>) -> RunStatus {
        RunStatus {
            state: self.state(),
            step: self.step.load(Ordering::Relaxed),
            sim_time: f64::from_bits(self.sim_bits.load(Ordering::Relaxed)),
            namespace: self.namespace.clone(),
            pid: std::process::id(),
            components: components.map(|c| c.status()).unwrap_or_default(),
            state_reset: self.state_reset.load(Ordering::Acquire),
            speed: f64::from_bits(self.speed_bits.load(Ordering::Relaxed)),
            end_time: Some(f64::from_bits(self.end_bits.load(Ordering::Relaxed))).filter(|t| !t.is_nan()),
            seekable: self.seekable.load(Ordering::Relaxed),
        }
    }
}

/// Where the answer to a command goes.
pub(crate) type Reply = mpsc::Sender<Result<(), Refusal>>;

/// A command for the run's loop, with where its answer goes.
pub(crate) struct Command {
    pub request: Request,
    pub reply: Reply,
}

/// The run's end of the control plane: commands to carry out, and the socket's server.
pub(crate) struct ControlPort {
    pub commands: mpsc::Receiver<Command>,
    pub shared: Arc<Shared>,
    server: Option<JoinHandle<()>>,
    closing: Arc<AtomicBool>,
    /// The server thread's listening socket (another descriptor of it): shut down, it wakes
    /// the thread from `accept`, whatever has become of the socket's path.
    listener: UnixListener,
    path: PathBuf,
}

impl std::fmt::Debug for ControlPort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ControlPort").field("path", &self.path).finish()
    }
}

impl ControlPort {
    /// Binds the socket of namespace `ns` and starts serving it. `stop` is the run's stop
    /// flag, which `stop` raises at once (also while the run still waits to start).
    pub(crate) fn serve(
        ns: &str,
        stop: Arc<AtomicBool>,
        components: Option<Arc<dyn Components>>,
    ) -> Result<ControlPort, ControlError> {
        let path = socket_path(ns);
        let listener = bind(ns, &path)?;
        let io = |source| ControlError::Io { what: "serving", path: path.display().to_string(), source };
        let own = listener.try_clone().map_err(io)?;
        let shared = Arc::new(Shared {
            state: AtomicU8::new(RunState::Ready as u8),
            step: AtomicU64::new(0),
            sim_bits: AtomicU64::new(0),
            namespace: ns.to_string(),
            state_reset: AtomicBool::new(false),
            speed_bits: AtomicU64::new(1f64.to_bits()),
            end_bits: AtomicU64::new(f64::NAN.to_bits()),
            seekable: AtomicBool::new(false),
        });
        let (tx, commands) = mpsc::channel();
        let closing = Arc::new(AtomicBool::new(false));
        let server = Server { shared: shared.clone(), commands: tx, stop, components, closing: closing.clone() };
        let thread =
            std::thread::Builder::new().name("tutti-ctl".into()).spawn(move || server.accept(listener)).map_err(io)?;
        Ok(ControlPort { commands, shared, server: Some(thread), closing, listener: own, path })
    }
}

impl Drop for ControlPort {
    fn drop(&mut self) {
        self.closing.store(true, Ordering::Release);
        // Wakes the accepting thread, which then sees `closing`: a listening socket shut down
        // for reading fails `accept` (EINVAL), now and from then on. Not a connection to the
        // socket's path, which anyone may have removed (a clean-up of /dev/shm), leaving the
        // thread in `accept` and the run unable to end.
        let _ = rustix::net::shutdown(&self.listener, rustix::net::Shutdown::Read);
        if let Some(t) = self.server.take() {
            let _ = t.join();
        }
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Binds `path`, the owner's alone; a socket left by a run that died is replaced, one that
/// answers is another run's.
fn bind(ns: &str, path: &std::path::Path) -> Result<UnixListener, ControlError> {
    let shown = || path.display().to_string();
    if path.exists() {
        if UnixStream::connect(path).is_ok() {
            return Err(ControlError::Taken { namespace: ns.to_string(), path: shown() });
        }
        let _ = std::fs::remove_file(path);
    }
    let listener =
        UnixListener::bind(path).map_err(|source| ControlError::Io { what: "binding", path: shown(), source })?;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600)).map_err(|source| ControlError::Io {
        what: "restricting",
        path: shown(),
        source,
    })?;
    Ok(listener)
}

struct Server {
    shared: Arc<Shared>,
    commands: mpsc::Sender<Command>,
    stop: Arc<AtomicBool>,
    components: Option<Arc<dyn Components>>,
    closing: Arc<AtomicBool>,
}

impl Server {
    fn accept(self, listener: UnixListener) {
        let me = rustix::process::getuid();
        let server = Arc::new(self);
        for stream in listener.incoming() {
            if server.closing.load(Ordering::Acquire) {
                return;
            }
            let Ok(stream) = stream else { continue };
            // Another user's connection is closed unanswered.
            if rustix::net::sockopt::socket_peercred(&stream).map_or(true, |c| c.uid != me) {
                continue;
            }
            let s = server.clone();
            let _ = std::thread::Builder::new().name("tutti-ctl-conn".into()).spawn(move || s.serve(stream));
        }
    }

    /// Answers the requests of one connection until it closes.
    fn serve(&self, stream: UnixStream) {
        let Ok(mut out) = stream.try_clone() else { return };
        for line in BufReader::new(stream).lines() {
            let Ok(line) = line else { return };
            if line.trim().is_empty() {
                continue;
            }
            let reply = match serde_json::from_str::<Request>(&line) {
                Ok(request) => self.answer(request),
                Err(e) => Answer { ok: false, error: Some(format!("not a request: {e}")), status: None },
            };
            let Ok(mut text) = serde_json::to_string(&reply) else { return };
            text.push('\n');
            if out.write_all(text.as_bytes()).is_err() {
                return;
            }
        }
    }

    fn answer(&self, request: Request) -> Answer {
        let done = match &request {
            Request::State => Ok(()),
            Request::Component { action, name } => match &self.components {
                Some(c) => c.act(*action, name),
                None => Err(no_components()),
            },
            Request::Signal { name, signal } => match &self.components {
                Some(c) => parse_signal(signal).and_then(|sig| c.signal(name, sig)),
                None => Err(no_components()),
            },
            Request::Stop => {
                self.stop.store(true, Ordering::SeqCst);
                Ok(())
            }
            _ => self.forward(request),
        };
        let status = Some(self.shared.status(self.components.as_deref()));
        match done {
            Ok(()) => Answer { ok: true, error: None, status },
            Err(Refusal(why)) => Answer { ok: false, error: Some(why), status },
        }
    }

    /// Hands `request` to the run's loop and waits for it to be carried out.
    fn forward(&self, request: Request) -> Result<(), Refusal> {
        if self.shared.state() == RunState::Stopped {
            return Err(Refusal("the run has stopped".into()));
        }
        let (reply, answer) = mpsc::channel();
        self.commands.send(Command { request, reply }).map_err(|_| Refusal("the run has stopped".into()))?;
        answer.recv().unwrap_or_else(|_| Err(Refusal("the run stopped before carrying it out".into())))
    }
}

fn no_components() -> Refusal {
    Refusal("this run has no components: it is a framework alone (`tutti host`)".into())
}

/// A connection to the run of a namespace: what `tutti ctl` and the studio use.
#[derive(Debug)]
pub struct ControlClient {
    stream: BufReader<UnixStream>,
    timeout: Duration,
}

impl ControlClient {
    /// Connects to the run of namespace `ns`; each answer is awaited at most `timeout`.
    pub fn connect(ns: &str, timeout: Duration) -> Result<ControlClient, ControlError> {
        let path = socket_path(ns);
        let stream = UnixStream::connect(&path).map_err(|source| match source.kind() {
            std::io::ErrorKind::NotFound | std::io::ErrorKind::ConnectionRefused => {
                ControlError::NoRun { namespace: ns.to_string(), path: path.display().to_string() }
            }
            _ => ControlError::Io { what: "connecting to", path: path.display().to_string(), source },
        })?;
        let io = |source| ControlError::Io { what: "setting up", path: path.display().to_string(), source };
        // The socket directory is everyone's: a socket of this name that another user made
        // is not this user's run, and is not told anything.
        let me = rustix::process::getuid();
        let owner = rustix::net::sockopt::socket_peercred(&stream).map_err(|e| io(e.into()))?.uid;
        if owner != me {
            return Err(ControlError::NotOurs {
                namespace: ns.to_string(),
                path: path.display().to_string(),
                uid: owner.as_raw(),
            });
        }
        stream.set_read_timeout(Some(timeout)).map_err(io)?;
        Ok(ControlClient { stream: BufReader::new(stream), timeout })
    }

    /// Sends `request` and returns the run's state after it.
    pub fn request(&mut self, request: &Request) -> Result<RunStatus, ControlError> {
        // A run that closes a connection unanswered (another user's) may do so before the
        // request is written, while it is, or after.
        let io = |what, source: std::io::Error| match source.kind() {
            std::io::ErrorKind::BrokenPipe | std::io::ErrorKind::ConnectionReset => {
                ControlError::Protocol("the run closed the connection".into())
            }
            _ => ControlError::Io { what, path: "the control socket".into(), source },
        };
        let mut text = serde_json::to_string(request).map_err(|e| ControlError::Protocol(e.to_string()))?;
        text.push('\n');
        self.stream.get_mut().write_all(text.as_bytes()).map_err(|e| io("writing to", e))?;
        let mut line = String::new();
        match self.stream.read_line(&mut line) {
            Ok(0) => return Err(ControlError::Protocol("the run closed the connection".into())),
            Ok(_) => {}
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                return Err(ControlError::NoAnswer(self.timeout))
            }
            Err(e) => return Err(io("reading from", e)),
        }
        let reply: Answer = serde_json::from_str(&line).map_err(|e| ControlError::Protocol(format!("{e}: {line}")))?;
        match (reply.ok, reply.status) {
            (true, Some(status)) => Ok(status),
            (false, _) => Err(ControlError::Refused(Refusal(reply.error.unwrap_or_default()))),
            (true, None) => Err(ControlError::Protocol(line)),
        }
    }

    pub fn state(&mut self) -> Result<RunStatus, ControlError> {
        self.request(&Request::State)
    }
    pub fn pause(&mut self) -> Result<RunStatus, ControlError> {
        self.request(&Request::Pause)
    }
    pub fn resume(&mut self) -> Result<RunStatus, ControlError> {
        self.request(&Request::Resume)
    }
    pub fn step(&mut self, n: u64) -> Result<RunStatus, ControlError> {
        self.request(&Request::Step { n })
    }
    pub fn save(&mut self, path: &std::path::Path, skip_stateless: bool) -> Result<RunStatus, ControlError> {
        self.request(&Request::Save { path: path.display().to_string(), skip_stateless })
    }
    pub fn restore(&mut self, path: &std::path::Path) -> Result<RunStatus, ControlError> {
        self.request(&Request::Restore { path: path.display().to_string() })
    }
    pub fn reset(&mut self) -> Result<RunStatus, ControlError> {
        self.request(&Request::Reset)
    }
    pub fn stop(&mut self) -> Result<RunStatus, ControlError> {
        self.request(&Request::Stop)
    }
    pub fn component(&mut self, action: ComponentAction, name: &str) -> Result<RunStatus, ControlError> {
        self.request(&Request::Component { action, name: name.to_string() })
    }
    /// Sends `signal` (`USR1`, `SIGTERM`, …) to component `name`'s process.
    pub fn signal(&mut self, name: &str, signal: &str) -> Result<RunStatus, ControlError> {
        self.request(&Request::Signal { name: name.to_string(), signal: signal.to_string() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signals_are_named_with_or_without_sig_and_unknown_ones_are_refused() {
        assert_eq!(parse_signal("USR1"), Ok(10));
        assert_eq!(parse_signal("sigusr2"), Ok(12));
        assert_eq!(parse_signal("SIGTERM"), Ok(15));
        let e = parse_signal("USR3").unwrap_err().0;
        assert!(e.contains("unknown signal 'USR3'") && e.contains("USR1, USR2"), "{e}");
        assert!(parse_signal("10").is_err(), "numbers are not names");
    }

    #[test]
    fn a_signal_request_travels_as_one_json_object() {
        let r = Request::Signal { name: "uav3".into(), signal: "USR1".into() };
        let text = serde_json::to_string(&r).unwrap();
        assert_eq!(text, r#"{"op":"signal","name":"uav3","signal":"USR1"}"#);
        assert_eq!(serde_json::from_str::<Request>(&text).unwrap(), r);
    }
}
