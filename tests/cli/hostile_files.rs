//! Hostile files and settings never crash `tutti`: a replay of a damaged recording (a record
//! length of all ones, a chunk that states an exabyte, a file cut short, bytes flipped all
//! over it) and a gateway given a config nested 100,000 deep, `status_every: 0` or a peer of
//! garbage bytes each end with exit status 2 (`docs/cli.md`), never a signal, with stderr
//! naming the file (and, for a damaged recording, the byte offset; for a config, the line and
//! column); and nothing is left in /dev/shm. See `docs/recording.md` ("Reading a damaged
//! file") and `docs/gateway.md` (the config file's errors).

use tutti_test_support as common;

use std::path::Path;
use std::process::{Command, ExitStatus};

use common::{run_with_timeout, TIMEOUT};

/// The exit status of invalid input.
const INVALID: i32 = 2;

fn tutti(ns: &str, args: &[&str]) -> Command {
    let mut c = common::tutti_command();
    c.args(args).env("TUTTI_NAMESPACE", ns);
    c
}

/// Asserts that `status` is an exit (not a signal) with status `code`.
fn exited_with(status: ExitStatus, code: i32, what: &str, err: &str) {
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(status.signal(), None, "{what}: killed by a signal\n{err}");
    assert_eq!(status.code(), Some(code), "{what}\n{err}");
}

/// A small finished recording of `ddf/product-sample.ddf` (both domains, a few steps).
fn recording(path: &Path) -> Vec<u8> {
    let ddf = common::repo_root().join("ddf/product-sample.ddf");
    let model = tutti_core::ddf::load(&ddf).unwrap();
    let mut rec = tutti_record::create(path, &model, &ddf).unwrap();
    let sets: Vec<(Vec<u8>, Vec<u8>)> =
        model.domains.iter().map(|d| (d.publish.layout.default_bytes(), d.subscribe.layout.default_bytes())).collect();
    for k in 1..=5u64 {
        for (i, (p, s)) in sets.iter().enumerate() {
            let step = tutti_record::Step {
                step: k,
                sim_time: k as f64 * 0.01,
                wall_ns: 1_000_000 + k * 1_000,
                elapsed_s: 0.0,
                connections: 0,
                owner_pid: None,
                publish: p,
                subscribe: s,
            };
            rec.step(i, &step).unwrap();
        }
    }
    rec.finish().unwrap();
    std::fs::read(path).unwrap()
}

