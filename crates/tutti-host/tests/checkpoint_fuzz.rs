//! Property tests of the checkpoint reader on untrusted input, as the MCAP, DDF and config
//! readers are fuzzed: a real checkpoint's bytes mutated (bytes flipped or set, cut short,
//! slices deleted or duplicated, pieces of the format spliced in), and its manifest mutated
//! and zipped again (so that the reader gets past the archive's CRC to the JSON and the
//! offsets). Whatever the input, the reader returns (no panic), and what it accepts reads
//! back from its own bytes as the same checkpoint.
//!
//! `PROPTEST_CASES=N` runs more cases than the default 256 per property.

use std::io::Write;
use std::path::Path;

use proptest::prelude::*;
use tutti_host::checkpoint::{Checkpoint, ComponentState, DomainState, Skipped};
use tutti_test_support::mutate::{apply_all, Mutation};

fn sample() -> Checkpoint {
    Checkpoint {
        ddf: "cosim.ddf".into(),
        step_seconds: 0.01,
        next_index: 500,
        steps: 500,
        domains: vec![
            DomainState {
                name: "plant".into(),
                layout_hash: 0x0123_4567_89ab_cdef,
                publish: (0..16).collect(),
                subscribe: (16..24).collect(),
                last_publish: Some((0..16).rev().collect()),
                seeded: true,
                due: vec![("c".into(), 501)],
            },
            DomainState {
                name: "ctrl".into(),
                layout_hash: 7,
                publish: vec![],
                subscribe: vec![1; 8],
                last_publish: None,
                seeded: false,
                due: vec![],
            },
        ],
        components: vec![ComponentState {
            domain: "plant".into(),
            name: "c".into(),
            state: vec![9; 40],
            remote: false,
        }],
        skipped: vec![Skipped { domain: "ctrl".into(), name: "s".into(), why: "stateless".into() }],
    }
}

const PIECES: [&str; 12] =
    ["{", "}", "[", "]", ",", ":", "\"", "18446744073709551615", "-1", "1e308", "\"version\": 2", "null"];

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

/// A zip of `manifest` and `data`, stored, as the writer makes them.
fn zipped(manifest: &[u8], data: &[u8]) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    let mut zip = zip::ZipWriter::new(&mut out);
    let opts = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    zip.start_file("manifest.json", opts).unwrap();
    zip.write_all(manifest).unwrap();
    zip.start_file("data.bin", opts).unwrap();
    zip.write_all(data).unwrap();
    zip.finish().unwrap();
    out.into_inner()
}

/// The sample's manifest and data.bin, as its file holds them.
fn parts() -> (Vec<u8>, Vec<u8>) {
    let bytes = sample().to_bytes();
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
    let mut read = |name: &str| {
        let mut v = Vec::new();
        std::io::Read::read_to_end(&mut zip.by_name(name).unwrap(), &mut v).unwrap();
        v
    };
    (read("manifest.json"), read("data.bin"))
}

/// Reads `bytes`; what is accepted must read back the same from its own bytes.
fn holds(bytes: &[u8]) {
    if let Ok(c) = Checkpoint::from_bytes(bytes, Path::new("fuzzed")) {
        let again = Checkpoint::from_bytes(&c.to_bytes(), Path::new("again")).expect("its own bytes");
        assert_eq!(again, c);
    }
}

proptest! {
    #[test]
    fn a_mutated_file_is_read_or_refused(edits in proptest::collection::vec(mutation(), 1..6)) {
        let mut bytes = sample().to_bytes();
        apply_all(&mut bytes, &edits);
        holds(&bytes);
    }

    #[test]
    fn a_mutated_manifest_is_read_or_refused(edits in proptest::collection::vec(mutation(), 1..6)) {
        let (mut manifest, data) = parts();
        apply_all(&mut manifest, &edits);
        holds(&zipped(&manifest, &data));
    }
}

#[test]
fn the_sample_reads_back_and_an_unknown_version_is_named() {
    let c = sample();
    assert_eq!(Checkpoint::from_bytes(&c.to_bytes(), Path::new("c")).unwrap(), c);
    let (manifest, data) = parts();
    let text = String::from_utf8(manifest).unwrap().replace("\"version\": 1", "\"version\": 9");
    let e = Checkpoint::from_bytes(&zipped(text.as_bytes(), &data), Path::new("c")).unwrap_err();
    assert!(e.to_string().contains("version 9"), "{e}");
    let e = Checkpoint::from_bytes(b"not a zip", Path::new("c")).unwrap_err();
    assert!(e.to_string().contains("not a tutti checkpoint"), "{e}");
}
