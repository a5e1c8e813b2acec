//! A synchronous domain's remote writer with a lookahead of K steps (docs/run.md, "Sites and
//! lookahead"): its answer to step n is committed for step n + K, exactly, however early or
//! late it arrives, so the framework runs up to K steps ahead of the link and waits for it
//! only when the answer to step n - K has not come by step n.
//!
//! The writer's thread answers every step the framework publishes, as soon as it is
//! published: step k gets the answer to step k - K from the queue of answers received; the
//! steps before the first answer could exist (k <= K, or k - K before the connection's first
//! step) get the values as they are ([`Delivery::hold`]), as a connection K steps long would
//! give its initial value; a step whose answer will never come (a later one arrived first:
//! the remote side joined after it) is held too; an answer to a step already past is late.
//! A writer that owes its answer and sends nothing for the lease is released, as in
//! lock-step.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::sync::{MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use tracing::{info, warn};
use tutti_core::shm::segment::LinkInfo;
use tutti_core::shm::ShmError;

use super::from_dds::{connect, LockstepState, Sample, WriterState};
use super::ShmConfig;
use crate::cdr::Payload;
use crate::stats::{LogLimit, SetStats, Stats};

/// The thread of a remote writer with a lookahead: until its [`super::from_dds::RemoteWriter`]
/// is dropped, answers each step the framework publishes from the answers handed to it on
/// `rx` (each with the time it arrived).
pub(super) fn run(ls: &LockstepState, rx: &Receiver<(Payload, Instant)>, cfg: &ShmConfig) {
    let lock = || ls.state.lock().unwrap_or_else(PoisonError::into_inner);
    let (k_ahead, set) = {
        let st = lock();
        (st.out.ahead, st.out.counters.set.clone())
    };
    set.lookahead.store(k_ahead, Ordering::Relaxed);
    let mut link = Link {
        rx,
        pending: &ls.pending,
        set: &set,
        answers: VecDeque::new(),
        published: VecDeque::new(),
        newest: None,
        gaps: LogLimit::new(Duration::from_secs(5)),
    };
    let check = (cfg.lease / 4).clamp(Duration::from_millis(10), Duration::from_millis(100));
    // The connection's first step (answers to earlier ones cannot come), and whether the
    // lease let it go (then only an answer brings it back).
    let mut first: Option<u64> = None;
    let mut lapsed = false;
    loop {
        let mut st = lock();
        if st.part.is_none() {
            drop(st);
            match rx.recv_timeout(Duration::from_millis(500)) {
                Ok(m) => {
                    lapsed = false;
                    link.take(m);
                }
                Err(RecvTimeoutError::Timeout) if lapsed => continue,
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return,
            }
            let mut st = lock();
            let WriterState { out, part } = &mut *st;
            *part = connect(out, cfg);
            first = None;
            continue;
        }
        // The next step to answer: waits for the framework to publish it (its timeout).
        let locked = match st.part.as_mut().map(|p| p.publish_lock()) {
            Some(Ok(k)) => k,
            Some(Err(ShmError::Timeout { .. })) => {
                drop(st);
                if !link.drain() {
                    return;
                }
                continue;
            }
            _ => {
                // Gone (the framework stopped, the connection was released): connect again.
                let WriterState { out, part } = &mut *st;
                info!(domain = %out.domain, "{}: the domain's connection ended; connecting again", out.name);
                *part = None;
                continue;
            }
        };
        link.published(locked);
        let start = *first.get_or_insert_with(|| {
            let out = &st.out;
            info!(
                domain = %out.domain,
                "{}: joins at step {locked}; its answers are read from step {} on ({k_ahead} steps of lookahead), the steps before read the values as they are",
                out.name,
                locked.max(1) + k_ahead
            );
            locked
        });
        if !link.drain() {
            return;
        }
        // The step whose answer this one takes (None: before any answer could exist; a
        // seed, step 0, takes the first answer there is).
        let wanted = match locked.checked_sub(k_ahead) {
            _ if locked == 0 => Some(None),
            Some(n) if n >= start && n > 0 => Some(Some(n)),
            _ => None,
        };
        let mut owing_since: Option<Instant> = None;
        let mut told = false;
        let outcome = loop {
            let Some(n) = wanted else { break Outcome::Hold };
            link.drop_before(n, &mut st);
            match link.answers.front() {
                Some((m, _)) if n.map_or(true, |n| *m == n) => {
                    break link.answers.pop_front().map_or(Outcome::Hold, |(_, p)| Outcome::Answer(p))
                }
                Some((m, _)) => {
                    if let (Some(n), Some(_)) = (n, link.gaps.allow()) {
                        warn!(
                            domain = %st.out.domain,
                            "{}: the answer to step {n} never came (the answer to step {m} came first): the other site started again, or its mirror keeps fewer steps than this lookahead (give it --lookahead {k_ahead} too); step {locked} reads the values as they are",
                            st.out.name
                        );
                    }
                    break Outcome::Hold;
                }
                None => {}
            }
            // The answer has not come: the framework waits for the link.
            let since = *owing_since.get_or_insert_with(|| {
                Stats::add(&set.link_waits, 1);
                Instant::now()
            });
            let WriterState { out, part } = &mut *st;
            if part.as_ref().and_then(|p| p.owed_step()) != Some(locked) {
                // The framework went on without this answer (its step timed out, and it has
                // said so): answer the step it is at now.
                break Outcome::Skip;
            }
            if since.elapsed() >= cfg.lease {
                warn!(
                    domain = %out.domain,
                    "{}: nothing came over the link for {:?} while step {locked} waited for the answer to step {} ({k_ahead} steps of lookahead): its share of the step is released (its next sample joins it again; --lease waits longer)",
                    out.name, cfg.lease, locked.saturating_sub(k_ahead)
                );
                Stats::add(&out.counters.total.lapsed, 1);
                *part = None;
                lapsed = true;
                break Outcome::Skip;
            }
            if !told && since.elapsed() >= Duration::from_secs(1) {
                told = true;
                warn!(
                    domain = %out.domain,
                    "{}: step {locked} waits for the link: no answer to step {} for 1 s ({k_ahead} steps of lookahead)",
                    out.name, locked.saturating_sub(k_ahead)
                );
            }
            match rx.recv_timeout(check) {
                Ok(m) => link.take(m),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return,
            }
        };
        if told {
            info!(domain = %st.out.domain, "{}: the link answers again (step {locked})", st.out.name);
        }
        let WriterState { out, part } = &mut *st;
        match outcome {
            Outcome::Answer(p) => out.deliver(part, Sample::Owned(p)),
            Outcome::Hold => out.hold(part),
            Outcome::Skip => {}
        }
        if let Some(newest) = link.newest {
            set.ahead.store(locked.saturating_sub(newest), Ordering::Relaxed);
        }
        // `tutti status` shows them on the connection.
        if let Some(p) = st.part.as_ref() {
            let g = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
            p.set_link(&LinkInfo {
                lookahead: k_ahead,
                ahead: g(&set.ahead),
                rtt_us: g(&set.rtt_us),
                link_waits: g(&set.link_waits),
            });
        }
    }
}

