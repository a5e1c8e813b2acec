//! The studio's JSON API through HTTP (no browser): opening, checking, saving with its
//! refusals, root confinement and the token; bad requests (`api/bad_requests.rs`).

use std::path::Path;

#[path = "api/bad_requests.rs"]
mod bad_requests;

use serde_json::{json, Value};
use tutti_studio::{Config, Running};
use tutti_test_support::{lazy, wait_for, ShmFile};

struct Studio {
    running: Running,
    agent: ureq::Agent,
    token: Option<String>,
    _dir: tempfile::TempDir,
    root: std::path::PathBuf,
}

fn studio(token: Option<&str>, read_only: bool) -> Studio {
    studio_with(token, read_only, None)
}

fn studio_with(token: Option<&str>, read_only: bool, exe: Option<&str>) -> Studio {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("root");
    std::fs::create_dir(&root).unwrap();
    let ddf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../ddf");
    for f in ["paper-figure2.ddf", "multiuav.ddf"] {
        std::fs::copy(ddf.join(f), root.join(f)).unwrap();
    }
    std::fs::write(dir.path().join("outside.ddf"), "secret").unwrap();
    let running = Running::start(Config {
        listen: "127.0.0.1:0".parse().unwrap(),
        root: root.clone(),
        files: vec!["paper-figure2.ddf".into()],
        read_only,
        token: token.map(str::to_string),
        namespace: format!("studioapi{}", std::process::id()),
        tutti_exe: exe.map(Into::into),
    })
    .unwrap();
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(std::time::Duration::from_secs(20)))
        .build()
        .into();
    Studio { running, agent, token: token.map(str::to_string), _dir: dir, root }
}

impl Studio {
    fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.running.addr())
    }

    fn get(&self, path: &str) -> (u16, Value) {
        let mut req = self.agent.get(self.url(path));
        if let Some(t) = &self.token {
            req = req.header("x-tutti-token", t);
        }
        let mut resp = req.call().unwrap();
        (resp.status().as_u16(), resp.body_mut().read_json().unwrap_or(Value::Null))
    }

    /// `method path` with `body` as it is (a `Content-Type` when given): the status and the
    /// answer as JSON (`Null` when it is not JSON).
    fn send(&self, method: &str, path: &str, content_type: Option<&str>, body: &[u8]) -> (u16, Value) {
        let mut req = ureq::http::Request::builder().method(method).uri(self.url(path));
        if let Some(t) = &self.token {
            req = req.header("x-tutti-token", t);
        }
        if let Some(ct) = content_type {
            req = req.header("content-type", ct);
        }
        let mut resp = self.agent.run(req.body(body).unwrap()).unwrap();
        (resp.status().as_u16(), resp.body_mut().read_json().unwrap_or(Value::Null))
    }

    fn post(&self, path: &str, body: Value) -> (u16, Value) {
        let mut req = self.agent.post(self.url(path));
        if let Some(t) = &self.token {
            req = req.header("x-tutti-token", t);
        }
        let mut resp = req.send_json(&body).unwrap();
        (resp.status().as_u16(), resp.body_mut().read_json().unwrap_or(Value::Null))
    }
}

fn figure2(name: &str) -> Value {
    let item = |n: &str| json!({ "name": n, "type": "double" });
    json!({ "domains": [{
        "name": name, "synchronous": true, "multiple_publish_allowed": false, "states": false,
        "publish": [item("Autopilot"), item("X")],
        "subscribe": [item("Latitude"), item("Longitude"), item("Elevation")],
    }]})
}

#[test]
fn page_and_files_are_served() {
    let s = studio(None, false);
    let mut resp = s.agent.get(s.url("/")).call().unwrap();
    assert_eq!(resp.status().as_u16(), 200);
    assert!(resp.body_mut().read_to_string().unwrap().contains("tutti studio"));
    let (status, files) = s.get("/api/files");
    assert_eq!(status, 200);
    assert_eq!(files["files"], json!(["multiuav.ddf", "paper-figure2.ddf"]));
    let (_, info) = s.get("/api/info");
    assert_eq!(info["files"], json!(["paper-figure2.ddf"]));
    let (status, body) = s.get("/api/nothing");
    assert_eq!(status, 404);
    assert!(body["error"].as_str().unwrap().contains("no such"));
}

