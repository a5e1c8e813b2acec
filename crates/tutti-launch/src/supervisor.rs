//! The components of a launch file as child processes ([`Supervisor`]).
//!
//! One thread of the supervisor's own owns every child: it starts them (in file order, each
//! once the one before it has connected), notices when one ends, restarts it as its policy
//! says, and tears them all down in reverse order. Every child is started from that thread
//! because a child that dies with its parent (`die_with_parent_on_spawn`) is told so when the
//! *thread* that started it ends; the thread lives as long as the supervisor. The handle
//! ([`Supervisor`], cloneable, `Send + Sync`) sends it requests: [`Supervisor::restart`],
//! [`Supervisor::stop_component`], [`Supervisor::start_component`], [`Supervisor::status`],
//! [`Supervisor::shutdown`], which is what a control plane (`tutti ctl`) calls.
//!
//! A component **has connected** when a connection whose process id is the component's
//! appears in its domain's segment; a component with no `domain` has connected as soon as
//! its process runs. (A component whose program starts the participant as a child of its
//! own, a shell script that does not `exec`, never connects by this rule.)
//!
//! Each component's output, stdout and stderr, goes line by line to `LOG_DIR/NAME.log`
//! (created empty when the supervisor starts, appended to by restarts) and to
//! [`Event::Line`].

use std::fmt;
use std::fs::File;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tutti_host::{ChildProcess, SIGTERM};

use crate::file::{Component, Program, Restart};
use crate::SupervisorError;

/// How a component's process ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    /// It exited with this status.
    Exited(i32),
    /// A signal ended it (SIGKILL is 9).
    Signal(i32),
}

impl End {
    fn of(status: ExitStatus) -> End {
        use std::os::unix::process::ExitStatusExt;
        match (status.code(), status.signal()) {
            (Some(c), _) => End::Exited(c),
            (None, Some(s)) => End::Signal(s),
            (None, None) => End::Exited(-1),
        }
    }

    /// Exit status 0.
    pub fn success(self) -> bool {
        self == End::Exited(0)
    }
}

impl fmt::Display for End {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            End::Exited(c) => write!(f, "exit status {c}"),
            End::Signal(s) => write!(f, "signal {s}"),
        }
    }
}

/// Where a component stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ComponentState {
    /// Not started yet: it waits for the component before it to connect.
    Waiting,
    /// Declared with `autostart: false`: not started until asked ([`Supervisor::start_component`]).
    NotStarted,
    /// Its process runs and has not connected yet.
    Starting,
    /// Connected to its domain (without a domain: running).
    Connected,
    /// Stopped by the supervisor (a teardown, [`Supervisor::stop_component`]).
    Stopped,
    /// Ended by itself, and its policy starts it no more.
    Ended(End),
}

impl ComponentState {
    /// How `tutti ctl state` names it.
    pub fn name(&self) -> String {
        match self {
            ComponentState::Waiting => "waiting".into(),
            ComponentState::NotStarted => "not started".into(),
            ComponentState::Starting => "starting".into(),
            ComponentState::Connected => "connected".into(),
            ComponentState::Stopped => "stopped".into(),
            ComponentState::Ended(end) => format!("ended ({end})"),
        }
    }
}

/// A component as [`Supervisor::status`] shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ComponentStatus {
    pub name: String,
    pub state: ComponentState,
    /// Its process, while it has one.
    pub pid: Option<u32>,
    /// Restarts by its policy so far.
    pub restarts: u32,
    /// How its last process ended.
    pub last_end: Option<End>,
    /// Its log file.
    pub log: PathBuf,
}

impl ComponentStatus {
    /// Whether it ended well: stopped by the supervisor, ended with status 0, or never
    /// started (a run stopped before its turn).
    pub fn ended_well(&self) -> bool {
        match self.state {
            ComponentState::Stopped | ComponentState::Waiting | ComponentState::NotStarted => true,
            ComponentState::Ended(e) => e.success(),
            ComponentState::Starting | ComponentState::Connected => false,
        }
    }
}

