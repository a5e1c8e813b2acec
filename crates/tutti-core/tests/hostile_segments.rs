//! Segments that another process tampers with from outside: shrunk under a live framework,
//! planted as a symbolic link, or owned by another user. Each ends in a clean error; none
//! kills the process (docs/security.md).
//!
//! One test function: the trust cases set `TUTTI_TRUST_UIDS`, which must not race another
//! test of this binary.

mod common;

use std::os::unix::fs::MetadataExt;
use std::path::PathBuf;
use std::time::Duration;

use tutti_core::ddf::Model;
use tutti_core::shm::segment::segment_path;
use tutti_core::shm::{
    list_domains, ConnectOptions, Framework, FrameworkOptions, Look, Observer, Participant, ShmError,
};

fn model(sync: bool) -> Model {
    // Sets of a few pages each, so that a cut can fall between the header and the sets.
    let item = |name: &str| format!(r#"<item name="{name}"><type>float64</type><length>2048</length></item>"#);
    common::domain(sync, true, false, &item("p"), &item("s"))
}

fn framework(ns: &str, sync: bool) -> Framework {
    let opts = FrameworkOptions { namespace: ns.into(), timeout: Duration::from_millis(200), ..Default::default() };
    Framework::create(&model(sync), &opts).expect("creating the framework")
}

fn copts(ns: &str) -> ConnectOptions {
    ConnectOptions {
        namespace: ns.into(),
        name: "victim".into(),
        timeout: Duration::from_secs(2),
        connect_timeout: Duration::from_secs(2),
        ..Default::default()
    }
}

/// Removes what a case leaves in /dev/shm, even when it fails.
struct Cleanup(Vec<PathBuf>);

impl Drop for Cleanup {
    fn drop(&mut self) {
        for p in &self.0 {
            let _ = std::fs::remove_file(p);
        }
    }
}

fn truncated(e: &ShmError) -> bool {
    matches!(e, ShmError::Truncated { .. })
}

fn shrunk_under_a_live_framework(cut: u64, sync: bool) {
    let ns = tutti_test_support::namespace(&format!("hs-cut{cut}-"));
    let _clean = Cleanup(vec![segment_path(&ns, "d")]);
    let mut fw = framework(&ns, sync);
    let size = fw.domain("d").unwrap().info().publish.size as usize;
    let full = std::fs::metadata(segment_path(&ns, "d")).unwrap().len();
    let mut p = Participant::connect("d", copts(&ns)).expect("connecting");
    let mut obs = Observer::new("d".into());
    assert!(matches!(obs.look(&ns), Look::Fresh));
    tutti_test_support::shrink_segment(&ns, "d", cut.min(full - 1));

    // The framework: a step touches its header and both sets; it ends in Truncated, and
    // this process lives on to say so.
    let d = fw.domain("d").unwrap();
    let publish = vec![0u8; size];
    let mut ended = None;
    for _ in 0..3 {
        if let Err(e) = d.step(&publish, 0.0) {
            ended = Some(e);
            break;
        }
    }
    let e = ended.unwrap_or_else(|| panic!("cut at {cut}: the framework stepped on over a shrunk segment"));
    assert!(truncated(&e), "cut at {cut}: the framework ended with {e}, not Truncated");
    let text = e.to_string();
    assert!(text.contains("domain 'd'") && text.contains(&segment_path(&ns, "d").display().to_string()), "{text}");

    // The participant: its next exchange ends in the same error (its mapping is its own).
    let mut exchange = || -> Result<(), ShmError> {
        if sync {
            p.subscribe_lock()?;
        } else {
            p.publish_lock()?;
            p.stage_at(0, &[1u8; 2048 * 8])?;
        }
        p.commit()
    };
    let e = (0..3)
        .find_map(|_| exchange().err())
        .unwrap_or_else(|| panic!("cut at {cut}: the participant went on over a shrunk segment"));
    assert!(truncated(&e), "cut at {cut}: the participant ended with {e}, not Truncated");

    // An observer (the gateway's, the recorder's) lets go of it.
    match obs.look(&ns) {
        Look::Refused(e) => assert!(truncated(&e), "cut at {cut}: the observer refused with {e}"),
        // Its mapping may not have touched a cut page yet: its next read does.
        _ => {
            let seg = obs.segment().expect("observer still holds the segment");
            let mut out = vec![0u8; size];
            let e = seg.read_set(tutti_core::ddf::Role::Publish, &mut out).expect_err("read a shrunk set");
            assert!(truncated(&e), "cut at {cut}: the observer's read ended with {e}");
        }
    }

    // What `tutti status` reads: the segment's size is wrong, said so.
    std::thread::sleep(Duration::from_millis(1100)); // a 0-byte file younger than 1 s reads as being created
    let listed = list_domains(&ns).expect("listing");
    let e = listed.into_iter().next().expect("the segment is listed").expect_err("status read a shrunk segment");
    assert!(e.to_string().contains("truncated") || e.to_string().contains("resized"), "status said: {e}");
}

fn refuses_links_and_other_users() {
    let ns = tutti_test_support::namespace("hs-trust-");
    let other = tutti_test_support::namespace("hs-link-");
    let planted = segment_path(&other, "d");
    let _clean = Cleanup(vec![segment_path(&ns, "d"), planted.clone()]);
    let mut fw = framework(&ns, false);

    // A symbolic link at another namespace's segment path, to this live segment.
    std::os::unix::fs::symlink(segment_path(&ns, "d"), &planted).unwrap();
    let e = Participant::connect("d", copts(&other)).expect_err("a participant followed a planted link");
    assert!(matches!(e, ShmError::Untrusted { .. }) && e.to_string().contains("symbolic link"), "{e}");
    // A framework there refuses it too, and leaves the link (it is not its to remove).
    let opts = FrameworkOptions { namespace: other.clone(), ..Default::default() };
    let Err(e) = Framework::create(&model(false), &opts) else { panic!("a framework took over a planted link") };
    assert!(matches!(e, ShmError::Untrusted { .. }), "{e}");
    assert!(planted.symlink_metadata().is_ok(), "the framework removed the link");
    std::fs::remove_file(&planted).unwrap();

    // A segment of the expected name that another user owns.
    let path = segment_path(&ns, "d");
    let me = std::fs::metadata(&path).unwrap().uid();
    let stranger = if me == 65534 { 65533 } else { 65534 };
    let chowned = std::os::unix::fs::chown(&path, Some(stranger), None);
    let Some(()) = tutti_test_support::require("root (to give a segment to another user)", chowned) else {
        return;
    };
    let e = Participant::connect("d", copts(&ns)).expect_err("a participant joined another user's segment");
    assert!(matches!(e, ShmError::Untrusted { .. }), "{e}");
    assert!(e.to_string().contains(&format!("uid {stranger}")), "{e}");
    assert!(list_domains(&ns).unwrap()[0].is_err(), "status trusted another user's segment");

    // Told to trust that user, it joins and exchanges data.
    std::env::set_var("TUTTI_TRUST_UIDS", format!("1,{stranger}"));
    let mut p = Participant::connect("d", copts(&ns)).expect("a trusted user's segment is refused");
    std::env::remove_var("TUTTI_TRUST_UIDS");
    let size = fw.domain("d").unwrap().info().publish.size as usize;
    let mut publish = vec![0u8; size];
    publish[..8].copy_from_slice(&4.5f64.to_ne_bytes());
    fw.domain("d").unwrap().step(&publish, 0.0).unwrap();
    p.subscribe_lock().unwrap();
    assert_eq!(&p.snapshot()[..8], &4.5f64.to_ne_bytes());
}

#[test]
fn tampered_segments_end_in_clean_errors() {
    // Cut: to nothing, inside the header, after the header (the sets go), inside the sets.
    for (cut, sync) in [(0, false), (100, true), (4096, false), (4096 * 3, true)] {
        shrunk_under_a_live_framework(cut, sync);
    }
    refuses_links_and_other_users();
}
