//! The exported calls, called directly from Rust in this process: the semantics of each and
//! every documented return code (RTAPI_ERROR_INTERNAL is produced in the unit tests of
//! `ffi`, by a panicking call body: no exported call panics on purpose).
//!
//! The library state is process-wide, so the tests take turns (`serial`); they share one
//! namespace (set once) and use distinct domain names.

mod common;

use std::ffi::{c_char, c_uint, c_ushort, c_void, CStr};
use std::io::Write;
use std::ptr::{null, null_mut};
use std::sync::{Mutex, MutexGuard, Once};
use std::time::Duration;

use common::*;
use rtapi::*;
use tutti_core::ddf::{self, Model};
use tutti_core::shm::segment::VERSION;
use tutti_core::shm::{Framework, FrameworkOptions};
use tutti_test_support::ShmFile;

static SERIAL: Mutex<()> = Mutex::new(());
static NAMESPACE: Once = Once::new();

fn ns() -> String {
    namespace("extern")
}

/// Takes this test's turn and sets TUTTI_NAMESPACE (once, under the lock).
fn serial() -> MutexGuard<'static, ()> {
    let guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    NAMESPACE.call_once(|| std::env::set_var("TUTTI_NAMESPACE", ns()));
    guard
}

fn model(domain: &str, sync: bool, mpa: bool) -> Model {
    ddf::parse_str(&ddf_text(domain, sync, mpa, "int32"), "test.ddf").expect("DDF")
}

fn ddf_text(domain: &str, sync: bool, mpa: bool, b_type: &str) -> String {
    let yn = |b| if b { "yes" } else { "no" };
    format!(
        r#"<orchestra><domain name="{domain}"><synchronous>{}</synchronous><multiplePublishAllowed>{}</multiplePublishAllowed><states>no</states>
        <set name="PUBLISH"><item name="x"><type>float64</type></item><item name="v"><type>float32</type><length>3</length></item></set>
        <set name="SUBSCRIBE"><item name="a"><type>float64</type><default>2.5</default></item><item name="b"><type>{b_type}</type></item></set>
        </domain></orchestra>"#,
        yn(sync),
        yn(mpa)
    )
}

/// The PUBLISH set of the test domain (x = `x`, v = 0): 8 + 12 bytes, padded to 24.
fn pubset(x: f64) -> Vec<u8> {
    let mut b = vec![0u8; 24];
    b[0..8].copy_from_slice(&x.to_ne_bytes());
    b
}

fn fopts() -> FrameworkOptions {
    FrameworkOptions { namespace: ns(), timeout: Duration::from_secs(20), ..Default::default() }
}

fn framework(domain: &str, sync: bool, mpa: bool) -> Framework {
    Framework::create(&model(domain, sync, mpa), &fopts()).expect("framework")
}

fn c(s: &str) -> std::ffi::CString {
    std::ffi::CString::new(s).expect("no NUL")
}

fn name(code: RTAPIReturn_t) -> &'static str {
    rtapi::codes::name(code).unwrap_or("?")
}

fn detail() -> String {
    // SAFETY: RTGetLastErrorDetail returns a valid NUL-terminated string, never NULL.
    unsafe { CStr::from_ptr(RTGetLastErrorDetail()) }.to_string_lossy().into_owned()
}

#[track_caller]
fn expect(code: RTAPIReturn_t, want: RTAPIReturn_t) {
    assert_eq!(name(code), name(want), "detail: {}", detail());
}

/// A fresh connection key, made current.
fn key() -> c_uint {
    let mut k = 0;
    // SAFETY: `k` is a valid out-pointer.
    expect(unsafe { RTNewConnectionKey(&mut k) }, RTAPI_SUCCESS);
    expect(RTSetConnectionKey(k), RTAPI_SUCCESS);
    k
}

fn connect(domain: &str, timeout: i32) -> RTAPIReturn_t {
    let d = c(domain);
    // SAFETY: a valid C string.
    unsafe { RTConnect(d.as_ptr(), timeout) }
}

