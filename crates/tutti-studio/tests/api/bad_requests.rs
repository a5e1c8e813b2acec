//! Bad requests get the API's JSON answer `{"error", "code"}` with a 4xx status, never a
//! plain-text answer, a 500 or a connection cut: a path under a file, two creations of one
//! file at once, saves racing over one file, bodies over the limit (declared, sent whole or
//! chunked), and every request the handlers' extractors refuse.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::sync::Barrier;
use std::time::Duration;

use serde_json::{json, Value};
use tutti_studio::request::MAX_BODY_BYTES;

use super::{figure2, studio, Studio};

/// Asserts that an answer is the API's JSON error with `status` and `code`, and returns its
/// message.
fn json_error(what: &str, (got, body): (u16, Value), status: u16, code: &str) -> String {
    assert_eq!((got, body["code"].as_str()), (status, Some(code)), "{what}: {body}");
    body["error"].as_str().unwrap_or_else(|| panic!("{what}: no error message: {body}")).to_string()
}

#[test]
fn saving_under_a_file_is_a_conflict_that_names_the_path() {
    let s = studio(None, false);
    for path in ["paper-figure2.ddf/x.ddf", "paper-figure2.ddf/deeper/x.ddf"] {
        let answer = s.post("/api/save", json!({ "path": path, "document": figure2("uav1") }));
        let message = json_error(path, answer, 409, "not-a-folder");
        assert!(message.contains(path) && message.contains("paper-figure2.ddf is a file"), "{message}");
    }
    assert!(s.root.join("paper-figure2.ddf").is_file());
}

#[test]
fn of_two_simultaneous_creations_of_one_file_exactly_one_wins_and_the_other_gets_409() {
    let s = studio(None, false);
    for round in 0..20 {
        let path = format!("race{round}.ddf");
        let barrier = Barrier::new(2);
        let answers: Vec<(u16, Value)> = std::thread::scope(|scope| {
            let racers: Vec<_> = ["uav1", "uav2"]
                .into_iter()
                .map(|name| {
                    let (s, path, barrier) = (&s, &path, &barrier);
                    scope.spawn(move || {
                        barrier.wait();
                        s.post("/api/save", json!({ "path": path, "document": figure2(name) }))
                    })
                })
                .collect();
            racers.into_iter().map(|t| t.join().unwrap()).collect()
        });
        let mut statuses: Vec<u16> = answers.iter().map(|a| a.0).collect();
        statuses.sort_unstable();
        assert_eq!(statuses, [201, 409], "round {round}: {answers:?}");
        let (won, lost) = if answers[0].0 == 201 { (&answers[0], &answers[1]) } else { (&answers[1], &answers[0]) };
        json_error("the loser", lost.clone(), 409, "exists");
        // The file is the winner's, whole.
        let text = std::fs::read_to_string(s.root.join(&path)).unwrap();
        assert_eq!(tutti_studio::files::version(text.as_bytes()), won.1["version"].as_str().unwrap(), "round {round}");
        assert!(tutti_core::ddf::parse_str(&text, &path).is_ok(), "round {round}: {text}");
    }
    let names: Vec<String> =
        std::fs::read_dir(&s.root).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert!(names.iter().all(|n| !n.contains("tmp")), "{names:?}");
}

