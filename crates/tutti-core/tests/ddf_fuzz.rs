//! Property tests of the DDF reader on untrusted input: arbitrary bytes, and the committed
//! samples mutated (bytes flipped, cut short, slices duplicated or deleted, XML tokens
//! spliced in). Whatever the input, `parse_bytes` returns (no panic, no hang), an error
//! carries at least one diagnostic at a position inside the file, and a success is a model
//! whose layouts are self-consistent.
//!
//! `PROPTEST_CASES=N` runs more cases than the default 256 per property.

use std::time::Duration;

use proptest::prelude::*;
use tutti_core::ddf::{self, DdfError, Model};
use tutti_test_support::mutate::{apply_all, Mutation};

const SAMPLES: [&[u8]; 3] = [
    include_bytes!("../../../ddf/paper-figure2.ddf"),
    include_bytes!("../../../ddf/product-sample.ddf"),
    include_bytes!("../../../ddf/multiuav.ddf"),
];

/// Fragments that are likely to reach deep parser and validator paths when spliced in.
const TOKENS: [&str; 24] = [
    "<item name=\"x\">",
    "</item>",
    "<type>bus</type>",
    "<type>int8</type>",
    "<length>65535</length>",
    "<length>0</length>",
    "<default>300</default>",
    "<default>yes</default>",
    "<set name=\"PUBLISH\">",
    "</set>",
    "<domain name=\"d\">",
    "</domain>",
    "<block name=\"d/Subscribe\">",
    "<!--",
    "-->",
    "<![CDATA[",
    "]]>",
    "&amp;",
    "&#0;",
    "&#x1F600;",
    "<?xml version=\"1.0\"?>",
    "<!DOCTYPE a>",
    "\u{feff}",
    "é\u{200b}",
];

/// Longest any single case may take, including a debug build on a loaded machine.
const CASE_TIMEOUT: Duration = Duration::from_secs(10);

/// Parses on a worker thread so a hang fails the test instead of blocking it, and a panic
/// is reported as such.
fn parse_with_watchdog(bytes: Vec<u8>) -> Result<Model, DdfError> {
    let (result, bytes) = tutti_test_support::within("parse_bytes", CASE_TIMEOUT, move || {
        let result = ddf::parse_bytes(&bytes, "fuzz.ddf");
        (result, bytes)
    });
    check(&bytes, &result);
    result
}