/// What the supervisor reports as it goes; `Display` is the line a user reads (for
/// [`Event::Line`], the line itself).
#[derive(Debug, Clone)]
pub enum Event {
    /// A line of a component's output.
    Line { component: String, line: String, stderr: bool },
    /// A component's process started.
    Started { component: String, pid: u32 },
    /// A component connected.
    Connected { component: String, pid: u32 },
    /// Every component has connected (the framework then releases them, with `hold`).
    AllConnected,
    /// A component's process ended by itself.
    Ended { component: String, pid: u32, end: End },
    /// Its policy starts it again.
    Restarting { component: String, restart: u32, max: u32 },
    /// Its policy would start it again, but it has been restarted `max_restarts` times.
    GaveUp { component: String, restarts: u32 },
    /// The supervisor stops it (SIGTERM, then SIGKILL after the grace).
    Stopping { component: String, pid: u32 },
    /// The components could not all be started: the run is torn down.
    Failed(SupervisorError),
    /// Something else worth a line (the session's, the gateway hook's).
    Notice(String),
    /// A report of the framework (progress, step timeouts).
    Host(tutti_host::Report),
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Event::Line { line, .. } => f.write_str(line),
            Event::Started { component, pid } => write!(f, "{component}: started (pid {pid})"),
            Event::Connected { component, pid } => write!(f, "{component}: connected (pid {pid})"),
            Event::AllConnected => f.write_str("every component has connected"),
            Event::Ended { component, pid, end } => write!(f, "{component}: pid {pid} ended ({end})"),
            Event::Restarting { component, restart, max } => {
                write!(f, "{component}: restarting ({restart} of at most {max})")
            }
            Event::GaveUp { component, restarts } => {
                write!(f, "{component}: not restarted again (restarted {restarts} times: max_restarts)")
            }
            Event::Stopping { component, pid } => write!(f, "{component}: stopping pid {pid}"),
            Event::Failed(e) => write!(f, "{e}"),
            Event::Notice(s) => f.write_str(s),
            Event::Host(r) => write!(f, "framework: {r}"),
        }
    }
}

/// Where events go (called from the supervisor's threads).
pub type OnEvent = Arc<dyn Fn(Event) + Send + Sync>;

/// How the supervisor runs the components.
#[derive(Debug, Clone)]
pub struct SupervisorOptions {
    /// The namespace of the segments (`TUTTI_NAMESPACE` of every component).
    pub namespace: String,
    /// Where `NAME.log` files go (created if missing).
    pub log_dir: PathBuf,
    /// The DDF, for FMU components (`tutti fmu run FMU --ddf DDF`).
    pub ddf: PathBuf,
    /// The `tutti` executable, for FMU components.
    pub tutti_exe: PathBuf,
    /// How long a component has to exit after SIGTERM before SIGKILL.
    pub grace: Duration,
    /// How often the children and the connections are looked at.
    pub poll: Duration,
    /// Raised from outside (Ctrl-C): tear everything down.
    pub interrupt: Arc<AtomicBool>,
    /// Raised by the supervisor when the components are torn down, when the start failed,
    /// or when every component has ended by itself: the framework's signal to stop.
    pub finished: Arc<AtomicBool>,
}

impl SupervisorOptions {
    /// Options with the defaults: a grace of 3 s, a look every 20 ms, fresh flags.
    pub fn new(namespace: String, log_dir: PathBuf, ddf: PathBuf, tutti_exe: PathBuf) -> Self {
        SupervisorOptions {
            namespace,
            log_dir,
            ddf,
            tutti_exe,
            grace: Duration::from_secs(3),
            poll: Duration::from_millis(20),
            interrupt: Arc::new(AtomicBool::new(false)),
            finished: Arc::new(AtomicBool::new(false)),
        }
    }
}

/// What the supervisor leaves when it is shut down.
#[derive(Debug, Clone)]
pub struct Finished {
    pub components: Vec<ComponentStatus>,
    /// Why the components could not all be started, if they could not.
    pub start_error: Option<SupervisorError>,
}

type Reply<T> = Sender<Result<T, SupervisorError>>;