#[test]
fn open_gives_the_document_the_layout_and_the_topics() {
    let s = studio(None, false);
    let (status, body) = s.get("/api/open?path=paper-figure2.ddf");
    assert_eq!(status, 200, "{body}");
    let checked = &body["checked"];
    assert_eq!(checked["valid"], true);
    let doc = &checked["document"]["domains"][0];
    assert_eq!(doc["name"], "multiuav_uav1");
    assert_eq!((&doc["synchronous"], &doc["multiple_publish_allowed"]), (&json!(true), &json!(false)));
    assert_eq!(doc["subscribe"][2]["name"], "Elevation");
    assert_eq!(doc["subscribe"][2]["type"], "float64");
    let set = &checked["show"]["domains"][0]["sets"][1];
    assert_eq!(set["role"], "SUBSCRIBE");
    assert_eq!(set["size"], 24);
    assert_eq!(set["items"][2]["offset"], 16);
    assert_eq!(set["dds"]["topic"], "rt/multiuav_uav1/subscribe");
    assert!(set["reader_qos"].is_object());
}

#[test]
fn check_puts_each_diagnostic_at_its_field() {
    let s = studio(None, false);
    let mut doc = figure2("uav one");
    doc["domains"][0]["subscribe"][1]["length"] = json!("0");
    let (status, body) = s.post("/api/check", json!({ "document": doc }));
    assert_eq!(status, 200);
    assert_eq!(body["valid"], false);
    let fields: Vec<&str> =
        body["diagnostics"].as_array().unwrap().iter().filter_map(|d| d["field"].as_str()).collect();
    assert_eq!(fields, vec!["d0", "d0.subscribe.i1.length"], "{body}");
    assert!(body["xml"].as_str().unwrap().contains("<set name=\"PUBLISH\">"));
    let (_, body) = s.post("/api/check", json!({ "document": figure2("uav1") }));
    assert_eq!(body["valid"], true, "{body}");
    assert_eq!(body["show"]["domains"][0]["name"], "uav1");
    // A bus nests its members: paths join with '/'.
    let mut doc = figure2("uav1");
    doc["domains"][0]["publish"][1] = json!({ "name": "gps", "type": "bus", "items": [
        { "name": "lat", "type": "double" }, { "name": "fix", "type": "uint8", "length": "3", "default": "1" } ] });
    let (_, body) = s.post("/api/check", json!({ "document": doc }));
    assert_eq!(body["valid"], true, "{body}");
    let items = &body["show"]["domains"][0]["sets"][0]["items"];
    assert_eq!(
        (&items[1]["path"], &items[2]["path"], &items[2]["length"]),
        (&json!("gps/lat"), &json!("gps/fix"), &json!(3))
    );
    // A body that is not a document: a clear message, not a crash.
    let (status, _) = s.post("/api/check", json!({ "document": 3 }));
    assert!((400..500).contains(&status));
}

#[test]
fn parse_reads_xml_typed_by_hand() {
    let s = studio(None, false);
    let xml = std::fs::read_to_string(s.root.join("multiuav.ddf")).unwrap();
    let (_, body) = s.post("/api/parse", json!({ "xml": xml }));
    assert_eq!(body["valid"], true);
    assert!(body["document"]["domains"].as_array().unwrap().len() >= 2);
    let (_, body) = s.post("/api/parse", json!({ "xml": "<orchestra><domain name=\"a b\"/></orchestra>" }));
    assert_eq!(body["valid"], false);
    assert_eq!(body["diagnostics"][0]["line"], 1);
}

