//! `tutti studio`: a web app to author DDFs and watch a running co-simulation live.
//!
//! An axum server on its own tokio runtime, above the core (which knows nothing of either).
//! The page and its script are embedded in the binary (`assets/`, no CDN, no Node
//! toolchain). The JSON API:
//!
//! | request | what |
//! |---|---|
//! | `GET /api/info` | root, files given on the command line, read-only, namespace |
//! | `GET /api/files` | the DDFs under the root |
//! | `GET /api/open?path=P` | a file: text, version, diagnostics, document, `tutti show` view |
//! | `POST /api/check` | a document: its XML, diagnostics at their fields, `tutti show` view |
//! | `POST /api/parse` | XML typed by hand: diagnostics, document |
//! | `POST /api/save` | atomic write of the product dialect (refusals: see [`editor::save`]) |
//! | `GET /api/monitor` | Server-Sent Events at 10 Hz: domains, plotted items, runs ([`monitor`]) |
//! | `POST /api/run/start`, `/api/run/stop` | a framework (in-process) or a `tutti gateway` child ([`run`]) |
//! | `POST /api/run/control` | pause, step N, reset or resume the framework, or save or restore a checkpoint of it (a file under the root), through its control plane (`tutti ctl`) |
//! | `GET /api/run/checkpoints` | the checkpoint files under the root (`*.tutti-checkpoint`) |
//!
//! Safety: the server binds 127.0.0.1 unless told otherwise, and any other address needs
//! the token made at start ([`Config::token`]); files are read and written only under the
//! root, symlinks resolved; every failure is a JSON message ([`error::ApiError`]), bad requests
//! included (a body too large, JSON that does not parse: [`request`]).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::thread::JoinHandle;

