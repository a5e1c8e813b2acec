//! The FMU's log: the messages an FMU logs through tutti's logger callbacks (src/fmi2.rs,
//! src/fmi3.rs). The latest are kept, so that a failing call can be reported with what the
//! FMU said. With `TUTTI_FMU_LOG=1` every message is also printed to stderr as it comes.

use std::collections::VecDeque;
use std::sync::Mutex;

/// Messages kept (the oldest go first).
const KEEP: usize = 200;

static LINES: Mutex<VecDeque<String>> = Mutex::new(VecDeque::new());

/// Keeps one message of the FMU.
pub fn record(line: String) {
    if std::env::var("TUTTI_FMU_LOG").is_ok_and(|v| v == "1") {
        eprintln!("fmu log: {line}");
    }
    if let Ok(mut lines) = LINES.lock() {
        if lines.len() == KEEP {
            lines.pop_front();
        }
        lines.push_back(line);
    }
}

/// The messages logged since the last call (oldest first).
pub fn take() -> Vec<String> {
    LINES.lock().map(|mut l| l.drain(..).collect()).unwrap_or_default()
}