enum Request {
    Start(String, Reply<u32>),
    Stop(String, Reply<()>),
    Restart(String, Reply<u32>),
    Signal(String, i32, Reply<()>),
    Status(Sender<Vec<ComponentStatus>>),
    WhenStarted(Reply<()>),
    Shutdown(Sender<Finished>),
}

/// The handle of a running supervisor; clones share it.
#[derive(Clone)]
pub struct Supervisor {
    tx: Sender<Request>,
    thread: Arc<Mutex<Option<JoinHandle<()>>>>,
}

impl fmt::Debug for Supervisor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Supervisor").finish_non_exhaustive()
    }
}

impl Supervisor {
    /// Starts the supervisor's thread, which starts `components` in order, each once the one
    /// before has connected. Log files are created (empty) first.
    pub fn start(
        components: Vec<Component>,
        opts: SupervisorOptions,
        on_event: OnEvent,
    ) -> Result<Supervisor, std::io::Error> {
        std::fs::create_dir_all(&opts.log_dir)?;
        let mut slots = Vec::new();
        for c in components {
            let log = opts.log_dir.join(format!("{}.log", c.name));
            File::create(&log)?;
            let state = if c.autostart { ComponentState::Waiting } else { ComponentState::NotStarted };
            slots.push(Slot {
                c,
                log,
                state,
                proc: None,
                restarts: 0,
                last_end: None,
                connected_once: false,
                waiters: Vec::new(),
            });
        }
        let (tx, rx) = mpsc::channel();
        let mut actor = Actor { opts, on_event, slots, next: 0, startup: Startup::Going, start_waiters: Vec::new() };
        let thread = std::thread::Builder::new().name("tutti-supervisor".into()).spawn(move || actor.run(rx))?;
        Ok(Supervisor { tx, thread: Arc::new(Mutex::new(Some(thread))) })
    }

    fn ask<T>(&self, make: impl FnOnce(Sender<T>) -> Request) -> Option<T> {
        let (tx, rx) = mpsc::channel();
        self.tx.send(make(tx)).ok()?;
        rx.recv().ok()
    }

    fn ask_result<T>(&self, make: impl FnOnce(Reply<T>) -> Request) -> Result<T, SupervisorError> {
        self.ask(make).unwrap_or(Err(SupervisorError::Stopping))
    }

    /// Waits until every component has connected (Ok), or the start failed or was
    /// interrupted (the error).
    pub fn wait_started(&self) -> Result<(), SupervisorError> {
        self.ask_result(Request::WhenStarted)
    }

    /// Stops component `name` (SIGTERM, SIGKILL after the grace) and starts it again; returns
    /// the new process id once it has connected. Not counted against `max_restarts`.
    pub fn restart(&self, name: &str) -> Result<u32, SupervisorError> {
        self.ask_result(|r| Request::Restart(name.to_string(), r))
    }

    /// Stops component `name`; it stays stopped (and counts as ended well) until started.
    pub fn stop_component(&self, name: &str) -> Result<(), SupervisorError> {
        self.ask_result(|r| Request::Stop(name.to_string(), r))
    }

    /// Starts component `name`, which must not be running; returns its process id once it
    /// has connected.
    pub fn start_component(&self, name: &str) -> Result<u32, SupervisorError> {
        self.ask_result(|r| Request::Start(name.to_string(), r))
    }

    /// Sends signal number `signal` to component `name`'s process (which must run); the
    /// supervisor does nothing else: what the component makes of it is its own affair.
    pub fn signal(&self, name: &str, signal: i32) -> Result<(), SupervisorError> {
        self.ask_result(|r| Request::Signal(name.to_string(), signal, r))
    }

    /// Every component, in file order.
    pub fn status(&self) -> Vec<ComponentStatus> {
        self.ask(Request::Status).unwrap_or_default()
    }

    /// Tears every component down in reverse order (SIGTERM, SIGKILL after the grace),
    /// ends the supervisor's thread and returns how each ended. Later calls return what the
    /// first returned only if it is still known: call it once.
    pub fn shutdown(&self) -> Finished {
        let done = self.ask(Request::Shutdown);
        if let Some(t) = self.thread.lock().unwrap_or_else(|e| e.into_inner()).take() {
            let _ = t.join();
        }
        done.unwrap_or(Finished { components: Vec::new(), start_error: Some(SupervisorError::Stopping) })
    }
}

