//! Property tests of the gateway's config file reader on untrusted input: random JSON5 made of
//! its keys and odd values (zero, negative, huge and non-finite numbers and durations, deep
//! nesting, garbage peers), the commented example mutated (bytes flipped, cut short, slices
//! deleted or duplicated, brackets spliced in), and arbitrary bytes. Whatever the input,
//! `config::parse` returns (no panic, no stack overflow, no hang) with a config or an error
//! that names the file, and a config that parses is applied to the options and resolved
//! against a DDF without a panic either.
//!
//! A stack overflow aborts the test binary, which fails the test too. Peer host names are
//! resolved when read, so the inputs hold no `peer` key with a host name (a case must not
//! wait for DNS): the example's `peer` line is left out. `TUTTI_FUZZ_CASES=N` runs N cases per
//! property instead of the default 256 (`docs/gateway.md`).

use std::path::Path;
use std::time::Duration;

use proptest::prelude::*;
use tutti_gateway::config::{self, GatewayOptions};
use tutti_test_support::mutate::{apply_all, Mutation};

/// Longest any single case may take, including a debug build on a loaded machine.
const CASE_TIMEOUT: Duration = Duration::from_secs(20);

fn cases() -> u32 {
    std::env::var("TUTTI_FUZZ_CASES").ok().and_then(|v| v.trim().parse().ok()).unwrap_or(256)
}

fn repo(path: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(path)
}

/// The example config without its `peer` line (see the module's comment).
fn example() -> String {
    let text = std::fs::read_to_string(repo("examples/gateway.json5")).expect("the example config");
    text.lines().filter(|l| !l.trim_start().starts_with("peer:")).collect::<Vec<_>>().join("\n")
}

/// Parses, applies and resolves `text` on a worker thread, so that a hang fails the test
/// instead of blocking it and a panic is reported as such.
fn read_with_watchdog(text: String) {
    let result = tutti_test_support::within("reading the config", CASE_TIMEOUT, move || {
        let parsed = config::parse(&text, "fuzz.json5");
        if let Ok(cfg) = &parsed {
            let ddf = repo("ddf/multiuav.ddf");
            let model = tutti_core::ddf::load(&ddf).expect("the DDF");
            let mut opts = GatewayOptions::new(&ddf, model);
            if cfg.apply(&mut opts).is_ok() {
                let _ = config::resolve(&opts);
                let _ = opts.engine_config();
            }
        }
        parsed.map(|_| ()).map_err(|e| e.to_string())
    });
    if let Err(e) = result {
        assert!(e.starts_with("fuzz.json5"), "an error that does not name the file: {e}");
    }
}

/// Values of every kind, the odd ones first.
fn value() -> impl Strategy<Value = String> {
    let odd = prop_oneof![
        Just("0".to_string()),
        Just("-1".to_string()),
        Just("1e-300".to_string()),
        Just("1e308".to_string()),
        Just("Infinity".to_string()),
        Just("NaN".to_string()),
        Just("18446744073709551615".to_string()),
        Just("-9223372036854775808".to_string()),
        Just("\"0s\"".to_string()),
        Just("\"0ns\"".to_string()),
        Just("\"18446744073709551615s\"".to_string()),
        Just("\"584942417355years\"".to_string()),
        Just("\"poll:0s\"".to_string()),
        Just("\"poll:1000000years\"".to_string()),
        Just("\"\\u0000\\u00ff%%\"".to_string()),
        Just("\"::1\"".to_string()),
        Just("[\"127.0.0.1:0\", \"\\u0001garbage\", \"[::1]:7400\", \"a\\\"/><x\"]".to_string()),
        Just("\"127.0.0.1:99999\"".to_string()),
        Just("\"(\"".to_string()),
        Just("{}".to_string()),
        Just("[]".to_string()),
        Just("null".to_string()),
        Just("true".to_string()),
    ];
    let deep = (1..200usize).prop_map(|n| format!("{}{}", "[".repeat(n), "]".repeat(n)));
    let deep_obj = (1..200usize).prop_map(|n| format!("{}1{}", "{a:".repeat(n), "}".repeat(n)));
    prop_oneof![
        4 => odd,
        1 => deep,
        1 => deep_obj,
        1 => any::<i64>().prop_map(|v| v.to_string()),
        1 => any::<f64>().prop_map(|v| format!("{v:e}")),
        1 => "[a-z0-9:/._ -]{0,12}".prop_map(|s| format!("\"{s}\"")),
    ]
}

