//! The library's state: the connection table and the "current connection", as in the
//! product. It is process-wide (one `Mutex`): calls from several threads take turns on it,
//! and no call holds it while it waits for the framework (the locks wait with it released,
//! see `api::lock`), so one thread's wait does not hold up another's calls.

use std::collections::BTreeMap;
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

use tutti_core::ddf::{self, Leaf, Role};
use tutti_core::shm::{ConnectOptions, Participant, ShmError, WaitMode};

use crate::codes::{self, *};
use crate::ffi::{CallResult, Failure};

/// The key that exists from the start and is current until `RTSetConnectionKey`: a client
/// that never asks for a key (the paper's `RTConnect`/`RTPublish`/`RTSubscribe`) uses it.
pub const DEFAULT_KEY: u32 = 0;

/// Lock timeout when `RTConnect` is given 0 seconds.
const DEFAULT_LOCK_TIMEOUT: Duration = Duration::from_secs(5);

/// A connected key: its participant and the lock pairs open on it. A key that is not
/// connected has none (dropping it releases the connection).
#[derive(Debug)]
pub struct Conn {
    pub participant: Participant,
    pub sub_locked: bool,
    pub pub_locked: bool,
    /// Set when the other side went away (the framework stopped, or it removed this
    /// connection): every exchange then fails the same way until `RTDisconnect`, and the
    /// buffers stay valid until then.
    pub ended: Option<Ended>,
}

/// Why a connection ended, with the detail of the error that ended it.
#[derive(Debug, Clone)]
pub struct Ended {
    stopped: bool,
    detail: String,
}

impl Ended {
    fn of(e: &ShmError) -> Ended {
        Ended { stopped: matches!(e, ShmError::FrameworkStopped { .. }), detail: e.to_string() }
    }

    /// The failure of any exchange on an ended connection: the product's UNMAPPED codes
    /// after the framework stopped, CONNECTION_LOST after it removed this connection.
    fn failure(&self, side: Side) -> Failure {
        let code = match (self.stopped, side) {
            (false, _) => RTAPI_ERROR_CONNECTION_LOST,
            (true, Side::Publish) => RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED,
            (true, _) => RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED,
        };
        Failure::new(code, format!("{} (call RTDisconnect, then connect again)", self.detail))
    }
}

#[derive(Debug)]
pub struct State {
    conns: BTreeMap<u32, Option<Conn>>,
    next_key: u32,
    current: u32,
    skip_wait_to_go: bool,
    wait: WaitMode,
    /// Keys for which `RTSetupRefMemRemoteConnection` was called: (card, PCI index).
    remote: BTreeMap<u32, (String, i32)>,
    /// Keys for which `RTSetStateCallbacks` was called: their connections keep a state.
    callbacks: BTreeMap<u32, crate::checkpoint::Callbacks>,
}

static STATE: Mutex<State> = Mutex::new(State {
    conns: BTreeMap::new(),
    next_key: DEFAULT_KEY + 1,
    current: DEFAULT_KEY,
    skip_wait_to_go: false,
    wait: WaitMode::adaptive(),
    remote: BTreeMap::new(),
    callbacks: BTreeMap::new(),
});

/// The state, locked. A panic in an earlier call (caught by the guard) poisons the mutex;
/// the state stays usable, so the poison is ignored.
pub fn state() -> MutexGuard<'static, State> {
    STATE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The failure of a remote connection to a domain that no framework or mirror serves here.
fn not_served(domain: &str, card: &str, pci_index: i32, why: &str) -> Failure {
    Failure::new(
        RTAPI_ERROR_REMOTE_NOT_SERVED,
        format!(
            "domain '{domain}' is not served on this machine ({why}): a remote connection (card '{card}', PCI index \
             {pci_index}) reaches the framework through DDS, so start `tutti gateway --mirror DDF` on this machine \
             (docs/rtapi.md)"
        ),
    )
}

