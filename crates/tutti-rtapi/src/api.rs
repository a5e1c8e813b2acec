//! The exported calls, with the product's names and C signatures (`docs/rtapi.md`). Each one
//! checks its pointers, runs under a guard that catches panics, and returns an `RTAPI_*` code; the semantics are
//! in docs/rtapi.md.

use std::ffi::{c_char, c_double, c_int, c_uint, c_ushort, c_void};
use std::time::Duration;

use tutti_core::ddf::Role;
use tutti_core::shm::{Participant, ShmError, StepGate, WaitMode};

use crate::checkpoint::{Callbacks, RTRestoreStateCallback_t, RTSaveStateCallback_t};
use crate::codes::*;
use crate::ffi::{bytes_in, bytes_out, c_str, guard, last_detail_ptr, write_out, CallResult, Failure};
use crate::state::{check_size, leaf_by_key, leaf_by_path, leaf_in, state, Conn};

/// Creates a connection key (1, 2, …). Key 0 exists from the start and is the current
/// connection until RTSetConnectionKey selects another.
///
/// # Safety
/// `connKey` must be NULL or valid for writing one `unsigned int`.
#[no_mangle]
pub unsafe extern "C" fn RTNewConnectionKey(connKey: *mut c_uint) -> RTAPIReturn_t {
    guard("RTNewConnectionKey", || {
        crate::ffi::non_null(connKey.cast_const(), "connKey")?;
        let key = state().new_key()?;
        // SAFETY: the caller promises `connKey` is NULL (refused above) or writable.
        unsafe { write_out(connKey, "connKey", key) }
    })
}

/// Makes `connKey` the current connection: every call without a key argument works on it.
#[no_mangle]
pub extern "C" fn RTSetConnectionKey(connKey: c_uint) -> RTAPIReturn_t {
    guard("RTSetConnectionKey", || state().set_current(connKey))
}

/// Connects the current connection to the running domain `domainName`, waiting up to
/// `timeoutSeconds` for its framework and then (unless skipped) for wait-to-go. The layout
/// is read from the live segment. `timeoutSeconds` is also the lock timeout (5 s if 0).
///
/// # Safety
/// `domainName` must be NULL or a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn RTConnect(domainName: *const c_char, timeoutSeconds: c_int) -> RTAPIReturn_t {
    guard("RTConnect", || {
        // SAFETY: the caller promises a NUL-terminated string or NULL.
        let domain = unsafe { c_str(domainName, "domainName") }?;
        crate::state::connect(domain, None, timeoutSeconds)
    })
}

/// As RTConnect, after loading the DDF at `ddfPath` and checking that it describes the live
/// domain exactly (items, types, lengths, flags): RTAPI_ERROR_LAYOUT_MISMATCH otherwise.
///
/// # Safety
/// `ddfPath` and `domainName` must be NULL or NUL-terminated strings.
#[no_mangle]
pub unsafe extern "C" fn RTConnectWithFile(
    ddfPath: *const c_char,
    domainName: *const c_char,
    timeoutSeconds: c_int,
) -> RTAPIReturn_t {
    guard("RTConnectWithFile", || {
        // SAFETY: the caller promises NUL-terminated strings or NULL.
        let path = unsafe { c_str(ddfPath, "ddfPath") }?;
        // SAFETY: as above.
        let domain = unsafe { c_str(domainName, "domainName") }?;
        crate::state::connect(domain, Some(path), timeoutSeconds)
    })
}

/// Disconnects the current connection. Its key stays valid (it can connect again); the
/// pointers from RTGetBuffer, RTGetBufferInfo and RTGetConnectionStatusPtr become invalid.
#[no_mangle]
pub extern "C" fn RTDisconnect() -> RTAPIReturn_t {
    guard("RTDisconnect", || state().disconnect())
}

/// One direction of the exchange, as its calls name it: what RTPublish and RTSubscribe, and
/// their lock pairs, have in common is written once, over this.
struct Direction {
    side: Side,
    /// The set the direction exchanges (RTPublish writes SUBSCRIBE, RTSubscribe reads PUBLISH).
    role: Role,
    call: &'static str,
    lock: &'static str,
    unlock: &'static str,
    /// Whether the connection is between the lock and the unlock.
    locked: fn(&mut Conn) -> &mut bool,
    /// The part of the lock that may wait for the framework, run with the state released.
    gate_op: CoreOp<Option<StepGate>>,
    /// What the lock does in the core.
    lock_op: CoreOp<u64>,
    /// What the unlock does in the core, if anything.
    unlock_op: Option<CoreOp<()>>,
}