#[test]
fn save_is_atomic_and_refuses_what_it_must() {
    let s = studio(None, false);
    // A new file.
    let (status, body) = s.post("/api/save", json!({ "path": "new.ddf", "document": figure2("uav1") }));
    assert_eq!(status, 201, "{body}");
    let version = body["version"].as_str().unwrap().to_string();
    let saved = std::fs::read_to_string(s.root.join("new.ddf")).unwrap();
    assert!(tutti_core::ddf::parse_str(&saved, "new.ddf").is_ok());
    // Saving it again as new: it exists.
    let (status, body) = s.post("/api/save", json!({ "path": "new.ddf", "document": figure2("uav1") }));
    assert_eq!((status, body["code"].as_str()), (409, Some("exists")));
    // Saved over with its version: fine.
    let (status, body) =
        s.post("/api/save", json!({ "path": "new.ddf", "document": figure2("uav2"), "version": version }));
    assert_eq!(status, 200, "{body}");
    let version = body["version"].as_str().unwrap().to_string();
    // Changed on disk since: refused, file untouched.
    std::fs::write(s.root.join("new.ddf"), "changed by someone else").unwrap();
    let (status, body) =
        s.post("/api/save", json!({ "path": "new.ddf", "document": figure2("uav3"), "version": version }));
    assert_eq!((status, body["code"].as_str()), (409, Some("changed")));
    assert!(body["error"].as_str().unwrap().contains("changed on disk"));
    assert_eq!(std::fs::read_to_string(s.root.join("new.ddf")).unwrap(), "changed by someone else");
    // Invalid: refused unless forced.
    let (status, body) = s.post("/api/save", json!({ "path": "bad.ddf", "document": figure2("a b") }));
    assert_eq!((status, body["code"].as_str()), (422, Some("invalid")));
    assert!(body["details"][0]["message"].as_str().unwrap().contains("a b"));
    assert!(!s.root.join("bad.ddf").exists());
    let (status, _) = s.post("/api/save", json!({ "path": "bad.ddf", "document": figure2("a b"), "force": true }));
    assert_eq!(status, 201);
    assert!(s.root.join("bad.ddf").exists());
    // No temp file left behind.
    let names: Vec<String> =
        std::fs::read_dir(&s.root).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert!(names.iter().all(|n| !n.contains("tmp")), "{names:?}");
}

#[test]
fn paths_outside_the_root_are_refused() {
    let s = studio(None, false);
    std::os::unix::fs::symlink(s.root.join("../outside.ddf"), s.root.join("link.ddf")).unwrap();
    for bad in ["../../etc/passwd", "/etc/passwd", "../outside.ddf", "link.ddf", "..%2Foutside.ddf"] {
        let (status, body) = s.get(&format!("/api/open?path={bad}"));
        assert!(status == 403 || status == 404, "{bad}: {status} {body}");
        assert!(body["error"].is_string(), "{bad}: {body}");
        if !bad.contains('%') {
            let (status, body) = s.post("/api/save", json!({ "path": bad, "document": figure2("x"), "force": true }));
            assert!((400..500).contains(&status), "{bad}: {status} {body}");
        }
    }
    let (status, body) = s.get("/api/open?path=../../etc/passwd");
    assert_eq!(status, 403);
    assert!(body["error"].as_str().unwrap().contains("outside the studio's root"));
    assert_eq!(std::fs::read_to_string(s.root.join("../outside.ddf")).unwrap(), "secret");
}

#[test]
fn read_only_refuses_to_save() {
    let s = studio(None, true);
    let (status, body) = s.post("/api/save", json!({ "path": "new.ddf", "document": figure2("uav1") }));
    assert_eq!((status, body["code"].as_str()), (403, Some("read-only")));
}

#[test]
fn a_token_is_required_when_set() {
    let mut s = studio(Some("sesame"), false);
    let (status, _) = s.get("/api/files");
    assert_eq!(status, 200);
    let (status, _) = s.get("/api/files?token=sesame");
    assert_eq!(status, 200);
    s.token = None;
    let (status, body) = s.get("/api/files");
    assert_eq!(status, 401);
    assert!(body["error"].as_str().unwrap().contains("token"));
    let (status, _) = s.get("/api/files?token=wrong");
    assert_eq!(status, 401);
}

/// The first event of the monitor's stream.
fn first_event(s: &Studio, query: &str) -> Value {
    use std::io::BufRead;
    let resp = s.agent.get(s.url(&format!("/api/monitor?{query}"))).call().unwrap();
    assert_eq!(resp.status().as_u16(), 200);
    let reader = std::io::BufReader::new(resp.into_body().into_reader());
    for line in reader.lines() {
        let line = line.unwrap();
        if let Some(data) = line.strip_prefix("data: ") {
            return serde_json::from_str(data).unwrap();
        }
    }
    panic!("the stream ended without an event");
}