/// Invariants of a result, whatever the input.
fn check(bytes: &[u8], result: &Result<Model, DdfError>) {
    match result {
        Err(e) => {
            let diags = e.diagnostics();
            assert!(!diags.is_empty(), "an error without diagnostics: {e}");
            let lines = bytes.iter().filter(|&&b| b == b'\n').count() as u32 + 1;
            for d in diags {
                assert!(d.pos.line >= 1 && d.pos.col >= 1, "position {:?} is not 1-based", d.pos);
                assert!(d.pos.line <= lines, "line {} past the end ({lines} lines)", d.pos.line);
                assert!(!d.message.is_empty());
                assert!(!d.message.contains('\n'), "a diagnostic spans lines: {:?}", d.message);
            }
        }
        Ok(model) => {
            assert!(!model.domains.is_empty());
            for d in &model.domains {
                assert_eq!(d.layout_hash, d.compute_layout_hash());
                for set in [&d.publish, &d.subscribe] {
                    let l = &set.layout;
                    assert!(l.align.is_power_of_two() && l.size % l.align == 0);
                    for leaf in &l.leaves {
                        assert_eq!(leaf.offset % leaf.ty.size(), 0, "{} misaligned", leaf.path);
                        assert!(leaf.offset + leaf.size <= l.size, "{} past the end of its set", leaf.path);
                    }
                }
            }
        }
    }
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = any::<usize>();
    prop_oneof![
        (at, 1..=255u8).prop_map(|(at, mask)| Mutation::Flip { at, mask }),
        (at, any::<u8>()).prop_map(|(at, byte)| Mutation::Set { at, byte }),
        at.prop_map(|at| Mutation::Truncate { at }),
        (at, 1..200usize).prop_map(|(at, len)| Mutation::Delete { at, len }),
        (at, 1..400usize).prop_map(|(at, len)| Mutation::Duplicate { at, len }),
        (at, 0..TOKENS.len()).prop_map(|(at, token)| Mutation::Insert { at, bytes: TOKENS[token].into() }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let _ = parse_with_watchdog(bytes);
    }

    #[test]
    fn arbitrary_text_never_panics(text in "(<[a-z/!?]{0,3}|[a-z\"'= ]{0,5}|>|&[a-z#0-9]{0,4};?|\n){0,200}") {
        let _ = parse_with_watchdog(text.into_bytes());
    }

    #[test]
    fn mutated_samples_never_panic(
        sample in 0..SAMPLES.len(),
        edits in proptest::collection::vec(mutation(), 1..8),
    ) {
        let mut bytes = SAMPLES[sample].to_vec();
        apply_all(&mut bytes, &edits);
        let _ = parse_with_watchdog(bytes);
    }

    #[test]
    fn mutated_synthetic_ddfs_never_panic(
        domains in 1..6usize,
        items in 0..30usize,
        edits in proptest::collection::vec(mutation(), 1..6),
    ) {
        let mut bytes = ddf::synth::large_ddf(domains, items).into_bytes();
        apply_all(&mut bytes, &edits);
        let _ = parse_with_watchdog(bytes);
    }

    #[test]
    fn every_prefix_of_a_sample_is_handled(sample in 0..SAMPLES.len(), cut in any::<usize>()) {
        let bytes = SAMPLES[sample];
        let cut = cut % (bytes.len() + 1);
        let result = parse_with_watchdog(bytes[..cut].to_vec());
        // Only the whole file (give or take its trailing newline and blanks) is valid.
        if result.is_ok() {
            prop_assert!(bytes[cut..].iter().all(u8::is_ascii_whitespace), "prefix of {cut} bytes accepted");
        }
    }
}

#[test]
fn unmutated_samples_are_valid() {
    for bytes in SAMPLES {
        assert!(parse_with_watchdog(bytes.to_vec()).is_ok());
    }
}

#[test]
fn deeply_nested_input_is_refused_quickly() {
    // 100,000 open tags: refused at depth 40, long before memory or stack is at risk.
    let text = "<a>".repeat(100_000);
    let err = parse_with_watchdog(text.into_bytes()).unwrap_err();
    assert!(err.to_string().contains("nested deeper than 40"), "{err}");
    // The same for buses: XML depth 40 is reached before bus depth becomes a problem.
    let mut text = String::from("<orchestra><domain name=\"d\"><set name=\"PUBLISH\">");
    for i in 0..1000 {
        text.push_str(&format!("<item name=\"b{i}\"><type>bus</type>"));
    }
    assert!(parse_with_watchdog(text.into_bytes()).is_err());
}

#[test]
fn wide_input_is_handled() {
    // Many siblings and long text: linear work, no quadratic blow-up worth a timeout.
    let mut text = String::from("<orchestra><domain name=\"d\"><set name=\"PUBLISH\">");
    for i in 0..20_000 {
        text.push_str(&format!("<item name=\"x{i}\"><type>int8</type></item>"));
    }
    text.push_str("</set><states>no</states></domain></orchestra>");
    let model = parse_with_watchdog(text.into_bytes()).expect("valid");
    assert_eq!(model.domains[0].publish.layout.leaves.len(), 20_000);
    // The 1,000-domain file on one line: positions are found without rescanning the line.
    let one_line = ddf::synth::large_ddf(1000, 20).replace('\n', " ");
    let model = parse_with_watchdog(one_line.into_bytes()).expect("valid");
    assert_eq!(model.domains.len(), 1000);
    let long_text = format!("<orchestra>{}</orchestra>", "x".repeat(1 << 20));
    assert!(parse_with_watchdog(long_text.into_bytes()).is_err());
}
