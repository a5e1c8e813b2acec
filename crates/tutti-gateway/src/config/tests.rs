//! The config file's tests: every key read, refused where it stands, and the plan it makes.

use std::fmt;

use tutti_core::mapping::{self, Durability, Endpoint, History, Reliability};
use tutti_ros2::env::discovery_range;

use super::*;

fn repo(path: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(path)
}

/// Options for `ddf` (in the repo's `ddf/`) with the config text `cfg` applied.
fn opts(ddf: &str, cfg: &str) -> Result<GatewayOptions, ConfigError> {
    let path = repo(&format!("ddf/{ddf}"));
    let model = tutti_core::ddf::load(&path).unwrap();
    let mut o = GatewayOptions::new(&path, model);
    parse(cfg, "gw.json5")?.apply(&mut o)?;
    Ok(o)
}

fn err(r: Result<impl fmt::Debug, ConfigError>) -> String {
    r.expect_err("refused").to_string()
}

fn resolved(ddf: &str, cfg: &str) -> Result<Plan, ConfigError> {
    resolve(&opts(ddf, cfg)?)
}

#[test]
fn every_key_is_read() {
    let c = parse(
        r#"{ ros_domain_id: 7, ros2_types: "per-item", qos_profile: "dds", strength: 3, mirror: true,
             node_name: "gw", interface: ["127.0.0.1"], dds: "rustdds", peer: ["localhost"], clock: "none",
             clock_rate: 50, timeout: "2s", wait: "poll:50us", poll: "1ms", status_every: "10s",
             duration: "1min", quiet: true, ros_namespace: "/sim1/", hosted_only: false, lease: "3s",
             http: "127.0.0.1:9100", foxglove: "127.0.0.1:8765", allow: ["a/.*"], deny: ["b"], topics: {} }"#,
        "f",
    )
    .unwrap();
    assert_eq!(c.engine.ros_domain_id, Some(7));
    assert_eq!(c.gateway.ros2_types, Some(TypeMode::PerItem));
    assert_eq!(c.engine.engine, Some(EngineKind::Rustdds));
    assert_eq!(c.gateway.wait, Some(WaitMode::Poll(Duration::from_micros(50))));
    assert_eq!(c.gateway.ros_namespace.as_deref(), Some("sim1"));
    assert_eq!(c.gateway.lease, Some(Duration::from_secs(3)));
    assert_eq!(c.http.http, Some("127.0.0.1:9100".parse().unwrap()));
    let mut o = opts("product-sample.ddf", "{}").unwrap();
    c.apply(&mut o).unwrap();
    assert_eq!(o.foxglove, Some("127.0.0.1:8765".parse().unwrap()));
    assert_eq!((o.ros_domain_id, o.strength, o.mirror, o.hosted_only), (7, 3, true, false));
    assert_eq!((o.profile, o.engine, o.clock.clone()), (Profile::Dds, EngineKind::Rustdds, ClockSource::Off));
    assert_eq!((o.timeout, o.clock_rate, o.ros_namespace.as_str()), (Duration::from_secs(2), Some(50.0), "sim1"));
    assert_eq!(o.rules.allow.len() + o.rules.deny.len(), 2);
    assert_eq!(o.rules.source, "f");
}

