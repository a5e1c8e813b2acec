//! A thread that loops until it is dropped: the in-process frameworks of the tests.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// A thread running `f(stop)`, which returns once `stop` is set; dropping the worker sets it
/// and joins the thread, so a failing test stops its framework (and removes its segments).
#[derive(Debug)]
pub struct Worker {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts `f` on a thread of its own.
    pub fn spawn(f: impl FnOnce(&AtomicBool) + Send + 'static) -> Worker {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::spawn(move || f(&flag));
        Worker { stop, thread: Some(thread) }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Runs `f` on a thread of its own and returns what it returns; a run longer than `limit`
/// (a hang) or a panic in `f` fails the calling test, saying `what` did so and, for a
/// panic, its message. For code that must neither hang nor panic on any input (the fuzz
/// targets).
pub fn within<T: Send + 'static>(what: &str, limit: std::time::Duration, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    let worker = std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    match rx.recv_timeout(limit) {
        Ok(v) => v,
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => panic!("{what} took longer than {limit:?}"),
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            let cause = worker.join().err().map(|p| {
                p.downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default()
            });
            panic!("{what} panicked: {cause:?}");
        }
    }
}