#[test]
fn the_monitor_reports_a_corrupted_segment_and_keeps_running() {
    let s = studio(None, false);
    let ns = format!("studiobad{}", std::process::id());
    let junk = ShmFile::segment(&ns, "broken");
    std::fs::write(junk.path(), vec![0xa5u8; 4096]).unwrap();
    for _ in 0..2 {
        let ev = first_event(&s, &format!("namespace={ns}&items=broken%23PUBLISH%23x,gone%23SUBSCRIBE%23y"));
        assert_eq!(ev["namespace"], ns.as_str());
        assert!(ev["domains"][0]["error"].is_string(), "{ev}");
        assert!(ev["values"]["broken#PUBLISH#x"]["error"].is_string(), "{ev}");
        assert_eq!(ev["values"]["gone#SUBSCRIBE#y"]["error"], "no running framework");
    }
    let (status, body) = s.get("/api/monitor?namespace=a%20b");
    assert_eq!(status, 400, "{body}");
    let (status, body) = s.get("/api/monitor?items=x%23BOTH%23y");
    assert_eq!(status, 400, "{body}");
}

#[test]
fn run_control_refuses_what_it_must_and_keeps_the_log() {
    let s = studio_with(None, false, Some("/bin/echo"));
    std::fs::write(s.root.join("bad.ddf"), "<orchestra/>").unwrap();
    let start =
        |path: &str, step: &str| s.post("/api/run/start", json!({ "kind": "host", "path": path, "step": step }));
    let (status, body) = start("bad.ddf", "10ms");
    assert_eq!((status, body["code"].as_str()), (422, Some("invalid")), "{body}");
    let (status, _) = start("../../etc/passwd", "10ms");
    assert_eq!(status, 403);
    let (status, body) = start("multiuav.ddf", "1ms; rm -rf /");
    assert_eq!(status, 400, "{body}");
    let (status, body) = start("multiuav.ddf", "10ms");
    assert_eq!(status, 200, "{body}");
    // The framework runs on a thread of the studio: the log holds its first line (with the
    // step it was given) once that thread has written it (poll, with a watchdog).
    let never = lazy(|| format!("the host's output never reached the log: {}", first_event(&s, "")));
    let ev = wait_for(never, std::time::Duration::from_secs(30), || {
        Some(first_event(&s, "")).filter(|ev| ev["runs"]["host"]["log"].to_string().contains("step 10ms"))
    });
    assert!(ev["runs"]["host"]["log"].to_string().contains("host"), "{ev}");

    // The framework is paused, stepped, reset and resumed through its control plane.
    let control = |body: Value| s.post("/api/run/control", body);
    let (status, paused) = control(json!({ "op": "pause" }));
    assert_eq!((status, paused["state"].as_str()), (200, Some("paused")), "{paused}");
    let (status, stepped) = control(json!({ "op": "step", "n": 3 }));
    assert_eq!(status, 200, "{stepped}");
    assert_eq!(
        (stepped["state"].as_str(), stepped["step"].as_u64()),
        (Some("paused"), Some(paused["step"].as_u64().unwrap() + 3))
    );
    let (status, reset) = control(json!({ "op": "reset" }));
    assert_eq!((status, reset["step"].as_u64(), reset["sim_time"].as_f64()), (200, Some(0), Some(0.0)), "{reset}");
    let (status, body) = control(json!({ "op": "step" }));
    assert_eq!(status, 400, "{body}");
    let (status, body) = control(json!({ "op": "jump" }));
    assert!(status == 400 && body["error"].to_string().contains("unknown op 'jump'"), "{body}");
    let (status, resumed) = control(json!({ "op": "resume" }));
    assert_eq!((status, resumed["state"].as_str()), (200, Some("playing")), "{resumed}");
    let (status, refused) = control(json!({ "op": "step", "n": 1 }));
    assert_eq!((status, refused["code"].as_str()), (409, Some("refused")), "stepping a playing run: {refused}");

    let (status, body) = s.post("/api/run/stop", json!({ "kind": "host" }));
    assert_eq!(status, 200, "{body}");
    let ev = first_event(&s, "");
    assert_eq!(ev["runs"]["host"]["running"], false, "{ev}");
    let (status, _) = s.post("/api/run/stop", json!({ "kind": "gateway" }));
    assert_eq!(status, 404);
    let (status, body) = s.post("/api/run/control", json!({ "op": "pause" }));
    assert_eq!((status, body["code"].as_str()), (409, Some("stopped")), "{body}");

    let s = studio_with(None, true, Some("/bin/echo"));
    let (status, body) = s.post("/api/run/start", json!({ "kind": "host", "path": "multiuav.ddf" }));
    assert_eq!((status, body["code"].as_str()), (403, Some("read-only")));
    let s = studio(None, false);
    let (status, body) = s.post("/api/run/start", json!({ "kind": "host", "path": "multiuav.ddf" }));
    assert_eq!((status, body["code"].as_str()), (503, Some("no-exe")));
}

