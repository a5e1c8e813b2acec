//! tutti's rmw_zenoh format (`tutti_engine::rmw_zenoh`) judged by Zenoh's own Python binding
//! (`eclipse-zenoh`, in the `.venv` that launch-scripts/test.sh makes), code nobody here wrote:
//!
//! * an attachment's bytes are what zenoh-ext's serializer writes for (int64, int64, 16 bytes),
//!   which is how rmw_zenoh's `AttachmentData::serialize_to_zbytes` serializes the sequence
//!   number, the source timestamp and the GID; and what Zenoh writes, tutti reads back;
//! * every liveliness token key and data key the module writes is a Zenoh key expression in
//!   canonical form (Zenoh refuses anything else), and the key rmw_zenoh subscribes to for a
//!   domain's graph matches every token of that domain and none of another.
//!
//! Without the binding the test is skipped with a message (a failure under `CI=true`).

use std::process::Command;
use std::time::Duration;

use serde_json::{json, Value};
use tutti_engine::rmw_zenoh::liveliness::subscription_key;
use tutti_engine::rmw_zenoh::qos::{Durability, History, Reliability};
use tutti_engine::rmw_zenoh::{Attachment, DataKey, Entity, EntityKind, NodeInfo, QosProfile, TopicInfo};
use tutti_test_support::{hex, unhex};

/// What the Python side does with the JSON of its first argument; prints JSON.
const JUDGE: &str = r#"
import json, sys
import zenoh
from zenoh.ext import z_serialize, z_deserialize, Int64

case = json.loads(sys.argv[1])
out = {"attachments": [], "ours": [], "keys": [], "matches": []}
for seq, ts, gid in case["attachments"]:
    out["attachments"].append(z_serialize((Int64(seq), Int64(ts), bytes.fromhex(gid))).to_bytes().hex())
for ours in case["ours"]:
    seq, ts, gid = z_deserialize(tuple[Int64, Int64, bytes], zenoh.ZBytes(bytes.fromhex(ours)))
    out["ours"].append([int(seq), int(ts), gid.hex()])
for key in case["keys"]:
    try:
        out["keys"].append(str(zenoh.KeyExpr(key)))
    except Exception as e:
        out["keys"].append("refused: " + str(e))
for sub, key in case["matches"]:
    out["matches"].append(zenoh.KeyExpr(sub).intersects(zenoh.KeyExpr(key)))
print(json.dumps(out))
"#;

const ZID: &str = "1b4a8e2f9c3d5e6f7a8b9c0d1e2f3a4b";
const HASH: &str = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";

/// Entities of every kind, with plain and nested names, enclaves and QoS profiles.
fn entities() -> Vec<Entity> {
    let d = QosProfile::ZENOH_DEFAULT;
    let topic = |name: &str, type_name: &str, qos| TopicInfo {
        name: name.into(),
        type_name: type_name.into(),
        type_hash: HASH.into(),
        qos,
    };
    let state = "tutti_msgs::msg::dds_::UavState_";
    let kinds = [
        EntityKind::Node,
        EntityKind::Publisher(topic("/uav1/state", state, QosProfile { depth: 7, ..d })),
        EntityKind::Subscription(topic(
            "/uav1/set_point",
            "std_msgs::msg::dds_::Float64_",
            QosProfile { reliability: Reliability::BestEffort, durability: Durability::TransientLocal, ..d },
        )),
        EntityKind::Service(topic(
            "/sim/step_simulation",
            "simulation_interfaces::srv::dds_::StepSimulation_",
            QosProfile { depth: 10, ..d },
        )),
        EntityKind::Client(topic(
            "/sim/get_simulation_state",
            "simulation_interfaces::srv::dds_::GetSimulationState_",
            QosProfile { history: History::KeepAll, ..d },
        )),
        EntityKind::Publisher(topic("/clock", "rosgraph_msgs::msg::dds_::Clock_", d)),
    ];
    let nodes = [("/", "tutti_gateway", "/"), ("/multiuav", "tutti_gateway", "/tutti/enclave")];
    let mut out = Vec::new();
    for (n, (namespace, name, enclave)) in nodes.iter().enumerate() {
        for (i, kind) in kinds.iter().enumerate() {
            out.push(Entity {
                zid: ZID.parse().expect("a session id"),
                node_id: n as u64,
                entity_id: i as u64 + 1,
                node: NodeInfo {
                    domain_id: 7 * n as u64,
                    namespace: (*namespace).into(),
                    name: (*name).into(),
                    enclave: (*enclave).into(),
                },
                kind: kind.clone(),
            });
        }
    }
    out
}

