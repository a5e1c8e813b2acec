//! Counters of the gateway, shown in its periodic status line.

use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};

/// What went through the gateway, and what it refused.
#[derive(Debug, Default)]
pub struct Stats {
    /// Samples written to DDS.
    pub to_dds: AtomicU64,
    /// DDS samples committed to shared memory (or published by a mirror).
    pub from_dds: AtomicU64,
    /// DDS samples that could not be decoded (truncated, wrong encoding).
    pub bad_samples: AtomicU64,
    /// DDS samples refused by the role rules (a second writer on an exclusive set).
    pub refused: AtomicU64,
    /// Synchronous: DDS samples answering a step the framework had already left.
    pub late: AtomicU64,
    /// DDS samples that came back from this gateway itself (dropped).
    pub own_samples: AtomicU64,
    /// Samples and announcements the engine dropped as malformed before decoding (Zenoh: no
    /// valid attachment, a token that is not rmw_zenoh's).
    pub bad_input: AtomicU64,
    /// Shared-memory or DDS write failures.
    pub errors: AtomicU64,
    /// Steps of a synchronous PUBLISH set that the framework published faster than DDS
    /// could be sent them (a DDS reader never holds a domain back); on a mirror, the home's
    /// steps it skipped to start at the home's current step.
    pub skipped: AtomicU64,
    /// Steps of a synchronous set that never reached DDS: its DDS writer refused them for
    /// the whole step timeout (each logged with its domain and topic).
    pub lost: AtomicU64,
    /// Synchronous DDS writers released after owing a step's answer, silent, for the lease.
    pub lapsed: AtomicU64,
    /// Topics (each direction of each) left out because the DDS Security enclave's
    /// permissions do not allow them.
    pub denied: AtomicU64,
    /// Matched remote DDS writers and readers.
    pub remote_writers: AtomicU64,
    pub remote_readers: AtomicU64,
}

impl Stats {
    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    /// Counters as (name, value), for machine-readable output.
    pub fn snapshot(&self) -> Vec<(&'static str, u64)> {
        let g = |c: &AtomicU64| c.load(Ordering::Relaxed);
        vec![
            ("to_dds", g(&self.to_dds)),
            ("from_dds", g(&self.from_dds)),
            ("bad_samples", g(&self.bad_samples)),
            ("refused", g(&self.refused)),
            ("late", g(&self.late)),
            ("own_samples", g(&self.own_samples)),
            ("bad_input", g(&self.bad_input)),
            ("errors", g(&self.errors)),
            ("skipped", g(&self.skipped)),
            ("lost", g(&self.lost)),
            ("lapsed", g(&self.lapsed)),
            ("denied", g(&self.denied)),
            ("remote_writers", g(&self.remote_writers)),
            ("remote_readers", g(&self.remote_readers)),
        ]
    }
}

/// The sample counters (the status line gives the endpoint counts in words before them).
impl fmt::Display for Stats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut s = self.snapshot();
        s.retain(|(k, _)| !k.starts_with("remote_"));
        let parts: Vec<String> = s.iter().map(|(k, v)| format!("{k}={v}")).collect();
        f.write_str(&parts.join(" "))
    }
}

/// The counters of one bridged set (its topic, or its per-item topics), for the stats
/// endpoint; the totals stay in [`Stats`].
#[derive(Debug, Default)]
pub struct SetStats {
    /// Samples written to DDS.
    pub samples_out: AtomicU64,
    /// DDS samples committed to shared memory (or published by a mirror).
    pub samples_in: AtomicU64,
    /// Samples not delivered: DDS samples refused by the role rules, late or failing,
    /// synchronous steps the pump could not send, and synchronous steps DDS refused for the
    /// whole step timeout.
    pub dropped: AtomicU64,
    /// DDS samples that could not be decoded.
    pub bad_input: AtomicU64,
    /// Matched remote readers and writers of the set's topics (each once).
    pub readers: AtomicU64,
    pub writers: AtomicU64,
    /// A synchronous SUBSCRIBE set with a lookahead (docs/run.md, "Sites and lookahead"):
    /// its steps of lookahead; how many steps the framework is ahead of the newest answer
    /// received; the round trip from a step's publication to its answer's arrival (µs, the
    /// latest); and the steps the framework waited for the link (its answer had not come).
    pub lookahead: AtomicU64,
    pub ahead: AtomicU64,
    pub rtt_us: AtomicU64,
    pub link_waits: AtomicU64,
}

impl SetStats {
    /// Counts `n` in `counter` of the set (if any) and `total` of the gateway.
    pub fn add(set: Option<&SetStats>, counter: fn(&SetStats) -> &AtomicU64, total: &AtomicU64, n: u64) {
        if let Some(s) = set {
            counter(s).fetch_add(n, Ordering::Relaxed);
        }
        total.fetch_add(n, Ordering::Relaxed);
    }
}

/// Lets a repeated warning through once per interval (a misbehaving peer must not flood
/// the log); counts what it held back.
#[derive(Debug)]
pub struct LogLimit {
    every: std::time::Duration,
    last: Option<std::time::Instant>,
    held: u64,
}

impl LogLimit {
    pub fn new(every: std::time::Duration) -> Self {
        LogLimit { every, last: None, held: 0 }
    }

    /// `Some(held back since the last one)` when this occurrence may be logged.
    pub fn allow(&mut self) -> Option<u64> {
        let now = std::time::Instant::now();
        if self.last.is_some_and(|t| now.duration_since(t) < self.every) {
            self.held += 1;
            return None;
        }
        self.last = Some(now);
        Some(std::mem::take(&mut self.held))
    }
}