fn not_connected(key: u32) -> Failure {
    Failure::new(RTAPI_ERROR_NOT_CONNECTED, format!("connection key {key} is not connected (call RTConnect first)"))
}

impl State {
    pub fn new_key(&mut self) -> CallResult<u32> {
        let key = self.next_key;
        self.next_key = key
            .checked_add(1)
            .ok_or_else(|| Failure::new(RTAPI_ERROR_INVALID_ARGUMENT, "connection keys exhausted"))?;
        self.conns.insert(key, None);
        Ok(key)
    }

    pub fn set_current(&mut self, key: u32) -> CallResult {
        if key != DEFAULT_KEY && !self.conns.contains_key(&key) {
            return Err(Failure::new(RTAPI_ERROR_UNKNOWN_CONNECTION_KEY, format!("no connection key {key}")));
        }
        self.current = key;
        Ok(())
    }

    /// The connection behind `key` (connected or not).
    fn conn(&mut self, key: u32) -> CallResult<&mut Option<Conn>> {
        if key == DEFAULT_KEY {
            return Ok(self.conns.entry(DEFAULT_KEY).or_default());
        }
        self.conns
            .get_mut(&key)
            .ok_or_else(|| Failure::new(RTAPI_ERROR_UNKNOWN_CONNECTION_KEY, format!("no connection key {key}")))
    }

    /// The participant behind `key`; fails if it is not connected.
    pub fn participant(&mut self, key: u32) -> CallResult<&mut Participant> {
        self.connected(key).map(|c| &mut c.participant)
    }

    /// The key of the current connection.
    pub fn current_key(&self) -> u32 {
        self.current
    }

    /// Connection `key`, which must be connected.
    pub fn connected(&mut self, key: u32) -> CallResult<&mut Conn> {
        self.conn(key)?.as_mut().ok_or_else(|| not_connected(key))
    }

    /// The current connection, which must be connected.
    pub fn current(&mut self) -> CallResult<&mut Conn> {
        self.connected(self.current)
    }

    pub fn set_skip_wait_to_go(&mut self, skip: bool) {
        self.skip_wait_to_go = skip;
    }

    /// Sets how every connection waits, now and for later connections.
    pub fn set_wait(&mut self, wait: WaitMode) {
        self.wait = wait;
        for c in self.conns.values_mut().flatten() {
            c.participant.set_wait_mode(wait);
        }
    }

    /// Why connection `key` cannot connect now (it is connected), after forgetting a
    /// connection whose framework went away (it connects again without RTDisconnect).
    fn ready_to_connect(&mut self, key: u32) -> CallResult {
        let slot = self.conn(key)?;
        if slot.as_ref().is_some_and(|c| c.ended.is_some()) {
            *slot = None;
        }
        if slot.is_some() {
            return Err(Failure::new(
                RTAPI_ERROR_ALREADY_CONNECTED,
                format!("connection key {key} is already connected"),
            ));
        }
        Ok(())
    }
}