/// An operation of the core on the current connection's participant.
type CoreOp<T> = fn(&mut Participant) -> Result<T, ShmError>;

const PUBLISH: Direction = Direction {
    side: Side::Publish,
    role: Role::Subscribe,
    call: "RTPublish",
    lock: "RTPublishLock",
    unlock: "RTPublishUnlock",
    locked: |c| &mut c.pub_locked,
    gate_op: Participant::publish_gate,
    lock_op: Participant::publish_lock,
    unlock_op: Some(Participant::commit),
};

const SUBSCRIBE: Direction = Direction {
    side: Side::Subscribe,
    role: Role::Publish,
    call: "RTSubscribe",
    lock: "RTSubscribeLock",
    unlock: "RTSubscribeUnlock",
    locked: |c| &mut c.sub_locked,
    gate_op: Participant::read_gate,
    lock_op: Participant::subscribe_lock,
    unlock_op: None,
};

/// RTPublish and RTSubscribe: resolves `path` once to the item's index in the set `d`
/// exchanges (nothing is copied or allocated), checks the size, gets the caller's buffer with
/// `buffer`, refuses a synchronous domain outside a lock pair, and runs `op(participant,
/// locked, index, buffer)` on the current connection.
fn exchange_item<B>(
    d: &Direction,
    path: &str,
    size: c_uint,
    buffer: impl FnOnce() -> CallResult<B>,
    op: impl FnOnce(&mut Participant, bool, usize, B) -> Result<(), ShmError>,
) -> CallResult {
    let mut st = state();
    let conn = st.current()?;
    let locked = *(d.locked)(conn);
    let p = &conn.participant;
    let item = leaf_in(p, d.role, path)?;
    check_size(p, item.leaf, size)?;
    let index = item.index;
    let buf = buffer()?;
    if !locked && p.info().flags.synchronous {
        return Err(Failure::new(
            RTAPI_ERROR_OUT_OF_ORDER,
            format!("domain '{}' is synchronous: call {} between {} and {}", p.info().name, d.call, d.lock, d.unlock),
        ));
    }
    st.exchange(d.side, |c| op(&mut c.participant, locked, index, buf))
}

/// RTPublishLock and RTSubscribeLock. The wait for the framework (the next step to read, a
/// step to answer) runs with the library's state released, so that another thread's calls
/// go on meanwhile: a writer thread beside a reader looping on RTSubscribeLock waits for
/// nothing but its own work (docs/rtapi.md, "Threads").
fn lock(d: &Direction) -> CallResult {
    let twice = || Failure::new(RTAPI_ERROR_OUT_OF_ORDER, format!("{} called twice without {}", d.lock, d.unlock));
    let (key, gate) = {
        let mut st = state();
        if *(d.locked)(st.current()?) {
            return Err(twice());
        }
        let key = st.current_key();
        (key, st.exchange_on(key, d.side, |c| (d.gate_op)(&mut c.participant))?)
    };
    let waited = gate.map_or(Ok(()), |g| g.wait());
    let mut st = state();
    // Another thread may have taken this lock while we waited.
    if *(d.locked)(st.connected(key)?) {
        return Err(twice());
    }
    st.exchange_on(key, d.side, |c| {
        waited?;
        (d.lock_op)(&mut c.participant)?;
        *(d.locked)(c) = true;
        Ok(())
    })
}

/// RTPublishUnlock and RTSubscribeUnlock.
fn unlock(d: &Direction) -> CallResult {
    let mut st = state();
    let locked = (d.locked)(st.current()?);
    if !*locked {
        return Err(Failure::new(RTAPI_ERROR_OUT_OF_ORDER, format!("{} without {}", d.unlock, d.lock)));
    }
    *locked = false;
    match d.unlock_op {
        Some(op) => st.exchange(d.side, |c| op(&mut c.participant)),
        None => Ok(()),
    }
}

