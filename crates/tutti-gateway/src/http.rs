//! The stats endpoint (`--http ADDR`): the gateway's counters, in total and per topic, as
//! JSON (`GET /stats`) and in the Prometheus text format 0.0.4 (`GET /metrics`).
//!
//! The server runs on a thread of its own with its own current-thread runtime, never on the
//! manager's loop: a slow or stuck scraper can delay nothing but its own answer. Each request
//! calls the `report` closure it was given, which reads the counters (atomics) as they are.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::net::SocketAddr;
use std::sync::Arc;
use std::thread::JoinHandle;

use axum::http::header;
use axum::response::IntoResponse;
use axum::routing::get;
use serde::{Deserialize, Serialize};

use tutti_config::sections::Section;

use crate::config::PlannedSet;
use crate::stats::SetStats;
use crate::{GatewayError, Stats};

/// The HTTP server's key of the gateway's config file (`http`, as `--http`), parsed here as a
/// section of its own (`crate::config::file`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HttpKeys {
    /// The address the stats endpoint listens on.
    pub http: Option<SocketAddr>,
}

impl Section for HttpKeys {
    const KEYS: &'static [&'static str] = &["http"];

    fn over(self, lower: Self) -> Self {
        HttpKeys { http: self.http.or(lower.http) }
    }
}

/// What `GET /stats` returns (and `GET /metrics` renders).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Report {
    pub gateway: GatewayReport,
    /// One entry per bridged topic (per set, in DDF order).
    pub topics: Vec<TopicReport>,
}

/// The gateway as a whole.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct GatewayReport {
    /// DDS engine: `cyclone` or `rustdds`.
    pub engine: String,
    /// The DDS domain id (ROS_DOMAIN_ID).
    pub dds_domain: u16,
    /// Canonical ROS namespace (`sim1`, `a/b`; empty for none).
    pub ros_namespace: String,
    /// The node's full name (`/sim1/tutti_gateway`).
    pub node: String,
    /// Seconds since the gateway started.
    pub uptime_s: f64,
    /// The status line's counters ([`Stats::snapshot`]) by name.
    pub totals: BTreeMap<String, u64>,
}

/// Which way a topic's samples go.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// Shared memory to DDS.
    #[default]
    Out,
    /// DDS to shared memory.
    In,
    /// Both ways.
    Both,
}

impl Direction {
    pub fn name(self) -> &'static str {
        match self {
            Direction::Out => "out",
            Direction::In => "in",
            Direction::Both => "both",
        }
    }
}

/// One topic's counters.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TopicReport {
    /// DDS topic (`rt/sim1/multiuav_uav1/publish`).
    pub topic: String,
    /// ROS 2 name (`/sim1/multiuav_uav1/publish`).
    pub ros2_topic: String,
    /// The set's key, `DOMAIN/publish` or `DOMAIN/subscribe` (as in the config file).
    pub set: String,
    pub domain: String,
    pub direction: Direction,
    /// DDS samples committed to shared memory (or published by a mirror): DDS to tutti.
    pub samples_in: u64,
    /// Samples written to DDS: tutti to DDS.
    pub samples_out: u64,
    /// Samples not delivered: DDS samples refused by the role rules, late or failing,
    /// synchronous steps the pump could not send, samples held back by `max_rate`.
    pub dropped: u64,
    /// DDS samples that could not be decoded.
    pub bad_input: u64,
    /// Remote DDS readers matched with the gateway's writer (now).
    pub matched_readers: u64,
    /// Remote DDS writers matched with the gateway's reader (now).
    pub matched_writers: u64,
    /// A synchronous SUBSCRIBE set with a lookahead (docs/run.md, "Sites and lookahead"): its
    /// steps of lookahead (0: lock-step), how many steps the framework is ahead of the newest
    /// answer received, the latest round trip from a step to its answer (µs), and the steps
    /// the framework waited for the link.
    pub lookahead: u64,
    pub ahead: u64,
    pub rtt_us: u64,
    pub link_waits: u64,
}

impl TopicReport {
    /// A report of `set` (of domain `domain`) with every counter 0.
    pub fn new(set: &PlannedSet, domain: &str, direction: Direction) -> TopicReport {
        TopicReport {
            topic: set.topic.clone(),
            ros2_topic: set.ros2_topic.clone(),
            set: set.key.clone(),
            domain: domain.to_string(),
            direction,
            ..TopicReport::default()
        }
    }

