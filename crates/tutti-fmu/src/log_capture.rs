//! The FMU's log. FMI 2.0 messages come from tutti's own logger callback (src/fmi2.rs); the
//! `fmi` crate hands FMI 3.0 messages to the `log` facade, for which this module installs a
//! backend. The latest messages are kept, so
//! that a failing call can be reported with what the FMU said. With `TUTTI_FMU_LOG=1` every
//! message is also printed to stderr as it comes.

use std::collections::VecDeque;
use std::sync::{Mutex, Once};

/// Messages kept (the oldest go first).
const KEEP: usize = 200;

static LINES: Mutex<VecDeque<String>> = Mutex::new(VecDeque::new());
static INSTALL: Once = Once::new();

struct Capture {
    echo: bool,
}

impl log::Log for Capture {
    fn enabled(&self, metadata: &log::Metadata<'_>) -> bool {
        metadata.level() <= log::Level::Info
    }

    fn log(&self, record: &log::Record<'_>) {
        // The FMU's own messages come with module path "logger" (FMI 2.0) or "fmu" (FMI 3.0);
        // the crate's diagnostics about itself are not the FMU's log.
        if !matches!(record.module_path(), Some("logger") | Some("fmu")) || !self.enabled(record.metadata()) {
            return;
        }
        record_line(format!("[{}] {}: {}", record.level(), record.target(), record.args()), self.echo);
    }

    fn flush(&self) {}
}

/// Installs the capture as the process's `log` backend (once; if the program has another
/// backend already, the FMU's messages go there instead and failures show no log).
pub fn install() {
    INSTALL.call_once(|| {
        let echo = std::env::var("TUTTI_FMU_LOG").is_ok_and(|v| v == "1");
        if log::set_boxed_logger(Box::new(Capture { echo })).is_ok() {
            log::set_max_level(log::LevelFilter::Info);
        }
    });
}

fn record_line(line: String, echo: bool) {
    if echo {
        eprintln!("fmu log: {line}");
    }
    if let Ok(mut lines) = LINES.lock() {
        if lines.len() == KEEP {
            lines.pop_front();
        }
        lines.push_back(line);
    }
}

/// Keeps one message of the FMU (from tutti's own FMI 2.0 logger).
pub fn record(line: String) {
    record_line(line, std::env::var("TUTTI_FMU_LOG").is_ok_and(|v| v == "1"));
}

/// The messages logged since the last call (oldest first).
pub fn take() -> Vec<String> {
    LINES.lock().map(|mut l| l.drain(..).collect()).unwrap_or_default()
}