/// Writes the SUBSCRIBE item `itemPath` (`sizeBytes` must equal its size). Inside
/// RTPublishLock/RTPublishUnlock it is staged and committed at the unlock; outside a lock
/// pair in an asynchronous domain it is committed at once; in a synchronous domain outside
/// a lock pair it returns RTAPI_ERROR_OUT_OF_ORDER.
///
/// # Safety
/// `itemPath` must be NULL or a NUL-terminated string; `value` NULL or valid for reading
/// `sizeBytes` bytes.
#[no_mangle]
pub unsafe extern "C" fn RTPublish(itemPath: *const c_char, value: *const c_void, sizeBytes: c_uint) -> RTAPIReturn_t {
    guard("RTPublish", || {
        // SAFETY: the caller promises a NUL-terminated string or NULL.
        let path = unsafe { c_str(itemPath, "itemPath") }?;
        exchange_item(
            &PUBLISH,
            path,
            sizeBytes,
            // SAFETY: the caller promises `sizeBytes` readable bytes at `value` (or NULL).
            || unsafe { bytes_in(value.cast(), sizeBytes as usize, "value") },
            |p, locked, index, bytes| {
                if locked {
                    p.stage_at(index, bytes)
                } else {
                    p.publish_lock()?;
                    p.stage_at(index, bytes)?;
                    p.commit()
                }
            },
        )
    })
}

/// Reads the PUBLISH item `itemPath` into `value` (`sizeBytes` must equal its size). Inside
/// RTSubscribeLock/RTSubscribeUnlock it reads the lock's snapshot; outside a lock pair in an
/// asynchronous domain it takes a fresh snapshot; in a synchronous domain outside a lock
/// pair it returns RTAPI_ERROR_OUT_OF_ORDER.
///
/// # Safety
/// `itemPath` must be NULL or a NUL-terminated string; `value` NULL or valid for writing
/// `sizeBytes` bytes.
#[no_mangle]
pub unsafe extern "C" fn RTSubscribe(itemPath: *const c_char, value: *mut c_void, sizeBytes: c_uint) -> RTAPIReturn_t {
    guard("RTSubscribe", || {
        // SAFETY: the caller promises a NUL-terminated string or NULL.
        let path = unsafe { c_str(itemPath, "itemPath") }?;
        exchange_item(
            &SUBSCRIBE,
            path,
            sizeBytes,
            // SAFETY: the caller promises `sizeBytes` writable bytes at `value` (or NULL).
            || unsafe { bytes_out(value.cast(), sizeBytes as usize, "value") },
            |p, locked, index, out| {
                if !locked {
                    p.subscribe_lock()?;
                }
                p.reads_item(index);
                // The index was resolved in this participant's own layout: always there.
                if let Some(bytes) = p.snapshot_item(index) {
                    out.copy_from_slice(bytes);
                }
                Ok(())
            },
        )
    })
}

/// Starts a write of the SUBSCRIBE set: claims it where one writer is allowed (else
/// RTAPI_ERROR_NOT_OWNER) and, in a synchronous domain, waits for the step to answer.
#[no_mangle]
pub extern "C" fn RTPublishLock() -> RTAPIReturn_t {
    guard("RTPublishLock", || lock(&PUBLISH))
}

/// Commits what was staged since RTPublishLock (RTPublish calls and writes through the
/// SUBSCRIBE buffers) atomically; in a synchronous domain this is the connection's
/// contribution to the step.
#[no_mangle]
pub extern "C" fn RTPublishUnlock() -> RTAPIReturn_t {
    guard("RTPublishUnlock", || unlock(&PUBLISH))
}

/// Takes a consistent snapshot of the PUBLISH set into the connection's own buffer; in a
/// synchronous domain waits for the framework's next step (each step is read once).
#[no_mangle]
pub extern "C" fn RTSubscribeLock() -> RTAPIReturn_t {
    guard("RTSubscribeLock", || lock(&SUBSCRIBE))
}

/// Ends a read started by RTSubscribeLock (the snapshot stays readable until the next lock).
#[no_mangle]
pub extern "C" fn RTSubscribeUnlock() -> RTAPIReturn_t {
    guard("RTSubscribeUnlock", || unlock(&SUBSCRIBE))
}

/// The item key of `itemPath` in the current connection's domain: its index among the
/// PUBLISH items, then the SUBSCRIBE items, in DDF order.
///
/// # Safety
/// `itemPath` must be NULL or a NUL-terminated string; `itemKey` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn RTGetKeyForItem(itemPath: *const c_char, itemKey: *mut c_ushort) -> RTAPIReturn_t {
    guard("RTGetKeyForItem", || {
        // SAFETY: the caller promises a NUL-terminated string or NULL.
        let path = unsafe { c_str(itemPath, "itemPath") }?;
        crate::ffi::non_null(itemKey.cast_const(), "itemKey")?;
        let mut st = state();
        let key = leaf_by_path(&st.current()?.participant, path)?.key;
        // SAFETY: the caller promises `itemKey` is writable (NULL was refused above).
        unsafe { write_out(itemKey, "itemKey", key) }
    })
}