fn connect_file(path: &std::path::Path, domain: &str) -> RTAPIReturn_t {
    let (p, d) = (c(path.to_str().expect("utf-8")), c(domain));
    // SAFETY: valid C strings.
    unsafe { RTConnectWithFile(p.as_ptr(), d.as_ptr(), 2) }
}

fn publish(item: &str, value: &[u8]) -> RTAPIReturn_t {
    let i = c(item);
    // SAFETY: valid string and buffer of the given size.
    unsafe { RTPublish(i.as_ptr(), value.as_ptr().cast(), value.len() as c_uint) }
}

fn subscribe(item: &str, out: &mut [u8]) -> RTAPIReturn_t {
    let i = c(item);
    // SAFETY: valid string and buffer of the given size.
    unsafe { RTSubscribe(i.as_ptr(), out.as_mut_ptr().cast(), out.len() as c_uint) }
}

fn count(domain: &str) -> Result<c_uint, RTAPIReturn_t> {
    let d = c(domain);
    let mut n = 0;
    // SAFETY: valid string and out-pointer.
    match unsafe { RTGetConnectionCount(d.as_ptr(), &mut n) } {
        RTAPI_SUCCESS => Ok(n),
        e => Err(e),
    }
}

#[test]
fn messages_exist_for_every_code_and_unknown_codes() {
    for code in rtapi::codes::ALL {
        // SAFETY: RTGetErrorMessage never returns NULL and its text is static.
        let text = unsafe { CStr::from_ptr(RTGetErrorMessage(code)) };
        assert!(!text.to_bytes().is_empty());
    }
    // SAFETY: as above.
    let unknown = unsafe { CStr::from_ptr(RTGetErrorMessage(12345)) };
    assert_eq!(unknown.to_str(), Ok("unknown RTAPI return code"));
    let header = std::fs::read_to_string(root().join("include/RTAPI.h")).expect("header");
    for code in rtapi::codes::ALL {
        assert!(header.contains(&format!("#define {} {code}\n", name(code))), "{} missing from RTAPI.h", name(code));
    }
}