// ---------------------------------------------------------------------------------------
// The supervisor's thread.

enum Startup {
    Going,
    Done,
    Failed(SupervisorError),
}

struct Running {
    child: ChildProcess,
    since: Instant,
    readers: Vec<JoinHandle<()>>,
}

struct Slot {
    c: Component,
    log: PathBuf,
    state: ComponentState,
    proc: Option<Running>,
    restarts: u32,
    last_end: Option<End>,
    /// Whether it has connected since the supervisor started (the start goes on to the
    /// next component then, even if this one has ended meanwhile).
    connected_once: bool,
    /// Replies owed once it has connected.
    waiters: Vec<Reply<u32>>,
}

impl Slot {
    fn status(&self) -> ComponentStatus {
        ComponentStatus {
            name: self.c.name.clone(),
            state: self.state,
            pid: self.proc.as_ref().map(|p| p.child.pid()),
            restarts: self.restarts,
            last_end: self.last_end,
            log: self.log.clone(),
        }
    }
}

struct Actor {
    opts: SupervisorOptions,
    on_event: OnEvent,
    slots: Vec<Slot>,
    /// The next component to start.
    next: usize,
    startup: Startup,
    start_waiters: Vec<Reply<()>>,
}

impl Actor {
    fn run(&mut self, rx: mpsc::Receiver<Request>) {
        let mut torn_down = false;
        loop {
            match rx.recv_timeout(self.opts.poll) {
                Ok(Request::Shutdown(reply)) => {
                    self.teardown();
                    let _ = reply.send(self.finished());
                    return;
                }
                Ok(req) => self.handle(req, torn_down),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => {
                    self.teardown();
                    return;
                }
            }
            if torn_down {
                continue;
            }
            if self.opts.interrupt.load(Ordering::SeqCst) {
                self.teardown();
                torn_down = true;
                continue;
            }
            self.tick();
            if matches!(self.startup, Startup::Failed(_)) {
                torn_down = true;
            }
        }
    }

    fn finished(&self) -> Finished {
        let start_error = match &self.startup {
            Startup::Failed(e) => Some(e.clone()),
            _ => None,
        };
        Finished { components: self.slots.iter().map(Slot::status).collect(), start_error }
    }

    fn event(&self, e: Event) {
        (self.on_event)(e);
    }

    fn find(&self, name: &str) -> Result<usize, SupervisorError> {
        self.slots.iter().position(|s| s.c.name == name).ok_or_else(|| SupervisorError::NoComponent {
            name: name.to_string(),
            known: self.slots.iter().map(|s| s.c.name.as_str()).collect::<Vec<_>>().join(", "),
        })
    }

    fn handle(&mut self, req: Request, torn_down: bool) {
        match req {
            Request::Status(reply) => {
                let _ = reply.send(self.slots.iter().map(Slot::status).collect());
            }
            Request::WhenStarted(reply) => match &self.startup {
                Startup::Going if !torn_down => self.start_waiters.push(reply),
                Startup::Done => {
                    let _ = reply.send(Ok(()));
                }
                Startup::Failed(e) => {
                    let _ = reply.send(Err(e.clone()));
                }
                Startup::Going => {
                    let _ = reply.send(Err(SupervisorError::Stopping));
                }
            },
            Request::Stop(name, reply) => {
                let r = self.find(&name).map(|i| {
                    self.stop(i);
                    // Stopped by request: it ended well, whatever its last process did.
                    self.slots[i].state = ComponentState::Stopped;
                });
                let _ = reply.send(r);
            }
            Request::Signal(name, signal, reply) => {
                let r = self.find(&name).and_then(|i| {
                    let s = &self.slots[i];
                    let Some(p) = s.proc.as_ref() else {
                        return Err(SupervisorError::NotRunning { name, state: s.state.name() });
                    };
                    let pid = p.child.pid();
                    tutti_core::shm::os::send_signal(pid, signal).map_err(|e| SupervisorError::Signal {
                        name,
                        pid,
                        signal,
                        reason: e.to_string(),
                    })
                });
                let _ = reply.send(r);
            }
            Request::Start(_, reply) | Request::Restart(_, reply) if torn_down => {
                let _ = reply.send(Err(SupervisorError::Stopping));
            }
            Request::Start(name, reply) => match self.find(&name) {
                Err(e) => {
                    let _ = reply.send(Err(e));
                }
                Ok(i) => match self.slots[i].proc.as_ref().map(|p| p.child.pid()) {
                    Some(pid) => {
                        let _ = reply.send(Err(SupervisorError::AlreadyRunning { name, pid }));
                    }
                    None => self.start_for(i, reply),
                },
            },
            Request::Restart(name, reply) => match self.find(&name) {
                Err(e) => {
                    let _ = reply.send(Err(e));
                }
                Ok(i) => {
                    self.stop(i);
                    self.start_for(i, reply);
                }
            },
            Request::Shutdown(_) => unreachable!("handled by the loop"),
        }
    }