/// A framework started from the studio on `ddf` in a namespace of its own (`tag`), once
/// its control plane serves (its first log line is written after that): the namespace.
fn start_host_in(s: &Studio, ddf: &str, tag: &str) -> String {
    let ns = format!("{tag}{}", std::process::id());
    let (status, body) =
        s.post("/api/run/start", json!({ "kind": "host", "path": ddf, "step": "10ms", "namespace": ns }));
    assert_eq!(status, 200, "{body}");
    let never = lazy(|| format!("the host's output never reached the log: {}", first_event(s, "")));
    wait_for(never, std::time::Duration::from_secs(30), || {
        Some(first_event(s, "")).filter(|ev| ev["runs"]["host"]["log"].to_string().contains("step 10ms"))
    });
    ns
}

#[test]
fn run_control_saves_and_restores_checkpoints() {
    use tutti_host::checkpoint::Checkpoint;
    let s = studio_with(None, false, Some("/bin/echo"));
    let control = |body: Value| s.post("/api/run/control", body);
    let listed = || s.get("/api/run/checkpoints").1["checkpoints"].clone();
    let (status, body) = control(json!({ "op": "save", "path": "early" }));
    assert_eq!((status, body["code"].as_str()), (404, Some("not-found")), "no framework yet: {body}");
    let ns = start_host_in(&s, "multiuav.ddf", "studiockpt");
    assert_eq!(listed(), json!([]));

    // A run without components: its checkpoint holds the domains only. The extension is
    // added to a name without it.
    let (status, saved) = control(json!({ "op": "save", "path": "first" }));
    assert_eq!((status, saved["checkpoint"].as_str()), (200, Some("first.tutti-checkpoint")), "{saved}");
    let first = Checkpoint::read(&s.root.join("first.tutti-checkpoint")).unwrap();
    assert!(first.components.is_empty() && first.skipped.is_empty(), "{first:?}");
    assert!(first.ddf.ends_with("multiuav.ddf"), "{}", first.ddf);
    assert!(!first.domains.is_empty());

    // Paused at step S, saved, stepped on, restored: back at step S, still paused.
    let (status, paused) = control(json!({ "op": "pause" }));
    assert_eq!((status, paused["state"].as_str()), (200, Some("paused")), "{paused}");
    let at = paused["step"].as_u64().unwrap();
    let (status, saved) = control(json!({ "op": "save", "path": "paused.tutti-checkpoint" }));
    assert_eq!((status, saved["checkpoint"].as_str()), (200, Some("paused.tutti-checkpoint")), "{saved}");
    assert_eq!(Checkpoint::read(&s.root.join("paused.tutti-checkpoint")).unwrap().next_index, at);
    let (status, stepped) = control(json!({ "op": "step", "n": 5 }));
    assert_eq!((status, stepped["step"].as_u64()), (200, Some(at + 5)), "{stepped}");
    let (status, restored) = control(json!({ "op": "restore", "path": "paused.tutti-checkpoint" }));
    assert_eq!(status, 200, "{restored}");
    assert_eq!(restored["checkpoint"], "paused.tutti-checkpoint");
    assert_eq!((restored["state"].as_str(), restored["step"].as_u64()), (Some("paused"), Some(at)), "{restored}");

    // Without a name: the DDF's, numbered; listed for Restore.
    let (status, saved) = control(json!({ "op": "save", "path": "" }));
    assert_eq!((status, saved["checkpoint"].as_str()), (200, Some("multiuav-1.tutti-checkpoint")), "{saved}");
    let (_, saved) = control(json!({ "op": "save" }));
    assert_eq!(saved["checkpoint"], "multiuav-2.tutti-checkpoint", "{saved}");
    assert_eq!(
        listed(),
        json!([
            "first.tutti-checkpoint",
            "multiuav-1.tutti-checkpoint",
            "multiuav-2.tutti-checkpoint",
            "paused.tutti-checkpoint"
        ])
    );
    // A name of another file is never written over: the checkpoint goes beside it.
    let ddf = std::fs::read(s.root.join("multiuav.ddf")).unwrap();
    let (_, saved) = control(json!({ "op": "save", "path": "multiuav.ddf" }));
    assert_eq!(saved["checkpoint"], "multiuav.ddf.tutti-checkpoint", "{saved}");
    assert_eq!(std::fs::read(s.root.join("multiuav.ddf")).unwrap(), ddf);

    // A file that is not a checkpoint: refused with the reason, the run untouched.
    let (status, refused) = control(json!({ "op": "restore", "path": "multiuav.ddf" }));
    assert_eq!((status, refused["code"].as_str()), (409, Some("refused")), "{refused}");
    assert!(refused["error"].as_str().unwrap().contains("not a tutti checkpoint"), "{refused}");
    std::fs::write(s.root.join("junk.tutti-checkpoint"), "PK not really").unwrap();
    let (status, refused) = control(json!({ "op": "restore", "path": "junk.tutti-checkpoint" }));
    assert_eq!((status, refused["code"].as_str()), (409, Some("refused")), "{refused}");
    assert!(refused["error"].as_str().unwrap().contains("not a tutti checkpoint"), "{refused}");
    let (_, state) = control(json!({ "op": "state" }));
    assert_eq!((state["state"].as_str(), state["step"].as_u64()), (Some("paused"), Some(at)), "{state}");

    // A component that keeps no state: a save fails naming it, unless told to skip it.
    let component = tutti_core::shm::Participant::connect(
        "multiuav_uav1",
        tutti_core::shm::ConnectOptions {
            namespace: ns.clone(),
            name: "nostate".into(),
            connect_timeout: std::time::Duration::from_secs(10),
            skip_wait_to_go: true,
            ..Default::default()
        },
    )
    .unwrap();
    let (status, refused) = control(json!({ "op": "save", "path": "stateless" }));
    assert_eq!((status, refused["code"].as_str()), (409, Some("refused")), "{refused}");
    let why = refused["error"].as_str().unwrap();
    assert!(why.contains("keep no state") && why.contains("'nostate'"), "{refused}");
    assert!(!s.root.join("stateless.tutti-checkpoint").exists());
    let (status, saved) = control(json!({ "op": "save", "path": "stateless", "skip_stateless": true }));
    assert_eq!((status, saved["checkpoint"].as_str()), (200, Some("stateless.tutti-checkpoint")), "{saved}");
    let skipped = Checkpoint::read(&s.root.join("stateless.tutti-checkpoint")).unwrap().skipped;
    assert_eq!(
        skipped.iter().map(|k| (k.name.as_str(), k.domain.as_str())).collect::<Vec<_>>(),
        [("nostate", "multiuav_uav1")]
    );
    drop(component);
    // Missing files, no name, and paths outside the root: refused before the run is asked.
    let (status, body) = control(json!({ "op": "restore", "path": "nothing.tutti-checkpoint" }));
    assert_eq!(status, 404, "{body}");
    let (status, body) = control(json!({ "op": "restore", "path": " " }));
    assert_eq!(status, 400, "{body}");
    for bad in ["../escape", "../../etc/passwd", "/tmp/escape", "../outside.ddf"] {
        let (status, body) = control(json!({ "op": "save", "path": bad }));
        assert_eq!((status, body["code"].as_str()), (403, Some("path")), "save {bad}: {body}");
        assert!(body["error"].as_str().unwrap().contains("outside the studio's root"), "{body}");
        let (status, body) = control(json!({ "op": "restore", "path": bad }));
        assert!(status == 403 || status == 404, "restore {bad}: {status} {body}");
    }
    assert!(!s.root.join("../escape.tutti-checkpoint").exists());
    let (status, body) = control(json!({ "op": "save", "path": "nofolder/" }));
    assert_eq!(status, 400, "{body}");

    let (status, body) = s.post("/api/run/stop", json!({ "kind": "host" }));
    assert_eq!(status, 200, "{body}");
    let (status, body) = control(json!({ "op": "save", "path": "late" }));
    assert_eq!((status, body["code"].as_str()), (409, Some("stopped")), "{body}");
    assert!(!s.root.join("late.tutti-checkpoint").exists());

    let s = studio_with(None, true, Some("/bin/echo"));
    let (status, body) = s.post("/api/run/control", json!({ "op": "save", "path": "x" }));
    assert_eq!((status, body["code"].as_str()), (403, Some("read-only")));
}