    /// The report with the counters of `s` (read now).
    pub fn with_counts(mut self, s: &SetStats) -> TopicReport {
        let g = |c: &std::sync::atomic::AtomicU64| c.load(std::sync::atomic::Ordering::Relaxed);
        self.samples_in = g(&s.samples_in);
        self.samples_out = g(&s.samples_out);
        self.dropped = g(&s.dropped);
        self.bad_input = g(&s.bad_input);
        self.matched_readers = g(&s.readers);
        self.matched_writers = g(&s.writers);
        self.lookahead = g(&s.lookahead);
        self.ahead = g(&s.ahead);
        self.rtt_us = g(&s.rtt_us);
        self.link_waits = g(&s.link_waits);
        self
    }
}

impl GatewayReport {
    /// [`Stats::snapshot`] as the `totals` map.
    pub fn totals(stats: &Stats) -> BTreeMap<String, u64> {
        stats.snapshot().into_iter().map(|(k, v)| (k.to_string(), v)).collect()
    }
}

/// The per-topic metrics: name, TYPE, HELP, value.
type TopicMetric = (&'static str, &'static str, &'static str, fn(&TopicReport) -> u64);

const TOPIC_METRICS: &[TopicMetric] = &[
    (
        "tutti_gateway_samples_in_total",
        "counter",
        "DDS samples of a topic committed to shared memory (or published by a mirror).",
        |t| t.samples_in,
    ),
    ("tutti_gateway_samples_out_total", "counter", "Samples of a topic written to DDS.", |t| t.samples_out),
    (
        "tutti_gateway_dropped_total",
        "counter",
        "Samples of a topic not delivered (role rules, late, failed, steps not sent, max_rate).",
        |t| t.dropped,
    ),
    ("tutti_gateway_bad_input_total", "counter", "DDS samples that could not be decoded.", |t| t.bad_input),
    (
        "tutti_gateway_matched_readers",
        "gauge",
        "Remote DDS readers matched with the gateway's writer of a topic.",
        |t| t.matched_readers,
    ),
    (
        "tutti_gateway_matched_writers",
        "gauge",
        "Remote DDS writers matched with the gateway's reader of a topic.",
        |t| t.matched_writers,
    ),
    (
        "tutti_gateway_lookahead_steps",
        "gauge",
        "Steps of lookahead of a synchronous SUBSCRIBE set (0: lock-step).",
        |t| t.lookahead,
    ),
    (
        "tutti_gateway_ahead_steps",
        "gauge",
        "Steps the framework is ahead of the newest answer received on a topic with a lookahead.",
        |t| t.ahead,
    ),
    (
        "tutti_gateway_link_rtt_microseconds",
        "gauge",
        "Latest round trip from a step's publication to its answer's arrival, on a topic with a lookahead.",
        |t| t.rtt_us,
    ),
    (
        "tutti_gateway_link_waits_total",
        "counter",
        "Steps the framework waited for the link's answer on a topic with a lookahead.",
        |t| t.link_waits,
    ),
];

/// HELP of the totals (the status line's counters); a counter the table does not know is
/// still rendered, as a counter with a generic HELP.
fn total_help(name: &str) -> (&'static str, &'static str) {
    match name {
        "to_dds" => ("counter", "Samples written to DDS."),
        "from_dds" => ("counter", "DDS samples committed to shared memory (or published by a mirror)."),
        "bad_samples" => ("counter", "DDS samples that could not be decoded."),
        "refused" => ("counter", "DDS samples refused by the role rules (a second writer on an exclusive set)."),
        "late" => ("counter", "DDS samples answering a step the framework had already left."),
        "own_samples" => ("counter", "DDS samples that came back from this gateway itself (dropped)."),
        "bad_input" => (
            "counter",
            "Samples and announcements the engine dropped as malformed (Zenoh: no valid attachment, a foreign token).",
        ),
        "errors" => ("counter", "Shared-memory or DDS write failures."),
        "skipped" => ("counter", "Synchronous steps the pump could not send to DDS before the framework moved on."),
        "lost" => ("counter", "Synchronous steps the DDS writer refused for the whole step timeout (never sent)."),
        "lapsed" => ("counter", "Synchronous DDS writers released after owing a step's answer, silent, for the lease."),
        "denied" => ("counter", "Topic directions left out because the DDS Security permissions do not allow them."),
        "remote_writers" => ("gauge", "Matched remote DDS writers."),
        "remote_readers" => ("gauge", "Matched remote DDS readers."),
        _ => ("counter", "A gateway counter (see the status line)."),
    }
}

/// A label value escaped as the text format wants (`\`, `"` and newlines).
fn label(v: &str) -> String {
    v.replace('\\', r"\\").replace('"', "\\\"").replace('\n', r"\n")
}

/// `report` in the Prometheus text exposition format 0.0.4: one family per metric (HELP,
/// TYPE, then a sample per topic labelled `topic`, `ros2_topic`, `set`, `direction`), the
/// totals as `tutti_gateway_NAME_total` (gauges without `_total`), and an info gauge.
pub fn prometheus(report: &Report) -> String {
    let mut s = String::new();
    let g = &report.gateway;
    let _ = writeln!(s, "# HELP tutti_gateway_info The gateway: DDS engine, DDS domain, ROS namespace and node.");
    let _ = writeln!(s, "# TYPE tutti_gateway_info gauge");
    let _ = writeln!(
        s,
        "tutti_gateway_info{{engine=\"{}\",dds_domain=\"{}\",ros_namespace=\"{}\",node=\"{}\"}} 1",
        label(&g.engine),
        g.dds_domain,
        label(&g.ros_namespace),
        label(&g.node)
    );
    let _ = writeln!(s, "# HELP tutti_gateway_uptime_seconds Seconds since the gateway started.");
    let _ = writeln!(s, "# TYPE tutti_gateway_uptime_seconds gauge");
    let _ = writeln!(s, "tutti_gateway_uptime_seconds {}", g.uptime_s);
    for (name, value) in &g.totals {
        let (kind, help) = total_help(name);
        let metric = sanitize(name);
        let metric =
            if kind == "counter" { format!("tutti_gateway_{metric}_total") } else { format!("tutti_gateway_{metric}") };
        let _ = writeln!(s, "# HELP {metric} {help}");
        let _ = writeln!(s, "# TYPE {metric} {kind}");
        let _ = writeln!(s, "{metric} {value}");
    }
    for (metric, kind, help, value) in TOPIC_METRICS {
        let _ = writeln!(s, "# HELP {metric} {help}");
        let _ = writeln!(s, "# TYPE {metric} {kind}");
        for t in &report.topics {
            let _ = writeln!(
                s,
                "{metric}{{topic=\"{}\",ros2_topic=\"{}\",set=\"{}\",direction=\"{}\"}} {}",
                label(&t.topic),
                label(&t.ros2_topic),
                label(&t.set),
                t.direction.name(),
                value(t)
            );
        }
    }
    s
}

/// A counter's name made a valid metric name part (`[a-zA-Z0-9_]`).
fn sanitize(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect()
}

/// Stops the server when told to, or when dropped.
#[derive(Debug)]
pub struct Shutdown(Option<tokio::sync::oneshot::Sender<()>>);

impl Shutdown {
    /// Asks the server to stop (join its thread to wait for it).
    pub fn stop(mut self) {
        if let Some(s) = self.0.take() {
            let _ = s.send(());
        }
    }
}

/// Where the report comes from: called once per request, on the server's thread.
pub type ReportFn = Arc<dyn Fn() -> Report + Send + Sync>;

/// Serves `GET /stats` (JSON), `GET /metrics` (Prometheus text 0.0.4) and `GET /` (an
/// index) on `addr` (port 0: any free port) from a thread of its own. Returns the thread, the
/// address bound and the handle that stops it (dropping the handle stops it too). A bind
/// failure is [`GatewayError::Listen`], naming the address.
pub fn serve(addr: SocketAddr, report: ReportFn) -> Result<(JoinHandle<()>, SocketAddr, Shutdown), GatewayError> {
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().map_err(GatewayError::Runtime)?;
    let bind_err = |error| GatewayError::Listen { addr, error };
    let listener = rt.block_on(tokio::net::TcpListener::bind(addr)).map_err(bind_err)?;
    let bound = listener.local_addr().map_err(bind_err)?;
    let stats = report.clone();
    let app = axum::Router::new()
        .route("/", get(|| async { INDEX }))
        .route("/stats", get(move || async move { axum::Json(stats()) }))
        .route(
            "/metrics",
            get(move || async move {
                ([(header::CONTENT_TYPE, "text/plain; version=0.0.4; charset=utf-8")], prometheus(&report()))
                    .into_response()
            }),
        );
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let thread = std::thread::Builder::new()
        .name("gateway-http".into())
        .spawn(move || {
            rt.block_on(async move {
                // Not graceful: a scrape in flight when the gateway stops is not worth waiting for.
                tokio::select! {
                    _ = async { axum::serve(listener, app).await } => {}
                    _ = stopped => {}
                }
            });
        })
        .map_err(GatewayError::Runtime)?;
    Ok((thread, bound, Shutdown(Some(stop))))
}

const INDEX: &str = "tutti gateway\n  /stats    counters as JSON\n  /metrics  counters in the Prometheus text format\n";

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> Report {
        let mut totals = BTreeMap::new();
        totals.insert("to_dds".to_string(), 12);
        totals.insert("remote_readers".to_string(), 2);
        Report {
            gateway: GatewayReport {
                engine: "cyclone".into(),
                dds_domain: 7,
                ros_namespace: "sim1".into(),
                node: "/sim1/tutti_gateway".into(),
                uptime_s: 1.5,
                totals,
            },
            topics: vec![
                TopicReport {
                    topic: "rt/sim1/uav1/publish".into(),
                    ros2_topic: "/sim1/uav1/publish".into(),
                    set: "uav1/publish".into(),
                    domain: "uav1".into(),
                    direction: Direction::Out,
                    samples_in: 10,
                    samples_out: 9,
                    dropped: 1,
                    bad_input: 0,
                    matched_readers: 3,
                    matched_writers: 0,
                    ..TopicReport::default()
                },
                TopicReport {
                    topic: "rt/odd\"name\\x".into(),
                    ros2_topic: "/odd\nname".into(),
                    set: "odd/subscribe".into(),
                    domain: "odd".into(),
                    direction: Direction::In,
                    bad_input: 4,
                    ..TopicReport::default()
                },
            ],
        }
    }

    #[test]
    fn prometheus_text_has_help_type_and_escaped_labels() {
        let t = prometheus(&report());
        for line in [
            "# HELP tutti_gateway_samples_in_total DDS samples of a topic committed",
            "# TYPE tutti_gateway_samples_in_total counter\n",
            "# TYPE tutti_gateway_matched_readers gauge\n",
            "tutti_gateway_samples_in_total{topic=\"rt/sim1/uav1/publish\",ros2_topic=\"/sim1/uav1/publish\",set=\"uav1/publish\",direction=\"out\"} 10\n",
            "tutti_gateway_matched_readers{topic=\"rt/sim1/uav1/publish\",ros2_topic=\"/sim1/uav1/publish\",set=\"uav1/publish\",direction=\"out\"} 3\n",
            "tutti_gateway_bad_input_total{topic=\"rt/odd\\\"name\\\\x\",ros2_topic=\"/odd\\nname\",set=\"odd/subscribe\",direction=\"in\"} 4\n",
            "# TYPE tutti_gateway_to_dds_total counter\ntutti_gateway_to_dds_total 12\n",
            "# TYPE tutti_gateway_remote_readers gauge\ntutti_gateway_remote_readers 2\n",
            "tutti_gateway_info{engine=\"cyclone\",dds_domain=\"7\",ros_namespace=\"sim1\",node=\"/sim1/tutti_gateway\"} 1\n",
            "tutti_gateway_uptime_seconds 1.5\n",
        ] {
            assert!(t.contains(line), "missing {line:?} in\n{t}");
        }
        // Every family: HELP, then TYPE, then its samples, and no family twice.
        let mut seen = std::collections::HashSet::new();
        let lines: Vec<&str> = t.lines().collect();
        for (i, l) in lines.iter().enumerate() {
            if let Some(rest) = l.strip_prefix("# HELP ") {
                let name = rest.split(' ').next().unwrap();
                assert!(seen.insert(name), "{name} twice");
                assert!(lines[i + 1].starts_with(&format!("# TYPE {name} ")), "{name}: HELP not followed by TYPE");
            } else if !l.starts_with('#') {
                let name = l.split(['{', ' ']).next().unwrap();
                assert!(seen.contains(name), "{name} has no HELP before it");
                assert!(!l.contains('\n'));
            }
        }
    }

    /// The Prometheus project's Python parser (`prometheus_client`, in the repo's test venv)
    /// reads the text as meant: families, types, labels (escapes undone) and values.
    #[test]
    fn prometheus_client_parses_the_text() {
        use std::io::Write as _;
        use std::process::{Command, Stdio};
        let Some(py) = tutti_test_support::python(&["prometheus_client"]) else { return };
        const SCRIPT: &str = "import json, sys\n\
            from prometheus_client.parser import text_string_to_metric_families\n\
            out = {}\n\
            for f in text_string_to_metric_families(sys.stdin.read()):\n\
            \x20   out[f.name] = [f.type, [[s.name, s.labels, s.value] for s in f.samples]]\n\
            print(json.dumps(out))\n";
        let mut child = Command::new(&py)
            .args(["-c", SCRIPT])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        child.stdin.take().unwrap().write_all(prometheus(&report()).as_bytes()).unwrap();
        // Watchdog: a parser that hangs is killed, and the test fails.
        if tutti_test_support::poll_for(std::time::Duration::from_secs(60), || child.try_wait().unwrap()).is_none() {
            let _ = child.kill();
            panic!("the Python parser did not finish");
        }
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["tutti_gateway_samples_in"][0], "counter");
        assert_eq!(v["tutti_gateway_matched_readers"][0], "gauge");
        assert_eq!(v["tutti_gateway_remote_readers"][0], "gauge");
        let total = &v["tutti_gateway_to_dds"][1][0];
        assert_eq!(
            (&total[0], &total[1], total[2].as_f64()),
            (&"tutti_gateway_to_dds_total".into(), &serde_json::json!({}), Some(12.0))
        );
        let odd = &v["tutti_gateway_bad_input"][1][1];
        assert_eq!(odd[0], "tutti_gateway_bad_input_total");
        assert_eq!(odd[1]["topic"], "rt/odd\"name\\x");
        assert_eq!(odd[1]["ros2_topic"], "/odd\nname");
        assert_eq!(odd[1]["set"], "odd/subscribe");
        assert_eq!(odd[2].as_f64(), Some(4.0));
        assert_eq!(v["tutti_gateway_samples_in"][1][0][2].as_f64(), Some(10.0));
        assert_eq!(v["tutti_gateway_info"][1][0][1]["node"], "/sim1/tutti_gateway");
    }

    #[test]
    fn topic_reports_take_a_sets_counters() {
        let s = SetStats::default();
        Stats::add(&s.samples_out, 5);
        Stats::add(&s.readers, 2);
        Stats::add(&s.bad_input, 1);
        let t = TopicReport::default().with_counts(&s);
        assert_eq!((t.samples_out, t.matched_readers, t.bad_input, t.samples_in), (5, 2, 1, 0));
    }

    fn agent() -> ureq::Agent {
        // No proxy from the environment: the server is on loopback.
        ureq::Agent::config_builder().proxy(None).http_status_as_error(false).build().new_agent()
    }

    fn get(agent: &ureq::Agent, url: &str) -> (u16, String, String) {
        let mut r = agent.get(url).call().unwrap();
        let ct = r.headers().get("content-type").map(|v| v.to_str().unwrap().to_string()).unwrap_or_default();
        (r.status().as_u16(), ct, r.body_mut().read_to_string().unwrap())
    }

    #[test]
    fn serves_stats_and_metrics_and_stops() {
        let calls = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let c = calls.clone();
        let (thread, addr, stop) = serve(
            "127.0.0.1:0".parse().unwrap(),
            Arc::new(move || {
                c.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                report()
            }),
        )
        .unwrap();
        assert_ne!(addr.port(), 0);
        let a = agent();
        let (status, ct, body) = get(&a, &format!("http://{addr}/stats"));
        assert_eq!((status, ct.as_str()), (200, "application/json"));
        let v: serde_json::Value = serde_json::from_str(&body).unwrap();
        assert_eq!(v["gateway"]["engine"], "cyclone");
        assert_eq!(v["gateway"]["totals"]["to_dds"], 12);
        assert_eq!(v["topics"][0]["set"], "uav1/publish");
        assert_eq!(v["topics"][0]["direction"], "out");
        assert_eq!(v["topics"][0]["samples_out"], 9);
        let (status, ct, body) = get(&a, &format!("http://{addr}/metrics"));
        assert_eq!((status, ct.as_str()), (200, "text/plain; version=0.0.4; charset=utf-8"));
        assert_eq!(body, prometheus(&report()));
        let (status, _, body) = get(&a, &format!("http://{addr}/"));
        assert!(status == 200 && body.contains("/metrics") && body.contains("/stats"), "{body}");
        assert_eq!(get(&a, &format!("http://{addr}/nope")).0, 404);
        assert_eq!(calls.load(std::sync::atomic::Ordering::Relaxed), 2, "one report per /stats or /metrics");
        // A second server on the same address is refused, naming it.
        let e = serve(addr, Arc::new(report)).unwrap_err().to_string();
        assert!(e.contains(&addr.to_string()) && e.contains("cannot listen"), "{e}");
        stop.stop();
        thread.join().unwrap();
    }
}