    /// Starts slot `i` for a request, which is answered once it has connected.
    fn start_for(&mut self, i: usize, reply: Reply<u32>) {
        match self.spawn(i) {
            Ok(()) => {
                self.slots[i].waiters.push(reply);
                self.check_connected(i);
            }
            Err(e) => {
                let _ = reply.send(Err(e));
            }
        }
    }

    /// One look at every component: ended ones, connections, the next one to start.
    fn tick(&mut self) {
        for i in 0..self.slots.len() {
            let ended = self.slots[i].proc.as_mut().and_then(|p| p.child.poll());
            if let Some(status) = ended {
                self.on_end(i, status);
            } else if self.slots[i].state == ComponentState::Starting {
                self.check_connected(i);
            }
            if matches!(self.startup, Startup::Failed(_)) {
                return;
            }
        }
        if matches!(self.startup, Startup::Going) {
            self.advance_startup();
        }
        let running = self.slots.iter().any(|s| s.proc.is_some());
        let ended = self.slots.iter().any(|s| matches!(s.state, ComponentState::Ended(_)));
        if matches!(self.startup, Startup::Done) && !running && ended {
            // Nothing runs, and something ended by itself: the run is over.
            self.opts.finished.store(true, Ordering::SeqCst);
        }
    }

    fn advance_startup(&mut self) {
        let previous = self.next.checked_sub(1).map(|i| &self.slots[i]);
        let previous_connected = previous.map_or(true, |s| s.connected_once || !s.c.autostart);
        if !previous_connected {
            return;
        }
        // `autostart: false`: declared, left for a `start`.
        while self.next < self.slots.len() && !self.slots[self.next].c.autostart {
            self.next += 1;
        }
        if self.next == self.slots.len() {
            self.startup = Startup::Done;
            self.event(Event::AllConnected);
            for w in self.start_waiters.drain(..) {
                let _ = w.send(Ok(()));
            }
            return;
        }
        let i = self.next;
        self.next += 1;
        if let Err(e) = self.spawn(i) {
            self.fail_startup(e);
        } else {
            self.check_connected(i);
        }
    }

    fn fail_startup(&mut self, e: SupervisorError) {
        self.event(Event::Failed(e.clone()));
        for w in self.start_waiters.drain(..) {
            let _ = w.send(Err(e.clone()));
        }
        self.startup = Startup::Failed(e);
        self.teardown();
    }

