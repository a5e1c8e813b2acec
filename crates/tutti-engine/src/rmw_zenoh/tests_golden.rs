//! Golden vectors: keys and bytes exactly as rmw_zenoh_cpp 0.2.10 writes them.
//!
//! The token keys follow `Entity`'s constructor
//! (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:449-484`: fields in `KeyexprIndex` order,
//! `mangle_name` on enclave, namespace, node name, topic, type and hash, `qos_to_keyexpr` at
//! `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:290-351` for the QoS of the profile adapted by
//! `rmw_zenoh_cpp/src/detail/qos.cpp:78-151`). Their GIDs were printed by rmw_zenoh's own
//! `rmw_zenoh_cpp/src/detail/simplified_xxhash3.cpp` compiled with g++ on x86-64 (16 bytes:
//! `low64` then `high64`, as `rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:489-493` copies
//! them). The session id and type hashes are examples: the format takes them as they are.

use super::liveliness::{Entity, EntityKind, NodeInfo, TopicInfo};
use super::qos::{Durability, History, Liveliness, QosProfile, Reliability, RmwDuration};
use super::{Attachment, DataKey};

const ZID: &str = "1b4a8e2f9c3d5e6f7a8b9c0d1e2f3a4b";
const STRING_HASH: &str = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";
const ADD_TWO_INTS_HASH: &str = "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a";

fn gid(hex: &str) -> [u8; 16] {
    tutti_test_support::unhex(hex).try_into().expect("16 bytes")
}

fn entity(domain_id: u64, ids: (u64, u64), node: (&str, &str, &str), kind: EntityKind) -> Entity {
    let (namespace, name, enclave) = node;
    Entity {
        zid: ZID.parse().expect("zid"),
        node_id: ids.0,
        entity_id: ids.1,
        node: NodeInfo { domain_id, namespace: namespace.into(), name: name.into(), enclave: enclave.into() },
        kind,
    }
}

fn topic(name: &str, type_name: &str, type_hash: &str, qos: QosProfile) -> TopicInfo {
    TopicInfo { name: name.into(), type_name: type_name.into(), type_hash: type_hash.into(), qos }
}