#[test]
fn async_domain_values_flow_both_ways() {
    let _turn = serial();
    let mut fw = framework("async1", false, true);
    fw.domains[0].step(&pubset(1.5), 0.0).expect("step");
    let k = key();
    expect(connect("async1", 2), RTAPI_SUCCESS);
    assert_eq!(count("async1"), Ok(1));
    // Outside a lock pair in an asynchronous domain, RTSubscribe/RTPublish lock themselves.
    let mut x = [0u8; 8];
    expect(subscribe("x", &mut x), RTAPI_SUCCESS);
    assert_eq!(f64::from_ne_bytes(x), 1.5);
    expect(publish("b", &7i32.to_ne_bytes()), RTAPI_SUCCESS);
    fw.domains[0].read_subscribe().expect("read");
    assert_eq!(&fw.domains[0].subscribe()[8..12], &7i32.to_ne_bytes());
    assert_eq!(&fw.domains[0].subscribe()[0..8], &2.5f64.to_ne_bytes(), "unstaged item keeps its default");

    // Item keys: PUBLISH items first, then SUBSCRIBE; info gives element size and count.
    let mut item_key: c_ushort = 99;
    let (mut size, mut len): (c_uint, c_ushort) = (0, 0);
    for (path, want_key, want_size, want_len) in [("x", 0, 8, 1), ("v", 1, 4, 3), ("a", 2, 8, 1), ("b", 3, 4, 1)] {
        let p = c(path);
        // SAFETY: valid string and out-pointers.
        unsafe {
            expect(RTGetKeyForItem(p.as_ptr(), &mut item_key), RTAPI_SUCCESS);
            expect(RTGetInfoForItem(p.as_ptr(), &mut size, &mut len), RTAPI_SUCCESS);
        }
        assert_eq!((item_key, size, len), (want_key, want_size, want_len), "{path}");
    }

    // Buffers: PUBLISH items point into the snapshot, SUBSCRIBE items into the staging buffer.
    let mut xp: *mut c_void = null_mut();
    let mut ap: *mut c_void = null_mut();
    let (mut pb, mut sb): (*mut c_char, *mut c_char) = (null_mut(), null_mut());
    let (mut ps, mut ss): (c_uint, c_uint) = (0, 0);
    let mut status: *mut c_uint = null_mut();
    // SAFETY: valid out-pointers.
    unsafe {
        expect(RTGetBuffer(k, 0, &mut xp), RTAPI_SUCCESS);
        expect(RTGetBuffer(k, 2, &mut ap), RTAPI_SUCCESS);
        expect(RTGetBufferInfo(k, &mut pb, &mut ps, &mut sb, &mut ss), RTAPI_SUCCESS);
        expect(RTGetConnectionStatusPtr(k, &mut status), RTAPI_SUCCESS);
    }
    assert_eq!((ps, ss), (24, 16));
    assert_eq!((xp.cast::<c_char>(), ap.cast::<c_char>()), (pb, sb));
    // SAFETY: the status pointer stays valid until RTDisconnect; read like C would (volatile).
    assert_eq!(unsafe { status.read_volatile() }, 1);
    fw.domains[0].step(&pubset(4.25), 0.0).expect("step");
    expect(RTSubscribeLock(), RTAPI_SUCCESS);
    // SAFETY: `xp` points at the 8 bytes of x in the connection's snapshot, valid until RTDisconnect.
    assert_eq!(unsafe { xp.cast::<f64>().read_unaligned() }, 4.25);
    expect(RTSubscribeUnlock(), RTAPI_SUCCESS);
    expect(RTPublishLock(), RTAPI_SUCCESS);
    // SAFETY: `ap` points at the 8 bytes of a in the staging buffer, valid until RTDisconnect.
    unsafe { ap.cast::<f64>().write_unaligned(-3.0) };
    expect(RTPublishUnlock(), RTAPI_SUCCESS);
    fw.domains[0].read_subscribe().expect("read");
    assert_eq!(&fw.domains[0].subscribe()[0..8], &(-3.0f64).to_ne_bytes());

    // Flag delay and wait-to-go options are accepted at any time.
    expect(RTDefineFlagDelay(50), RTAPI_SUCCESS);
    expect(RTUseFlagWithTool(0), RTAPI_SUCCESS);
    expect(RTWaitReadyToGo(), RTAPI_SUCCESS);
    expect(RTDefineFlagDelay(0), RTAPI_SUCCESS);
    expect(RTSubscribeLock(), RTAPI_SUCCESS);
    expect(RTSubscribeUnlock(), RTAPI_SUCCESS);
    expect(RTUseFlagWithTool(100), RTAPI_SUCCESS);
    expect(RTSubscribeLock(), RTAPI_SUCCESS);
    expect(RTSubscribeUnlock(), RTAPI_SUCCESS);

    expect(RTDisconnect(), RTAPI_SUCCESS);
    assert_eq!(count("async1"), Ok(0));
    // The key can connect again.
    expect(connect("async1", 2), RTAPI_SUCCESS);
    expect(RTDisconnect(), RTAPI_SUCCESS);
}