    /// Whether slot `i`'s process has connected to its domain; if so it is marked so, and
    /// the requests waiting for it are answered. A start that takes too long is refused.
    fn check_connected(&mut self, i: usize) {
        let Some(p) = &self.slots[i].proc else { return };
        let pid = p.child.pid();
        let since = p.since;
        let s = &self.slots[i];
        let connected = match &s.c.domain {
            None => true,
            Some(d) => tutti_core::shm::Segment::open(&self.opts.namespace, d)
                .is_ok_and(|seg| seg.status().connections.iter().any(|c| c.pid == pid)),
        };
        if connected {
            let name = s.c.name.clone();
            self.slots[i].state = ComponentState::Connected;
            self.slots[i].connected_once = true;
            self.event(Event::Connected { component: name, pid });
            for w in self.slots[i].waiters.drain(..) {
                let _ = w.send(Ok(pid));
            }
            return;
        }
        if since.elapsed() < s.c.connect_timeout {
            return;
        }
        let e = SupervisorError::ConnectTimeout {
            name: s.c.name.clone(),
            domain: s.c.domain.clone().unwrap_or_default(),
            timeout: s.c.connect_timeout,
            log: s.log.clone(),
        };
        for w in self.slots[i].waiters.drain(..) {
            let _ = w.send(Err(e.clone()));
        }
        if matches!(self.startup, Startup::Going) && i + 1 == self.next {
            self.fail_startup(e);
        }
    }

    /// Slot `i`'s process ended by itself.
    fn on_end(&mut self, i: usize, status: ExitStatus) {
        let end = End::of(status);
        let s = &mut self.slots[i];
        let Some(p) = s.proc.take() else { return };
        let pid = p.child.pid();
        join_readers(p.readers);
        s.last_end = Some(end);
        let was = s.state;
        let name = s.c.name.clone();
        self.event(Event::Ended { component: name.clone(), pid, end });
        let s = &mut self.slots[i];
        if was == ComponentState::Starting {
            let e =
                SupervisorError::EndedBeforeConnecting { name: name.clone(), end: end.to_string(), log: s.log.clone() };
            for w in s.waiters.drain(..) {
                let _ = w.send(Err(e.clone()));
            }
            if matches!(self.startup, Startup::Going) && i + 1 == self.next {
                s.state = ComponentState::Ended(end);
                self.fail_startup(e);
                return;
            }
        }
        let wants = match s.c.restart {
            Restart::Never => false,
            Restart::OnFailure => !end.success(),
            Restart::Always => true,
        };
        s.state = ComponentState::Ended(end);
        if !wants {
            return;
        }
        if s.restarts >= s.c.max_restarts {
            let restarts = s.restarts;
            self.event(Event::GaveUp { component: name, restarts });
            return;
        }
        s.restarts += 1;
        let (restart, max) = (s.restarts, s.c.max_restarts);
        self.event(Event::Restarting { component: name, restart, max });
        if let Err(e) = self.spawn(i) {
            self.event(Event::Notice(e.to_string()));
        }
    }

    /// Stops slot `i` if it runs (SIGTERM, SIGKILL after the grace); it is then Stopped. A
    /// process that has ended by itself meanwhile, not yet looked at, keeps how it ended: a
    /// component that crashed just before the end of a run did not end well.
    fn stop(&mut self, i: usize) {
        let grace = self.opts.grace;
        let s = &mut self.slots[i];
        if let Some(mut p) = s.proc.take() {
            let pid = p.child.pid();
            let name = s.c.name.clone();
            if let Some(status) = p.child.poll() {
                join_readers(std::mem::take(&mut p.readers));
                let end = End::of(status);
                s.last_end = Some(end);
                s.state = ComponentState::Ended(end);
                for w in s.waiters.drain(..) {
                    let _ = w.send(Err(SupervisorError::Stopping));
                }
                (self.on_event)(Event::Ended { component: name, pid, end });
                return;
            }
            (self.on_event)(Event::Stopping { component: name, pid });
            let status = p.child.stop(Some(SIGTERM), grace);
            join_readers(std::mem::take(&mut p.readers));
            let s = &mut self.slots[i];
            s.last_end = status.map(End::of);
            s.state = ComponentState::Stopped;
            for w in s.waiters.drain(..) {
                let _ = w.send(Err(SupervisorError::Stopping));
            }
        }
    }

    /// Every component, last first; the framework may stop then.
    fn teardown(&mut self) {
        for i in (0..self.slots.len()).rev() {
            self.stop(i);
        }
        for w in self.start_waiters.drain(..) {
            let _ = w.send(Err(SupervisorError::Stopping));
        }
        if matches!(self.startup, Startup::Going) {
            self.startup = Startup::Done;
        }
        self.opts.finished.store(true, Ordering::SeqCst);
    }