/// The element size in bytes and the element count of `itemPath`.
///
/// # Safety
/// `itemPath` must be NULL or a NUL-terminated string; `typeSize` and `length` NULL or
/// writable.
#[no_mangle]
pub unsafe extern "C" fn RTGetInfoForItem(
    itemPath: *const c_char,
    typeSize: *mut c_uint,
    length: *mut c_ushort,
) -> RTAPIReturn_t {
    guard("RTGetInfoForItem", || {
        // SAFETY: the caller promises a NUL-terminated string or NULL.
        let path = unsafe { c_str(itemPath, "itemPath") }?;
        crate::ffi::non_null(typeSize.cast_const(), "typeSize")?;
        crate::ffi::non_null(length.cast_const(), "length")?;
        let mut st = state();
        let leaf = leaf_by_path(&st.current()?.participant, path)?.leaf;
        // SAFETY: both pointers are writable as the caller promises (NULL refused above).
        unsafe {
            write_out(typeSize, "typeSize", leaf.ty.size())?;
            write_out(length, "length", leaf.length)
        }
    })
}

/// A pointer to item `itemKey` in connection `connKey`'s own buffers: the snapshot of the
/// PUBLISH set (refreshed by RTSubscribeLock) for PUBLISH items, the staging buffer of the
/// SUBSCRIBE set (committed by RTPublishUnlock) for SUBSCRIBE items. Elements are
/// contiguous, typeSize apart, in native byte order. Valid until RTDisconnect.
///
/// # Safety
/// `buffer` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn RTGetBuffer(connKey: c_uint, itemKey: c_ushort, buffer: *mut *mut c_void) -> RTAPIReturn_t {
    guard("RTGetBuffer", || {
        crate::ffi::non_null(buffer.cast_const(), "buffer")?;
        let mut st = state();
        let p = st.participant(connKey)?;
        let (role, range) = leaf_by_key(p, itemKey).map(|(role, leaf)| (role, leaf.range()))?;
        if role == Role::Publish {
            // Its buffer is read from now on (the key of a PUBLISH item is its index).
            p.reads_item(usize::from(itemKey));
        }
        let set = match role {
            Role::Publish => p.snapshot_mut(),
            Role::Subscribe => p.staging_mut(),
        };
        let ptr = set[range].as_mut_ptr().cast::<c_void>();
        // SAFETY: `buffer` is writable as the caller promises (NULL refused above).
        unsafe { write_out(buffer, "buffer", ptr) }
    })
}

/// The connection's whole PUBLISH snapshot and SUBSCRIBE staging buffers, with their sizes
/// (a NULL pointer and size 0 for an empty set). Valid until RTDisconnect.
///
/// # Safety
/// The four out-pointers must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn RTGetBufferInfo(
    connKey: c_uint,
    pubBuffer: *mut *mut c_char,
    pubSize: *mut c_uint,
    subBuffer: *mut *mut c_char,
    subSize: *mut c_uint,
) -> RTAPIReturn_t {
    guard("RTGetBufferInfo", || {
        crate::ffi::non_null(pubBuffer.cast_const(), "pubBuffer")?;
        crate::ffi::non_null(pubSize.cast_const(), "pubSize")?;
        crate::ffi::non_null(subBuffer.cast_const(), "subBuffer")?;
        crate::ffi::non_null(subSize.cast_const(), "subSize")?;
        let mut st = state();
        let p = st.participant(connKey)?;
        let whole = |b: &mut [u8]| -> (*mut c_char, c_uint) {
            if b.is_empty() {
                (std::ptr::null_mut(), 0)
            } else {
                (b.as_mut_ptr().cast(), b.len() as c_uint)
            }
        };
        let (pb, ps) = whole(p.snapshot_mut());
        let (sb, ss) = whole(p.staging_mut());
        // SAFETY: the four pointers are writable as the caller promises (NULL refused above).
        unsafe {
            write_out(pubBuffer, "pubBuffer", pb)?;
            write_out(pubSize, "pubSize", ps)?;
            write_out(subBuffer, "subBuffer", sb)?;
            write_out(subSize, "subSize", ss)
        }
    })
}