#[test]
fn synchronous_domain_needs_lock_pairs_and_steps_in_lock_step() {
    let _turn = serial();
    let mut fw = framework("sync1", true, false);
    let k = key();
    expect(connect("sync1", 5), RTAPI_SUCCESS);
    let mut x = [0u8; 8];
    expect(subscribe("x", &mut x), RTAPI_ERROR_OUT_OF_ORDER);
    expect(publish("a", &1.0f64.to_ne_bytes()), RTAPI_ERROR_OUT_OF_ORDER);
    let t = std::thread::spawn(move || {
        let mut seen = Vec::new();
        expect(RTSetConnectionKey(k), RTAPI_SUCCESS);
        for _ in 0..30 {
            let mut x = [0u8; 8];
            expect(RTSubscribeLock(), RTAPI_SUCCESS);
            expect(subscribe("x", &mut x), RTAPI_SUCCESS);
            expect(RTSubscribeUnlock(), RTAPI_SUCCESS);
            let x = f64::from_ne_bytes(x);
            expect(RTPublishLock(), RTAPI_SUCCESS);
            expect(publish("a", &(x * 10.0).to_ne_bytes()), RTAPI_SUCCESS);
            expect(RTPublishUnlock(), RTAPI_SUCCESS);
            seen.push(x);
        }
        expect(RTDisconnect(), RTAPI_SUCCESS);
        seen
    });
    let host = &mut fw.domains[0];
    let mut answers = Vec::new();
    // Step until the participant has done its 30 cycles (bounded: a hang fails the test).
    while !t.is_finished() && answers.len() < 200 {
        let step = answers.len() as u64 + 1;
        host.step(&pubset(step as f64), 0.0).expect("step");
        let a = f64::from_ne_bytes(host.subscribe()[0..8].try_into().expect("8"));
        answers.push((step as f64, a));
    }
    let seen = t.join().expect("participant thread");
    assert_eq!(seen.len(), 30);
    // Lock-step from the participant's second step on: every step read once, none skipped
    // (its first step may be followed by a skip: see docs/rtapi.md, "Joining a synchronous
    // domain"), and the framework sees that very step's answer.
    for w in seen[1..].windows(2) {
        assert_eq!(w[1], w[0] + 1.0, "{seen:?}");
    }
    for x in &seen[1..] {
        let (_, a) = answers.iter().find(|(k, _)| k == x).expect("step");
        assert_eq!(*a, x * 10.0, "step {x}");
    }
}

