//! Run control: a framework (`tutti host`'s run, in-process on a thread of its own) or a
//! `tutti gateway` (a child process) for a DDF under the root, with their logs kept; stopped
//! on request and when the studio stops. The monitor's events carry their state
//! ([`snapshot`]).
//!
//! The framework is `tutti-host`'s [`Host`], driven here as `tutti host` drives it, with the
//! same log lines; its `pid` is the studio's own. Pause, step, reset, resume, and the
//! checkpoints' save and restore, reach it through its control plane ([`control`]), as
//! `tutti ctl` reaches it. The gateway is started as a child that dies
//! with the studio (SIGTERM, then SIGKILL after a grace period, when stopped).

use std::collections::{HashMap, VecDeque};
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use axum::extract::State;
use axum::http::StatusCode;
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};
use tutti_host::control::{ControlClient, ControlError, Request};
use tutti_host::{ChildProcess, Host, HostOptions, SIGTERM};

use crate::error::ApiError;
use crate::files::Root;
use crate::request::ApiJson;
use crate::AppState;

/// Lines of log kept per run.
const LOG_LINES: usize = 400;
/// How long a stopped gateway gets to exit before SIGKILL.
const GRACE: Duration = Duration::from_secs(3);

type Log = Arc<Mutex<VecDeque<String>>>;

/// The two kinds of run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    Host,
    Gateway,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Host => "host",
            Kind::Gateway => "gateway",
        }
    }
}

/// What runs: a framework on a thread of the studio, or a gateway process.
#[derive(Debug)]
enum Runner {
    Host { stop: Arc<AtomicBool>, thread: Option<JoinHandle<String>> },
    Gateway(ChildProcess),
}

/// One run and its log.
#[derive(Debug)]
pub struct Run {
    runner: Runner,
    path: String,
    namespace: String,
    started: Instant,
    log: Log,
    exit: Option<String>,
}

impl Run {
    fn pid(&self) -> u32 {
        match &self.runner {
            Runner::Host { .. } => std::process::id(),
            Runner::Gateway(child) => child.pid(),
        }
    }

    fn poll(&mut self) {
        if self.exit.is_some() {
            return;
        }
        match &mut self.runner {
            Runner::Host { thread, .. } => {
                if thread.as_ref().is_some_and(|t| t.is_finished()) {
                    self.exit = thread.take().map(|t| t.join().unwrap_or_else(|_| "panicked".into()));
                }
            }
            Runner::Gateway(child) => self.exit = child.poll().map(|s| s.to_string()),
        }
    }

    fn stop(&mut self) {
        self.poll();
        if self.exit.is_some() {
            return;
        }
        match &mut self.runner {
            Runner::Host { stop, thread } => {
                stop.store(true, Ordering::SeqCst);
                self.exit = thread.take().map(|t| t.join().unwrap_or_else(|_| "panicked".into()));
            }
            Runner::Gateway(child) => self.exit = child.stop(Some(SIGTERM), GRACE).map(|s| s.to_string()),
        }
    }
}

impl Drop for Run {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The runs of one studio.
#[derive(Debug, Default)]
pub struct Runs {
    runs: Mutex<HashMap<Kind, Run>>,
    /// The `tutti` executable that runs a gateway.
    pub exe: Option<PathBuf>,
    /// Held by a checkpoint save from choosing its file to the run's answer: the studio's
    /// checkpoint saves take turns (two saves without a name never pick the same one).
    checkpoint_turn: tokio::sync::Mutex<()>,
}

impl Runs {
    pub fn new(exe: Option<PathBuf>) -> Self {
        Runs { runs: Mutex::new(HashMap::new()), exe, checkpoint_turn: tokio::sync::Mutex::new(()) }
    }