/// Connects the current connection; with a DDF, checks that it matches the live domain. The
/// wait for the framework (up to the timeout, and its wait-to-go) runs with the state
/// released, so that other threads' calls go on meanwhile.
pub fn connect(domain: &str, ddf_path: Option<&str>, timeout_seconds: i32) -> CallResult {
    let timeout = u64::try_from(timeout_seconds)
        .map(Duration::from_secs)
        .map_err(|_| Failure::new(RTAPI_ERROR_INVALID_ARGUMENT, format!("timeout {timeout_seconds} s is negative")))?;
    if domain.is_empty() {
        return Err(Failure::new(RTAPI_ERROR_INVALID_ARGUMENT, "the domain name is empty"));
    }
    let (key, skip, wait, remote, callbacks) = {
        let mut st = state();
        let key = st.current;
        st.ready_to_connect(key)?;
        (key, st.skip_wait_to_go, st.wait, st.remote.get(&key).cloned(), st.callbacks.get(&key).copied())
    };
    let opts = ConnectOptions {
        connect_timeout: timeout,
        timeout: if timeout.is_zero() { DEFAULT_LOCK_TIMEOUT } else { timeout },
        wait,
        skip_wait_to_go: skip,
        state: callbacks.map(|c| tutti_core::shm::SharedState::new(Box::new(c))),
        ..ConnectOptions::default()
    };
    let shm = |e: ShmError| {
        let f = Failure::shm(&e, Side::Connect);
        match &remote {
            Some((card, pci)) if matches!(f.code, RTAPI_ERROR_TIMEOUT | RTAPI_ERROR_DOMAIN_NOT_FOUND) => {
                not_served(domain, card, *pci, &f.detail)
            }
            _ => f,
        }
    };
    let participant = match ddf_path {
        None => Participant::connect(domain, opts).map_err(shm)?,
        Some(path) => {
            let model = ddf::load(path).map_err(|e| Failure::new(RTAPI_ERROR_DDF_INVALID, e.to_string()))?;
            let d = model.domain(domain).ok_or_else(|| {
                Failure::new(RTAPI_ERROR_DDF_INVALID, format!("{path} does not describe domain '{domain}'"))
            })?;
            Participant::connect_checked(d, opts).map_err(shm)?
        }
    };
    let mut st = state();
    // Another thread may have connected this key meanwhile: the later connection loses.
    st.ready_to_connect(key)?;
    *st.conn(key)? = Some(Conn { participant, sub_locked: false, pub_locked: false, ended: None });
    Ok(())
}

impl State {
    /// `RTSetupRefMemRemoteConnection`: the product prepares the current connection to reach
    /// a framework on another machine through a reflective-memory card. Here another machine
    /// is reached through DDS, by a mirror gateway that serves the domain on this one; so the
    /// call succeeds when the domain is served here (by its framework or a mirror), and says
    /// to start the mirror otherwise. Before the connection is made it is remembered, and a
    /// connect that finds no framework says the same.
    pub fn setup_remote(&mut self, card: &str, pci_index: i32) -> CallResult {
        if pci_index < 0 {
            return Err(Failure::new(RTAPI_ERROR_INVALID_ARGUMENT, format!("PCI index {pci_index} is negative")));
        }
        let key = self.current;
        let slot = self.conn(key)?;
        if let Some(conn) = slot.as_mut() {
            let domain = conn.participant.info().name.clone();
            if conn.ended.is_some() || conn.participant.check().is_err() {
                return Err(not_served(&domain, card, pci_index, "its framework has stopped"));
            }
        }
        self.remote.insert(key, (card.to_string(), pci_index));
        Ok(())
    }

    /// `RTSetStateCallbacks` on the current key: remembered for its later connections, and
    /// in force at once on a connection it has.
    pub fn set_callbacks(&mut self, callbacks: crate::checkpoint::Callbacks) -> CallResult {
        let key = self.current;
        if let Some(conn) = self.conn(key)?.as_mut() {
            conn.participant.set_state_handler(Box::new(callbacks));
        }
        self.callbacks.insert(key, callbacks);
        Ok(())
    }

    pub fn disconnect(&mut self) -> CallResult {
        self.current()?;
        let key = self.current;
        *self.conn(key)? = None;
        Ok(())
    }

    /// Runs one core operation on the current connection; when it fails because the other
    /// side is gone, the connection is closed (see docs/rtapi.md, "Errors").
    pub fn exchange<T>(&mut self, side: Side, op: impl FnOnce(&mut Conn) -> Result<T, ShmError>) -> CallResult<T> {
        self.exchange_on(self.current, side, op)
    }