#[test]
fn argument_and_order_errors() {
    let _turn = serial();
    let _fw = framework("args1", false, true);
    // SAFETY: NULL and valid pointers only, as each call documents.
    unsafe {
        expect(RTNewConnectionKey(null_mut()), RTAPI_ERROR_NULL_POINTER);
        expect(RTConnect(null(), 1), RTAPI_ERROR_NULL_POINTER);
        expect(RTConnectWithFile(null(), c("args1").as_ptr(), 1), RTAPI_ERROR_NULL_POINTER);
        expect(RTGetConnectionCount(c("args1").as_ptr(), null_mut()), RTAPI_ERROR_NULL_POINTER);
    }
    expect(RTSetConnectionKey(4_000_000_000), RTAPI_ERROR_UNKNOWN_CONNECTION_KEY);
    let mut p: *mut c_void = null_mut();
    // SAFETY: valid out-pointer.
    expect(unsafe { RTGetBuffer(4_000_000_000, 0, &mut p) }, RTAPI_ERROR_UNKNOWN_CONNECTION_KEY);
    let k = key();
    // Not connected yet.
    expect(RTDisconnect(), RTAPI_ERROR_NOT_CONNECTED);
    expect(RTSubscribeLock(), RTAPI_ERROR_NOT_CONNECTED);
    expect(RTPublishUnlock(), RTAPI_ERROR_NOT_CONNECTED);
    expect(RTWaitReadyToGo(), RTAPI_ERROR_NOT_CONNECTED);
    // SAFETY: valid out-pointer.
    expect(unsafe { RTGetBuffer(k, 0, &mut p) }, RTAPI_ERROR_NOT_CONNECTED);
    expect(connect("args1", -1), RTAPI_ERROR_INVALID_ARGUMENT);
    expect(connect("", 1), RTAPI_ERROR_INVALID_ARGUMENT);
    let bad_utf8 = [0xffu8, 0xfe, 0];
    // SAFETY: a NUL-terminated byte string.
    expect(unsafe { RTConnect(bad_utf8.as_ptr().cast(), 1) }, RTAPI_ERROR_INVALID_ARGUMENT);

    expect(connect("args1", 2), RTAPI_SUCCESS);
    expect(connect("args1", 2), RTAPI_ERROR_ALREADY_CONNECTED);
    // SAFETY: NULL pointers, refused.
    unsafe {
        expect(RTGetBuffer(k, 0, null_mut()), RTAPI_ERROR_NULL_POINTER);
        expect(RTGetKeyForItem(c("x").as_ptr(), null_mut()), RTAPI_ERROR_NULL_POINTER);
        expect(RTGetConnectionStatusPtr(k, null_mut()), RTAPI_ERROR_NULL_POINTER);
        expect(RTPublish(c("a").as_ptr(), null(), 8), RTAPI_ERROR_NULL_POINTER);
        expect(RTSubscribe(null(), null_mut(), 8), RTAPI_ERROR_NULL_POINTER);
    }
    // Unknown items, items of the other set, unknown keys.
    let mut ik: c_ushort = 0;
    // SAFETY: valid string and out-pointer.
    expect(unsafe { RTGetKeyForItem(c("nope").as_ptr(), &mut ik) }, RTAPI_ERROR_UNKNOWN_ITEM);
    expect(publish("x", &[0; 8]), RTAPI_ERROR_UNKNOWN_ITEM);
    expect(subscribe("a", &mut [0; 8]), RTAPI_ERROR_UNKNOWN_ITEM);
    // SAFETY: valid out-pointer.
    expect(unsafe { RTGetBuffer(k, 4, &mut p) }, RTAPI_ERROR_UNKNOWN_ITEM);
    // Wrong sizes: exactly the item's size is required.
    expect(publish("a", &[0; 4]), RTAPI_ERROR_WRONG_SIZE);
    expect(subscribe("v", &mut [0; 4]), RTAPI_ERROR_WRONG_SIZE);
    expect(subscribe("v", &mut [0; 12]), RTAPI_SUCCESS);
    // Out of order.
    expect(RTSubscribeUnlock(), RTAPI_ERROR_OUT_OF_ORDER);
    expect(RTPublishUnlock(), RTAPI_ERROR_OUT_OF_ORDER);
    expect(RTSubscribeLock(), RTAPI_SUCCESS);
    expect(RTSubscribeLock(), RTAPI_ERROR_OUT_OF_ORDER);
    expect(RTSubscribeUnlock(), RTAPI_SUCCESS);
    expect(RTPublishLock(), RTAPI_SUCCESS);
    expect(RTPublishLock(), RTAPI_ERROR_OUT_OF_ORDER);
    assert!(detail().contains("RTPublishLock called twice"), "{}", detail());
    expect(RTPublishUnlock(), RTAPI_SUCCESS);
    // None of these errors disconnected.
    expect(RTSubscribeLock(), RTAPI_SUCCESS);
    expect(RTSubscribeUnlock(), RTAPI_SUCCESS);
    assert_eq!(detail(), "", "the successes left a detail");
    expect(RTDisconnect(), RTAPI_SUCCESS);
}

