//! A component's state, saved and restored through its domain (docs/run.md, "Checkpoints").
//!
//! A connection that keeps a state says so with a [`StateHandler`] (given in
//! [`ConnectOptions::state`](crate::shm::ConnectOptions) or later with
//! [`Participant::set_state_handler`](crate::shm::Participant::set_state_handler)). The
//! framework asks at a step boundary: it puts a request in the segment (save, or restore with
//! a file per connection holding the bytes to take back), bumps the request's number and wakes
//! the participants. A participant answers while it waits for the framework (the read of the
//! next step: it has answered the last step and not started the next, so its state is the
//! boundary's; or the framework's go, before its first step) and at the start of every read: it calls its handler, writes the saved bytes
//! to its connection's file (or reads them from it), and marks the request answered in its
//! slot. The framework collects the files and removes them.
//!
//! The files lie beside the segment, `/dev/shm/tutti.NS.DOMAIN.state.SLOT`, mode 0600: a
//! component's state may be megabytes (an FMU's), more than a segment should carry for every
//! step, and a file is written once per request.

use std::fmt;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::segment::{wake, Segment};
use super::{os, ShmError};
use crate::sync::Ordering;

/// A handler's failure, with its own words.
pub type StateError = Box<dyn std::error::Error + Send + Sync>;

/// What a component that keeps a state does on the framework's request: hand its state over
/// as bytes, and take such bytes back. Both run at a step boundary, in the thread that waits
/// for the framework's next step.
pub trait StateHandler: Send {
    /// The component's state now, as bytes only this component needs to understand.
    fn save(&mut self) -> Result<Vec<u8>, StateError>;
    /// Takes back a state that [`save`](Self::save) gave.
    fn restore(&mut self, state: &[u8]) -> Result<(), StateError>;
}

/// A [`StateHandler`] shared between a connection and its waits.
#[derive(Clone)]
pub struct SharedState(pub(crate) Arc<Mutex<Box<dyn StateHandler>>>);

impl SharedState {
    pub fn new(handler: Box<dyn StateHandler>) -> SharedState {
        SharedState(Arc::new(Mutex::new(handler)))
    }
}

impl fmt::Debug for SharedState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("SharedState")
    }
}

/// Why a connection could not answer a request: the text the framework reads back.
#[derive(Debug, thiserror::Error)]
enum ServeError {
    /// The component's handler failed, in its own words.
    #[error("{0}")]
    Handler(StateError),
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("unknown state request {0}")]
    UnknownRequest(u32),
}

/// What a request asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StateRequest {
    Save,
    Restore,
}

const KIND_SAVE: u32 = 1;
const KIND_RESTORE: u32 = 2;
/// Set in a slot's `state_done` when the connection could not do what was asked.
pub(crate) const STATE_FAILED: u64 = 1 << 63;

/// A connection of a domain as a checkpoint sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StateConnection {
    pub slot: usize,
    pub pid: u32,
    /// The name it connected with (a launched component's name).
    pub name: String,
    /// It keeps a state ([`StateHandler`]).
    pub keeps_state: bool,
    /// Event-driven: the index (simulated time over the step) from which it is next due.
    pub due_index: u64,
    /// A remote writer across a link to another site that keeps a state (its lookahead's
    /// answers on their way: the gateway's).
    pub remote: bool,
}

/// A connection's answer to a request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StateAnswer {
    /// Its state (a save).
    Saved(Vec<u8>),
    /// It took its state back (a restore).
    Restored,
    /// Its handler failed, with its words.
    Failed(String),
    /// It did not answer within the time given, or left.
    NoAnswer,
}

impl Segment {
    /// The file connection `slot` exchanges its state through.
    pub(crate) fn state_file(&self, slot: usize) -> PathBuf {
        std::path::Path::new(os::SHM_DIR).join(format!("{}.state.{slot}", self.shm_name))
    }

    /// Whether a request is waiting for connection `slot` (one that keeps a state).
    pub(crate) fn state_pending(&self, slot: usize) -> bool {
        self.pending_request(slot).is_some()
    }

    /// The request waiting for connection `slot`: its number, and the slot's `state_done`
    /// as it stood (an answer is stored only over that value, see [`Segment::serve_state`]).
    fn pending_request(&self, slot: usize) -> Option<(u64, u64)> {
        let seq = self.header().state_seq.load(Ordering::Acquire);
        let c = self.conn(slot)?;
        let done = c.state_done.load(Ordering::Acquire);
        (c.keeps_state.load(Ordering::Acquire) != 0 && done & !STATE_FAILED < seq).then_some((seq, done))
    }

