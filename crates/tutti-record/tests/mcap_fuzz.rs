//! Property tests of the MCAP reader of `tutti replay` on damaged files: a small valid
//! recording, mutated (bytes flipped or set, cut short, 64-bit and 32-bit fields set to huge
//! values, slices deleted or duplicated), is read back with `Recording::read`. Whatever the
//! input, it returns (no panic, no abort, no hang), and an error names the file, and the byte
//! offset when the file is damaged.
//!
//! The cases run in this process: an abort (a huge allocation, a stack overflow) kills the
//! test binary, which fails the test too. `TUTTI_FUZZ_CASES=N` runs N cases per property
//! instead of the default 256 (`docs/recording.md`).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use proptest::prelude::*;
use tutti_record::replay::Recording;
use tutti_record::RecordError;
use tutti_test_support::mutate::{apply_all, Mutation};

/// Longest any single case may take, including a debug build on a loaded machine.
const CASE_TIMEOUT: Duration = Duration::from_secs(20);

/// Cases per property: `TUTTI_FUZZ_CASES`, else 256.
fn cases() -> u32 {
    std::env::var("TUTTI_FUZZ_CASES").ok().and_then(|v| v.trim().parse().ok()).unwrap_or(256)
}

/// The valid recording the cases start from: two domains of the product sample, a few steps.
fn sample() -> &'static [u8] {
    static SAMPLE: OnceLock<Vec<u8>> = OnceLock::new();
    SAMPLE.get_or_init(|| {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let ddf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../ddf/product-sample.ddf");
        let model = tutti_core::ddf::load(&ddf).expect("the sample DDF");
        let path = dir.path().join("sample.mcap");
        let mut rec = tutti_record::create(&path, &model, &ddf).expect("a recorder");
        let sets: Vec<(Vec<u8>, Vec<u8>)> = model
            .domains
            .iter()
            .map(|d| (d.publish.layout.default_bytes(), d.subscribe.layout.default_bytes()))
            .collect();
        for k in 1..=6u64 {
            for (i, (p, s)) in sets.iter().enumerate() {
                let step = tutti_record::Step {
                    step: k,
                    sim_time: k as f64 * 0.1,
                    wall_ns: 1_000 + k,
                    elapsed_s: 0.0,
                    connections: (k % 3) as u32,
                    owner_pid: None,
                    publish: p,
                    subscribe: s,
                };
                rec.step(i, &step).expect("a step");
            }
        }
        rec.finish().expect("the recording finished");
        let bytes = std::fs::read(&path).expect("the recording");
        assert!(Recording::read(&path).is_ok(), "the unmutated sample must read back");
        bytes
    })
}

/// A scratch file per case (removed with the directory).
fn scratch() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().expect("a temporary directory")).path()
}

/// Reads `bytes` as a recording on a worker thread, so that a hang fails the test instead of
/// blocking it and a panic is reported as such; checks what an error says.
fn read_with_watchdog(bytes: Vec<u8>) {
    static CASE: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = CASE.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let path: PathBuf = scratch().join(format!("case-{n}.mcap"));
    std::fs::write(&path, &bytes).expect("writing the case");
    let p = path.clone();
    let result = tutti_test_support::within("Recording::read", CASE_TIMEOUT, move || Recording::read(&p).map(|_| ()));
    let _ = std::fs::remove_file(&path);
    if let Err(e) = result {
        let shown = e.to_string();
        assert!(shown.contains(&format!("case-{n}.mcap")), "the error does not name the file: {shown}");
        assert!(!shown.is_empty());
        if let RecordError::Mcap { .. } = e {
            assert!(shown.contains("at byte "), "a damaged file's error has no offset: {shown}");
        }
    }
}

fn huge_u64() -> impl Strategy<Value = u64> {
    prop_oneof![
        Just(u64::MAX),
        Just(u64::MAX - 8),
        Just(1 << 63),
        Just(u64::from(u32::MAX)),
        Just(1 << 40),
        Just(1 << 28),
        Just(0),
        0..100_000u64,
        any::<u64>(),
    ]
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = any::<usize>();
    prop_oneof![
        (at, 1..=255u8).prop_map(|(at, mask)| Mutation::Flip { at, mask }),
        (at, any::<u8>()).prop_map(|(at, byte)| Mutation::Set { at, byte }),
        at.prop_map(|at| Mutation::Truncate { at }),
        // A little-endian u64 or u32 written at `at` (a record, chunk, string or data length).
        (at, huge_u64()).prop_map(|(at, value)| Mutation::Overwrite { at, bytes: value.to_le_bytes().into() }),
        (at, prop_oneof![Just(u32::MAX), Just(1 << 31), any::<u32>()])
            .prop_map(|(at, value)| Mutation::Overwrite { at, bytes: value.to_le_bytes().into() }),
        (at, 1..64usize).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (at, 1..128usize).prop_map(|(at, len)| Mutation::Duplicate { at, len }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn a_mutated_recording_reads_or_fails_cleanly(edits in proptest::collection::vec(mutation(), 1..6)) {
        let mut bytes = sample().to_vec();
        apply_all(&mut bytes, &edits);
        read_with_watchdog(bytes);
    }

    /// Every length field the recording has, wherever it is: a huge value at each offset.
    #[test]
    fn a_huge_value_at_any_offset_is_refused_cleanly(at in any::<usize>(), value in huge_u64()) {
        let mut bytes = sample().to_vec();
        Mutation::Overwrite { at, bytes: value.to_le_bytes().into() }.apply(&mut bytes);
        read_with_watchdog(bytes);
    }

    #[test]
    fn every_prefix_of_the_recording_is_refused_cleanly(cut in any::<usize>()) {
        let bytes = sample();
        read_with_watchdog(bytes[..cut % bytes.len()].to_vec());
    }

    #[test]
    fn arbitrary_bytes_after_the_magic_never_panic(tail in proptest::collection::vec(any::<u8>(), 0..512)) {
        let mut bytes = sample()[..8].to_vec();
        bytes.extend(tail);
        read_with_watchdog(bytes);
    }
}

/// The exact case of the first report: a record length of 0xffffffffffffffff (the header
/// record's, right after the magic) and a chunk that states an exabyte-sized content.
#[test]
fn the_reported_inputs_are_errors_at_their_offsets() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = sample().to_vec();
    bytes[9..17].copy_from_slice(&u64::MAX.to_le_bytes());
    let path = dir.path().join("huge-record.mcap");
    std::fs::write(&path, &bytes).unwrap();
    let e = Recording::read(&path).unwrap_err().to_string();
    assert!(e.contains("huge-record.mcap: at byte 8: a header record") && e.contains("18446744073709551615"), "{e}");

    // Every chunk's uncompressed size (the 17th byte of its body) set to 0xffff…
    let mut bytes = sample().to_vec();
    let chunk = first_chunk(&bytes);
    bytes[chunk + 9 + 16..chunk + 9 + 24].copy_from_slice(&u64::MAX.to_le_bytes());
    let path = dir.path().join("huge-chunk.mcap");
    std::fs::write(&path, &bytes).unwrap();
    let e = Recording::read(&path).unwrap_err().to_string();
    assert!(
        e.contains(&format!("huge-chunk.mcap: at byte {chunk}: a chunk says it holds 18446744073709551615")),
        "{e}"
    );
}

/// The offset of the first chunk record, walking the records from the magic.
fn first_chunk(bytes: &[u8]) -> usize {
    let mut at = 8;
    while bytes[at] != 0x06 {
        at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    at
}