#[test]
fn connect_errors() {
    let _turn = serial();
    let _k = key();
    expect(connect("nosuchdomain", 0), RTAPI_ERROR_DOMAIN_NOT_FOUND);
    assert_eq!(count("nosuchdomain"), Err(RTAPI_ERROR_DOMAIN_NOT_FOUND));
    let dir = tempfile::tempdir().expect("temp dir");
    expect(connect_file(&dir.path().join("missing.ddf"), "conn1"), RTAPI_ERROR_DDF_INVALID);
    let invalid = dir.path().join("invalid.ddf");
    std::fs::write(&invalid, "<orchestra><domain name='conn1'><bogus/></domain></orchestra>").expect("write");
    expect(connect_file(&invalid, "conn1"), RTAPI_ERROR_DDF_INVALID);

    let _fw = Framework::create(&model("conn1", false, false), &FrameworkOptions { connections: 1, ..fopts() })
        .expect("framework");
    let good = dir.path().join("good.ddf");
    std::fs::write(&good, ddf_text("conn1", false, false, "int32")).expect("write");
    let other = dir.path().join("other.ddf");
    std::fs::write(&other, ddf_text("conn1", false, false, "int64")).expect("write");
    // A DDF that describes other domains only.
    expect(connect_file(&good, "conn2"), RTAPI_ERROR_DDF_INVALID);
    expect(connect_file(&other, "conn1"), RTAPI_ERROR_LAYOUT_MISMATCH);
    assert!(detail().contains("SUBSCRIBE item: the DDF has b int64[1], the running domain b int32[1]"), "{}", detail());
    // The same items in another order (VILLASnode's two DDF generators disagree on it):
    // accepted, and every item is reached through the running domain's layout.
    let reordered = dir.path().join("reordered.ddf");
    std::fs::write(
        &reordered,
        r#"<orchestra><domain name="conn1"><synchronous>no</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>
        <set name="PUBLISH"><item name="v"><type>float32</type><length>3</length></item><item name="x"><type>float64</type></item></set>
        <set name="SUBSCRIBE"><item name="b"><type>int32</type></item><item name="a"><type>float64</type><default>2.5</default></item></set>
        </domain></orchestra>"#,
    )
    .expect("write");
    expect(connect_file(&reordered, "conn1"), RTAPI_SUCCESS);
    let mut item_key: c_ushort = 0;
    // SAFETY: NUL-terminated literal, valid out-pointer.
    expect(unsafe { RTGetKeyForItem(c"x".as_ptr(), &mut item_key) }, RTAPI_SUCCESS);
    assert_eq!(item_key, 0, "keys follow the running domain, where x comes first");
    expect(RTDisconnect(), RTAPI_SUCCESS);
    // One item more: refused, naming it.
    let more = dir.path().join("more.ddf");
    std::fs::write(
        &more,
        ddf_text("conn1", false, false, "int32").replace(
            "</set>\n        </domain>",
            "<item name=\"c\"><type>uint8</type></item></set>\n        </domain>",
        ),
    )
    .expect("write");
    expect(connect_file(&more, "conn1"), RTAPI_ERROR_LAYOUT_MISMATCH);
    assert!(detail().contains("SUBSCRIBE item 'c' is not in the running domain"), "{}", detail());
    assert_eq!(count("conn1"), Ok(0), "a refused connection leaves no trace");
    expect(connect_file(&good, "conn1"), RTAPI_SUCCESS);
    let _k2 = key();
    expect(connect("conn1", 0), RTAPI_ERROR_TOO_MANY_CONNECTIONS);
    expect(RTSetConnectionKey(_k), RTAPI_SUCCESS);
    expect(RTDisconnect(), RTAPI_SUCCESS);
}

#[test]
fn exclusive_domain_refuses_a_second_writer() {
    let _turn = serial();
    let _fw = framework("excl1", false, false);
    let a = key();
    expect(connect("excl1", 2), RTAPI_SUCCESS);
    let b = key();
    expect(connect("excl1", 2), RTAPI_SUCCESS);
    assert_eq!(count("excl1"), Ok(2));
    expect(RTSetConnectionKey(a), RTAPI_SUCCESS);
    expect(publish("a", &1.0f64.to_ne_bytes()), RTAPI_SUCCESS);
    expect(RTSetConnectionKey(b), RTAPI_SUCCESS);
    expect(RTPublishLock(), RTAPI_ERROR_NOT_OWNER);
    expect(publish("a", &2.0f64.to_ne_bytes()), RTAPI_ERROR_NOT_OWNER);
    // Still connected: reading works; once the owner leaves, b may write.
    expect(subscribe("x", &mut [0; 8]), RTAPI_SUCCESS);
    expect(RTSetConnectionKey(a), RTAPI_SUCCESS);
    expect(RTDisconnect(), RTAPI_SUCCESS);
    expect(RTSetConnectionKey(b), RTAPI_SUCCESS);
    expect(publish("a", &2.0f64.to_ne_bytes()), RTAPI_SUCCESS);
    expect(RTDisconnect(), RTAPI_SUCCESS);
}