/// How a step is answered.
enum Outcome {
    /// With the answer to step n - K.
    Answer(Payload),
    /// With the values as they are (no answer can come for it).
    Hold,
    /// Not at all: the framework has left the step, or the connection was released.
    Skip,
}

/// The answers received and not yet committed, and when each recent step was published (for
/// the round trip).
struct Link<'a> {
    rx: &'a Receiver<(Payload, Instant)>,
    pending: &'a AtomicUsize,
    set: &'a SetStats,
    /// (the step it answers, the answer), in the order received.
    answers: VecDeque<(u64, Payload)>,
    /// (step, when the writer saw it published), oldest first.
    published: VecDeque<(u64, Instant)>,
    /// The latest step answered so far.
    newest: Option<u64>,
    /// Steps whose answer never came (a later one did), logged.
    gaps: LogLimit,
}

impl Link<'_> {
    /// Takes an answer handed to the thread; measures the round trip of its step.
    fn take(&mut self, (payload, at): (Payload, Instant)) {
        self.pending.fetch_sub(1, Ordering::AcqRel);
        // Typed sets carry the step they answer (a lookahead needs typed mode).
        let m = match &payload {
            Payload::Set(s) => s.step,
            Payload::Item { .. } => 0,
        };
        self.newest = self.newest.max(Some(m));
        while self.published.front().is_some_and(|(k, _)| *k < m) {
            self.published.pop_front();
        }
        // An answer that arrived before this thread saw its step published (the thread was
        // not scheduled meanwhile: a loaded machine) has no round trip to measure; the
        // latest one measured stands.
        if let Some(rtt) =
            self.published.front().filter(|(k, _)| *k == m).and_then(|(_, t)| at.checked_duration_since(*t))
        {
            self.set.rtt_us.store(u64::try_from(rtt.as_micros()).unwrap_or(u64::MAX), Ordering::Relaxed);
        }
        self.answers.push_back((m, payload));
    }

    /// Takes every answer waiting; false when the writer is gone (the thread ends).
    fn drain(&mut self) -> bool {
        loop {
            match self.rx.try_recv() {
                Ok(m) => self.take(m),
                Err(TryRecvError::Empty) => return true,
                Err(TryRecvError::Disconnected) => return false,
            }
        }
    }

    /// Notes that step `k` was published now.
    fn published(&mut self, k: u64) {
        if self.published.back().map_or(true, |(last, _)| *last < k) {
            self.published.push_back((k, Instant::now()));
        }
        // Bounded: a link that never answers must not grow it.
        if self.published.len() > 4096 {
            self.published.pop_front();
        }
    }

    /// Drops the answers to steps before `n` (late: the framework has left the step they
    /// were due at), counting them.
    fn drop_before(&mut self, n: Option<u64>, st: &mut MutexGuard<'_, WriterState>) {
        let Some(n) = n else { return };
        while self.answers.front().is_some_and(|(m, _)| *m < n) {
            self.answers.pop_front();
            SetStats::add(Some(self.set), |s| &s.dropped, &st.out.counters.total.late, 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::mpsc::channel;

    use tutti_core::cdr::TypedSample;

    use super::*;

    fn answer(step: u64) -> Payload {
        Payload::Set(TypedSample { step, sim_time: 0.0, data: Vec::new() })
    }

    /// The round trip of a step is measured from when this thread saw it published; an answer
    /// that came before that (the thread was not scheduled meanwhile) measures nothing, and the
    /// latest round trip measured stands, never a round trip of 0.
    #[test]
    fn an_answer_that_arrived_before_its_step_was_seen_published_measures_no_round_trip() {
        let (_tx, rx) = channel();
        let (pending, set) = (AtomicUsize::new(3), SetStats::default());
        let mut link = Link {
            rx: &rx,
            pending: &pending,
            set: &set,
            answers: VecDeque::new(),
            published: VecDeque::new(),
            newest: None,
            gaps: LogLimit::new(Duration::from_secs(5)),
        };
        let t0 = Instant::now();
        link.published(1);
        link.take((answer(1), t0 + Duration::from_micros(700)));
        let measured = set.rtt_us.load(Ordering::Relaxed);
        assert!(measured > 0 && measured <= 700, "{measured}");
        // Step 2 seen published after its answer arrived.
        let arrived = Instant::now();
        std::thread::sleep(Duration::from_millis(2));
        link.published(2);
        link.take((answer(2), arrived));
        assert_eq!(set.rtt_us.load(Ordering::Relaxed), measured);
        // Both answers are queued in order all the same.
        let steps: Vec<u64> = link.answers.iter().map(|(m, _)| *m).collect();
        assert_eq!(steps, [1, 2]);
        assert_eq!(link.newest, Some(2));
    }
}