#[test]
fn saves_racing_over_one_file_leave_it_whole_and_only_one_wins_a_version() {
    let s = studio(None, false);
    let (_, opened) = s.get("/api/open?path=paper-figure2.ddf");
    let version = opened["version"].as_str().unwrap().to_string();
    let file = s.root.join("paper-figure2.ddf");
    let done = std::sync::atomic::AtomicBool::new(false);
    let barrier = Barrier::new(8);
    let (answers, reads) = std::thread::scope(|scope| {
        // A reader that never may see the file empty or in part.
        let reader = scope.spawn(|| {
            let mut reads = 0;
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                let text = std::fs::read_to_string(&file).unwrap();
                assert!(tutti_core::ddf::parse_str(&text, "paper-figure2.ddf").is_ok(), "torn: {text:?}");
                reads += 1;
            }
            reads
        });
        let savers: Vec<_> = (0..8)
            .map(|i| {
                let (s, version, barrier) = (&s, &version, &barrier);
                scope.spawn(move || {
                    barrier.wait();
                    let doc = figure2(&format!("uav{i}"));
                    s.post("/api/save", json!({ "path": "paper-figure2.ddf", "document": doc, "version": version }))
                })
            })
            .collect();
        let answers: Vec<(u16, Value)> = savers.into_iter().map(|t| t.join().unwrap()).collect();
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        (answers, reader.join().unwrap())
    });
    assert!(reads > 0);
    let won: Vec<&(u16, Value)> = answers.iter().filter(|a| a.0 == 200).collect();
    assert_eq!(won.len(), 1, "{answers:?}");
    for lost in answers.iter().filter(|a| a.0 != 200) {
        json_error("a later save of the same version", lost.clone(), 409, "changed");
    }
    let text = std::fs::read(&file).unwrap();
    assert_eq!(tutti_studio::files::version(&text), won[0].1["version"].as_str().unwrap());
}

/// One HTTP/1.1 exchange over a plain socket, as a client that sends the head and then waits
/// for the answer while (on a thread of its own) `body` writes what it wants: the status, the
/// headers (lower case) and the answer's body as JSON. Every read and write has a watchdog.
fn exchange(
    s: &Studio,
    head: &[&str],
    body: impl FnOnce(&mut TcpStream) + Send,
) -> (u16, Vec<(String, String)>, Value) {
    let mut stream = TcpStream::connect(s.running.addr()).unwrap();
    stream.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    stream.set_write_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut text = head.join("\r\n");
    text.push_str(&format!("\r\nhost: {}\r\n\r\n", s.running.addr()));
    stream.write_all(text.as_bytes()).unwrap();
    let mut writer = stream.try_clone().unwrap();
    std::thread::scope(|scope| {
        scope.spawn(move || body(&mut writer));
        let mut reader = BufReader::new(&stream);
        let mut line = String::new();
        reader.read_line(&mut line).unwrap();
        let status: u16 = line.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or_else(|| panic!("{line:?}"));
        let mut headers = Vec::new();
        loop {
            line.clear();
            reader.read_line(&mut line).unwrap();
            match line.trim_end().split_once(':') {
                Some((k, v)) => headers.push((k.to_ascii_lowercase(), v.trim().to_string())),
                None => break,
            }
        }
        let len: usize = headers.iter().find(|(k, _)| k == "content-length").map_or(0, |(_, v)| v.parse().unwrap());
        let mut answer = vec![0; len];
        reader.read_exact(&mut answer).unwrap();
        (status, headers, serde_json::from_slice(&answer).unwrap_or(Value::Null))
    })
}

#[test]
fn a_declared_length_over_the_limit_is_answered_413_before_the_body_is_sent() {
    let s = studio(None, false);
    for expect in [None, Some("expect: 100-continue")] {
        let mut head = vec!["POST /api/save HTTP/1.1", "content-type: application/json", "content-length: 1000000000"];
        head.extend(expect);
        // Nothing of the body is sent: the answer must come all the same.
        let (status, headers, body) = exchange(&s, &head, |_| {});
        let message = json_error("1 GB declared", (status, body), 413, "too-large");
        assert!(message.contains(&format!("{} MiB", MAX_BODY_BYTES >> 20)), "{message}");
        assert!(headers.contains(&("connection".into(), "close".into())), "{headers:?}");
    }
}

#[test]
fn a_body_over_the_limit_sent_whole_is_answered_413_not_cut_off() {
    let s = studio(None, false);
    // 64 MiB of JSON, sent by an HTTP client that writes all of it and then reads the answer.
    let mut big = br#"{"path": "big.ddf", "document": {"domains": []}, "pad": ""#.to_vec();
    big.resize(64 << 20, b'x');
    big.extend_from_slice(b"\"}");
    let answer = s.send("POST", "/api/save", Some("application/json"), &big);
    json_error("64 MiB sent", answer, 413, "too-large");
    assert!(!s.root.join("big.ddf").exists(), "the handler ran");
    // The studio still answers.
    assert_eq!(s.get("/api/files").0, 200);
}