#[test]
fn timeout_waiting_for_a_step() {
    let _turn = serial();
    let _fw = framework("slow1", true, true);
    key();
    expect(connect("slow1", 1), RTAPI_SUCCESS);
    // The framework never steps.
    expect(RTSubscribeLock(), RTAPI_ERROR_TIMEOUT);
    // A timeout leaves the connection in place.
    expect(RTPublishLock(), RTAPI_ERROR_TIMEOUT);
    expect(RTDisconnect(), RTAPI_SUCCESS);
}

#[test]
fn framework_stop_disconnects_with_the_product_codes() {
    let _turn = serial();
    for (lock, want) in [
        (RTSubscribeLock as extern "C" fn() -> RTAPIReturn_t, RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED),
        (RTPublishLock, RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED),
    ] {
        let fw = framework("stop1", false, true);
        let k = key();
        expect(connect("stop1", 2), RTAPI_SUCCESS);
        let mut status: *mut c_uint = null_mut();
        // SAFETY: valid out-pointer.
        expect(unsafe { RTGetConnectionStatusPtr(k, &mut status) }, RTAPI_SUCCESS);
        // SAFETY: valid until RTDisconnect; volatile like C.
        assert_eq!(unsafe { status.read_volatile() }, 1);
        drop(fw);
        // SAFETY: still valid: the connection maps the segment until it disconnects.
        assert_eq!(unsafe { status.read_volatile() }, 2);
        expect(lock(), want);
        // Every publish and subscribe call says so until RTDisconnect (VILLASnode stops on
        // these codes), and the status word stays readable.
        for _ in 0..2 {
            expect(RTSubscribeLock(), RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED);
            expect(RTPublishLock(), RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED);
            expect(publish("a", &1.0f64.to_ne_bytes()), RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED);
            expect(RTWaitReadyToGo(), RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED);
        }
        // SAFETY: still valid until RTDisconnect.
        assert_eq!(unsafe { status.read_volatile() }, 2);
        expect(RTDisconnect(), RTAPI_SUCCESS);
        expect(RTSubscribeLock(), RTAPI_ERROR_NOT_CONNECTED);
        expect(RTDisconnect(), RTAPI_ERROR_NOT_CONNECTED);
    }
}

/// A framework that restarts: the key of a connection it left connects again, with or
/// without RTDisconnect first.
#[test]
fn a_stopped_connection_connects_again_to_a_restarted_framework() {
    let _turn = serial();
    let fw = framework("again1", false, true);
    key();
    expect(connect("again1", 2), RTAPI_SUCCESS);
    drop(fw);
    expect(RTSubscribeLock(), RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED);
    let _fw = framework("again1", false, true);
    expect(connect("again1", 2), RTAPI_SUCCESS);
    expect(publish("a", &3.0f64.to_ne_bytes()), RTAPI_SUCCESS);
    expect(RTDisconnect(), RTAPI_SUCCESS);
}

/// RTSetupRefMemRemoteConnection: succeeds on a domain served here; before the connection it
/// is remembered, and a connect that finds no framework (or a framework that stopped) says to
/// start a mirror gateway.
#[test]
fn remote_connection_setup_checks_the_domain_is_served_here() {
    let _turn = serial();
    let card = c"rfm2g";
    // SAFETY: NULL is allowed (reported); the others are NUL-terminated literals.
    unsafe {
        key();
        expect(RTSetupRefMemRemoteConnection(null(), 0), RTAPI_ERROR_NULL_POINTER);
        expect(RTSetupRefMemRemoteConnection(card.as_ptr(), -1), RTAPI_ERROR_INVALID_ARGUMENT);
        // Nothing serves the domain: the connect says what to start.
        expect(RTSetupRefMemRemoteConnection(card.as_ptr(), 0), RTAPI_SUCCESS);
        expect(connect("remote_nowhere1", 1), RTAPI_ERROR_REMOTE_NOT_SERVED);
        assert!(detail().contains("tutti gateway --mirror"), "{}", detail());
        // Served here: the call succeeds after the connection too.
        let fw = framework("remote1", false, true);
        key();
        expect(connect("remote1", 2), RTAPI_SUCCESS);
        expect(RTSetupRefMemRemoteConnection(card.as_ptr(), 0), RTAPI_SUCCESS);
        drop(fw);
        expect(RTSetupRefMemRemoteConnection(card.as_ptr(), 0), RTAPI_ERROR_REMOTE_NOT_SERVED);
        expect(RTDisconnect(), RTAPI_SUCCESS);
    }
}