#[test]
fn unknown_keys_are_refused_with_the_key_its_place_and_the_accepted_keys() {
    let e = err(parse("{\n  timeout: \"1s\",\n  tiemout: \"2s\" }", "gw.json5"));
    assert!(e.starts_with("gw.json5:3:3: unknown field `tiemout`"), "{e}");
    assert!(e.contains("`timeout`") && e.contains("`ros_namespace`") && e.contains("`topics`"), "{e}");
    let e = err(parse(r#"{ topics: { "a/publish": { qos: { reliablity: "reliable" } } } }"#, "gw.json5"));
    assert!(e.contains("unknown field `reliablity`") && e.contains("`durability`"), "{e}");
    let e = err(parse("{ engine: \"cyclone\",\n  dds: \"rustdds\" }", "gw.json5"));
    assert!(e.starts_with("gw.json5:2:3: duplicate field `engine`"), "{e}");
    let e = err(parse(r#"{ topics: { "a/publish": { rate: 5 } } }"#, "gw.json5"));
    assert!(e.contains("unknown field `rate`") && e.contains("`max_rate`"), "{e}");
}

#[test]
fn bad_values_and_syntax_are_refused_where_they_stand() {
    let e = err(parse("{\n  timeout: \"soon\" }", "gw.json5"));
    assert!(e.starts_with("gw.json5:2:12:") && e.contains("'soon' is not a duration"), "{e}");
    let e = err(parse("{ timeout: \"1s\" ", "gw.json5"));
    assert!(e.starts_with("gw.json5:1:") && e.contains("syntax error"), "{e}");
    let e = err(parse("{ allow: [\"ok\", \"uav(\"] }", "gw.json5"));
    assert!(e.starts_with("gw.json5:1:17:") && e.contains("bad pattern 'uav('"), "{e}");
    let e = err(parse("{ ros_domain_id: 300 }", "gw.json5"));
    assert!(e.contains("300 is not a DDS domain id (0-232)"), "{e}");
    let e = err(parse("{ topics: { \"a/publish\": { max_rate: 0 } } }", "gw.json5"));
    assert!(e.contains("0 is not a rate in Hz above 0"), "{e}");
    let e = err(parse("{ topics: { \"a/publish\": { qos: { reliability: \"sometimes\" } } } }", "gw.json5"));
    assert!(e.contains("unknown variant `sometimes`") && e.contains("`best_effort`"), "{e}");
    let e = err(parse("{ topics: { \"a/publish\": { remap: \"2fast\" } } }", "gw.json5"));
    assert!(e.contains("'2fast' is not a ROS topic name"), "{e}");
    let e = err(parse("{ ros_namespace: \"a b\" }", "gw.json5"));
    assert!(e.contains("ROS namespace 'a b'"), "{e}");
    assert!(err(load(Path::new("/nonexistent/gw.json5"))).starts_with("/nonexistent/gw.json5: cannot read"));
}

#[test]
fn a_file_nested_too_deep_is_refused_where_it_goes_too_deep_before_it_is_parsed() {
    for (open, close) in [("[", "]"), ("{a:", "}")] {
        let text = format!("{{ topics: {}{} }}", open.repeat(100_000), close.repeat(100_000));
        let e = err(parse(&text, "deep.json5"));
        let col = 11 + (MAX_NESTING - 1) * open.len();
        assert!(e.starts_with(&format!("deep.json5:1:{col}: nested more than {MAX_NESTING} deep")), "{e}");
    }
    // Brackets in strings and comments do not count; the limit itself is parsed.
    let quoted = format!("{{ node_name: \"{}\", // {}\n /* {} */ }}", "[".repeat(99), "{".repeat(99), "[".repeat(99));
    assert_eq!(parse(&quoted, "q.json5").unwrap().gateway.node_name.as_deref(), Some("[".repeat(99).as_str()));
    let at_limit = format!("{}{}", "[".repeat(MAX_NESTING), "]".repeat(MAX_NESTING));
    assert!(!err(parse(&at_limit, "l.json5")).contains("nested more than"));
}

#[test]
fn durations_and_rates_that_would_panic_are_refused_naming_the_key() {
    for key in ["timeout", "status_every", "lease"] {
        let e = err(parse(&format!("{{\n {key}: \"0s\" }}"), "gw.json5"));
        assert!(e.starts_with("gw.json5:2:") && e.contains("'0s': it must be longer than zero"), "{key}: {e}");
    }
    for key in ["timeout", "status_every", "lease", "poll", "duration"] {
        let e = err(parse(&format!("{{ {key}: \"400days\" }}"), "gw.json5"));
        assert!(e.contains("'400days': longer than 365 days"), "{key}: {e}");
        let e = err(parse(&format!("{{ {key}: \"18446744073709551615s\" }}"), "gw.json5"));
        assert!(e.starts_with("gw.json5:1:"), "{key}: {e}");
    }
    assert_eq!(parse("{ poll: \"0s\" }", "f").unwrap().gateway.poll, Some(Duration::ZERO));
    assert_eq!(parse("{ duration: \"0s\" }", "f").unwrap().gateway.duration, Some(Duration::ZERO));
    assert!(err(parse("{ wait: \"poll:400days\" }", "f")).contains("longer than 365 days"));
    for rate in ["1e-300", "-1", "0"] {
        let e = err(parse(&format!("{{ clock_rate: {rate} }}"), "f"));
        assert!(e.contains("is not a rate in Hz above 0"), "{rate}: {e}");
        let e = err(parse(&format!("{{ topics: {{ \"a/publish\": {{ max_rate: {rate} }} }} }}"), "f"));
        assert!(e.contains("is not a rate in Hz above 0"), "{rate}: {e}");
    }
    assert!(parse_rate("1e-300").is_err() && parse_rate("100Hz").is_ok());
    assert!(parse_period("0ms").is_err() && parse_span("0ms").is_ok());
}

#[test]
fn peers_are_ipv4_addresses_or_host_names_that_resolve() {
    for ok in ["192.0.2.1", "127.0.0.1:7410", "localhost", "localhost:7412", " 10.0.0.2 "] {
        assert_eq!(parse_peer(ok).ok().as_deref(), Some(ok.trim()), "{ok}");
    }
    let refused = [
        ("\u{1}\u{ff}%%garbage", "not an IPv4 address or a host name"),
        ("", "not an IPv4 address or a host name"),
        ("a\"/><Peer address=\"x", "not an IPv4 address or a host name"),
        ("h<x>&", "not an IPv4 address or a host name"),
        ("-a.example", "not an IPv4 address or a host name"),
        ("::1", "IPv6 peers are not supported"),
        ("[::1]:7400", "IPv6 peers are not supported"),
        ("127.0.0.1:0", "is not a port"),
        ("127.0.0.1:99999", "is not a port"),
        ("nosuchhost.invalid", "does not resolve"),
    ];
    for (bad, why) in refused {
        let e = err(parse_peer(bad).map_err(ConfigError::from));
        assert!(e.contains(why), "{bad:?}: {e}");
    }
    // In the file: at the element, naming the file.
    let e = err(parse("{ peer: [\"127.0.0.1\",\n \"\\u0001garbage\"] }", "gw.json5"));
    assert!(e.starts_with("gw.json5:2:2: peer '\\u{1}garbage': not an IPv4 address"), "{e}");
}

#[test]
fn ros_topic_names_are_checked() {
    for ok in ["a", "a/b", "/a/b_2", "_x/y"] {
        assert_eq!(parse_topic_name(ok).ok().as_deref(), Some(ok));
    }
    for bad in ["", "/", "a/", "a//b", "a/2b", "~/a", "{node}/a", "a-b", "a b"] {
        assert!(parse_topic_name(bad).is_err(), "{bad}");
    }
}

#[test]
fn without_rules_every_set_is_bridged_as_the_table_says() {
    let p = resolved("product-sample.ddf", "{}").unwrap();
    assert!(p.left_out.is_empty());
    let keys: Vec<&str> = p.sets.iter().map(|s| s.key.as_str()).collect();
    assert_eq!(keys, ["grid_feeder/publish", "grid_feeder/subscribe", "grid_clock/publish", "grid_clock/subscribe"]);
    let s = &p.sets[0];
    assert_eq!((s.topic.as_str(), s.ros2_topic.as_str()), ("rt/grid_feeder/publish", "/grid_feeder/publish"));
    let o = opts("product-sample.ddf", "{}").unwrap();
    let d = &o.model.domains[0];
    assert_eq!(s.writer_qos, mapping::qos(d.flags, Profile::Ros2, Endpoint::Writer, 0));
    assert_eq!(s.reader_qos, mapping::qos(d.flags, Profile::Ros2, Endpoint::Reader, 0));
}

#[test]
fn allow_and_deny_select_sets_and_say_why_one_is_left_out() {
    let p = resolved(
        "product-sample.ddf",
        r#"{ allow: ["grid_feeder/.*", "grid_clock/publish"], deny: [".*/subscribe"] }"#,
    )
    .unwrap();
    let keys: Vec<&str> = p.sets.iter().map(|s| s.key.as_str()).collect();
    assert_eq!(keys, ["grid_feeder/publish", "grid_clock/publish"]);
    let out: Vec<(&str, &str)> = p.left_out.iter().map(|l| (l.key.as_str(), l.reason.as_str())).collect();
    assert_eq!(
        out,
        [
            ("grid_feeder/subscribe", "matches deny pattern '.*/subscribe'"),
            ("grid_clock/subscribe", "matches deny pattern '.*/subscribe'"),
        ]
    );
    // Patterns match the whole key: `grid` alone matches nothing.
    let p = resolved("product-sample.ddf", r#"{ allow: ["grid"] }"#).unwrap();
    assert!(p.sets.is_empty());
    assert_eq!(p.left_out[0].reason, "matches no allow pattern ('grid')");
}

#[test]
fn namespace_and_remapping_name_the_topics() {
    let cfg = r#"{ ros_namespace: "sim1", topics: {
        "grid_feeder/publish": { remap: "feeder/cmd" },
        "grid_clock/publish": { remap: "/plant/clock_out" } } }"#;
    let p = resolved("product-sample.ddf", cfg).unwrap();
    let names: Vec<(&str, &str)> = p.sets.iter().map(|s| (s.topic.as_str(), s.ros2_topic.as_str())).collect();
    assert_eq!(
        names,
        [
            ("rt/sim1/feeder/cmd", "/sim1/feeder/cmd"),
            ("rt/sim1/grid_feeder/subscribe", "/sim1/grid_feeder/subscribe"),
            ("rt/plant/clock_out", "/plant/clock_out"),
            ("rt/sim1/grid_clock/subscribe", "/sim1/grid_clock/subscribe"),
        ]
    );
    let o = opts("product-sample.ddf", cfg).unwrap();
    assert_eq!(o.engine_config().node_namespace, "/sim1");
    let items = item_topics(&o, &p.sets[0]);
    assert!(items.iter().all(|t| t.topic.starts_with("rt/sim1/feeder/cmd/")), "{items:?}");
}

#[test]
fn overrides_apply_to_writer_and_reader_and_rates_are_copied() {
    let cfg = r#"{ topics: { "grid_feeder/subscribe": {
        qos: { reliability: "reliable", history: "keep_last", depth: 5 }, max_rate: 20 },
        "grid_clock/publish": { qos: { durability: "transient_local", history: "keep_all" } } } }"#;
    let p = resolved("product-sample.ddf", cfg).unwrap();
    let s = &p.sets[1];
    assert_eq!(s.max_rate, Some(20.0));
    for q in [s.writer_qos, s.reader_qos] {
        assert_eq!((q.reliability, q.history), (Reliability::Reliable, History::KeepLast(5)));
    }
    // states=yes: the writer's transient-local depth follows the overridden history.
    assert_eq!(s.writer_qos.durability, Durability::TransientLocal { depth: 5 });
    assert_eq!(s.reader_qos.durability, Durability::Volatile);
    let c = &p.sets[2];
    for q in [c.writer_qos, c.reader_qos] {
        assert_eq!((q.history, q.durability), (History::KeepAll, Durability::TransientLocal { depth: 1 }));
    }
    assert_eq!(p.sets[0].max_rate, None);
}

