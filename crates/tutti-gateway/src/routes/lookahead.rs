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
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use tracing::{info, warn};
use tutti_core::cdr::TypedSample;
use tutti_core::shm::segment::LinkInfo;
use tutti_core::shm::{Participant, SharedState, ShmError, StateError, StateHandler};

use super::from_dds::{connect, Delivery, LockstepState, Sample, WriterState};
use super::ShmConfig;
use crate::cdr::Payload;
use crate::stats::{LogLimit, SetStats, Stats};

/// The thread of a remote writer with a lookahead: until its [`super::from_dds::RemoteWriter`]
/// is dropped, answers each step the framework publishes from the answers handed to it on
/// `rx` (each with the time it arrived). Its connection keeps a state (docs/run.md,
/// "Checkpoints"): the answers on their way, which a checkpoint saves and puts back.
pub(super) fn run(ls: Arc<LockstepState>, rx: Receiver<(Payload, Instant)>, cfg: &ShmConfig) {
    let lock = || ls.state.lock().unwrap_or_else(PoisonError::into_inner);
    let (k_ahead, set) = {
        let st = lock();
        (st.out.ahead, st.out.counters.set.clone())
    };
    set.lookahead.store(k_ahead, Ordering::Relaxed);
    let link = Arc::new(Mutex::new(Link::new(rx, ls.clone(), set.clone())));
    // The link's lock is never held across a call to the connection: the state handler runs
    // inside the connection's waits, on this thread.
    let l = || link.lock().unwrap_or_else(PoisonError::into_inner);
    let state = SharedState::new(Box::new(LinkState { link: link.clone(), k: k_ahead, lease: cfg.lease }));
    let connect = |out: &Delivery| connect(out, cfg, Some(state.clone()));
    let check = (cfg.lease / 4).clamp(Duration::from_millis(10), Duration::from_millis(100));
    // Whether the lease let the connection go (then only an answer brings it back).
    let mut lapsed = false;
    loop {
        let mut st = lock();
        if st.part.is_none() {
            drop(st);
            match l().recv_timeout(Duration::from_millis(500)) {
                Ok(()) => lapsed = false,
                Err(RecvTimeoutError::Timeout) if lapsed => continue,
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return,
            }
            let mut st = lock();
            let WriterState { out, part } = &mut *st;
            *part = connect(out);
            l().first = None;
            continue;
        }
        // The next step to answer: waits for the framework to publish it (its timeout).
        let locked = match st.part.as_mut().map(Participant::publish_lock) {
            Some(Ok(k)) => k,
            Some(Err(ShmError::Timeout { .. })) => {
                drop(st);
                if !l().drain() {
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
        let wanted = {
            let mut link = l();
            link.rebase(locked);
            link.published(locked);
            let joined = link.first.is_none();
            let start = *link.first.get_or_insert(locked as i64);
            if joined {
                let out = &st.out;
                info!(
                    domain = %out.domain,
                    "{}: joins at step {locked}; its answers are read from step {} on ({k_ahead} steps of lookahead), the steps before read the values as they are",
                    out.name,
                    locked.max(1) + k_ahead
                );
            }
            if !link.drain() {
                return;
            }
            // The step whose answer this one takes (None: before any answer could exist; a
            // seed, step 0, takes the first answer there is). After a restore, the steps up to
            // the restored one (before this run's first, in a new run) have their answers from
            // the checkpoint.
            let n = locked as i64 - k_ahead as i64;
            match locked {
                0 => Some(None),
                _ if n >= start && (n > 0 || link.is_restored(n)) => Some(Some(n)),
                _ => None,
            }
        };
        let mut owing_since: Option<Instant> = None;
        let mut told = false;
        let outcome = loop {
            let Some(n) = wanted else { break Outcome::Hold };
            {
                let mut link = l();
                link.drop_stale(locked, &st.out);
                link.drop_before(n, &st.out);
                match link.answers.front().map(|(m, _)| *m) {
                    Some(m) if n.map_or(true, |n| m == n) => {
                        break link.answers.pop_front().map_or(Outcome::Hold, |(_, p)| Outcome::Answer(p))
                    }
                    Some(m) => {
                        if let (Some(n), Some(_)) = (n, link.gaps.allow()) {
                            warn!(
                                domain = %st.out.domain,
                                "{}: the answer to step {n} never came (the answer to step {m} came first): the other site started again, or its mirror keeps fewer steps than this lookahead (give it --lookahead {k_ahead} too); step {locked} reads the values as they are",
                                st.out.name
                            );
                        }
                        break Outcome::Hold;
                    }
                    // A restored step whose answer the checkpoint did not have (the link had
                    // not joined yet): it cannot come.
                    None if n.is_some_and(|n| link.is_restored(n)) => break Outcome::Hold,
                    None => {}
                }
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
            match l().recv_timeout(check) {
                Ok(()) | Err(RecvTimeoutError::Timeout) => {}
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
        if let Some(newest) = l().newest {
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
/// the round trip): the writer's thread's, and its checkpoints' ([`LinkState`]).
///
/// Steps are signed here: a checkpoint put back into a new run brings answers to steps before
/// that run's first (its step 1 takes the answer to step 1 - K).
struct Link {
    rx: Receiver<(Payload, Instant)>,
    /// Its `pending`: the answers handed over and not taken yet.
    ls: Arc<LockstepState>,
    set: Arc<SetStats>,
    /// (the step it answers, the answer), in the order received.
    answers: VecDeque<(i64, Payload)>,
    /// (step, when the writer saw it published), oldest first.
    published: VecDeque<(u64, Instant)>,
    /// The latest step answered so far.
    newest: Option<u64>,
    /// The connection's first step: answers to earlier ones cannot come.
    first: Option<i64>,
    /// After a restore: the last step whose answers came from the checkpoint.
    restored: Option<i64>,
    /// A checkpoint's queue taken back, put in place when the next step is published (its
    /// steps counted back from that one).
    to_restore: Option<Saved>,
    /// Steps whose answer never came (a later one did), logged.
    gaps: LogLimit,
}

impl Link {
    fn new(rx: Receiver<(Payload, Instant)>, ls: Arc<LockstepState>, set: Arc<SetStats>) -> Link {
        Link {
            rx,
            ls,
            set,
            answers: VecDeque::new(),
            published: VecDeque::new(),
            newest: None,
            first: None,
            restored: None,
            to_restore: None,
            gaps: LogLimit::new(Duration::from_secs(5)),
        }
    }

    /// Takes an answer handed to the thread; measures the round trip of its step.
    fn take(&mut self, (payload, at): (Payload, Instant)) {
        self.ls.pending.fetch_sub(1, Ordering::AcqRel);
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
        self.answers.push_back((i64::try_from(m).unwrap_or(i64::MAX), payload));
    }

    /// Waits up to `d` for an answer, and takes it.
    fn recv_timeout(&mut self, d: Duration) -> Result<(), RecvTimeoutError> {
        let m = self.rx.recv_timeout(d)?;
        self.take(m);
        Ok(())
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

    /// Whether step `n`'s answer came from a checkpoint (a step up to the one restored).
    fn is_restored(&self, n: i64) -> bool {
        self.restored.is_some_and(|b| n <= b)
    }

    /// Drops the answers at the front of the queue whose step `drop` says, counting them as
    /// late; returns how many.
    fn drop_front_while(&mut self, out: &Delivery, drop: impl Fn(i64) -> bool) -> u64 {
        let mut dropped = 0;
        while self.answers.front().is_some_and(|(m, _)| drop(*m)) {
            self.answers.pop_front();
            SetStats::add(Some(&*self.set), |s| &s.dropped, &out.counters.total.late, 1);
            dropped += 1;
        }
        dropped
    }

    /// Drops the answers to steps before `n` (late: the framework has left the step they
    /// were due at), counting them.
    fn drop_before(&mut self, n: Option<i64>, out: &Delivery) {
        if let Some(n) = n {
            self.drop_front_while(out, |m| m < n);
        }
    }

    /// Drops the answers at the front of the queue to steps after `locked`: none is
    /// published yet, so they come from an earlier life of the domain (a run before this one,
    /// whose answers the other site still sent), counted as late.
    fn drop_stale(&mut self, locked: u64, out: &Delivery) {
        let stale = self.drop_front_while(out, |m| m > locked as i64);
        if stale > 0 && self.gaps.allow().is_some() {
            info!(domain = %out.domain, "{}: {stale} answers to steps after step {locked} dropped: they answer an earlier run's steps", out.name);
        }
    }

    /// Waits (at most `lease`) until the answer to step `n` has come: every answer before it
    /// has then come too, since the link delivers them in order.
    fn wait_for_answer(&mut self, n: u64, lease: Duration) -> Result<(), StateError> {
        let since = Instant::now();
        while self.newest.map_or(true, |m| m < n) {
            match self.recv_timeout(lease.saturating_sub(since.elapsed())) {
                Ok(()) => {}
                Err(RecvTimeoutError::Timeout) => {
                    return Err(format!(
                        "the answer to step {n} did not come over the link within {lease:?} (the lease); the answers on their way cannot be told apart from later ones"
                    )
                    .into())
                }
                Err(RecvTimeoutError::Disconnected) => return Err("the link's writer is gone".into()),
            }
        }
        Ok(())
    }

    /// The queue at this step boundary, its steps counted back from the last step published
    /// (after the answers to every step published so far have come).
    fn save(&mut self, k: u64, lease: Duration) -> Result<Saved, StateError> {
        if let Some(s) = &self.to_restore {
            // Put back and not stepped since: as it was put back.
            return Ok(s.clone());
        }
        let last = self.published.back().map(|(n, _)| *n);
        let Some(last) = last else {
            // No step seen yet: the link joins at the next step.
            return Ok(Saved { k, first: None, answers: Vec::new() });
        };
        self.wait_for_answer(last, lease)?;
        let base = last as i64;
        let mut answers = Vec::new();
        for (m, p) in &self.answers {
            let Payload::Set(s) = p else {
                return Err("an answer is not a typed set (a lookahead needs typed mode)".into());
            };
            if *m <= base && *m > base - k as i64 {
                answers.push((base - *m, s.sim_time, s.data.clone()));
            }
        }
        Ok(Saved { k, first: self.first.map(|f| base - f), answers })
    }

    /// Puts a saved queue back: waits for the answers to the steps published so far (they
    /// must not be taken for the steps after the restore), drops them, and puts the saved
    /// ones in place at the next step.
    fn restore(&mut self, saved: Saved, lease: Duration) -> Result<(), StateError> {
        if let Some(last) = self.published.back().map(|(n, _)| *n) {
            self.wait_for_answer(last, lease)?;
        }
        self.drain();
        self.answers.clear();
        self.published.clear();
        self.restored = None;
        self.to_restore = Some(saved);
        Ok(())
    }

    /// At step `locked`, the first published since a restore: the restored answers take their
    /// steps, counted back from the step before it.
    fn rebase(&mut self, locked: u64) {
        let Some(s) = self.to_restore.take() else { return };
        let base = locked as i64 - 1;
        self.answers = s
            .answers
            .into_iter()
            .map(|(back, sim_time, data)| {
                let step = base - back;
                // A step before this run's first is committed with no wait (as a seed is).
                let typed = TypedSample { step: u64::try_from(step).unwrap_or(0), sim_time, data };
                (step, Payload::Set(typed))
            })
            .collect();
        self.first = Some(s.first.map_or(locked as i64, |back| base - back));
        self.restored = Some(base);
        self.newest = u64::try_from(base).ok();
    }
}

/// A link's queue in a checkpoint: its answers' steps counted back from the boundary's step
/// (a restored run's step numbers are its own).
#[derive(Debug, Clone, PartialEq)]
struct Saved {
    k: u64,
    /// How many steps before the boundary the connection joined (None: not yet).
    first: Option<i64>,
    /// (steps back, simulated time, the set's bytes), oldest first.
    answers: Vec<(i64, f64, Vec<u8>)>,
}

const MAGIC: &[u8; 8] = b"tuttiLQ1";

impl Saved {
    fn to_bytes(&self) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        b.extend_from_slice(&self.k.to_le_bytes());
        b.extend_from_slice(&u64::from(self.first.is_some()).to_le_bytes());
        b.extend_from_slice(&self.first.unwrap_or(0).to_le_bytes());
        b.extend_from_slice(&(self.answers.len() as u64).to_le_bytes());
        for (back, sim, data) in &self.answers {
            b.extend_from_slice(&back.to_le_bytes());
            b.extend_from_slice(&sim.to_bits().to_le_bytes());
            b.extend_from_slice(&(data.len() as u64).to_le_bytes());
            b.extend_from_slice(data);
        }
        b
    }

    fn from_bytes(b: &[u8]) -> Result<Saved, StateError> {
        fn bad() -> StateError {
            "not a lookahead link's state (damaged, or saved by another link)".into()
        }
        fn word(r: &mut &[u8]) -> Result<u64, StateError> {
            let (w, rest) = r.split_first_chunk::<8>().ok_or_else(bad)?;
            *r = rest;
            Ok(u64::from_le_bytes(*w))
        }
        let mut r = b.strip_prefix(MAGIC.as_slice()).ok_or_else(bad)?;
        let k = word(&mut r)?;
        let has_first = word(&mut r)?;
        let first = word(&mut r)? as i64;
        let n = word(&mut r)?;
        let mut answers = Vec::new();
        for _ in 0..n {
            let back = word(&mut r)? as i64;
            let sim = f64::from_bits(word(&mut r)?);
            let len = usize::try_from(word(&mut r)?).map_err(|_| bad())?;
            let data = r.get(..len).ok_or_else(bad)?.to_vec();
            r = &r[len..];
            answers.push((back, sim, data));
        }
        if !r.is_empty() {
            return Err(bad());
        }
        Ok(Saved { k, first: (has_first != 0).then_some(first), answers })
    }
}

/// The state a lookahead's connection keeps (docs/run.md, "Checkpoints"): its queue of
/// answers. Called inside the connection's wait for its next step, on the writer's thread.
struct LinkState {
    link: Arc<Mutex<Link>>,
    k: u64,
    lease: Duration,
}

impl LinkState {
    fn link(&self) -> MutexGuard<'_, Link> {
        self.link.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl StateHandler for LinkState {
    fn save(&mut self) -> Result<Vec<u8>, StateError> {
        let saved = self.link().save(self.k, self.lease)?;
        Ok(saved.to_bytes())
    }

    fn restore(&mut self, state: &[u8]) -> Result<(), StateError> {
        // Nothing: the link had not joined at the checkpoint, and joins at the next step.
        let saved = if state.is_empty() {
            Saved { k: self.k, first: None, answers: Vec::new() }
        } else {
            Saved::from_bytes(state)?
        };
        if saved.k != self.k {
            return Err(format!(
                "the checkpoint's link has a lookahead of {} steps, this one {} (give the gateway --lookahead {})",
                saved.k, self.k, saved.k
            )
            .into());
        }
        self.link().restore(saved, self.lease)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::mpsc::{channel, Sender};

    use super::*;

    fn answer(step: u64) -> Payload {
        Payload::Set(TypedSample { step, sim_time: step as f64 * 0.01, data: step.to_le_bytes().to_vec() })
    }

    /// A link whose answers come from the sender returned, which hands them over (and counts
    /// them pending) as the gateway's reader does.
    fn link() -> (Link, impl Fn(u64)) {
        let (tx, rx): (Sender<(Payload, Instant)>, _) = channel();
        let ls = LockstepState::for_tests(4);
        let link = Link::new(rx, ls.clone(), Arc::default());
        let send = move |step: u64| {
            ls.pending.fetch_add(1, Ordering::AcqRel);
            tx.send((answer(step), Instant::now())).unwrap();
        };
        (link, send)
    }

    /// The steps of the answers queued, and the steps their samples carry.
    fn queued(link: &Link) -> Vec<(i64, u64)> {
        link.answers
            .iter()
            .map(|(m, p)| match p {
                Payload::Set(s) => (*m, s.step),
                Payload::Item { .. } => panic!("an item"),
            })
            .collect()
    }

    /// The round trip of a step is measured from when this thread saw it published; an answer
    /// that came before that (the thread was not scheduled meanwhile) measures nothing, and the
    /// latest round trip measured stands, never a round trip of 0.
    #[test]
    fn an_answer_that_arrived_before_its_step_was_seen_published_measures_no_round_trip() {
        let (mut link, _send) = link();
        link.ls.pending.store(3, Ordering::Relaxed);
        let t0 = Instant::now();
        link.published(1);
        link.take((answer(1), t0 + Duration::from_micros(700)));
        let measured = link.set.rtt_us.load(Ordering::Relaxed);
        assert!(measured > 0 && measured <= 700, "{measured}");
        // Step 2 seen published after its answer arrived.
        let arrived = Instant::now();
        std::thread::sleep(Duration::from_millis(2));
        link.published(2);
        link.take((answer(2), arrived));
        assert_eq!(link.set.rtt_us.load(Ordering::Relaxed), measured);
        // Both answers are queued in order all the same.
        assert_eq!(queued(&link), [(1, 1), (2, 2)]);
        assert_eq!(link.newest, Some(2));
    }

    /// The link of a run at the boundary after step 10 (K = 4, joined at step 1): the answers to
    /// steps 1 to 6 committed, those to 7 to 10 (the next four steps') queued.
    fn at_step_10() -> Link {
        let (mut link, send) = link();
        link.first = Some(1);
        for n in 1..=10 {
            link.published(n);
            send(n);
        }
        assert!(link.drain());
        link.answers.retain(|(m, _)| *m > 6);
        link
    }

    /// A save holds the answers the next K steps take, counted back from the boundary; put back
    /// into a new run they are the answers to steps -3 to 0 (the steps 1 to 4 of that run take
    /// them), committed with no wait; put back into a run at step 500 they answer 497 to 500.
    #[test]
    fn a_saved_queue_is_put_back_with_its_steps_counted_from_the_next_step() {
        let saved = at_step_10().save(4, Duration::from_secs(1)).unwrap();
        assert_eq!(saved.first, Some(9));
        let backs: Vec<i64> = saved.answers.iter().map(|a| a.0).collect();
        assert_eq!(backs, [3, 2, 1, 0]);
        assert_eq!(Saved::from_bytes(&saved.to_bytes()).unwrap(), saved);

        // A new run: nothing published yet.
        let (mut fresh, _send) = link();
        fresh.restore(saved.clone(), Duration::from_secs(1)).unwrap();
        // Saved again before any step: as it was put back.
        assert_eq!(fresh.save(4, Duration::from_secs(1)).unwrap(), saved);
        fresh.rebase(1);
        assert_eq!(queued(&fresh), [(-3, 0), (-2, 0), (-1, 0), (0, 0)]);
        assert_eq!((fresh.first, fresh.restored), (Some(-9), Some(0)));
        // The values are those saved: the answer to step 7 first.
        let Some((_, Payload::Set(s))) = fresh.answers.front() else { panic!() };
        assert_eq!((s.data.as_slice(), s.sim_time), (7u64.to_le_bytes().as_slice(), 0.07));

        // The run that goes on at step 500 (the answers to 497 to 500 came): those are dropped.
        let (mut going, send) = link();
        going.first = Some(1);
        for n in 1..=500 {
            going.published(n);
            send(n);
        }
        going.restore(saved, Duration::from_secs(1)).unwrap();
        assert!(going.answers.is_empty() && going.published.is_empty());
        going.rebase(501);
        assert_eq!(queued(&going), [(497, 497), (498, 498), (499, 499), (500, 500)]);
        assert_eq!(going.first, Some(491));
    }

    /// A restore waits for the answers to the steps already published that are still on their
    /// way, and drops them: taken after it, they would answer the steps made again.
    #[test]
    fn a_restore_waits_for_the_answers_on_their_way_and_drops_them() {
        let saved = at_step_10().save(4, Duration::from_secs(1)).unwrap();
        let (tx, rx) = channel();
        let ls = LockstepState::for_tests(4);
        let mut going = Link::new(rx, ls.clone(), Arc::default());
        for n in 1..=8 {
            going.published(n);
        }
        let late = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(50));
            for n in 1..=8 {
                ls.pending.fetch_add(1, Ordering::AcqRel);
                tx.send((answer(n), Instant::now())).unwrap();
            }
            tx
        });
        going.restore(saved, Duration::from_secs(30)).unwrap();
        let tx = late.join().unwrap();
        assert!(going.drain());
        going.rebase(9);
        assert_eq!(queued(&going), [(5, 5), (6, 6), (7, 7), (8, 8)]);
        assert_eq!(going.ls.pending.load(Ordering::Acquire), 0, "every answer taken");
        drop(tx);
    }

    /// A save whose answers do not come within the lease fails with the reason; so does a
    /// restore of a link with another K, or of bytes that are not a link's state.
    #[test]
    fn a_save_without_its_answers_and_a_foreign_or_damaged_state_are_refused() {
        let (mut link, send) = link();
        link.first = Some(1);
        for n in 1..=5 {
            link.published(n);
        }
        send(1);
        let e = link.save(4, Duration::from_millis(30)).unwrap_err().to_string();
        assert!(e.contains("the answer to step 5 did not come over the link"), "{e}");

        let saved = at_step_10().save(4, Duration::from_secs(1)).unwrap().to_bytes();
        let mut other = LinkState { link: Arc::new(Mutex::new(at_step_10())), k: 10, lease: Duration::from_secs(1) };
        let e = other.restore(&saved).unwrap_err().to_string();
        assert!(e.contains("a lookahead of 4 steps, this one 10"), "{e}");
        // No state (the link had not joined at the checkpoint): it joins at the next step.
        other.restore(&[]).unwrap();
        let mut link = other.link();
        link.rebase(501);
        assert!(link.answers.is_empty());
        assert_eq!((link.first, link.restored), (Some(501), Some(500)));
        for bad in [&saved[..saved.len() - 1], &saved[1..], b"".as_slice()] {
            let e = Saved::from_bytes(bad).unwrap_err().to_string();
            assert!(e.contains("not a lookahead link's state"), "{e}");
        }
    }
}