    /// Stops every run (the studio is stopping).
    pub fn stop_all(&self) {
        let taken: Vec<Run> = match self.runs.lock() {
            Ok(mut g) => g.drain().map(|(_, r)| r).collect(),
            Err(_) => Vec::new(),
        };
        drop(taken);
    }
}

fn keep_line(log: &Log, line: String) {
    if let Ok(mut l) = log.lock() {
        if l.len() == LOG_LINES {
            l.pop_front();
        }
        l.push_back(line);
    }
}

fn keep_lines(r: impl Read + Send + 'static, log: Log) {
    std::thread::spawn(move || {
        for line in BufReader::new(r).lines().map_while(Result::ok) {
            keep_line(&log, line);
        }
    });
}

/// The state of every run, with the end of its log, for the monitor's events.
pub fn snapshot(state: &AppState) -> Value {
    let Ok(mut runs) = state.runs.runs.lock() else { return Value::Null };
    let mut out = serde_json::Map::new();
    for (kind, run) in runs.iter_mut() {
        run.poll();
        let log: Vec<String> =
            run.log.lock().map(|l| l.iter().rev().take(60).rev().cloned().collect()).unwrap_or_default();
        out.insert(
            kind.name().into(),
            json!({
                "pid": run.pid(),
                "path": run.path,
                "namespace": run.namespace,
                "running": run.exit.is_none(),
                "exit": run.exit,
                "seconds": run.started.elapsed().as_secs_f64(),
                "log": log,
            }),
        );
    }
    Value::Object(out)
}

#[derive(Debug, Deserialize)]
pub struct StartBody {
    pub kind: Kind,
    pub path: String,
    /// The framework's step (e.g. `10ms`).
    #[serde(default)]
    pub step: Option<String>,
    /// How long the framework runs (default: until stopped).
    #[serde(default)]
    pub duration: Option<String>,
    /// TUTTI_NAMESPACE of the run (default: the studio's).
    #[serde(default)]
    pub namespace: Option<String>,
}

fn duration(what: &str, v: Option<&str>) -> Result<Option<Duration>, ApiError> {
    let Some(v) = v.filter(|s| !s.is_empty()) else { return Ok(None) };
    tutti_core::parse::parse_duration(v)
        .map(Some)
        .map_err(|_| ApiError::bad_request(format!("{what} '{v}': expected a duration such as 10ms or 60s")))
}

/// The framework of `model` in `namespace`, on a thread of its own; its log lines are those
/// of `tutti host`. The thread returns how the run ended.
fn start_host(model: tutti_core::ddf::Model, opts: HostOptions, log: Log) -> Result<Runner, ApiError> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let thread = std::thread::Builder::new().name("studio-host".into()).spawn(move || {
        let started = Instant::now();
        let (step, ddf) = (opts.step, opts.ddf_name.clone());
        let host = Host::new(&model, opts).and_then(|mut h| h.serve_control(flag.clone(), None).map(|()| h));
        let host = match host {
            Ok(h) => h,
            Err(e) => {
                keep_line(&log, format!("host: {e}"));
                return format!("failed: {e}");
            }
        };
        keep_line(
            &log,
            format!(
                "host: {} domain(s) of {ddf} created in {:.1} ms (namespace {}), step {step:?}",
                host.framework().domains.len(),
                started.elapsed().as_secs_f64() * 1e3,
                host.namespace()
            ),
        );
        match host.run(&flag, |report| keep_line(&log, format!("host: {report}"))) {
            Ok(summary) => {
                if summary.started {
                    keep_line(&log, format!("host: {summary}"));
                }
                "done".into()
            }
            Err(e) => {
                keep_line(&log, format!("host: {e}"));
                format!("failed: {e}")
            }
        }
    });
    // A run whose thread never started would show as running for ever and block the next.
    let thread = thread.map_err(|e| {
        ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "spawn", format!("cannot start the framework's thread: {e}"))
    })?;
    Ok(Runner::Host { stop, thread: Some(thread) })
}

/// `tutti gateway` on `real` in `namespace`, a child that dies with the studio.
fn start_gateway(exe: PathBuf, real: &std::path::Path, namespace: &str, log: &Log) -> Result<Runner, ApiError> {
    let mut cmd = Command::new(exe);
    cmd.arg("gateway").arg(real);
    cmd.env("TUTTI_NAMESPACE", namespace).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut child = ChildProcess::spawn("tutti gateway", cmd, None)
        .map_err(|e| {
            ApiError::new(
                StatusCode::INTERNAL_SERVER_ERROR,
                "spawn",
                format!("cannot start tutti gateway: {}", e.source),
            )
        })?
        .stop_on_drop(Some(SIGTERM), GRACE);
    if let Some(out) = child.child.stdout.take() {
        keep_lines(out, log.clone());
    }
    if let Some(err) = child.child.stderr.take() {
        keep_lines(err, log.clone());
    }
    Ok(Runner::Gateway(child))
}

