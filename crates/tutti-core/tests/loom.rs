//! Model checks (loom) of the two concurrency protocols of the shared-memory layer, run on
//! the very code the segments use. Build with `--cfg tutti_loom`:
//!
//! ```text
//! RUSTFLAGS="--cfg tutti_loom" CARGO_TARGET_DIR=target/loom cargo test -p tutti-core --test loom --release
//! ```
#![cfg(tutti_loom)]

use loom::sync::Arc;
use loom::thread;
use tutti_core::shm::bucket::{Bucket, SlotWords, Stamp, SLOTS};
use tutti_core::shm::handshake::{ConnCtl, StepCtl, CONN_EVENT, CONN_SYNC_READER, CONN_WRITER, MASK_WORDS};
use tutti_core::sync::{AtomicU32, AtomicU64, Ordering};

/// The bucket's slots, two words each: enough to see a torn value (the words differ).
struct Mem {
    meta: [SlotWords; SLOTS],
    current: AtomicU64,
    slots: [[AtomicU64; 2]; SLOTS],
}

impl Mem {
    fn new() -> Self {
        let z = || AtomicU64::new(0);
        Mem {
            meta: std::array::from_fn(|_| SlotWords::new()),
            current: z(),
            slots: std::array::from_fn(|_| [z(), z()]),
        }
    }
    fn bucket(&self) -> Bucket<'_> {
        Bucket { meta: &self.meta, current: &self.current, slots: std::array::from_fn(|i| self.slots[i].as_slice()) }
    }
}

fn value(v: u64) -> [u8; 16] {
    let mut b = [0u8; 16];
    b[..8].copy_from_slice(&v.to_ne_bytes());
    b[8..].copy_from_slice(&v.to_ne_bytes());
    b
}

/// The stamp the writers give value `v`.
fn stamp(v: u64) -> Stamp {
    Stamp { step: v, sim_time: v as f64 / 4.0 }
}

fn words(b: &[u8; 16]) -> (u64, u64) {
    (u64::from_ne_bytes(b[..8].try_into().unwrap()), u64::from_ne_bytes(b[8..].try_into().unwrap()))
}

/// Explores every interleaving with up to three preemptions: enough to lap a reader around
/// the whole ring (it takes `SLOTS` writes during one copy), and fast enough for CI.
fn model(f: impl Fn() + Sync + Send + 'static) {
    let mut builder = loom::model::Builder::new();
    builder.preemption_bound = Some(3);
    builder.check(f);
}

/// A writer of values 1 ..= SLOTS + 1, enough to lap a reader around the ring; with
/// `give_up`, it also abandons a write after value 2 (which must leave value 2 current).
fn spawn_writer(mem: &Arc<Mem>, give_up: bool) -> thread::JoinHandle<()> {
    let w = mem.clone();
    thread::spawn(move || {
        for v in 1..=SLOTS as u64 + 1 {
            w.bucket().write(&value(v), stamp(v));
            if give_up && v == 2 {
                assert_eq!(w.bucket().try_write_with(|_, _| None), None);
            }
        }
    })
}

#[test]
fn bucket_reads_are_never_torn() {
    model(|| {
        let mem = Arc::new(Mem::new());
        let writer = spawn_writer(&mem, false);
        let mut out = [0u8; 16];
        for _ in 0..2 {
            if let Some((generation, st)) = mem.bucket().try_read_stamped_at(0, &mut out) {
                let (a, b) = words(&out);
                assert_eq!(a, b, "torn read");
                assert_eq!(a, generation, "value and generation disagree");
                assert_eq!(st, stamp(a), "value and stamp disagree");
            }
        }
        writer.join().unwrap();
        let g = mem.bucket().try_read(&mut out).expect("quiescent read succeeds");
        let last = SLOTS as u64 + 1;
        assert_eq!((g, words(&out)), (last, (last, last)));
    });
}

#[test]
fn values_read_in_place_are_kept_only_when_whole() {
    model(|| {
        let mem = Arc::new(Mem::new());
        let writer = spawn_writer(&mem, true);
        let seen = mem.bucket().read_in_place(|b| words(b.try_into().unwrap()), 16, 2);
        if let Some((generation, st, (a, b))) = seen {
            assert_eq!(a, b, "torn value kept");
            assert_eq!(a, generation, "value and generation disagree");
            assert_eq!(st, stamp(a), "value and stamp disagree");
        }
        writer.join().unwrap();
        let (g, st, (a, b)) = mem.bucket().read_in_place(|b| words(b.try_into().unwrap()), 16, 1).unwrap();
        let last = SLOTS as u64 + 1;
        assert_eq!((g, st, a, b), (last, stamp(last), last, last));
    });
}

struct Shared {
    publish: Mem,
    subscribe: Mem,
    pub_step: AtomicU64,
    step_seq: AtomicU32,
    ack_seq: AtomicU32,
    active: AtomicU32,
    flags: AtomicU32,
    first_step: AtomicU64,
    last_read: AtomicU64,
    last_commit: AtomicU64,
    changed_step: AtomicU64,
    all_due_step: AtomicU64,
    due_index: AtomicU64,
    pub_index: AtomicU64,
    answered: AtomicU64,
    due_at: AtomicU64,
    due_seq: AtomicU32,
    changed_items: [AtomicU64; MASK_WORDS],
    read_items: [AtomicU64; MASK_WORDS],
}