use axum::extract::{DefaultBodyLimit, Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde_json::json;

pub mod editor;
pub mod error;
pub mod files;
pub mod monitor;
pub mod request;
pub mod run;

use error::ApiError;

/// How the studio runs.
#[derive(Debug, Clone)]
pub struct Config {
    /// Where to listen (port 0: any free port).
    pub listen: SocketAddr,
    /// Files are read and written only under this folder.
    pub root: PathBuf,
    /// DDFs to offer first (relative to the root, or absolute under it).
    pub files: Vec<String>,
    /// No saving, no run control.
    pub read_only: bool,
    /// Required on every API request (header `x-tutti-token` or `?token=`) when set.
    pub token: Option<String>,
    /// The namespace the monitor shows first.
    pub namespace: String,
    /// The `tutti` executable, which run control starts a gateway with (`None`: no run control).
    pub tutti_exe: Option<PathBuf>,
}

/// Shared by the handlers.
#[derive(Debug)]
pub struct AppState {
    pub root: files::Root,
    pub read_only: bool,
    pub token: Option<String>,
    pub files: Vec<String>,
    pub namespace: String,
    pub runs: run::Runs,
    /// Held by a save from its version check to its write: the studio's saves take turns.
    pub save_turn: tokio::sync::Mutex<()>,
}

/// Why the studio could not start.
#[derive(Debug, thiserror::Error)]
pub enum StudioError {
    #[error("--root {path}: {source}")]
    Root {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    File { path: String, message: String },
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        addr: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error("listening on {0}, beyond this machine, requires a token")]
    NeedsToken(SocketAddr),
    #[error("cannot start the server's runtime: {0}")]
    Runtime(#[source] std::io::Error),
}

/// A token for a non-loopback address: 128 random bits from the kernel, in hex.
pub fn make_token() -> std::io::Result<String> {
    use std::io::Read;
    let mut b = [0u8; 16];
    std::fs::File::open("/dev/urandom")?.read_exact(&mut b)?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}

const INDEX_HTML: &str = include_str!("../assets/index.html");
const APP_JS: &str = include_str!("../assets/app.js");
const STYLE_CSS: &str = include_str!("../assets/style.css");

fn asset(content_type: &'static str, body: &'static str) -> Response {
    ([(header::CONTENT_TYPE, content_type), (header::CACHE_CONTROL, "no-store")], body).into_response()
}

async fn info(State(st): State<Arc<AppState>>) -> Json<serde_json::Value> {
    Json(json!({
        "root": st.root.dir().display().to_string(),
        "files": st.files,
        "read_only": st.read_only,
        "namespace": st.namespace,
        "run_control": st.runs.exe.is_some() && !st.read_only,
        "version": env!("CARGO_PKG_VERSION"),
    }))
}

/// Whether a `Host` header names this machine's loopback (so that a page of another site,
/// whose name was rebound to 127.0.0.1, cannot use the API).
fn loopback_host(host: &str) -> bool {
    let name = match host.strip_prefix('[') {
        Some(v6) => v6.split(']').next().unwrap_or(""),
        None => host.rsplit_once(':').map_or(host, |(h, _)| h),
    };
    name.eq_ignore_ascii_case("localhost") || name.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

async fn require_token(State(st): State<Arc<AppState>>, req: Request, next: Next) -> Response {
    if st.token.is_none() {
        let host = req.headers().get(header::HOST).and_then(|v| v.to_str().ok()).unwrap_or("");
        if !loopback_host(host) {
            return ApiError::new(
                StatusCode::FORBIDDEN,
                "host",
                format!("request for host '{host}' refused: this studio answers only to 127.0.0.1 or localhost"),
            )
            .into_response();
        }
    }
    if let Some(token) = &st.token {
        let header_ok = req.headers().get("x-tutti-token").and_then(|v| v.to_str().ok()) == Some(token.as_str());
        let query_ok =
            req.uri().query().is_some_and(|q| q.split('&').any(|kv| kv.strip_prefix("token=") == Some(token.as_str())));
        if !header_ok && !query_ok {
            return ApiError::new(
                StatusCode::UNAUTHORIZED,
                "token",
                "this studio listens beyond 127.0.0.1: open the address with ?token=TOKEN as printed at its start",
            )
            .into_response();
        }
    }
    next.run(req).await
}

async fn not_found() -> ApiError {
    ApiError::not_found("no such API request")
}

/// The router of the whole app.
pub fn router(state: Arc<AppState>) -> Router {
    let api = Router::new()
        .route("/info", get(info))
        .route("/files", get(editor::list))
        .route("/open", get(editor::open))
        .route("/check", post(editor::check))
        .route("/parse", post(editor::parse))
        .route("/save", post(editor::save))
        .route("/monitor", get(monitor::stream))
        .route("/run/start", post(run::start))
        .route("/run/stop", post(run::stop))
        .route("/run/control", post(run::control))
        .route("/run/checkpoints", get(run::checkpoints))
        .method_not_allowed_fallback(request::method_not_allowed)
        .fallback(not_found)
        .layer(middleware::from_fn_with_state(state.clone(), require_token));
    Router::new()
        .route("/", get(|| async { asset("text/html; charset=utf-8", INDEX_HTML) }))
        .route("/app.js", get(|| async { asset("text/javascript; charset=utf-8", APP_JS) }))
        .route("/style.css", get(|| async { asset("text/css; charset=utf-8", STYLE_CSS) }))
        .nest("/api", api)
        .method_not_allowed_fallback(request::method_not_allowed)
        .fallback(not_found)
        // Outermost: every body is held to the limit (and read whole) before anything else
        // answers, so that no answer leaves a client writing into a closed connection.
        .layer(DefaultBodyLimit::max(request::MAX_BODY_BYTES))
        .layer(middleware::from_fn(request::limit_body))
        .with_state(state)
}

/// A running studio: its server runs on its own threads until this is dropped or
/// [`Running::stop`] is called.
#[derive(Debug)]
pub struct Running {
    addr: SocketAddr,
    state: Arc<AppState>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl StudioError {
    /// Whether the user asked for something impossible (exit status 2), rather than the
    /// machine failing (1).
    pub fn is_usage(&self) -> bool {
        matches!(self, StudioError::Root { .. } | StudioError::File { .. } | StudioError::NeedsToken(_))
    }
}

impl Running {
    /// Binds and starts serving.
    pub fn start(config: Config) -> Result<Running, StudioError> {
        if !config.listen.ip().is_loopback() && config.token.is_none() {
            return Err(StudioError::NeedsToken(config.listen));
        }
        let root = files::Root::new(&config.root)
            .map_err(|source| StudioError::Root { path: config.root.display().to_string(), source })?;
        let mut offered = Vec::new();
        for f in &config.files {
            let real = root.existing(f).map_err(|e| StudioError::File { path: f.clone(), message: e.message })?;
            offered.push(root.relative(&real));
        }
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("studio")
            .enable_all()
            .build()
            .map_err(StudioError::Runtime)?;
        let listener = rt
            .block_on(tokio::net::TcpListener::bind(config.listen))
            .map_err(|source| StudioError::Bind { addr: config.listen, source })?;
        let addr = listener.local_addr().map_err(|source| StudioError::Bind { addr: config.listen, source })?;
        let state = Arc::new(AppState {
            root,
            read_only: config.read_only,
            token: config.token,
            files: offered,
            namespace: config.namespace,
            runs: run::Runs::new(config.tutti_exe),
            save_turn: tokio::sync::Mutex::new(()),
        });
        let app = router(state.clone());
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("studio-server".into())
            .spawn(move || {
                // Not a graceful shutdown: a live stream (the monitor) never ends by itself.
                rt.block_on(async move {
                    tokio::select! {
                        _ = async { axum::serve(listener, app).await } => {}
                        _ = stopped => {}
                    }
                });
                rt.shutdown_timeout(std::time::Duration::from_millis(500));
            })
            .map_err(StudioError::Runtime)?;
        Ok(Running { addr, state, stop: Some(stop), thread: Some(thread) })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops the server and waits for it.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.state.runs.stop_all();
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.shutdown();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_loopback_hosts_pass() {
        for ok in ["127.0.0.1:8470", "localhost:8470", "LOCALHOST", "[::1]:8470", "127.0.0.2:1"] {
            assert!(loopback_host(ok), "{ok}");
        }
        for bad in ["", "evil.example:8470", "10.0.0.1:8470", "[::2]:1", "localhost.evil.example"] {
            assert!(!loopback_host(bad), "{bad}");
        }
    }
}