    /// [`exchange`](Self::exchange) on connection `key`, current or not (a call that
    /// released the state to wait comes back to the connection it started on).
    pub fn exchange_on<T>(
        &mut self,
        key: u32,
        side: Side,
        op: impl FnOnce(&mut Conn) -> Result<T, ShmError>,
    ) -> CallResult<T> {
        let conn = self.connected(key)?;
        if let Some(ended) = &conn.ended {
            return Err(ended.failure(side));
        }
        match op(conn) {
            Ok(v) => Ok(v),
            Err(e) => {
                if codes::disconnects(&e) {
                    let ended = Ended::of(&e);
                    let f = ended.failure(side);
                    conn.ended = Some(ended);
                    return Err(f);
                }
                Err(Failure::shm(&e, side))
            }
        }
    }

    /// Connection count of `domain`: from a connection of this process if one is connected
    /// to it, else from the segment.
    pub fn connection_count(&self, domain: &str) -> CallResult<u32> {
        if let Some(p) = self.conns.values().flatten().map(|c| &c.participant).find(|p| p.info().name == domain) {
            return Ok(p.connection_count());
        }
        let ns = tutti_core::shm::segment::namespace_from_env();
        let seg = tutti_core::shm::segment::Segment::open(&ns, domain).map_err(|e| Failure::shm(&e, Side::Connect))?;
        Ok(seg.connection_count())
    }
}

/// The leaf with key `key` (PUBLISH leaves first, then SUBSCRIBE).
pub fn leaf_by_key(p: &Participant, key: u16) -> CallResult<(Role, &Leaf)> {
    p.info().leaves().nth(usize::from(key)).ok_or_else(|| {
        Failure::new(RTAPI_ERROR_UNKNOWN_ITEM, format!("domain '{}' has no item key {key}", p.info().name))
    })
}

/// An item found by its path, borrowed from the participant's layout (nothing is copied).
#[derive(Debug, Clone, Copy)]
pub struct Found<'a> {
    /// The item key: its index among all items, PUBLISH first.
    pub key: u16,
    pub role: Role,
    /// Its index in its own set (what `Participant::stage_at` and `snapshot_item` take).
    pub index: usize,
    pub leaf: &'a Leaf,
}

/// The leaf at `path` in either set, with its item key.
pub fn leaf_by_path<'a>(p: &'a Participant, path: &str) -> CallResult<Found<'a>> {
    let publish = p.info().publish.leaves.len();
    p.info()
        .leaves()
        .enumerate()
        .find(|(_, (_, l))| l.path == path)
        .and_then(|(i, (role, leaf))| {
            let index = if role == Role::Publish { i } else { i - publish };
            Some(Found { key: u16::try_from(i).ok()?, role, index, leaf })
        })
        .ok_or_else(|| {
            Failure::new(RTAPI_ERROR_UNKNOWN_ITEM, format!("domain '{}' has no item '{path}'", p.info().name))
        })
}

/// The leaf at `path` in set `role`; an item of the other set is named in the detail.
pub fn leaf_in<'a>(p: &'a Participant, role: Role, path: &str) -> CallResult<Found<'a>> {
    let found = leaf_by_path(p, path)?;
    if found.role != role {
        let hint = match role {
            Role::Publish => "RTSubscribe reads the PUBLISH set; write SUBSCRIBE items with RTPublish",
            Role::Subscribe => "RTPublish writes the SUBSCRIBE set; read PUBLISH items with RTSubscribe",
        };
        return Err(Failure::new(
            RTAPI_ERROR_UNKNOWN_ITEM,
            format!("item '{path}' of domain '{}' is in the {} set: {hint}", p.info().name, found.role),
        ));
    }
    Ok(found)
}

/// Checks that `got` bytes fit leaf `leaf` exactly.
pub fn check_size(p: &Participant, leaf: &Leaf, got: u32) -> CallResult {
    if got != leaf.size {
        return Err(Failure::new(
            RTAPI_ERROR_WRONG_SIZE,
            format!(
                "item '{}' of domain '{}' is {} bytes ({} × {}), got {got}",
                leaf.path,
                p.info().name,
                leaf.size,
                leaf.length,
                leaf.ty.canonical()
            ),
        ));
    }
    Ok(())
}
