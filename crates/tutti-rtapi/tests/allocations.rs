//! Once a connection is made, the exchange calls allocate nothing: RTPublishLock,
//! RTPublish, RTPublishUnlock (the commit), RTSubscribeLock, RTSubscribe and
//! RTSubscribeUnlock, in an asynchronous domain and in a synchronous one whose framework
//! steps in another thread. An item is resolved to its index once per call, with no copy of
//! its layout entry and no second lookup in the core, and a commit reuses its scratch list.
//!
//! A counting global allocator counts the allocations of the test's own thread only (a
//! thread-local switch), so the framework's thread and the test harness do not disturb the
//! count.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ffi::{c_uint, CString};
use std::sync::Mutex;
use std::time::Duration;

use common::{namespace, Host};
use rtapi::*;
use tutti_core::ddf::{self, Model};
use tutti_core::shm::{Framework, FrameworkOptions};

struct Counting;

thread_local! {
    /// Whether this thread's allocations are counted now, and how many were.
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

fn count_one() {
    // `try_with`: an allocation while the thread's locals are torn down is not counted.
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
    }
}

// SAFETY: every call is passed on to the system allocator unchanged; counting touches only
// const-initialised thread-locals, which never allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: as above.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f`, counting the allocations this thread makes meanwhile.
fn allocations_of(f: impl FnOnce()) -> u64 {
    let before = COUNT.with(Cell::get);
    COUNTING.with(|c| c.set(true));
    f();
    COUNTING.with(|c| c.set(false));
    COUNT.with(Cell::get) - before
}

/// The library's state is process-wide: the tests take turns.
static SERIAL: Mutex<()> = Mutex::new(());

fn model(domain: &str, sync: bool) -> Model {
    let yn = if sync { "yes" } else { "no" };
    let text = format!(
        r#"<orchestra><domain name="{domain}"><synchronous>{yn}</synchronous><multiplePublishAllowed>no</multiplePublishAllowed><states>no</states>
        <set name="PUBLISH"><item name="x"><type>float64</type></item><item name="v"><type>float32</type><length>3</length></item></set>
        <set name="SUBSCRIBE"><item name="a"><type>float64</type></item><item name="b"><type>int32</type></item><item name="c"><type>float64</type><length>4</length></item></set>
        </domain></orchestra>"#
    );
    ddf::parse_str(&text, "test.ddf").expect("DDF")
}

#[track_caller]
fn ok(code: RTAPIReturn_t) {
    assert_eq!(code, RTAPI_SUCCESS, "{}", rtapi::codes::name(code).unwrap_or("?"));
}

/// The item paths and buffers of one round, made before counting starts.
struct Round {
    a: CString,
    b: CString,
    c: CString,
    x: CString,
}

impl Round {
    fn new() -> Round {
        let c = |s: &str| CString::new(s).expect("no NUL");
        Round { a: c("a"), b: c("b"), c: c("c"), x: c("x") }
    }

    /// RTPublishLock, RTPublish ×3, RTPublishUnlock, RTSubscribeLock, RTSubscribe,
    /// RTSubscribeUnlock (`subscribe_first`: the read first, as a synchronous client answers
    /// the step it read). Returns the value of `x` read.
    fn run(&self, i: u32, subscribe_first: bool) -> f64 {
        let mut x = [0u8; 8];
        let subscribe = |x: &mut [u8; 8]| {
            ok(RTSubscribeLock());
            // SAFETY: a valid C string and an 8-byte buffer for a float64 item.
            ok(unsafe { RTSubscribe(self.x.as_ptr(), x.as_mut_ptr().cast(), 8) });
            ok(RTSubscribeUnlock());
        };
        if subscribe_first {
            subscribe(&mut x);
        }
        let a = f64::from(i).to_ne_bytes();
        let b = (i as i32).to_ne_bytes();
        let c = [f64::from(i); 4].map(f64::to_ne_bytes).concat_array();
        ok(RTPublishLock());
        // SAFETY: valid C strings and buffers of the items' sizes.
        unsafe {
            ok(RTPublish(self.a.as_ptr(), a.as_ptr().cast(), a.len() as c_uint));
            ok(RTPublish(self.b.as_ptr(), b.as_ptr().cast(), b.len() as c_uint));
            ok(RTPublish(self.c.as_ptr(), c.as_ptr().cast(), c.len() as c_uint));
        }
        ok(RTPublishUnlock());
        if !subscribe_first {
            subscribe(&mut x);
        }
        f64::from_ne_bytes(x)
    }
}

/// Four float64 as 32 bytes, on the stack.
trait ConcatArray {
    fn concat_array(self) -> [u8; 32];
}

impl ConcatArray for [[u8; 8]; 4] {
    fn concat_array(self) -> [u8; 32] {
        let mut out = [0u8; 32];
        for (chunk, v) in out.chunks_exact_mut(8).zip(self) {
            chunk.copy_from_slice(&v);
        }
        out
    }
}

fn connect(domain: &str) {
    let d = CString::new(domain).expect("no NUL");
    // SAFETY: a valid C string.
    ok(unsafe { RTConnect(d.as_ptr(), 5) });
}

const ROUNDS: u32 = 200;

#[test]
fn an_asynchronous_exchange_allocates_nothing() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let ns = namespace("alloc-async");
    std::env::set_var("TUTTI_NAMESPACE", &ns);
    let model = model("alloc_async", false);
    let mut fw =
        Framework::create(&model, &FrameworkOptions { namespace: ns, ..Default::default() }).expect("framework");
    let host = fw.domain("alloc_async").expect("domain");
    let mut publish = vec![0u8; host.info().publish.size as usize];
    publish[..8].copy_from_slice(&7.5f64.to_ne_bytes());
    host.step(&publish, 0.0).expect("step");
    connect("alloc_async");
    let round = Round::new();
    // Warm-up: the first commit and read fill the connection's buffers.
    for i in 0..3 {
        assert_eq!(round.run(i, false), 7.5);
    }
    let n = allocations_of(|| {
        for i in 0..ROUNDS {
            assert_eq!(round.run(i, false), 7.5);
        }
    });
    assert_eq!(n, 0, "{ROUNDS} rounds of the exchange allocated {n} times");
    let sub = fw.domain("alloc_async").expect("domain").read_subscribe().expect("SUBSCRIBE").to_vec();
    assert_eq!(&sub[..8], &f64::from(ROUNDS - 1).to_ne_bytes(), "the last commit arrived");
    ok(RTDisconnect());
}

#[test]
fn a_synchronous_exchange_allocates_nothing() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let ns = namespace("alloc-sync");
    std::env::set_var("TUTTI_NAMESPACE", &ns);
    let model = model("alloc_sync", true);
    let opts = FrameworkOptions { namespace: ns, timeout: Duration::from_secs(20), ..Default::default() };
    let host = Host::start(&model, opts, Duration::from_micros(200));
    connect("alloc_sync");
    let round = Round::new();
    let mut last = 0.0;
    for i in 0..3 {
        last = round.run(i, true);
    }
    let n = allocations_of(|| {
        for i in 0..ROUNDS {
            // Each step is read once, and the framework publishes x = k at step k.
            let x = round.run(i, true);
            assert_eq!(x, last + 1.0);
            last = x;
        }
    });
    assert_eq!(n, 0, "{ROUNDS} rounds of the exchange allocated {n} times");
    ok(RTDisconnect());
    drop(host);
}