    /// Says whether connection `slot` keeps a state; requests already made are not its.
    pub(crate) fn set_keeps_state(&self, slot: usize, keeps: bool) {
        if let Some(c) = self.conn(slot) {
            c.state_done.store(self.header().state_seq.load(Ordering::Acquire), Ordering::Release);
            c.keeps_state.store(u64::from(keeps), Ordering::Release);
        }
    }

    /// Answers the request waiting for connection `slot` with `handler`, if one is; returns
    /// whether it did.
    ///
    /// The answer is stored over the slot's `state_done` as it was when the request was seen:
    /// if the framework gave up on the request meanwhile ([`Segment::cancel_state`]), the
    /// store fails and the file written for it is removed here, since nobody will collect it.
    pub(crate) fn serve_state(&self, slot: usize, handler: &SharedState) -> bool {
        let Some((seq, before)) = self.pending_request(slot) else {
            return false;
        };
        let h = self.header();
        let kind = h.state_kind.load(Ordering::Acquire);
        let path = self.state_file(slot);
        let result = {
            let mut handler = handler.0.lock().unwrap_or_else(|e| e.into_inner());
            match kind {
                KIND_SAVE => handler.save().map_err(ServeError::Handler).and_then(|bytes| {
                    write_private(&path, &bytes).map_err(|source| ServeError::Io { path: path.clone(), source })
                }),
                KIND_RESTORE => std::fs::read(&path)
                    .map_err(|source| ServeError::Io { path: path.clone(), source })
                    .and_then(|bytes| handler.restore(&bytes).map_err(ServeError::Handler)),
                other => Err(ServeError::UnknownRequest(other)),
            }
        };
        let done = match result {
            Ok(()) => seq,
            Err(why) => {
                // The framework reads the component's words from the file in its place.
                let _ = write_private(&path, why.to_string().as_bytes());
                seq | STATE_FAILED
            }
        };
        let stored = self
            .conn(slot)
            .is_some_and(|c| c.state_done.compare_exchange(before, done, Ordering::AcqRel, Ordering::Acquire).is_ok());
        if !stored {
            let _ = std::fs::remove_file(&path);
        }
        h.ack_seq.fetch_add(1, Ordering::Release);
        wake(&h.ack_seq, &h.ack_waiters);
        true
    }

    /// The participants' connections for a checkpoint: not observers, and not remote writers
    /// (DDS writers through the gateway) unless they keep a state.
    pub(crate) fn state_connections(&self) -> Vec<StateConnection> {
        use crate::shm::handshake::{CONN_OBSERVER, CONN_REMOTE};
        let mut out = Vec::new();
        for i in 0..self.scan_len() {
            let Some(c) = self.conn(i) else { break };
            let pid = c.active.load(Ordering::Acquire);
            if pid == 0 || c.ready.load(Ordering::Acquire) == 0 {
                continue;
            }
            let flags = c.flags.load(Ordering::Acquire);
            let keeps_state = c.keeps_state.load(Ordering::Acquire) != 0;
            let remote = flags & CONN_REMOTE != 0;
            if flags & CONN_OBSERVER != 0 || (remote && !keeps_state) {
                continue;
            }
            out.push(StateConnection {
                slot: i,
                pid,
                name: super::segment::conn_name(c),
                keeps_state,
                due_index: c.due_index.load(Ordering::Acquire),
                remote,
            });
        }
        out
    }

    /// Puts a request to the connections in `files` (each slot with the bytes its file holds
    /// for a restore, nothing for a save) and wakes them; returns its number.
    pub(crate) fn request_state(&self, kind: StateRequest, files: &[(usize, &[u8])]) -> Result<u64, ShmError> {
        for (slot, bytes) in files {
            let path = self.state_file(*slot);
            let _ = std::fs::remove_file(&path);
            if kind == StateRequest::Restore {
                write_private(&path, bytes).map_err(|e| ShmError::io(format!("writing {}", path.display()), e))?;
            }
        }
        let h = self.header();
        h.state_kind.store(
            match kind {
                StateRequest::Save => KIND_SAVE,
                StateRequest::Restore => KIND_RESTORE,
            },
            Ordering::Release,
        );
        let seq = h.state_seq.fetch_add(1, Ordering::AcqRel) + 1;
        // Wake whoever waits: for a step, for the framework's go (held), or (event-driven) on
        // its own word.
        h.step_seq.fetch_add(1, Ordering::Release);
        wake(&h.step_seq, &h.step_waiters);
        wake(&h.hold, &h.go_waiters);
        for (slot, _) in files {
            if let Some(c) = self.conn(*slot) {
                c.due_seq.fetch_add(1, Ordering::Release);
                wake(&c.due_seq, &c.due_waiters);
            }
        }
        Ok(seq)
    }