    /// Starts slot `i`'s process (this thread is its parent for as long as it lives).
    fn spawn(&mut self, i: usize) -> Result<(), SupervisorError> {
        let s = &self.slots[i];
        let c = &s.c;
        let mut cmd = match &c.program {
            Program::Run { program, args } => {
                let mut cmd = Command::new(program);
                cmd.args(args);
                cmd
            }
            Program::Fmu { fmu, params } => {
                let mut cmd = Command::new(&self.opts.tutti_exe);
                cmd.args(["fmu", "run"]).arg(fmu).arg("--ddf").arg(&self.opts.ddf);
                for p in params {
                    cmd.arg("--param").arg(p);
                }
                cmd.arg("--domain").arg(c.domain.as_deref().unwrap_or_default()).args(["--name", &c.name]);
                cmd
            }
        };
        // A group of its own: a terminal's Ctrl-C reaches the run alone, which then stops the
        // components in order, instead of every component at once.
        std::os::unix::process::CommandExt::process_group(&mut cmd, 0);
        cmd.current_dir(&c.cwd)
            .envs(&c.env)
            .env("TUTTI_NAMESPACE", &self.opts.namespace)
            // Its connections' name: a checkpoint finds its state again by it.
            .env(tutti_core::shm::COMPONENT_ENV, &c.name)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let program = cmd.get_program().to_string_lossy().into_owned();
        let spawn_error =
            |reason: String| SupervisorError::Spawn { name: c.name.clone(), program: program.clone(), reason };
        let log = std::fs::OpenOptions::new().append(true).create(true).open(&s.log);
        let mut log = log.map_err(|e| spawn_error(format!("opening its log {}: {e}", s.log.display())))?;
        if s.restarts > 0 || s.last_end.is_some() {
            let _ = writeln!(log, "--- started again ---");
        }
        let log = Arc::new(Mutex::new(log));
        let child = ChildProcess::spawn(&c.name, cmd, None).map_err(|e| spawn_error(e.source.to_string()))?;
        let mut child = child.stop_on_drop(Some(SIGTERM), self.opts.grace);
        let pid = child.pid();
        let mut readers = Vec::new();
        let out = child.child.stdout.take().map(|r| (Box::new(r) as Box<dyn Read + Send>, false));
        let err = child.child.stderr.take().map(|r| (Box::new(r) as Box<dyn Read + Send>, true));
        for (stream, stderr) in [out, err].into_iter().flatten() {
            let (log, on_event, name) = (log.clone(), self.on_event.clone(), c.name.clone());
            let reader = std::thread::Builder::new()
                .name(format!("tutti-log-{}", c.name))
                .spawn(move || copy_lines(stream, &log, &on_event, &name, stderr));
            if let Ok(r) = reader {
                readers.push(r);
            }
        }
        let s = &mut self.slots[i];
        s.proc = Some(Running { child, since: Instant::now(), readers });
        s.state = ComponentState::Starting;
        let name = s.c.name.clone();
        self.event(Event::Started { component: name, pid });
        Ok(())
    }
}

/// Copies the lines of `stream` to the log and the events until it ends.
fn copy_lines(stream: Box<dyn Read + Send>, log: &Mutex<File>, on_event: &OnEvent, name: &str, stderr: bool) {
    let mut r = BufReader::new(stream);
    let mut buf = Vec::new();
    while r.read_until(b'\n', &mut buf).is_ok_and(|n| n > 0) {
        let line = String::from_utf8_lossy(&buf).trim_end_matches(['\n', '\r']).to_string();
        buf.clear();
        if let Ok(mut f) = log.lock() {
            let _ = writeln!(f, "{line}");
        }
        on_event(Event::Line { component: name.to_string(), line, stderr });
    }
}

/// Waits a little for the readers of an ended process to pass on its last lines (a child
/// of its own may keep the pipe open: it is then left to finish alone).
fn join_readers(readers: Vec<JoinHandle<()>>) {
    let end = Instant::now() + Duration::from_secs(1);
    for r in readers {
        while !r.is_finished() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(5));
        }
        if r.is_finished() {
            let _ = r.join();
        }
    }
}