/// A pointer to the live status word of connection `connKey`'s domain: 1 while the
/// framework runs, 2 once it has stopped (0 while it initialises). Read it as `volatile`
/// (another process writes it); valid until RTDisconnect.
///
/// # Safety
/// `status` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn RTGetConnectionStatusPtr(connKey: c_uint, status: *mut *mut c_uint) -> RTAPIReturn_t {
    guard("RTGetConnectionStatusPtr", || {
        crate::ffi::non_null(status.cast_const(), "status")?;
        let mut st = state();
        let word = st.participant(connKey)?.state_word_ptr();
        // SAFETY: `status` is writable as the caller promises (NULL refused above).
        unsafe { write_out(status, "status", word) }
    })
}

/// Blocks while the framework holds its wait-to-go signal (at most the connect timeout).
#[no_mangle]
pub extern "C" fn RTWaitReadyToGo() -> RTAPIReturn_t {
    guard("RTWaitReadyToGo", wait_ready)
}

fn wait_ready() -> Result<(), Failure> {
    state().exchange(Side::Subscribe, |c| c.participant.wait_ready_to_go())
}

/// Whether the next RTConnect / RTConnectWithFile returns without waiting for wait-to-go.
#[no_mangle]
pub extern "C" fn RTSetSkipWaitToGoAtConnection(skip: bool) -> RTAPIReturn_t {
    guard("RTSetSkipWaitToGoAtConnection", || {
        state().set_skip_wait_to_go(skip);
        Ok(())
    })
}

/// The product's call for a domain whose DDF connection is `remote` (a client on another
/// machine than the framework, through a reflective-memory card `cardName` at PCI index
/// `pciIndex`). In tutti another machine is reached through DDS, with `tutti gateway
/// --mirror DDF` serving the domain on the client's machine: on a connected key it succeeds
/// when the domain is served (by its framework or a mirror) and returns
/// RTAPI_ERROR_REMOTE_NOT_SERVED otherwise; before the connection it is remembered, and a
/// connect of that key that finds no framework returns RTAPI_ERROR_REMOTE_NOT_SERVED. The card
/// and index are not used. A negative `pciIndex`: RTAPI_ERROR_INVALID_ARGUMENT.
///
/// # Safety
/// `cardName` must be NULL or a NUL-terminated string.
#[no_mangle]
pub unsafe extern "C" fn RTSetupRefMemRemoteConnection(cardName: *const c_char, pciIndex: c_int) -> RTAPIReturn_t {
    guard("RTSetupRefMemRemoteConnection", || {
        // SAFETY: the caller promises a NUL-terminated string or NULL.
        let card = unsafe { c_str(cardName, "cardName") }?;
        state().setup_remote(card, pciIndex)
    })
}

fn flag_delay(microseconds: c_uint) -> WaitMode {
    if microseconds == 0 {
        WaitMode::Spin
    } else {
        WaitMode::Poll(Duration::from_micros(u64::from(microseconds)))
    }
}

/// Waits by polling every `microseconds` µs instead of sleeping in the kernel (0 = spin).
/// Applies to every connection of the process, now and later.
#[no_mangle]
pub extern "C" fn RTDefineFlagDelay(microseconds: c_uint) -> RTAPIReturn_t {
    guard("RTDefineFlagDelay", || {
        state().set_wait(flag_delay(microseconds));
        Ok(())
    })
}

/// Same effect as RTDefineFlagDelay in this implementation (the product distinguishes a
/// tool-side flag; here there is one waiting mechanism).
#[no_mangle]
pub extern "C" fn RTUseFlagWithTool(microseconds: c_uint) -> RTAPIReturn_t {
    guard("RTUseFlagWithTool", || {
        state().set_wait(flag_delay(microseconds));
        Ok(())
    })
}

/// The number of participants now in domain `domainName` (this process's included; not the
/// DDS writers and readers a gateway bridges). Works without being connected, from the
/// domain's segment (in TUTTI_NAMESPACE).
///
/// # Safety
/// `domainName` must be NULL or a NUL-terminated string; `count` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn RTGetConnectionCount(domainName: *const c_char, count: *mut c_uint) -> RTAPIReturn_t {
    guard("RTGetConnectionCount", || {
        // SAFETY: the caller promises a NUL-terminated string or NULL.
        let domain = unsafe { c_str(domainName, "domainName") }?;
        crate::ffi::non_null(count.cast_const(), "count")?;
        let n = state().connection_count(domain)?;
        // SAFETY: `count` is writable as the caller promises (NULL refused above).
        unsafe { write_out(count, "count", n) }
    })
}

