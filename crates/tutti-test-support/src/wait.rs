//! Waiting for something to happen, with a deadline that is a watchdog, not a timing.
//!
//! A test that waits for a process, a segment or a value to appear polls for it with one of
//! these instead of a loop of its own:
//!
//! ```ignore
//! wait_until("the control socket", Duration::from_secs(30), || socket.exists());
//! let step = wait_for(lazy(|| format!("no step\n{}", host.dump())), Duration::from_secs(60), || first_step(&host));
//! ```
//!
//! The patience only bounds a wait that would otherwise hang: a condition that holds ends
//! the wait at once, so a generous patience costs nothing on a run that goes well.

use std::fmt;
use std::time::{Duration, Instant};

/// How often the waits look: at once, then every `POLL`.
pub const POLL: Duration = Duration::from_millis(10);

/// Calls `poll` at once and then every [`POLL`] until it gives a value, for at most
/// `patience`; `None` when the patience ran out first (a zero patience looks once). For a
/// test that does something else than failing when the wait ends empty-handed; the others
/// use [`wait_for`] or [`wait_until`].
pub fn poll_for<T>(patience: Duration, mut poll: impl FnMut() -> Option<T>) -> Option<T> {
    let end = Instant::now() + patience;
    loop {
        if let Some(v) = poll() {
            return Some(v);
        }
        if Instant::now() >= end {
            return None;
        }
        std::thread::sleep(POLL);
    }
}

/// [`poll_for`] that fails the test when the patience runs out: it panics with `what` (what
/// never happened, or the state a failure should show: [`lazy`] builds it only then) and
/// the patience. The failure is reported where the test called it.
#[track_caller]
pub fn wait_for<T>(what: impl fmt::Display, patience: Duration, poll: impl FnMut() -> Option<T>) -> T {
    match poll_for(patience, poll) {
        Some(v) => v,
        None => panic!("timed out after {patience:?}: {what}"),
    }
}

/// Waits until `done` is true, as [`wait_for`] does: fails the test with `what` when it is
/// still false after `patience`.
#[track_caller]
pub fn wait_until(what: impl fmt::Display, patience: Duration, mut done: impl FnMut() -> bool) {
    wait_for(what, patience, || done().then_some(()))
}

/// A message built only when it is shown: the `what` of a wait that names the state at the
/// time it failed (a count, a process's output) without building it at every look.
pub fn lazy<F: Fn() -> String>(message: F) -> Lazy<F> {
    Lazy(message)
}

/// See [`lazy`].
pub struct Lazy<F>(F);

impl<F: Fn() -> String> fmt::Display for Lazy<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&(self.0)())
    }
}

impl<F> fmt::Debug for Lazy<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Lazy(..)")
    }
}
