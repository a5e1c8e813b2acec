//! Property tests: every value survives its encoder and parser, and no input, however malformed,
//! makes a parser panic.

use proptest::prelude::*;

use super::liveliness::{Entity, EntityKind, NodeInfo, TopicInfo};
use super::qos::{Durability, History, Liveliness, QosProfile, Reliability, RmwDuration};
use super::{xxh3_128, Attachment, DataKey, ZenohId};

fn fqn() -> impl Strategy<Value = String> {
    prop::collection::vec("[a-z_][a-z0-9_]{0,7}", 1..4).prop_map(|chunks| format!("/{}", chunks.join("/")))
}

fn namespace() -> impl Strategy<Value = String> {
    prop_oneof![Just("/".to_owned()), fqn()]
}

fn type_name() -> impl Strategy<Value = String> {
    ("[a-z_]{1,8}", prop_oneof![Just("msg"), Just("srv"), Just("action")], "[A-Z][A-Za-z0-9]{0,8}")
        .prop_map(|(pkg, dir, name)| format!("{pkg}::{dir}::dds_::{name}_"))
}

fn type_hash() -> impl Strategy<Value = String> {
    "RIHS01_[0-9a-f]{64}"
}

fn duration() -> impl Strategy<Value = RmwDuration> {
    prop_oneof![
        Just(RmwDuration::INFINITE),
        Just(RmwDuration::UNSPECIFIED),
        (any::<u64>(), any::<u64>()).prop_map(|(sec, nsec)| RmwDuration { sec, nsec })
    ]
}

fn qos() -> impl Strategy<Value = QosProfile> {
    (
        prop::sample::select(Reliability::ALL),
        prop::sample::select(Durability::ALL),
        prop::sample::select(History::ALL),
        prop_oneof![Just(42u64), any::<u64>()],
        (duration(), duration(), duration()),
        prop::sample::select(Liveliness::ALL),
    )
        .prop_map(|(reliability, durability, history, depth, (deadline, lifespan, lease), liveliness)| {
            QosProfile {
                reliability,
                durability,
                history,
                depth,
                deadline,
                lifespan,
                liveliness,
                liveliness_lease_duration: lease,
            }
        })
}

fn topic() -> impl Strategy<Value = TopicInfo> {
    (fqn(), type_name(), type_hash(), qos()).prop_map(|(name, type_name, type_hash, qos)| TopicInfo {
        name,
        type_name,
        type_hash,
        qos,
    })
}

fn kind() -> impl Strategy<Value = EntityKind> {
    prop_oneof![
        Just(EntityKind::Node),
        topic().prop_map(EntityKind::Publisher),
        topic().prop_map(EntityKind::Subscription),
        topic().prop_map(EntityKind::Service),
        topic().prop_map(EntityKind::Client),
    ]
}

fn entity() -> impl Strategy<Value = Entity> {
    let zid = any::<u128>().prop_filter_map("a zid is never zero", |n| ZenohId::from_le_bytes(n.to_le_bytes()));
    let node = (any::<u64>(), namespace(), "[a-z_][a-z0-9_]{0,10}", namespace())
        .prop_map(|(domain_id, namespace, name, enclave)| NodeInfo { domain_id, namespace, name, enclave });
    (zid, any::<u64>(), any::<u64>(), node, kind()).prop_map(|(zid, node_id, entity_id, node, kind)| Entity {
        zid,
        node_id,
        entity_id,
        node,
        kind,
    })
}

/// Token-like strings: the admin space or not, then up to 14 short fields of the characters that
/// matter to the parser.
fn token_like() -> impl Strategy<Value = String> {
    (prop_oneof![Just("@ros2_lv"), Just("@ros2"), Just("")], prop::collection::vec("[0-9a-fNMPSC%:,_*-]{0,6}", 0..15))
        .prop_map(|(head, fields)| fields.iter().fold(head.to_owned(), |key, f| format!("{key}/{f}")))
}

proptest! {
    #[test]
    fn entities_round_trip(e in entity()) {
        let key = e.to_key().expect("a valid entity has a key");
        prop_assert_eq!(Entity::parse(&key), Ok(e.clone()));
        prop_assert_eq!(e.gid(), Ok(super::gid_of_key(&key)));
    }

    #[test]
    fn qos_round_trips(q in qos()) {
        prop_assert_eq!(QosProfile::from_keyexpr(&q.to_keyexpr()), Ok(q));
    }

    #[test]
    fn attachments_round_trip(seq in any::<i64>(), time in any::<i64>(), gid in any::<[u8; 16]>()) {
        let a = Attachment { sequence_number: seq, source_timestamp: time, source_gid: gid };
        prop_assert_eq!(Attachment::decode(&a.encode()), Ok(a));
    }

    #[test]
    fn data_keys_round_trip(domain_id in any::<u64>(), name in fqn(), type_name in type_name(), hash in type_hash()) {
        let type_hash = hash;
        let k = DataKey { domain_id, name, type_name, type_hash };
        let text = k.to_keyexpr().expect("a valid key");
        prop_assert_eq!(DataKey::parse(&text), Ok(k));
    }

    #[test]
    fn token_parser_never_panics(key in prop_oneof![any::<String>(), token_like()]) {
        if let Ok(e) = Entity::parse(&key) {
            if let Ok(rewritten) = e.to_key() {
                prop_assert_eq!(Entity::parse(&rewritten), Ok(e));
            }
        }
    }

    #[test]
    fn qos_parser_never_panics(text in prop_oneof![any::<String>(), "[0-9:,x+ -]{0,40}"]) {
        if let Ok(q) = QosProfile::from_keyexpr(&text) {
            prop_assert_eq!(QosProfile::from_keyexpr(&q.to_keyexpr()), Ok(q));
        }
    }

    #[test]
    fn data_key_parser_never_panics(key in prop_oneof![any::<String>(), "[0-9a-z/:_*]{0,30}"]) {
        if let Ok(k) = DataKey::parse(&key) {
            let text = k.to_keyexpr().expect("a parsed key is valid");
            prop_assert_eq!(DataKey::parse(&text), Ok(k));
        }
    }

    #[test]
    fn attachment_parser_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..64)) {
        if let Ok(a) = Attachment::decode(&bytes) {
            prop_assert_eq!(Attachment::decode(&a.encode()), Ok(a));
        }
        let _ = Attachment::decode_prefix(&bytes);
    }

    #[test]
    fn hash_takes_any_input(bytes in prop::collection::vec(any::<u8>(), 0..3000)) {
        let _ = xxh3_128(&bytes);
    }
}
