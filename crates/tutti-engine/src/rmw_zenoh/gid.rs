//! An entity's GID: the XXH3-128 hash of its liveliness token key
//! (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:486-493`), low 64 bits then high 64 bits, each
//! in the host's byte order (`memcpy` of `uint64_t`: little-endian on every platform ROS 2 Jazzy
//! supports).
//!
//! The hash is rmw_zenoh's `simplified_XXH3_128bits`
//! (`rmw_zenoh_cpp/src/detail/simplified_xxhash3.cpp`): xxHash's XXH3 128-bit with the default
//! secret and seed 0, scalar path only, which is XXH3-128 as the `xxhash-rust` crate computes
//! it (the tests compare the two on every length up to 2,100 bytes). A parsed entity's GID is the
//! hash of the key rmw_zenoh rebuilds from the parsed fields
//! (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:611-618` goes through the same constructor),
//! which [`crate::rmw_zenoh::Entity::gid`] does too.

/// A GID as rmw_zenoh fills `rmw_gid_t.data` (`RMW_GID_STORAGE_SIZE`, 16 bytes).
pub type Gid = [u8; 16];

/// The GID of a liveliness token key (`rmw_zenoh_cpp/src/detail/liveliness_utils.cpp:489-493`).
pub fn gid_of_key(key: &str) -> Gid {
    let (low, high) = xxh3_128(key.as_bytes());
    let mut gid = [0u8; 16];
    gid[..8].copy_from_slice(&low.to_le_bytes());
    gid[8..].copy_from_slice(&high.to_le_bytes());
    gid
}

/// XXH3-128 of `input` as `(low64, high64)` (`simplified_XXH3_128bits`: xxHash's XXH3 128-bit
/// with the default secret and seed 0, which the `xxhash-rust` crate computes; the tests hold
/// it to vectors of rmw_zenoh's own C++).
pub fn xxh3_128(input: &[u8]) -> (u64, u64) {
    let h = xxhash_rust::xxh3::xxh3_128(input);
    (h as u64, (h >> 64) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    // Vectors from rmw_zenoh_cpp 0.2.10's own rmw_zenoh_cpp/src/detail/simplified_xxhash3.cpp, compiled with g++ and
    // run on x86-64 (a throwaway program printing simplified_XXH3_128bits of each input;
    // not kept in the tree).
    #[test]
    fn matches_rmw_zenoh_for_short_inputs() {
        let cases: [(&str, u64, u64); 9] = [
            ("", 0x6001c324468d497f, 0x99aa06d3014798d8),
            ("a", 0xe6c632b61e964e1f, 0xa96faf705af16834),
            ("ab", 0xa873719c24d5735c, 0x89c65ebc828eebac),
            ("abc", 0x78af5f94892f3950, 0x06b05ab6733a6185),
            ("abcd", 0x1be79eecd1b1353d, 0x8d6b60383dfa90c2),
            ("abcdefgh", 0x42b702b313880f12, 0xdac23237af373533),
            ("abcdefghi", 0xc0646b2d7986db98, 0xb43ff5bc5ff2e0ad),
            ("abcdefghijklmnop", 0x3e8e153ff12f6330, 0x1f58fc809b1b8c4b),
            ("abcdefghijklmnopq", 0xc3acc9940596efab, 0x11078c38a5ca3a8d),
        ];
        for (input, low, high) in cases {
            assert_eq!(xxh3_128(input.as_bytes()), (low, high), "{input:?}");
        }
    }

    /// The same program hashed `input[i] = (i * 31 + 7) & 0xff` for every length 0..=2100 (every
    /// path, block boundaries at 1024 and 2048 included), folding the halves as `fold = fold *
    /// 0x100000001b3 ^ half`; these are its printed results.
    #[test]
    fn matches_rmw_zenoh_for_every_length_to_2100() {
        let input: Vec<u8> = (0..=2100usize).map(|i| ((i * 31 + 7) & 0xff) as u8).collect();
        let spot: [(usize, u64, u64); 8] = [
            (3, 0x15f7093b173d005c, 0x46f66cb935381565),
            (17, 0x78c349fe81b2f26c, 0x18217300b5132d5a),
            (129, 0xc51bc887976aef63, 0x6881633650cd8924),
            (240, 0x93e173833f75ab66, 0xde57aab31e77a2ff),
            (241, 0x0b3b630948ce4a00, 0x92b991a7192f3f08),
            (1024, 0x23bc880ebf0d29c6, 0x4c17271c906df792),
            (1025, 0xc09fdfbc398c7d82, 0x70a4eb1b9691d77f),
            (2100, 0xa2c1945e463bdc29, 0x89220ad81bd18738),
        ];
        for (len, low, high) in spot {
            assert_eq!(xxh3_128(&input[..len]), (low, high), "length {len}");
        }
        let (mut fold_lo, mut fold_hi) = (0u64, 0u64);
        for len in 0..=2100 {
            let (low, high) = xxh3_128(&input[..len]);
            fold_lo = fold_lo.wrapping_mul(0x100000001b3) ^ low;
            fold_hi = fold_hi.wrapping_mul(0x100000001b3) ^ high;
        }
        assert_eq!((fold_lo, fold_hi), (0xbd19969e39e882de, 0x6f3a7e827cbebd39));
    }

    #[test]
    fn gid_is_low_then_high_little_endian() {
        // The empty key, as the same program printed its 16 GID bytes.
        let gid = gid_of_key("");
        assert_eq!(
            gid,
            [0x7f, 0x49, 0x8d, 0x46, 0x24, 0xc3, 0x01, 0x60, 0xd8, 0x98, 0x47, 0x01, 0xd3, 0x06, 0xaa, 0x99]
        );
    }
}