#[test]
fn what_the_flags_forbid_is_refused_naming_the_key_and_the_flag() {
    let t = |key: &str, entry: &str| format!(r#"{{ topics: {{ "{key}": {entry} }} }}"#);
    let cases = [
        (t("grid_clock/publish", r#"{ qos: { reliability: "best_effort" } }"#), "topics.\"grid_clock/publish\".qos.reliability: best_effort is refused: domain 'grid_clock' has synchronous=yes"),
        (t("grid_clock/subscribe", r#"{ qos: { history: "keep_last" } }"#), "topics.\"grid_clock/subscribe\".qos.history: keep_last is refused: domain 'grid_clock' has synchronous=yes"),
        (t("grid_clock/publish", r#"{ max_rate: 10 }"#), "topics.\"grid_clock/publish\".max_rate: a rate limit is refused: domain 'grid_clock' has synchronous=yes"),
        (t("grid_feeder/publish", r#"{ qos: { durability: "volatile" } }"#), "topics.\"grid_feeder/publish\".qos.durability: volatile is refused: domain 'grid_feeder' has states=yes"),
        (t("grid_feeder/publish", r#"{ qos: { depth: 3 } }"#), "topics.\"grid_feeder/publish\".qos.depth: depth needs history \"keep_last\""),
        (t("grid_feeder/publish", r#"{ qos: { history: "keep_all", depth: 3 } }"#), "topics.\"grid_feeder/publish\".qos.depth: depth needs history \"keep_last\""),
        (t("grid_feeder/publish", r#"{ qos: { history: "keep_last", depth: 0 } }"#), "0 is not a depth of 1 or more"),
        (t("grid_feeder/publsh", "{}"), "topics.\"grid_feeder/publsh\": the DDF has no set 'grid_feeder/publsh' (sets: grid_feeder/publish, grid_feeder/subscribe, grid_clock/publish, grid_clock/subscribe)"),
    ];
    for (cfg, want) in cases {
        let e = err(resolved("product-sample.ddf", &cfg));
        assert!(e.starts_with("gw.json5") && e.contains(want), "{cfg}\n{e}");
    }
    // Lock-step's own terms, and best-effort or keep-last on an asynchronous set, are fine.
    let fine = t("grid_clock/publish", r#"{ qos: { reliability: "reliable", history: "keep_all" } }"#);
    resolved("product-sample.ddf", &fine).unwrap();
    resolved("product-sample.ddf", &t("grid_feeder/publish", r#"{ qos: { reliability: "best_effort" } }"#)).unwrap();
}

#[test]
fn two_sets_on_one_topic_are_refused_naming_the_remap() {
    let both = r#"{ topics: { "grid_clock/publish": { remap: "/x" }, "grid_feeder/publish": { remap: "/x" } } }"#;
    let e = err(resolved("product-sample.ddf", both));
    assert!(
        e.contains("topics.\"grid_clock/publish\".remap: '/x' is also the topic of set 'grid_feeder/publish'"),
        "{e}"
    );
    // A remap onto another set's own name blames the remap, whichever comes first.
    let onto = r#"{ topics: { "grid_feeder/publish": { remap: "grid_clock/publish" } } }"#;
    let e = err(resolved("product-sample.ddf", onto));
    assert!(
        e.contains(
            "topics.\"grid_feeder/publish\".remap: '/grid_clock/publish' is also the topic of set 'grid_clock/publish'"
        ),
        "{e}"
    );
    let clock = r#"{ topics: { "grid_feeder/publish": { remap: "/clock" } } }"#;
    assert!(err(resolved("product-sample.ddf", clock)).contains("the gateway's /clock"));
    resolved("product-sample.ddf", &clock.replace("{ topics", "{ clock: \"none\", topics")).unwrap();
}

#[test]
fn flags_win_over_the_file_and_the_file_over_defaults() {
    let file = parse(r#"{ ros_domain_id: 7, strength: 3, timeout: "2s", allow: ["x"] }"#, "gw.json5").unwrap();
    let mut flags = ConfigFile::default();
    (flags.engine.ros_domain_id, flags.gateway.poll) = (Some(9), Some(Duration::from_millis(1)));
    let m = flags.over(file);
    let g = &m.gateway;
    assert_eq!((m.engine.ros_domain_id, g.strength, g.timeout), (Some(9), Some(3), Some(Duration::from_secs(2))));
    assert_eq!(
        (g.poll, m.plan.allow.as_deref(), m.source.as_deref()),
        (Some(Duration::from_millis(1)), Some(&["x".to_string()][..]), Some("gw.json5"))
    );
    let mut o = opts("product-sample.ddf", "{}").unwrap();
    let before = o.wait;
    m.apply(&mut o).unwrap();
    assert_eq!((o.ros_domain_id, o.wait), (9, before), "a key nobody gave keeps its default");
}

#[test]
fn the_participant_announces_the_lease_but_never_less_than_the_floor() {
    let lease = |cfg: &str| opts("product-sample.ddf", cfg).unwrap().engine_config().participant_lease;
    assert_eq!(lease("{}"), Some(MIN_PARTICIPANT_LEASE), "the default lease (1 s) is below the floor");
    assert_eq!(lease(r#"{ lease: "5s" }"#), Some(Duration::from_secs(5)));
    assert_eq!(lease(r#"{ lease: "10ms" }"#), Some(MIN_PARTICIPANT_LEASE));
}

#[test]
fn ros_discovery_variables() {
    use DiscoveryRange::*;
    assert_eq!(discovery_range(None, None).unwrap(), Default);
    assert_eq!(discovery_range(Some("1"), Some("SUBNET")).unwrap(), Localhost);
    assert_eq!(discovery_range(Some("0"), Some("LOCALHOST")).unwrap(), Localhost);
    assert_eq!(discovery_range(None, Some("OFF")).unwrap(), Off);
    assert_eq!(discovery_range(None, Some("SYSTEM_DEFAULT")).unwrap(), Default);
    assert!(err(discovery_range(None, Some("LAN")).map_err(ConfigError::from))
        .contains("ROS_AUTOMATIC_DISCOVERY_RANGE='LAN'"));
}

/// `examples/gateway.json5` stays valid for the DDF it is written for.
#[test]
fn the_example_config_loads_and_resolves() {
    let path = repo("ddf/multiuav.ddf");
    let mut o = GatewayOptions::new(&path, tutti_core::ddf::load(&path).unwrap());
    let cfg = load(&repo("examples/gateway.json5")).unwrap();
    cfg.apply(&mut o).unwrap();
    let p = resolve(&o).unwrap();
    assert!(
        !p.sets.is_empty() && !p.left_out.is_empty() && p.sets.iter().any(|s| s.ros2_topic != format!("/{}", s.key))
    );
}

/// Every key is documented in docs/gateway.md.
#[test]
fn every_key_is_documented() {
    let doc = std::fs::read_to_string(repo("docs/gateway.md")).unwrap();
    for k in KEYS {
        assert!(doc.contains(&format!("`{k}`")), "docs/gateway.md does not mention `{k}`");
    }
    for k in KEYS {
        let e = err(parse("{ nope: 1 }", "f"));
        assert!(e.contains(&format!("`{k}`")), "KEYS lists `{k}`, the parser does not: {e}");
    }
}

/// `KEYS` (the file's keys as the docs list them) is exactly the sections' keys, each owned by
/// one section.
#[test]
fn the_files_keys_are_the_sections_keys() {
    use tutti_config::sections::Section;
    let owned: Vec<&str> = [
        EngineKeys::KEYS,
        GatewayKeys::KEYS,
        PlanKeys::KEYS,
        crate::foxglove::FoxgloveKeys::KEYS,
        crate::http::HttpKeys::KEYS,
        super::entities::EntityKeys::KEYS,
    ]
    .concat();
    let mut a = owned.clone();
    a.sort_unstable();
    a.dedup();
    assert_eq!(a.len(), owned.len(), "a key owned twice: {owned:?}");
    let mut b = KEYS.to_vec();
    b.sort_unstable();
    assert_eq!(a, b);
}

#[test]
fn a_lookahead_is_a_number_of_steps_for_every_synchronous_domain_or_one_per_domain() {
    let o = opts("multiuav.ddf", "{ lookahead: 10 }").unwrap();
    assert_eq!((o.lookahead.of("multiuav_uav1"), o.lookahead.of("anything")), (10, 10));
    let o = opts("multiuav.ddf", "{ lookahead: { multiuav_uav1: 40 } }").unwrap();
    assert_eq!((o.lookahead.of("multiuav_uav1"), o.lookahead.of("multiuav_uav2")), (40, 0));
    o.lookahead.check(&o.model, TypeMode::Typed).unwrap();
    // Flags over the file: `--lookahead 3 --lookahead multiuav_uav2=5` over the file's 40.
    let flags = parse_lookahead("3").unwrap().over(Lookahead::default());
    let flags = parse_lookahead("multiuav_uav2=5").unwrap().over(flags);
    let l = flags.over(o.lookahead.clone());
    assert_eq!((l.of("multiuav_uav1"), l.of("multiuav_uav2"), l.of("x")), (40, 5, 3));
    for bad in ["-1", "1.5", "100001", "x", "=3", "d=", "d=-2"] {
        assert!(err(parse_lookahead(bad)).contains("is not a lookahead"), "{bad}");
    }
    for (cfg, want) in [
        ("{ lookahead: -1 }", "-1 is not a number of steps"),
        ("{ lookahead: 2.5 }", "2.5 is not a number of steps"),
        ("{ lookahead: \"10\" }", "a number of steps"),
        ("{ lookahead: { a: \"x\" } }", "a number of steps"),
        ("{ lookahead: { a: 1, a: 2 } }", "domain 'a' is given twice"),
    ] {
        let e = err(opts("multiuav.ddf", cfg));
        assert!(e.contains(want) && e.contains("gw.json5:1:"), "{cfg}: {e}");
    }
}

#[test]
fn a_lookahead_is_refused_for_a_domain_that_cannot_have_one_naming_it() {
    let model = |ddf: &str| tutti_core::ddf::load(repo(&format!("ddf/{ddf}"))).unwrap();
    let check = |ddf: &str, l: &str, types: TypeMode| {
        err(parse_lookahead(l).unwrap().check(&model(ddf), types).map(|()| "accepted"))
    };
    let e = check("multiuav.ddf", "nosuch=3", TypeMode::Typed);
    assert!(e.contains("'nosuch'") && e.contains("no such domain") && e.contains("multiuav_uav1"), "{e}");
    let e = check("multiuav.ddf", "2", TypeMode::PerItem);
    assert!(e.contains("per-item topics carry no step"), "{e}");
    let asynchronous = model("product-sample.ddf").domains.iter().find(|d| !d.flags.synchronous).unwrap().name.clone();
    let e = check("product-sample.ddf", &format!("{asynchronous}=1"), TypeMode::Typed);
    assert!(e.contains(&asynchronous) && e.contains("asynchronous"), "{e}");
    // 0 is lock-step: allowed anywhere.
    parse_lookahead("0").unwrap().check(&model("multiuav.ddf"), TypeMode::PerItem).unwrap();
}

/// A UAV of ddf/multiuav.ddf as an entity, with `extra` keys in its `geodetic` block (or in
/// the entry, after a comma).
fn uav_entity(geodetic_items: &str, entry: &str) -> String {
    format!(
        "{{\n  entities: [\n    {{ name: \"uav1\", category: \"robot\", domain: \"multiuav_uav1\", set: \"subscribe\",{entry}\n      \
         geodetic: {{ origin: [45.0, 7.0, 0], {geodetic_items} }} }},\n  ],\n}}"
    )
}

const UAV_ITEMS: &str = r#"latitude: "Latitude", longitude: "Longitude", altitude: "Elevation", heading: "Heading""#;

fn entities_of(text: &str) -> Result<ConfigFile, ConfigError> {
    let model = tutti_core::ddf::load(repo("ddf/multiuav.ddf")).unwrap();
    with_model(&model, || parse(text, "gw.json5"))
}

#[test]
fn entities_are_read_and_checked_against_the_ddf() {
    let text = uav_entity(&format!("{UAV_ITEMS}, speed: \"Airspeed\""), " tags: [\"air\"],");
    let c = entities_of(&text).unwrap();
    let e = &c.entities.entities.as_ref().unwrap()[0];
    assert_eq!(
        (e.name.as_str(), e.category, e.frame.as_str(), e.role),
        ("uav1", 1, "world", tutti_core::ddf::Role::Subscribe)
    );
    assert!(matches!(&e.form, Form::Geodetic { speed: Some(s), .. } if s == "Airspeed"));
    let mut o = opts("multiuav.ddf", &text).unwrap();
    c.apply(&mut o).unwrap();
    resolve(&o).unwrap();
    assert_eq!(o.entities.len(), 1);
}

/// Each mistake names the file, the entity's line and column, the entity and what is wrong.
#[test]
fn entity_mistakes_are_refused_where_they_stand() {
    let cases = [
        (uav_entity(UAV_ITEMS, "").replace("multiuav_uav1", "uav9"), "the DDF has no domain 'uav9'"),
        (uav_entity(&UAV_ITEMS.replace("\"Heading\"", "\"Bearing\""), ""), "no subscribe item 'Bearing' (its heading"),
        (uav_entity(UAV_ITEMS, "").replace("subscribe", "both"), "set 'both': use publish or subscribe"),
        (uav_entity(UAV_ITEMS, " category: \"plane\","), "duplicate field `category`"),
        (uav_entity(UAV_ITEMS, "").replace("\"robot\"", "\"plane\""), "category 'plane': use one of object, robot"),
        (uav_entity(UAV_ITEMS, "").replace("origin: [45.0", "origin: [95.0"), "a latitude within ±90°"),
        (uav_entity("latitude: \"Latitude\"", ""), "missing field `longitude`"),
        (uav_entity(UAV_ITEMS, " cartesian: { x: \"a\", y: \"b\", z: \"c\" },"), "not both"),
        (uav_entity(UAV_ITEMS, "").replace("\"uav1\"", "\"uav 1\""), "entity 'uav 1'"),
    ];
    for (text, why) in cases {
        let e = err(entities_of(&text));
        assert!(e.contains(why), "{e}\n{text}");
        assert!(e.starts_with("gw.json5:3:") || e.starts_with("gw.json5:4:"), "placed at the entity: {e}\n{text}");
    }
    // Items that are not one number: a boolean, an array.
    let ddf = r#"<orchestra><domain name="d"><synchronous>no</synchronous><multiplePublishAllowed>yes</multiplePublishAllowed><states>no</states>
      <set name="SUBSCRIBE"><item name="on"><type>boolean</type></item><item name="xy"><type>float64</type><length>2</length></item>
      <item name="z"><type>float64</type></item></set></domain></orchestra>"#;
    let model = tutti_core::ddf::parse_str(ddf, "d.ddf").unwrap();
    for (x, ty) in [("on", "is boolean, not one number"), ("xy", "is an array of 2 float64, not one number")] {
        let text = format!(
            "{{ entities: [ {{ name: \"b\", domain: \"d\", set: \"subscribe\", cartesian: {{ x: \"{x}\", y: \"z\", z: \"z\" }} }} ] }}"
        );
        let e = err(with_model(&model, || parse(&text, "gw.json5")));
        assert!(e.starts_with("gw.json5:1:") && e.contains(&format!("item '{x}' of domain 'd' (x) {ty}")), "{e}");
    }
    // Checked again without a DDF in scope, when the options are resolved (named by key).
    let text = uav_entity(UAV_ITEMS, "").replace("multiuav_uav1", "uav9");
    let e = err(resolved("multiuav.ddf", &text));
    assert!(e.starts_with("gw.json5: entities: entity 'uav1': the DDF has no domain 'uav9'"), "{e}");
    let twice = text.replace("uav9", "multiuav_uav1").replace("  ],", &format!("    {},\n  ],", "{ name: \"uav1\", domain: \"multiuav_uav2\", set: \"subscribe\", geodetic: { origin: [0,0,0], latitude: \"Latitude\", longitude: \"Longitude\", altitude: \"Elevation\", heading: \"Heading\" } }"));
    assert!(err(resolved("multiuav.ddf", &twice)).contains("entity 'uav1' is declared twice"));
}