/// Event-driven domains (tutti's extension, docs/timing.md): the current connection is next
/// due at the first step at or after simulated time `simTime` (seconds); a time within a
/// millionth of a step of a step's time counts as that step. Once: asked again at each due
/// step as needed. It takes effect when the connection asks for its next step (its next
/// RTSubscribeLock, or RTPublishLock if it only writes). In a lock-step or asynchronous
/// domain it changes nothing. RTAPI_ERROR_INVALID_ARGUMENT for a time that is not a number.
#[no_mangle]
pub extern "C" fn RTRequestTime(simTime: c_double) -> RTAPIReturn_t {
    guard("RTRequestTime", || state().exchange(Side::Subscribe, |c| c.participant.request_time(simTime)))
}

/// Event-driven domains (tutti's extension, docs/timing.md): the current connection is also
/// due at any step whose PUBLISH set differs from the step before (`on`), or no longer.
#[no_mangle]
pub extern "C" fn RTSetWakeOnChange(on: bool) -> RTAPIReturn_t {
    guard("RTSetWakeOnChange", || {
        state().exchange(Side::Subscribe, |c| {
            c.participant.set_wake_on_change(on);
            Ok(())
        })
    })
}

/// Event-driven domains (tutti's extension, docs/timing.md): the current connection is due
/// every `seconds` of simulated time, at the steps whose time is a multiple of it (RT-LAB's
/// multi-rate); `seconds` must be a whole multiple of the framework's step
/// (RTAPI_ERROR_INVALID_ARGUMENT otherwise). 0 turns the period off.
#[no_mangle]
pub extern "C" fn RTSetPeriod(seconds: c_double) -> RTAPIReturn_t {
    guard("RTSetPeriod", || state().exchange(Side::Subscribe, |c| c.participant.set_period(seconds)))
}

/// The simulated time (seconds) of the step the current connection is at: the step its last
/// RTSubscribeLock returned (in an asynchronous domain, the framework's latest step).
///
/// # Safety
/// `simTime` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn RTGetSimulationTime(simTime: *mut c_double) -> RTAPIReturn_t {
    guard("RTGetSimulationTime", || {
        crate::ffi::non_null(simTime.cast_const(), "simTime")?;
        let t = state().exchange(Side::Subscribe, |c| Ok(c.participant.simulation_time()))?;
        // SAFETY: `simTime` is writable as the caller promises (NULL refused above).
        unsafe { write_out(simTime, "simTime", t) }
    })
}

/// Checkpoints (tutti's extension, docs/rtapi.md "Checkpoints"): the current connection
/// keeps a state that `save` hands over and `restore` takes back as bytes, so that `tutti ctl
/// save` and `restore`, `tutti run --restore` and a ROS 2 `ResetSimulation` with SCOPE_STATE
/// include it. Call it before RTConnect (the connection then says so from the start, and the
/// run's checkpoint of step 0 has it) or after. The callbacks are called at a step boundary,
/// from within RTSubscribeLock (or RTPublishLock for a connection that only writes) while it
/// waits for the next step, in the calling thread, with `context`; they must not call the
/// RTAPI. `save` sets `*buffer` to bytes it owns, valid until the next call into the
/// component, and `*sizeBytes` to their length; both return 0 on success.
/// RTAPI_ERROR_NULL_POINTER if either is NULL.
#[no_mangle]
pub extern "C" fn RTSetStateCallbacks(
    save: RTSaveStateCallback_t,
    restore: RTRestoreStateCallback_t,
    context: *mut c_void,
) -> RTAPIReturn_t {
    guard("RTSetStateCallbacks", || {
        let missing = |what: &str| Failure::new(RTAPI_ERROR_NULL_POINTER, format!("{what} is NULL"));
        let save = save.ok_or_else(|| missing("save"))?;
        let restore = restore.ok_or_else(|| missing("restore"))?;
        state().set_callbacks(Callbacks { save, restore, context })
    })
}

/// The static text of a return code (a text saying so for an unknown code). Never NULL.
#[no_mangle]
pub extern "C" fn RTGetErrorMessage(code: RTAPIReturn_t) -> *const c_char {
    message(code).as_ptr()
}

/// Details of this thread's last call if it failed (domain, item, sizes, what to do), or ""
/// after a successful one — not in the product. Valid until this thread's next failing
/// call. Never NULL.
#[no_mangle]
pub extern "C" fn RTGetLastErrorDetail() -> *const c_char {
    std::panic::catch_unwind(last_detail_ptr).unwrap_or(c"".as_ptr())
}