#[test]
fn requests_for_another_host_name_are_refused() {
    let s = studio(None, false);
    let mut resp = s.agent.get(s.url("/api/files")).header("host", "rebound.example:8470").call().unwrap();
    assert_eq!(resp.status().as_u16(), 403);
    let body: Value = resp.body_mut().read_json().unwrap();
    assert_eq!(body["code"], "host");
}

#[test]
fn a_non_loopback_address_needs_a_token() {
    let dir = tempfile::tempdir().unwrap();
    let err = Running::start(Config {
        listen: "0.0.0.0:0".parse().unwrap(),
        root: dir.path().to_path_buf(),
        files: vec![],
        read_only: true,
        token: None,
        namespace: "x".into(),
        tutti_exe: None,
    })
    .unwrap_err();
    assert!(err.to_string().contains("token"), "{err}");
}

/// The first event of the stream whose JSON passes `ok`, within 10 s.
fn event_where(s: &Studio, query: &str, ok: impl Fn(&Value) -> bool) -> Value {
    let none = lazy(|| format!("no such event; last: {}", first_event(s, query)));
    wait_for(none, std::time::Duration::from_secs(10), || Some(first_event(s, query)).filter(|ev| ok(ev)))
}

#[test]
fn the_monitor_reads_items_of_a_live_domain_as_an_observer() {
    let s = studio(None, false);
    let ns = format!("studiolive{}", std::process::id());
    let model = tutti_core::ddf::load(s.root.join("paper-figure2.ddf")).unwrap();
    let opts = tutti_core::shm::FrameworkOptions { namespace: ns.clone(), ..Default::default() };
    let mut fw = tutti_core::shm::Framework::create(&model, &opts).unwrap();
    let mut publish = vec![0u8; 16];
    publish[8..].copy_from_slice(&2.5f64.to_ne_bytes());
    fw.domains[0].publish_step(&publish, 0.01).unwrap();
    let query = format!("namespace={ns}&items=multiuav_uav1%23PUBLISH%23X");
    let ev = event_where(&s, &query, |ev| ev["values"]["multiuav_uav1#PUBLISH#X"]["v"].is_array());
    assert_eq!(ev["values"]["multiuav_uav1#PUBLISH#X"]["v"], json!([2.5]));
    let d = &ev["domains"][0];
    assert_eq!((&d["domain"], &d["framework_alive"]), (&json!("multiuav_uav1"), &json!(true)));
    // The studio is no participant.
    assert_eq!(d["connection_count"], 0);
    assert!(ev["catalog"].as_array().unwrap().iter().any(|c| c["path"] == "Elevation"));
    drop(fw);
    let ev = event_where(&s, &query, |ev| ev["domains"].as_array().is_some_and(Vec::is_empty));
    assert_eq!(ev["values"]["multiuav_uav1#PUBLISH#X"]["error"], "no running framework");
}