/// Attachments across the ranges: zero, small, negative, extreme, and varied GIDs.
fn attachments() -> Vec<Attachment> {
    let gid = |seed: u8| std::array::from_fn(|i| seed.wrapping_mul(31).wrapping_add(i as u8 * 17));
    [(0, 0, 0), (1, 1_700_000_000_123_456_789, 1), (-1, -5, 2), (i64::MAX, i64::MIN, 3), (42, 1, 255)]
        .into_iter()
        .map(|(sequence_number, source_timestamp, seed)| Attachment {
            sequence_number,
            source_timestamp,
            source_gid: gid(seed),
        })
        .collect()
}

/// Runs the judge on `case` with `py`; its JSON answer.
fn judge(py: &std::path::Path, case: &Value) -> Value {
    let mut cmd = Command::new(py);
    cmd.args(["-c", JUDGE, &case.to_string()]);
    let (status, out, err) = tutti_test_support::run_with_timeout(cmd, Duration::from_secs(120));
    assert!(status.success(), "the Python judge failed: {err}");
    serde_json::from_str(&out).expect("the judge's JSON")
}

#[test]
fn zenohs_python_binding_writes_and_reads_the_attachments_and_accepts_the_keys() {
    let Some(py) = tutti_test_support::python(&["zenoh"]) else { return };
    let attachments = attachments();
    let entities = entities();
    let mut keys: Vec<String> = Vec::new();
    let mut matches = Vec::new();
    for e in &entities {
        let token = e.to_key().expect("a token key");
        let domain = e.node.domain_id;
        matches.push(json!([subscription_key(domain), token]));
        matches.push(json!([subscription_key(domain + 1), token]));
        keys.push(token);
        if let Some(data) = e.data_key() {
            keys.push(data.to_keyexpr().expect("a data key"));
        }
    }
    let case = json!({
        "attachments": attachments.iter().map(|a| json!([a.sequence_number, a.source_timestamp, hex(&a.source_gid)]))
            .collect::<Vec<_>>(),
        "ours": attachments.iter().map(|a| hex(&a.encode())).collect::<Vec<_>>(),
        "keys": keys,
        "matches": matches,
    });
    let answer = judge(&py, &case);

    for (i, a) in attachments.iter().enumerate() {
        let zenohs = answer["attachments"][i].as_str().expect("bytes");
        assert_eq!(hex(&a.encode()), zenohs, "attachment {a:?}: ours, then zenoh-ext's");
        assert_eq!(Attachment::decode(&unhex(zenohs)).as_ref(), Ok(a), "zenoh-ext's bytes read back");
        let read = &answer["ours"][i];
        assert_eq!(read, &json!([a.sequence_number, a.source_timestamp, hex(&a.source_gid)]), "ours read by zenoh-ext");
    }
    for (i, key) in keys.iter().enumerate() {
        assert_eq!(answer["keys"][i].as_str(), Some(key.as_str()), "Zenoh's canonical form of {key}");
        if let Ok(data) = DataKey::parse(key) {
            assert_eq!(data.to_keyexpr().as_deref(), Ok(key.as_str()), "{key} read back");
        }
    }
    for (i, pair) in matches.iter().enumerate() {
        // Even entries: the token's own domain; odd: the next domain.
        let expected = i % 2 == 0;
        assert_eq!(answer["matches"][i].as_bool(), Some(expected), "{pair} intersects: {expected}");
    }
}