/// One golden case: the entity, its key, its GID (hex) and, but for nodes, its data key.
type Case = (Entity, String, &'static str, Option<String>);

fn cases() -> Vec<Case> {
    let d = QosProfile::ZENOH_DEFAULT;
    let (string, add) = ("std_msgs::msg::dds_::String_", "example_interfaces::srv::dds_::AddTwoInts_");
    // demo_nodes_cpp's talker: rclcpp's default profile with depth 7, adapted.
    let talker = topic("/chatter", string, STRING_HASH, QosProfile { depth: 7, ..d });
    // Best effort, transient local, keep last 10, deadline 1 s 500 ns, manual by topic with
    // a lease of 2 s 0 ns: every field but the lifespan written.
    let listener = QosProfile {
        reliability: Reliability::BestEffort,
        durability: Durability::TransientLocal,
        depth: 10,
        deadline: RmwDuration { sec: 1, nsec: 500 },
        liveliness: Liveliness::ManualByTopic,
        liveliness_lease_duration: RmwDuration { sec: 2, nsec: 0 },
        ..d
    };
    let listener = topic("/demo/chatter", string, STRING_HASH, listener);
    // rclcpp's services profile (keep last 10), adapted.
    let server = topic("/add_two_ints", add, ADD_TWO_INTS_HASH, QosProfile { depth: 10, ..d });
    // KEEP_ALL with depth 0: adapted to depth 42, rmw_zenoh's default, so written empty.
    let client = topic("/add_two_ints", add, ADD_TWO_INTS_HASH, QosProfile { history: History::KeepAll, ..d });
    let (talker_node, root) = (("/", "talker", "/"), "@ros2_lv/0/1b4a8e2f9c3d5e6f7a8b9c0d1e2f3a4b");
    vec![
        (
            entity(0, (0, 0), talker_node, EntityKind::Node),
            format!("{root}/0/0/NN/%/%/talker"),
            "86e0db60c26a8c470444d53557414fa7",
            None,
        ),
        (
            entity(0, (0, 10), talker_node, EntityKind::Publisher(talker)),
            format!("{root}/0/10/MP/%/%/talker/%chatter/{string}/{STRING_HASH}/::,7:,:,:,,"),
            "d77b96476a7c3a6a23df3d5ad6a35e3c",
            Some(format!("0/chatter/{string}/{STRING_HASH}")),
        ),
        (
            entity(7, (3, 4), ("/demo", "listener", "/"), EntityKind::Subscription(listener)),
            format!(
                "@ros2_lv/7/{ZID}/3/4/MS/%/%demo/listener/%demo%chatter/{string}/{STRING_HASH}/2:1:,10:1,500:,:3,2,0"
            ),
            "db646bd9c26bea3f912319e6e28ae782",
            Some(format!("7/demo/chatter/{string}/{STRING_HASH}")),
        ),
        (
            entity(0, (5, 6), ("/", "add_two_ints_server", "/"), EntityKind::Service(server)),
            format!("{root}/5/6/SS/%/%/add_two_ints_server/%add_two_ints/{add}/{ADD_TWO_INTS_HASH}/::,10:,:,:,,"),
            "9f7ce9529e197e3f81d990162e492ce8",
            Some(format!("0/add_two_ints/{add}/{ADD_TWO_INTS_HASH}")),
        ),
        (
            entity(0, (8, 9), ("/", "add_two_ints_client", "/my/enclave"), EntityKind::Client(client)),
            format!(
                "{root}/8/9/SC/%my%enclave/%/add_two_ints_client/%add_two_ints/{add}/{ADD_TWO_INTS_HASH}/::2,:,:,:,,"
            ),
            "c32185f8a9f5ece1cf1e326b61f05344",
            Some(format!("0/add_two_ints/{add}/{ADD_TWO_INTS_HASH}")),
        ),
    ]
}

#[test]
fn token_keys_gids_and_data_keys_are_rmw_zenohs() {
    for (entity, key, gid_hex, data_key) in cases() {
        assert_eq!(entity.to_key().as_deref(), Ok(key.as_str()));
        assert_eq!(Entity::parse(&key).as_ref(), Ok(&entity), "{key}");
        assert_eq!(entity.gid(), Ok(gid(gid_hex)), "{key}");
        let written = entity.data_key().map(|k| k.to_keyexpr().expect("valid data key"));
        assert_eq!(written, data_key, "{key}");
        if let Some(data_key) = data_key {
            assert_eq!(DataKey::parse(&data_key).ok(), entity.data_key());
        }
    }
}

#[test]
fn client_qos_is_adapted_as_rmw_zenoh_adapts_it() {
    // The client's profile as the application gave it: KEEP_ALL, depth 0, unspecified times.
    let given = QosProfile {
        history: History::KeepAll,
        depth: 0,
        deadline: RmwDuration::UNSPECIFIED,
        lifespan: RmwDuration::UNSPECIFIED,
        liveliness: Liveliness::SystemDefault,
        liveliness_lease_duration: RmwDuration::UNSPECIFIED,
        ..QosProfile::ZENOH_DEFAULT
    };
    assert_eq!(given.adapted().map(|q| q.to_keyexpr()).as_deref(), Ok("::2,:,:,:,,"));
}

/// The publisher's first sample: sequence number 1, sent at 1700000000.123456789 s, with the
/// publisher's GID above. zenoh-ext writes each `int64_t` as 8 little-endian bytes (`impl_num!`,
/// `to_le_bytes`), the `std::array<uint8_t, 16>` as a sequence: its length as LEB128
/// (`VarInt<usize>`: 0x10), then each byte (zenoh-cpp `serialization.hxx`,
/// `__serialize_sequence_with_serializer`; zenoh-c `ze_serializer_serialize_sequence_length`,
/// `ze_serializer_serialize_int64`, `ze_serializer_serialize_uint8`).
#[test]
fn attachment_bytes_are_rmw_zenohs() {
    #[rustfmt::skip]
    let bytes: [u8; 33] = [
        0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x15, 0xcd, 0x85, 0x3d, 0xfe, 0x9c, 0x97, 0x17,
        0x10,
        0xd7, 0x7b, 0x96, 0x47, 0x6a, 0x7c, 0x3a, 0x6a, 0x23, 0xdf, 0x3d, 0x5a, 0xd6, 0xa3, 0x5e, 0x3c,
    ];
    let attachment = Attachment {
        sequence_number: 1,
        source_timestamp: 1_700_000_000_123_456_789,
        source_gid: gid("d77b96476a7c3a6a23df3d5ad6a35e3c"),
    };
    assert_eq!(attachment.encode(), bytes);
    assert_eq!(Attachment::decode(&bytes), Ok(attachment));
}