#[test]
fn connection_removed_by_the_framework_is_reported_and_closed() {
    let _turn = serial();
    let mut fw = framework("lost1", false, true);
    key();
    expect(connect("lost1", 2), RTAPI_SUCCESS);
    // Remove the connection as the framework does for a connection it judges dead.
    assert!(fw.domain("lost1").expect("domain").remove_connection(0));
    expect(publish("a", &1.0f64.to_ne_bytes()), RTAPI_ERROR_CONNECTION_LOST);
    expect(RTSubscribeLock(), RTAPI_ERROR_CONNECTION_LOST);
    expect(RTDisconnect(), RTAPI_SUCCESS);
    expect(RTDisconnect(), RTAPI_ERROR_NOT_CONNECTED);
}

/// Writes a fake segment for `domain`: the magic, then `version` and `header_bytes`.
fn fake_segment(domain: &str, version: u32, header_bytes: u32) -> ShmFile {
    let guard = ShmFile(shm_path(&ns(), domain));
    let mut bytes = vec![0u8; 4096];
    bytes[0..8].copy_from_slice(b"TUTTISHM");
    bytes[8..12].copy_from_slice(&version.to_le_bytes());
    bytes[12..16].copy_from_slice(&header_bytes.to_le_bytes());
    bytes[16..24].copy_from_slice(&4096u64.to_le_bytes());
    std::fs::File::create(&guard.0).and_then(|mut f| f.write_all(&bytes)).expect("writing a fake segment");
    guard
}

#[test]
fn damaged_or_foreign_segments() {
    let _turn = serial();
    key();
    // This library's own version, with a header size no segment of it has.
    let _corrupt = fake_segment("corrupt1", VERSION, 999);
    expect(connect("corrupt1", 0), RTAPI_ERROR_CORRUPT_SEGMENT);
    assert_eq!(count("corrupt1"), Err(RTAPI_ERROR_CORRUPT_SEGMENT));
    let _future = fake_segment("future1", 99, 1024);
    expect(connect("future1", 0), RTAPI_ERROR_VERSION_MISMATCH);
    // A directory where the segment should be: opening it fails in the system.
    let dir = ShmFile(shm_path(&ns(), "dir1"));
    std::fs::create_dir(&dir.0).expect("mkdir");
    expect(connect("dir1", 0), RTAPI_ERROR_SYSTEM);
}

#[test]
fn a_successful_call_leaves_no_detail_and_an_old_pointer_stays_readable() {
    let _turn = serial();
    expect(RTSetConnectionKey(4_000_000_000), RTAPI_ERROR_UNKNOWN_CONNECTION_KEY);
    let held = RTGetLastErrorDetail();
    assert!(detail().contains("4000000000"), "{}", detail());
    let mut k = 0;
    // SAFETY: `k` is a valid out-pointer.
    expect(unsafe { RTNewConnectionKey(&mut k) }, RTAPI_SUCCESS);
    assert_eq!(detail(), "", "a success left the earlier failure's detail");
    // SAFETY: a pointer from before the success is still valid, and now reads "".
    assert_eq!(unsafe { CStr::from_ptr(held) }.to_bytes(), b"");
    expect(RTSetConnectionKey(0), RTAPI_SUCCESS);
}
