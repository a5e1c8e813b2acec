//! Property tests of the rmw_zenoh parsers on untrusted input, as the DDF and config readers
//! are fuzzed: what a real rmw_zenoh_cpp 0.2.10 node wrote (liveliness tokens, data keys and
//! attachments, captured from an rclpy node and `ros2 topic pub` on rmw_zenoh through
//! `rmw_zenohd`), mutated (bytes flipped, cut short, slices duplicated or deleted, the format's
//! separators spliced in). Whatever the input, the token, key, QoS and attachment parsers
//! return (no panic), and what they accept is written back to what they read.
//!
//! `PROPTEST_CASES=N` runs more cases than the default 256 per property.

use proptest::prelude::*;
use tutti_engine::rmw_zenoh::{Attachment, DataKey, Entity, QosProfile};
use tutti_test_support::mutate::{apply_all, Mutation};

/// Tokens of a real rclpy node (`/sim1/talker`: a publisher, a TRANSIENT_LOCAL `/clock`, a
/// best-effort subscription, a service and a client) and of ros2cli's node, as rmw_zenoh_cpp
/// 0.2.10 declared them.
const TOKENS: [&str; 9] = [
    "@ros2_lv/7/bd0ac4f054f8b876c9aff9a7d9b94077/0/0/NN/%/%sim1/talker",
    "@ros2_lv/7/8cc49e54c175ea73577a5e0a20435161/0/0/NN/%/%/_ros2cli_24534",
    "@ros2_lv/7/bd0ac4f054f8b876c9aff9a7d9b94077/0/10/MP/%/%sim1/talker/%sim1%chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18/::,10:,:,:,,",
    "@ros2_lv/7/bd0ac4f054f8b876c9aff9a7d9b94077/0/11/MP/%/%sim1/talker/%clock/rosgraph_msgs::msg::dds_::Clock_/RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564/:1:,1:,:,:,,",
    "@ros2_lv/7/bd0ac4f054f8b876c9aff9a7d9b94077/0/12/MS/%/%sim1/talker/%sim1%in%put/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18/2::,5:,:,:,,",
    "@ros2_lv/7/bd0ac4f054f8b876c9aff9a7d9b94077/0/13/SS/%/%sim1/talker/%sim1%get_simulation_state/simulation_interfaces::srv::dds_::GetSimulationState_/RIHS01_3362dcebee4b1afebbf9c4beee5c79c1455385aded62092a892d61fde8644f30/::,10:,:,:,,",
    "@ros2_lv/7/bd0ac4f054f8b876c9aff9a7d9b94077/0/14/SC/%/%sim1/talker/%other%get_simulation_state/simulation_interfaces::srv::dds_::GetSimulationState_/RIHS01_3362dcebee4b1afebbf9c4beee5c79c1455385aded62092a892d61fde8644f30/::,10:,:,:,,",
    "@ros2_lv/7/bd0ac4f054f8b876c9aff9a7d9b94077/0/1/MP/%/%sim1/talker/%rosout/rcl_interfaces::msg::dds_::Log_/RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac/:1:,1000:,:10,0:,,",
    "@ros2_lv/7/8cc49e54c175ea73577a5e0a20435161/0/4/MP/%/%/_ros2cli_24534/%sim1%chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18/::,10:,:,:,,",
];

/// The data key of `ros2 topic pub /sim1/chatter` in ROS domain 7.
const DATA_KEY: &str =
    "7/sim1/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";

/// Three consecutive attachments of its samples (sequence number, source timestamp, GID).
const ATTACHMENTS: [&str; 3] = [
    "240000000000000084576573443eec18108ff9865254bb08b2c9b9566c8631d03e",
    "2500000000000000fb685e76443eec18108ff9865254bb08b2c9b9566c8631d03e",
    "2600000000000000bfe35879443eec18108ff9865254bb08b2c9b9566c8631d03e",
];

/// Fragments of the format, spliced in to reach the parsers' deeper paths.
const PIECES: [&str; 14] =
    ["/", "%", "::", ",", ":", "@ros2_lv", "NN", "MP", "SC", "RIHS01_", "/%/%", "dds_::", "18446744073709551615", "-1"];

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex")).collect()
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = any::<usize>();
    prop_oneof![
        (at, 1..=255u8).prop_map(|(at, mask)| Mutation::Flip { at, mask }),
        (at, any::<u8>()).prop_map(|(at, byte)| Mutation::Set { at, byte }),
        at.prop_map(|at| Mutation::Truncate { at }),
        (at, 1..40usize).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (at, 1..80usize).prop_map(|(at, len)| Mutation::Duplicate { at, len }),
        (at, 0..PIECES.len()).prop_map(|(at, piece)| Mutation::Insert { at, bytes: PIECES[piece].into() }),
    ]
}

fn mutated(seed: &str, edits: &[Mutation]) -> String {
    let mut bytes = seed.as_bytes().to_vec();
    apply_all(&mut bytes, edits);
    String::from_utf8_lossy(&bytes).into_owned()
}

/// A token read is written back to the same entity; its QoS field, read alone, too.
fn check_token(key: &str) -> Result<(), TestCaseError> {
    if let Ok(e) = Entity::parse(key) {
        if let Ok(rewritten) = e.to_key() {
            prop_assert_eq!(Entity::parse(&rewritten), Ok(e));
        }
    }
    if let Some(qos) = key.rsplit('/').next() {
        if let Ok(q) = QosProfile::from_keyexpr(qos) {
            prop_assert_eq!(QosProfile::from_keyexpr(&q.to_keyexpr()), Ok(q));
        }
    }
    Ok(())
}

#[test]
fn the_captured_samples_are_read() {
    for t in TOKENS {
        let e = Entity::parse(t).unwrap_or_else(|e| panic!("{t}: {e}"));
        assert_eq!(e.to_key().as_deref(), Ok(t), "written back as rmw_zenoh wrote it");
    }
    let k = DataKey::parse(DATA_KEY).expect("the data key");
    assert_eq!(k.to_keyexpr().as_deref(), Ok(DATA_KEY));
    let seqs: Vec<i64> =
        ATTACHMENTS.iter().map(|a| Attachment::decode(&unhex(a)).expect("an attachment").sequence_number).collect();
    assert_eq!(seqs, [36, 37, 38]);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn mutated_tokens_never_panic(seed in 0..TOKENS.len(), edits in prop::collection::vec(mutation(), 1..6)) {
        check_token(&mutated(TOKENS[seed], &edits))?;
    }

    #[test]
    fn every_prefix_of_a_token_is_handled(seed in 0..TOKENS.len(), cut in any::<usize>()) {
        let t = TOKENS[seed];
        check_token(&t[..cut % (t.len() + 1)])?;
    }

    #[test]
    fn mutated_data_keys_never_panic(edits in prop::collection::vec(mutation(), 1..6)) {
        if let Ok(k) = DataKey::parse(&mutated(DATA_KEY, &edits)) {
            let text = k.to_keyexpr().expect("a parsed key is valid");
            prop_assert_eq!(DataKey::parse(&text), Ok(k));
        }
    }

    #[test]
    fn mutated_attachments_never_panic(seed in 0..ATTACHMENTS.len(), edits in prop::collection::vec(mutation(), 1..4)) {
        let mut bytes = unhex(ATTACHMENTS[seed]);
        apply_all(&mut bytes, &edits);
        if let Ok(a) = Attachment::decode(&bytes) {
            prop_assert_eq!(Attachment::decode(&a.encode()), Ok(a));
        }
        let _ = Attachment::decode_prefix(&bytes);
    }
}