impl Shared {
    /// One connection, flagged `flags`, taking part from step 1; nothing published yet.
    fn new(flags: u32) -> Self {
        let z = || AtomicU64::new(0);
        Shared {
            publish: Mem::new(),
            subscribe: Mem::new(),
            pub_step: z(),
            step_seq: AtomicU32::new(0),
            ack_seq: AtomicU32::new(0),
            active: AtomicU32::new(1),
            flags: AtomicU32::new(flags),
            first_step: AtomicU64::new(1),
            last_read: z(),
            last_commit: z(),
            changed_step: z(),
            all_due_step: z(),
            due_index: z(),
            pub_index: z(),
            answered: z(),
            due_at: z(),
            due_seq: AtomicU32::new(0),
            changed_items: std::array::from_fn(|_| z()),
            read_items: std::array::from_fn(|_| z()),
        }
    }

    fn step_ctl(&self) -> StepCtl<'_> {
        StepCtl {
            pub_step: &self.pub_step,
            step_seq: &self.step_seq,
            ack_seq: &self.ack_seq,
            changed_step: &self.changed_step,
            pub_index: &self.pub_index,
            all_due_step: &self.all_due_step,
            changed_items: &self.changed_items,
        }
    }
    fn conn(&self) -> ConnCtl<'_> {
        ConnCtl {
            active: &self.active,
            flags: &self.flags,
            first_step: &self.first_step,
            last_read: &self.last_read,
            last_commit: &self.last_commit,
            due_index: &self.due_index,
            answered: &self.answered,
            read_items: &self.read_items,
            due_at: &self.due_at,
            due_seq: &self.due_seq,
        }
    }
}

#[test]
fn lock_step_handshake_reads_each_step_once_and_sees_each_answer() {
    const STEPS: u64 = 2;
    model(|| {
        let s = Arc::new(Shared::new(CONN_SYNC_READER | CONN_WRITER));
        let p = s.clone();
        let participant = thread::spawn(move || {
            let mut last = 0;
            let mut out = [0u8; 16];
            for _ in 0..STEPS {
                let k = loop {
                    if let Some(k) = p.step_ctl().next_step(last) {
                        break k;
                    }
                    thread::yield_now();
                };
                assert_eq!(k, last + 1, "a step was skipped");
                let g = loop {
                    if let Some(g) = p.publish.bucket().try_read(&mut out) {
                        break g;
                    }
                    thread::yield_now();
                };
                assert_eq!(g, k, "read another step's data");
                assert_eq!(words(&out), (k, k));
                p.step_ctl().ack_read(&p.conn(), k);
                p.subscribe.bucket().write(&value(10 * k), stamp(k));
                p.step_ctl().ack_commit(&p.conn(), k);
                last = k;
            }
        });
        let mut out = [0u8; 16];
        for k in 1..=STEPS {
            s.publish.bucket().write(&value(k), stamp(k));
            s.step_ctl().publish(k, k, &[0; MASK_WORDS]);
            while s.conn().owes(&s.step_ctl(), k) {
                thread::yield_now();
            }
            s.subscribe.bucket().try_read(&mut out).expect("the only writer is done");
            assert_eq!(words(&out), (10 * k, 10 * k), "framework missed the answer to step {k}");
        }
        participant.join().unwrap();
        assert_eq!(s.last_read.load(Ordering::Relaxed), STEPS);
    });
}

/// The event-driven handshake: a participant due at steps 1 and 3 only (it asks for step 3
/// when it answers step 1) reads exactly those, and the framework never goes past a due step
/// before its answer, nor waits at a step the participant is not due at. The framework alone
/// decides who is due at its step (it knows the step's index), and tells them.
#[test]
fn event_handshake_reads_exactly_the_due_steps() {
    const STEPS: u64 = 4;
    model(|| {
        let s = Arc::new(Shared::new(CONN_SYNC_READER | CONN_WRITER | CONN_EVENT));
        let p = s.clone();
        let participant = thread::spawn(move || {
            let mut answered = 0;
            let mut out = [0u8; 16];
            let mut read = Vec::new();
            for next in [3, u64::MAX] {
                let k = loop {
                    if let Some(k) = p.step_ctl().next_due(&p.conn(), answered) {
                        break k;
                    }
                    thread::yield_now();
                };
                let g = loop {
                    if let Some(g) = p.publish.bucket().try_read(&mut out) {
                        break g;
                    }
                    thread::yield_now();
                };
                assert_eq!(words(&out), (k, k), "read another step's data (generation {g})");
                p.subscribe.bucket().write(&value(10 * k), stamp(k));
                read.push(k);
                p.step_ctl().answer(&p.conn(), k, next, &[0; MASK_WORDS]);
                answered = k;
            }
            read
        });
        let mut out = [0u8; 16];
        for k in 1..=STEPS {
            s.publish.bucket().write(&value(k), stamp(k));
            s.step_ctl().publish(k, k, &[0; MASK_WORDS]);
            // The framework tells it where it is due (here once, after the publish).
            s.step_ctl().mark_due(&s.conn(), k);
            if k % 2 == 0 {
                // Not due: the answer to the step before said so, before that step ended.
                assert!(!s.conn().owes(&s.step_ctl(), k), "the framework would wait at step {k}");
            }
            while s.conn().owes(&s.step_ctl(), k) {
                thread::yield_now();
            }
            if k == 1 || k == 3 {
                s.subscribe.bucket().try_read(&mut out).expect("the only writer is done");
                assert_eq!(words(&out), (10 * k, 10 * k), "framework missed the answer to step {k}");
            }
        }
        assert_eq!(participant.join().unwrap(), [1, 3], "the participant reads its due steps only");
    });
}
