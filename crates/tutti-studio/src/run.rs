//! Run control: a `tutti host` and a `tutti gateway` for a DDF under the root, started as
//! child processes of the studio with their logs kept; stopped on request (SIGTERM, then
//! SIGKILL after a grace period) and when the studio stops. The monitor's events carry their
//! state ([`snapshot`]).

use std::collections::{HashMap, VecDeque};
use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::extract::State;
use axum::http::StatusCode;
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};
use tutti_core::shm::os;

use crate::error::ApiError;
use crate::AppState;

/// Lines of log kept per run.
const LOG_LINES: usize = 400;
/// How long a stopped run gets to exit before SIGKILL.
const GRACE: Duration = Duration::from_secs(3);
const SIGTERM: i32 = 15;

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

/// One child process and its log.
#[derive(Debug)]
pub struct Run {
    child: Child,
    path: String,
    namespace: String,
    started: Instant,
    log: Arc<Mutex<VecDeque<String>>>,
    exit: Option<String>,
}

impl Run {
    fn poll(&mut self) {
        if self.exit.is_none() {
            if let Ok(Some(status)) = self.child.try_wait() {
                self.exit = Some(status.to_string());
            }
        }
    }

    fn stop(&mut self) {
        self.poll();
        if self.exit.is_some() {
            return;
        }
        let _ = os::send_signal(self.child.id(), SIGTERM);
        let deadline = Instant::now() + GRACE;
        while Instant::now() < deadline {
            if let Ok(Some(status)) = self.child.try_wait() {
                self.exit = Some(status.to_string());
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        self.exit = self.child.wait().ok().map(|s| s.to_string());
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
    /// The `tutti` executable the runs start.
    pub exe: Option<PathBuf>,
}

impl Runs {
    pub fn new(exe: Option<PathBuf>) -> Self {
        Runs { runs: Mutex::new(HashMap::new()), exe }
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

fn keep_lines(r: impl Read + Send + 'static, log: Arc<Mutex<VecDeque<String>>>) {
    std::thread::spawn(move || {
        for line in BufReader::new(r).lines().map_while(Result::ok) {
            if let Ok(mut l) = log.lock() {
                if l.len() == LOG_LINES {
                    l.pop_front();
                }
                l.push_back(line);
            }
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
                "pid": run.child.id(),
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
    /// `tutti host --step` (e.g. `10ms`).
    #[serde(default)]
    pub step: Option<String>,
    /// `tutti host --duration`.
    #[serde(default)]
    pub duration: Option<String>,
    /// TUTTI_NAMESPACE of the run (default: the studio's).
    #[serde(default)]
    pub namespace: Option<String>,
}

fn arg_ok(what: &str, v: &str) -> Result<(), ApiError> {
    if v.is_empty() || v.len() > 32 || !v.chars().all(|c| c.is_ascii_alphanumeric() || c == '.') {
        return Err(ApiError::bad_request(format!("{what} '{v}': expected a duration such as 10ms or 60s")));
    }
    Ok(())
}

/// `POST /api/run/start {kind, path, step?, duration?, namespace?}`.
pub async fn start(State(st): State<Arc<AppState>>, Json(body): Json<StartBody>) -> Result<Json<Value>, ApiError> {
    if st.read_only {
        return Err(ApiError::new(
            StatusCode::FORBIDDEN,
            "read-only",
            "the studio runs with --read-only: no run control",
        ));
    }
    let exe = st.runs.exe.clone().ok_or_else(|| {
        ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "no-exe", "this studio does not know the tutti executable")
    })?;
    let real = st.root.existing(&body.path)?;
    let rel = st.root.relative(&real);
    if let Err(e) = tutti_core::ddf::load(&real) {
        return Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid",
            format!("{rel} is not a valid DDF; not started:\n{e}"),
        ));
    }
    let namespace = body.namespace.filter(|n| !n.is_empty()).unwrap_or_else(|| st.namespace.clone());
    tutti_core::shm::segment::check_namespace(&namespace).map_err(|e| ApiError::bad_request(e.to_string()))?;
    let mut cmd = Command::new(exe);
    cmd.arg(body.kind.name()).arg(&real);
    if body.kind == Kind::Host {
        if let Some(step) = body.step.as_deref().filter(|s| !s.is_empty()) {
            arg_ok("step", step)?;
            cmd.args(["--step", step]);
        }
        if let Some(d) = body.duration.as_deref().filter(|s| !s.is_empty()) {
            arg_ok("duration", d)?;
            cmd.args(["--duration", d]);
        }
    }
    cmd.env("TUTTI_NAMESPACE", &namespace).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    // SAFETY: the closure runs between fork and exec and only makes one system call
    // (prctl through `die_with_parent`), which is async-signal-safe and allocates nothing.
    unsafe {
        cmd.pre_exec(os::die_with_parent);
    }
    let mut runs = st.runs.runs.lock().map_err(|_| ApiError::bad_request("run state unavailable"))?;
    if let Some(r) = runs.get_mut(&body.kind) {
        r.poll();
        if r.exit.is_none() {
            return Err(ApiError::conflict(
                "running",
                format!("a {} is already running (pid {}, {}): stop it first", body.kind.name(), r.child.id(), r.path),
            ));
        }
    }
    let mut child = cmd.spawn().map_err(|e| {
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "spawn",
            format!("cannot start tutti {}: {e}", body.kind.name()),
        )
    })?;
    let log = Arc::new(Mutex::new(VecDeque::new()));
    if let Some(out) = child.stdout.take() {
        keep_lines(out, log.clone());
    }
    if let Some(err) = child.stderr.take() {
        keep_lines(err, log.clone());
    }
    let pid = child.id();
    runs.insert(
        body.kind,
        Run { child, path: rel.clone(), namespace: namespace.clone(), started: Instant::now(), log, exit: None },
    );
    Ok(Json(json!({ "kind": body.kind.name(), "pid": pid, "path": rel, "namespace": namespace })))
}

#[derive(Debug, Deserialize)]
pub struct StopBody {
    pub kind: Kind,
}

/// `POST /api/run/stop {kind}`.
pub async fn stop(State(st): State<Arc<AppState>>, Json(body): Json<StopBody>) -> Result<Json<Value>, ApiError> {
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