/// `POST /api/run/start {kind, path, step?, duration?, namespace?}`.
pub async fn start(
    State(st): State<Arc<AppState>>,
    ApiJson(body): ApiJson<StartBody>,
) -> Result<Json<Value>, ApiError> {
    if st.read_only {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "read-only",
            "the studio runs with --read-only: no run control",
        ));
    }
    // Run control is on when the studio knows the tutti executable (the gateway's).
    let exe = st.runs.exe.clone().ok_or_else(|| {
        ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "no-exe", "this studio does not know the tutti executable")
    })?;
    let real = st.root.existing(&body.path)?;
    let rel = st.root.relative(&real);
    let model = tutti_core::ddf::load(&real).map_err(|e| {
        ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid",
            format!("{rel} is not a valid DDF; not started:\n{e}"),
        )
    })?;
    let namespace = body.namespace.filter(|n| !n.is_empty()).unwrap_or_else(|| st.namespace.clone());
    tutti_core::shm::segment::check_namespace(&namespace).map_err(|e| ApiError::bad_request(e.to_string()))?;
    let opts = HostOptions {
        step: duration("step", body.step.as_deref())?.unwrap_or(Duration::from_millis(10)),
        speed: 1.0,
        duration: duration("duration", body.duration.as_deref())?,
        namespace: Some(namespace.clone()),
        ddf_name: real.display().to_string(),
        ..HostOptions::default()
    };
    let mut runs = st.runs.runs.lock().map_err(|_| ApiError::bad_request("run state unavailable"))?;
    if let Some(r) = runs.get_mut(&body.kind) {
        r.poll();
        if r.exit.is_none() {
            return Err(ApiError::conflict(
                "running",
                format!("a {} is already running (pid {}, {}): stop it first", body.kind.name(), r.pid(), r.path),
            ));
        }
    }
    let log: Log = Arc::new(Mutex::new(VecDeque::new()));
    let runner = match body.kind {
        Kind::Host => start_host(model, opts, log.clone())?,
        Kind::Gateway => start_gateway(exe, &real, &namespace, &log)?,
    };
    let run = Run { runner, path: rel.clone(), namespace: namespace.clone(), started: Instant::now(), log, exit: None };
    let pid = run.pid();
    runs.insert(body.kind, run);
    Ok(Json(json!({ "kind": body.kind.name(), "pid": pid, "path": rel, "namespace": namespace })))
}

#[derive(Debug, Deserialize)]
pub struct StopBody {
    pub kind: Kind,
}

/// `POST /api/run/stop {kind}`.
pub async fn stop(State(st): State<Arc<AppState>>, ApiJson(body): ApiJson<StopBody>) -> Result<Json<Value>, ApiError> {
    let run = st.runs.runs.lock().ok().and_then(|mut g| g.remove(&body.kind));
    let Some(mut run) = run else {
        return Err(ApiError::not_found(format!("no {} was started", body.kind.name())));
    };
    let st2 = st.clone();
    let kind = body.kind;
    let exit = tokio::task::spawn_blocking(move || {
        run.stop();
        let exit = run.exit.clone();
        // Kept (stopped) so that its log stays on the page, unless a new one started.
        if let Ok(mut g) = st2.runs.runs.lock() {
            g.entry(kind).or_insert(run);
        }
        exit
    })
    .await
    .ok()
    .flatten();
    Ok(Json(json!({ "kind": body.kind.name(), "exit": exit })))
}

#[derive(Debug, Deserialize)]
pub struct ControlBody {
    /// `state`, `pause`, `resume`, `step` (with `n`), `reset`, `save` or `restore` (with
    /// `path`).
    pub op: String,
    pub n: Option<u64>,
    /// `save`: the checkpoint file to write, under the root (`checkpoint_to_write`);
    /// `restore`: the checkpoint file to put back, under the root.
    #[serde(default)]
    pub path: Option<String>,
    /// `save`: components that keep no state are left out (and named in the file) instead of
    /// failing the save (`tutti ctl save --skip-stateless`).
    #[serde(default)]
    pub skip_stateless: bool,
}

/// What `/api/run/control` asks of the framework.
enum Op {
    /// A request as it is.
    Plain(Request),
    /// A checkpoint written to a file under the root.
    Save,
    /// A checkpoint put back from a file under the root.
    Restore,
}

/// How a checkpoint file's name ends: `.tutti-checkpoint`.
fn checkpoint_suffix() -> String {
    format!(".{}", tutti_host::checkpoint::EXTENSION)
}