/// The offset of the first chunk record, walking the records from the magic.
fn first_chunk(bytes: &[u8]) -> usize {
    let mut at = 8;
    while bytes[at] != 0x06 {
        at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    at
}

#[test]
fn a_replay_of_a_damaged_recording_is_an_error_naming_the_file_and_the_offset() {
    let dir = tempfile::tempdir().unwrap();
    let ns = common::namespace("hostile-files-replay");
    let _segments = common::RemoveSegments(ns.clone());
    let good = recording(&dir.path().join("good.mcap"));
    let chunk = first_chunk(&good);
    let replay = |name: &str, bytes: &[u8]| {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let mut c = tutti(&ns, &["replay", "--speed", "0", "-q"]);
        c.arg(&path);
        let (status, _, err) = run_with_timeout(c, TIMEOUT);
        (status, err)
    };

    // The header record's length, right after the magic, set to 0xffffffffffffffff.
    let mut bytes = good.clone();
    bytes[9..17].copy_from_slice(&u64::MAX.to_le_bytes());
    let (status, err) = replay("huge-record.mcap", &bytes);
    exited_with(status, INVALID, "a record length of all ones", &err);
    assert!(
        err.contains(
            "huge-record.mcap: at byte 8: a header record (opcode 0x01) says it is 18446744073709551615 bytes long"
        ),
        "{err}"
    );

    // The first chunk says it holds 2^64-1 bytes uncompressed.
    let mut bytes = good.clone();
    bytes[chunk + 9 + 16..chunk + 9 + 24].copy_from_slice(&u64::MAX.to_le_bytes());
    let (status, err) = replay("huge-chunk.mcap", &bytes);
    exited_with(status, INVALID, "a chunk of 2^64-1 bytes", &err);
    assert!(
        err.contains(&format!("huge-chunk.mcap: at byte {chunk}: a chunk says it holds 18446744073709551615")),
        "{err}"
    );

    // The length of the first record inside the chunk (stored raw by zstd in so small a file)
    // with a byte flipped: the crash that aborted the process.
    let mut bytes = good.clone();
    let records = chunk + 9 + 8 + 8 + 8 + 4 + 4 + 4 + 8;
    assert_eq!(&bytes[chunk + 9 + 28..chunk + 9 + 32], &4u32.to_le_bytes(), "the chunk is zstd-compressed");
    bytes[records + 20] ^= 0x40;
    let (status, err) = replay("flipped-chunk.mcap", &bytes);
    exited_with(status, INVALID, "a flipped byte in a chunk", &err);
    assert!(err.contains(&format!("flipped-chunk.mcap: at byte {chunk}: a chunk")), "{err}");

    // Cut short: no footer.
    let (status, err) = replay("cut.mcap", &good[..good.len() / 2]);
    exited_with(status, INVALID, "a file cut in half", &err);
    assert!(err.contains("cut.mcap: at byte "), "{err}");

    // A byte flipped at 40 places spread over the file: a clean error or a replay.
    for i in 0..40 {
        let mut bytes = good.clone();
        let at = 8 + (i * 7919) % (bytes.len() - 8);
        bytes[at] ^= 1 << (i % 8);
        let name = format!("flip-{at}.mcap");
        let (status, err) = replay(&name, &bytes);
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(status.signal(), None, "{name}: killed by a signal\n{err}");
        assert!(matches!(status.code(), Some(0 | INVALID)), "{name}: {status:?}\n{err}");
        if status.code() == Some(INVALID) {
            assert!(err.contains(&name), "{name}: the error does not name the file\n{err}");
        }
    }
    assert!(common::segments_of(&ns).is_empty(), "a replay left segments: {:?}", common::segments_of(&ns));
}

#[test]
fn a_gateway_given_hostile_settings_refuses_them_naming_the_file_or_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let ns = common::namespace("hostile-files-gateway");
    let _segments = common::RemoveSegments(ns.clone());
    let domain = common::dds_domain_in(200..=209).to_string();
    let gateway = |extra: &[&str]| {
        let mut c = tutti(&ns, &["gateway", "ddf/multiuav.ddf", "--duration", "5s"]);
        c.args(extra).env("ROS_DOMAIN_ID", &domain);
        for v in ["TUTTI_DDS", "ROS_LOCALHOST_ONLY", "ROS_AUTOMATIC_DISCOVERY_RANGE", "TUTTI_GATEWAY_INTERFACE"] {
            c.env_remove(v);
        }
        let (status, _, err) = run_with_timeout(c, TIMEOUT);
        (status, err)
    };
    let file = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.display().to_string()
    };

    let deep = file("deep.json5", &format!("{{ topics: {}1{} }}", "{a:".repeat(100_000), "}".repeat(100_000)));
    let (status, err) = gateway(&["--config", &deep]);
    exited_with(status, INVALID, "a config nested 100,000 deep", &err);
    assert!(err.contains(&format!("{deep}:1:")) && err.contains("nested more than 32 deep"), "{err}");

    let zero = file("zero.json5", "{\n  status_every: \"0s\",\n}\n");
    let (status, err) = gateway(&["--config", &zero]);
    exited_with(status, INVALID, "status_every: 0s", &err);
    assert!(err.contains(&format!("{zero}:2:17: '0s': it must be longer than zero")), "{err}");
    let zero_number = file("zero-number.json5", "{ status_every: 0 }");
    let (status, err) = gateway(&["--config", &zero_number]);
    exited_with(status, INVALID, "status_every: 0", &err);
    assert!(err.contains(&format!("{zero_number}:1:")), "{err}");
    let (status, err) = gateway(&["--status-every", "0s"]);
    exited_with(status, INVALID, "--status-every 0s", &err);
    assert!(err.contains("'--status-every <DURATION>'") && err.contains("longer than zero"), "{err}");

    let garbage = file("peer.json5", "{\n  peer: [\"\\u0001\\u00ff%%garbage\"],\n}\n");
    let (status, err) = gateway(&["--config", &garbage]);
    exited_with(status, INVALID, "a peer of garbage bytes in the file", &err);
    assert!(err.contains(&format!("{garbage}:2:10: peer '\\u{{1}}ÿ%%garbage': not an IPv4 address")), "{err}");
    let (status, err) = gateway(&["--peer", "zz..##\u{1}"]);
    exited_with(status, INVALID, "a peer of garbage bytes", &err);
    assert!(err.contains("'--peer <ADDR>'") && err.contains("not an IPv4 address or a host name"), "{err}");
    let (status, err) = gateway(&["--peer", "nosuchhost.invalid"]);
    exited_with(status, INVALID, "a peer that does not resolve", &err);
    assert!(err.contains("'--peer <ADDR>'") && err.contains("does not resolve"), "{err}");
    let (status, err) = gateway(&["--peer", "a\"/><Peer address=\"x"]);
    exited_with(status, INVALID, "a peer with XML in it", &err);
    assert!(err.contains("not an IPv4 address or a host name"), "{err}");

    assert!(common::segments_of(&ns).is_empty(), "a refused gateway left segments");
}
