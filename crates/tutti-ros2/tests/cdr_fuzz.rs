//! Hostile CDR: whatever the bytes, decoding any message of the registry returns a value or an
//! error, never panics, and never allocates for a count the bytes cannot hold; what decodes
//! encodes back to the same bytes' value.

mod common;

use proptest::prelude::*;
use tutti_ros2::registry;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256), le in any::<bool>()) {
        for msg in registry().messages() {
            if let Ok(v) = msg.decode(&bytes, le) {
                let again = msg.encode(&v).expect("a decoded value encodes");
                // Compared as printed: a NaN decoded is a NaN again, but never equal to itself.
                let back = msg.decode(&again, true).map(|b| format!("{b:?}"));
                prop_assert_eq!(back, Ok(format!("{v:?}")));
            }
        }
    }

    #[test]
    fn damaged_samples_never_panic(
        which in any::<prop::sample::Index>(),
        seed in 0u64..4,
        damage in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
        le in any::<bool>(),
    ) {
        let messages: Vec<_> = registry().messages().collect();
        let msg = messages[which.index(messages.len())];
        let mut body = msg.encode(&common::sample(msg, seed)).expect("a sample encodes");
        for (at, byte) in damage {
            let i = at.index(body.len());
            body[i] = byte;
        }
        body.truncate(cut.index(body.len() + 1));
        let _ = msg.decode(&body, le);
    }
}