#[test]
fn a_chunked_body_that_crosses_the_limit_is_answered_413() {
    let s = studio(None, false);
    let head = ["POST /api/parse HTTP/1.1", "content-type: application/json", "transfer-encoding: chunked"];
    let (status, _, body) = exchange(&s, &head, |w| {
        let chunk = vec![b' '; 1 << 20];
        let mut sent = 0;
        // Up to 1 MiB beyond the limit, then the end; stop early if the studio stops reading.
        while sent <= MAX_BODY_BYTES {
            if w.write_all(format!("{:x}\r\n", chunk.len()).as_bytes()).is_err()
                || w.write_all(&chunk).is_err()
                || w.write_all(b"\r\n").is_err()
            {
                return;
            }
            sent += chunk.len();
        }
        let _ = w.write_all(b"0\r\n\r\n");
    });
    json_error("chunked over the limit", (status, body), 413, "too-large");
}

#[test]
fn a_body_within_the_limit_but_beyond_axums_default_is_taken() {
    let s = studio(None, false);
    // 4 MiB: more than axum's default limit of 2 MB, less than the studio's.
    let xml = format!("<orchestra><!-- {} --><domain name=\"a\"/></orchestra>", "x".repeat(4 << 20));
    let (status, body) =
        s.send("POST", "/api/parse", Some("application/json"), &serde_json::to_vec(&json!({ "xml": xml })).unwrap());
    assert_eq!(status, 200, "{body}");
    assert!(body["diagnostics"].is_array(), "{body}");
}

#[test]
fn every_request_the_extractors_refuse_is_answered_in_json() {
    let s = studio(None, false);
    let json = Some("application/json");
    let cases: Vec<(&str, (u16, Value), u16, &str)> = vec![
        ("JSON syntax", s.send("POST", "/api/check", json, b"{\"document\": "), 400, "json-syntax"),
        ("not JSON at all", s.send("POST", "/api/run/control", json, b"pause"), 400, "json-syntax"),
        ("no content type", s.send("POST", "/api/parse", None, br#"{"xml": ""}"#), 415, "content-type"),
        ("text/plain", s.send("POST", "/api/save", Some("text/plain"), b"{}"), 415, "content-type"),
        ("a missing field", s.send("POST", "/api/save", json, br#"{"path": "a.ddf"}"#), 422, "json-data"),
        ("a wrong type", s.send("POST", "/api/parse", json, br#"{"xml": 5}"#), 422, "json-data"),
        (
            "an unknown kind",
            s.send("POST", "/api/run/start", json, br#"{"kind": "nope", "path": "a.ddf"}"#),
            422,
            "json-data",
        ),
        ("a bad number", s.send("POST", "/api/run/control", json, br#"{"op": "step", "n": -1}"#), 422, "json-data"),
        ("stop without kind", s.send("POST", "/api/run/stop", json, b"{}"), 422, "json-data"),
        ("check without document", s.send("POST", "/api/check", json, b"[]"), 422, "json-data"),
        ("a missing query", s.get("/api/open"), 400, "query"),
        ("a query field twice", s.get("/api/monitor?namespace=a&namespace=b"), 400, "query"),
        ("GET of a POST request", s.get("/api/save"), 405, "method"),
        ("POST of a GET request", s.send("POST", "/api/info", json, b"{}"), 405, "method"),
        ("an unknown API request", s.get("/api/nothing"), 404, "not-found"),
        ("an unknown page", s.get("/nothing"), 404, "not-found"),
    ];
    for (what, answer, status, code) in cases {
        let message = json_error(what, answer, status, code);
        assert!(!message.is_empty(), "{what}");
    }
}