const KEYS: [&str; 12] = [
    "timeout",
    "status_every",
    "lease",
    "poll",
    "duration",
    "wait",
    "clock_rate",
    "ros_domain_id",
    "strength",
    "http",
    "interface",
    "ros_namespace",
];

/// A file of keys of the config with random values, and a `topics` entry with odd settings.
fn random_config() -> impl Strategy<Value = String> {
    let entry = (0..KEYS.len(), value()).prop_map(|(k, v)| format!("{}: {v}", KEYS[k]));
    let topic = (value(), value(), value()).prop_map(|(rate, depth, remap)| {
        format!(
            "topics: {{ \"multiuav_uav4/publish\": {{ max_rate: {rate}, remap: {remap}, \
             qos: {{ history: \"keep_last\", depth: {depth} }} }} }}"
        )
    });
    let peers = value().prop_filter("no host names (DNS)", |v| !v.contains(|c: char| c.is_ascii_alphabetic()));
    (proptest::collection::vec(entry, 0..6), proptest::option::of(topic), proptest::option::of(peers)).prop_map(
        |(entries, topic, peers)| {
            let mut all = entries;
            all.extend(topic);
            all.extend(peers.map(|p| format!("peer: {p}")));
            format!("{{ {} }}", all.join(",\n "))
        },
    )
}

const SPLICES: [&str; 10] = ["{", "}", "[", "]", "\"", "'", "/*", "//", ":", "\\"];

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = any::<usize>();
    prop_oneof![
        (at, 1..=127u8).prop_map(|(at, mask)| Mutation::Flip { at, mask }),
        at.prop_map(|at| Mutation::Truncate { at }),
        (at, 1..200usize).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (at, 1..400usize).prop_map(|(at, len)| Mutation::Duplicate { at, len }),
        (at, 0..SPLICES.len()).prop_map(|(at, i)| Mutation::Insert { at, bytes: SPLICES[i].into() }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn a_random_config_reads_or_fails_naming_the_file(text in random_config()) {
        read_with_watchdog(text);
    }

    #[test]
    fn the_mutated_example_reads_or_fails_naming_the_file(edits in proptest::collection::vec(mutation(), 1..6)) {
        let mut bytes = example().into_bytes();
        apply_all(&mut bytes, &edits);
        let text = String::from_utf8_lossy(&bytes).into_owned();
        // A flip could turn another key into `peer` with a host name: not here (DNS).
        prop_assume!(!text.contains("peer"));
        read_with_watchdog(text);
    }

    #[test]
    fn arbitrary_text_never_panics(text in "[{}\\[\\]:,\"'a-z0-9 \n/*\\\\.-]{0,300}") {
        prop_assume!(!text.contains("peer"));
        read_with_watchdog(text);
    }
}

/// The reported inputs: 100,000 levels of arrays and of objects, `status_every: 0`.
#[test]
fn the_reported_inputs_are_errors_naming_the_file() {
    for (open, close) in [("[", "]"), ("{a:", "}")] {
        read_with_watchdog(format!("{{ topics: {}{} }}", open.repeat(100_000), close.repeat(100_000)));
    }
    let e = config::parse("{ status_every: \"0s\" }", "fuzz.json5").unwrap_err().to_string();
    assert!(e.starts_with("fuzz.json5:1:") && e.contains("longer than zero"), "{e}");
    let e = config::parse("{ status_every: 0 }", "fuzz.json5").unwrap_err().to_string();
    assert!(e.starts_with("fuzz.json5:1:"), "{e}");
}