    /// The answer of connection `slot` (process `pid`) to request `seq`, once it came; its
    /// file is removed.
    pub(crate) fn state_answer(&self, slot: usize, pid: u32, seq: u64, kind: StateRequest) -> Option<StateAnswer> {
        let c = self.conn(slot)?;
        let path = self.state_file(slot);
        if c.active.load(Ordering::Acquire) != pid {
            let _ = std::fs::remove_file(&path);
            return Some(StateAnswer::NoAnswer);
        }
        let done = c.state_done.load(Ordering::Acquire);
        if done & !STATE_FAILED < seq {
            return None;
        }
        let bytes = std::fs::read(&path);
        let _ = std::fs::remove_file(&path);
        Some(match (done & STATE_FAILED != 0, kind, bytes) {
            (true, _, Ok(why)) => StateAnswer::Failed(String::from_utf8_lossy(&why).into_owned()),
            (true, _, Err(_)) => StateAnswer::Failed("no reason given".into()),
            (false, StateRequest::Save, Ok(bytes)) => StateAnswer::Saved(bytes),
            (false, StateRequest::Save, Err(e)) => StateAnswer::Failed(format!("reading {}: {e}", path.display())),
            (false, StateRequest::Restore, _) => StateAnswer::Restored,
        })
    }

    /// Gives up on request `seq` for connection `slot`: marks it answered (failed) so that the
    /// connection no longer answers it, and removes its file. A connection answering at the
    /// same moment either stored its answer first (its file is removed here) or finds its
    /// store refused and removes its file itself: no file outlives the request either way.
    pub(crate) fn cancel_state(&self, slot: usize, seq: u64) {
        if let Some(c) = self.conn(slot) {
            let mut done = c.state_done.load(Ordering::Acquire);
            while done & !STATE_FAILED < seq {
                match c.state_done.compare_exchange(done, seq | STATE_FAILED, Ordering::AcqRel, Ordering::Acquire) {
                    Ok(_) => break,
                    Err(now) => done = now,
                }
            }
        }
        let _ = std::fs::remove_file(self.state_file(slot));
    }
}

/// Writes `bytes` to a new file at `path`, readable by this user only.
fn write_private(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    let mut f = std::fs::OpenOptions::new().write(true).create(true).truncate(true).mode(0o600).open(path)?;
    f.write_all(bytes)
}

/// One domain's request: its segment, the request's number and the connections asked (slot,
/// pid).
pub(crate) type Asked<'a> = (&'a Segment, u64, Vec<(usize, u32)>);

/// Collects the answers of the connections asked in several domains at once (an [`Asked`]
/// per domain).
/// Waits until all answered or `deadline`; a connection that did not answer by then has
/// [`StateAnswer::NoAnswer`], and its request is given up on ([`Segment::cancel_state`]).
pub(crate) fn collect_answers(asked: &[Asked<'_>], kind: StateRequest, deadline: Instant) -> Vec<Vec<StateAnswer>> {
    let mut answers: Vec<Vec<Option<StateAnswer>>> = asked.iter().map(|(_, _, c)| vec![None; c.len()]).collect();
    loop {
        let mut missing = false;
        for ((seg, seq, conns), out) in asked.iter().zip(&mut answers) {
            for ((slot, pid), answer) in conns.iter().zip(out.iter_mut()) {
                if answer.is_none() {
                    *answer = seg.state_answer(*slot, *pid, *seq, kind);
                    missing |= answer.is_none();
                }
            }
        }
        if !missing || Instant::now() >= deadline {
            break;
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    asked
        .iter()
        .zip(answers)
        .map(|((seg, seq, conns), out)| {
            for ((slot, _), answer) in conns.iter().zip(&out) {
                if answer.is_none() {
                    seg.cancel_state(*slot, *seq);
                }
            }
            out.into_iter().map(|a| a.unwrap_or(StateAnswer::NoAnswer)).collect()
        })
        .collect()
}
