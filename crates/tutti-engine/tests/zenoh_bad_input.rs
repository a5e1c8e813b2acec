//! The Zenoh engine under bad input from the network: samples without rmw_zenoh's attachment
//! or with a malformed one, and liveliness tokens that are not rmw_zenoh's, sent by a raw Zenoh
//! session. Each is dropped and counted ([`Zenoh::bad_input_by_kind`], and in all `Engine::bad_input`), none reaches a sink or the
//! graph, nothing panics, and a good sample after them still arrives.
#![cfg(feature = "zenoh")]

use std::sync::{Arc, Mutex};
use std::time::Duration;

use ::zenoh::Wait;
use tutti_core::mapping::{Durability, History, Ownership, Qos, Reliability};
use tutti_engine::cdr::HEADER_LE;
use tutti_engine::rmw_zenoh::{Attachment, DataKey, TopicInfo};
use tutti_engine::zenoh::Zenoh;
use tutti_engine::{Data, Decode, Engine, EngineConfig, TopicType};
use tutti_test_support::{wait_for, ZenohRouter};

#[test]
fn bad_samples_and_tokens_are_counted_and_dropped() {
    let router = ZenohRouter::start();
    let cfg = EngineConfig {
        domain_id: 7,
        node_name: "bad_input".into(),
        node_namespace: "/".into(),
        zenoh_connect: vec![router.endpoint().to_string()],
        zenoh_listen: vec!["tcp/127.0.0.1:0".into()],
        ..EngineConfig::default()
    };
    let engine = Zenoh::open(&cfg).expect("a Zenoh engine");
    let q = Qos {
        reliability: Reliability::Reliable,
        history: History::KeepLast(10),
        durability: Durability::Volatile,
        ownership: Ownership::Shared,
        lifespan: None,
    };
    let ty = TopicType::plain("bad::msg::dds_::Input_");
    let got = Arc::new(Mutex::new(Vec::<Vec<u8>>::new()));
    let into = got.clone();
    let sink = Arc::new(move |_, d: Data<'_>| {
        if let Data::Raw(raw) = d {
            into.lock().unwrap().push(raw.to_vec());
        }
    });
    engine.reader("/bad/input", &ty, &q, Decode::Raw, sink).unwrap();
    let topic = TopicInfo {
        name: "/bad/input".into(),
        type_name: ty.name.clone(),
        type_hash: format!("RIHS01_{}", "0".repeat(64)),
        qos: tutti_engine::zenoh::profile(&q),
    };
    let key = DataKey::for_topic(7, &topic).to_keyexpr().unwrap();
    let raw = router.session();
    let publisher = raw.declare_publisher(key).wait().unwrap();
    let good = [&HEADER_LE[..], &42u64.to_le_bytes()].concat();
    let attachment = Attachment { sequence_number: 1, source_timestamp: 1, source_gid: [7; 16] }.encode();

    // Bad tokens in the domain's graph.
    let mut tokens = Vec::new();
    for bad in
        ["@ros2_lv/7/zz/0/0/NN/%/%/n", "@ros2_lv/7/1f/0/1/XX/%/%/n", "@ros2_lv/7/1f/0/1/MP/%/%/n/%t/T_/H/nonsense"]
    {
        tokens.push(raw.liveliness().declare_token(bad).wait().unwrap());
    }
    // Until the good one arrives: one without an attachment, one with a truncated one.
    wait_for("the good sample after the bad ones", Duration::from_secs(30), || {
        publisher.put(good.clone()).wait().unwrap();
        publisher.put(good.clone()).attachment(attachment[..20].to_vec()).wait().unwrap();
        publisher.put(good.clone()).attachment(attachment.to_vec()).wait().unwrap();
        std::thread::sleep(Duration::from_millis(50));
        (!got.lock().unwrap().is_empty()).then_some(())
    });
    let (attachments, bad_tokens) = wait_for("the bad tokens counted", Duration::from_secs(30), || {
        let (a, t) = engine.bad_input_by_kind();
        (t >= 3).then_some((a, t))
    });
    assert!(attachments >= 2, "both bad samples of the first round counted: {attachments}");
    assert_eq!(bad_tokens, 3, "each bad token once");
    assert!(Engine::bad_input(&engine) >= attachments + bad_tokens, "the engine's total for the gateway's stats");
    assert!(got.lock().unwrap().iter().all(|s| *s == good), "only good samples reach the sink");
    assert!(engine.remote().writers.is_empty(), "no bad token in the graph");
}