/// Where a checkpoint save writes, resolved as every file the studio writes ([`Root::for_write`]:
/// under the root, or refused). `asked` gets `.tutti-checkpoint` appended when its name does not
/// end with it, so that a save never writes over a DDF or any other file; without a name, the
/// checkpoint is `STEM-N.tutti-checkpoint` in the root (`STEM`: the run's DDF's, `N`: the first
/// not taken).
fn checkpoint_to_write(root: &Root, asked: Option<&str>, ddf: &str) -> Result<PathBuf, ApiError> {
    let suffix = checkpoint_suffix();
    let name = match asked.map(str::trim).filter(|a| !a.is_empty()) {
        Some(a) if a.ends_with('/') => {
            return Err(ApiError::bad_request(format!("'{a}' names a folder: give the checkpoint file's name")))
        }
        Some(a) if a.ends_with(&suffix) => a.to_string(),
        Some(a) => format!("{a}{suffix}"),
        None => {
            let stem = Path::new(ddf).file_stem().map_or_else(|| "run".into(), |s| s.to_string_lossy().into_owned());
            (1u64..)
                .map(|n| format!("{stem}-{n}{suffix}"))
                .find(|n| root.dir().join(n).symlink_metadata().is_err())
                .unwrap_or_default()
        }
    };
    root.for_write(&name)
}

/// `GET /api/run/checkpoints`: the checkpoint files under the root (`*.tutti-checkpoint`,
/// relative, sorted), which the page offers to Restore.
pub async fn checkpoints(State(st): State<Arc<AppState>>) -> Json<Value> {
    Json(json!({ "checkpoints": st.root.list_ending(&checkpoint_suffix(), 2000) }))
}

/// `POST /api/run/control {op, n?, path?, skip_stateless?}`: pauses, steps, resets or resumes
/// the framework the studio started, or saves a checkpoint of it to a file under the root or
/// restores one from there, through the run's control plane (as `tutti ctl` does); answers the
/// run's state after it, with `checkpoint` (the file, relative to the root) for a save or a
/// restore. A command the run refuses (a component that keeps no state, a file that is not a
/// checkpoint or one of another DDF) is 409 `refused` with the run's reason.
pub async fn control(
    State(st): State<Arc<AppState>>,
    ApiJson(body): ApiJson<ControlBody>,
) -> Result<Json<Value>, ApiError> {
    if st.read_only {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "read-only",
            "the studio runs with --read-only: no run control",
        ));
    }
    let op = match (body.op.as_str(), body.n) {
        ("state", _) => Op::Plain(Request::State),
        ("pause", _) => Op::Plain(Request::Pause),
        ("resume", _) => Op::Plain(Request::Resume),
        ("reset", _) => Op::Plain(Request::Reset),
        ("step", Some(n)) if n > 0 => Op::Plain(Request::Step { n }),
        ("step", _) => return Err(ApiError::bad_request("step needs n, a number of steps above 0")),
        ("save", _) => Op::Save,
        ("restore", _) => Op::Restore,
        (op, _) => {
            return Err(ApiError::bad_request(format!(
                "unknown op '{op}': expected state, pause, resume, step, reset, save or restore"
            )))
        }
    };
    let _turn = match op {
        Op::Save => Some(st.runs.checkpoint_turn.lock().await),
        _ => None,
    };
    let (namespace, ddf) = {
        let mut runs = st.runs.runs.lock().map_err(|_| ApiError::bad_request("run state unavailable"))?;
        let run = runs.get_mut(&Kind::Host).ok_or_else(|| ApiError::not_found("no framework was started"))?;
        run.poll();
        if run.exit.is_some() {
            return Err(ApiError::conflict("stopped", "the framework has stopped"));
        }
        (run.namespace.clone(), run.path.clone())
    };
    // The run is in this process: it gets the file's resolved, absolute path.
    let (request, file) = match op {
        Op::Plain(request) => (request, None),
        Op::Save => {
            let real = checkpoint_to_write(&st.root, body.path.as_deref(), &ddf)?;
            (Request::Save { path: real.display().to_string(), skip_stateless: body.skip_stateless }, Some(real))
        }
        Op::Restore => {
            let real = st.root.existing(body.path.as_deref().unwrap_or_default().trim())?;
            (Request::Restore { path: real.display().to_string() }, Some(real))
        }
    };
    let answer = tokio::task::spawn_blocking(move || {
        ControlClient::connect(&namespace, Duration::from_secs(30)).and_then(|mut c| c.request(&request))
    })
    .await
    .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "control", e.to_string()))?;
    match answer {
        Ok(status) => {
            let mut answer = serde_json::to_value(status).unwrap_or_default();
            if let (Some(file), Some(fields)) = (&file, answer.as_object_mut()) {
                fields.insert("checkpoint".into(), st.root.relative(file).into());
            }
            Ok(Json(answer))
        }
        Err(ControlError::Refused(why)) => Err(ApiError::conflict("refused", why.to_string())),
        Err(e) => Err(ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "control", e.to_string())),
    }
}
