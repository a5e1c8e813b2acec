//! The bucket: a set's latest value, in a ring of [`SLOTS`] slots guarded by seqlocks.
//!
//! A writer (one at a time: the framework for PUBLISH, the holder of the writer lock for
//! SUBSCRIBE) fills the slot after the current one, then makes it current. A reader copies
//! the current slot and keeps the copy only if the slot's sequence number was even and
//! unchanged across the copy. Writers never wait for readers; a reader retries only when
//! the writer laps it (`SLOTS` commits during one copy), which a ring of four makes rare even
//! under a writer that commits back to back. The sequence numbers, generations and fences
//! are atomics; the data itself is copied with `memcpy`, as in any C seqlock, and a copy
//! that raced a writer is thrown away by the sequence check. Under `--cfg tutti_loom` the
//! data goes through relaxed atomic word accesses instead, so that loom checks the very
//! protocol (`tests/loom.rs`); `docs/architecture.md` says why the fast build copies bytes.

use crate::sync::{fence, spin_hint, AtomicU64, Ordering};

/// Slots per bucket (a power of two: the generation's low bits name the current slot).
pub const SLOTS: usize = 4;

/// What a value belongs to: the framework's step and that step's simulated time (seconds),
/// kept with the value inside its slot's seqlock, so that a reader gets the value and the
/// step it belongs to as one (docs/architecture.md, "Stamps"). A PUBLISH value is stamped
/// with the step it publishes; a SUBSCRIBE value with the step its commit answers (in a
/// synchronous domain) or the step the framework had published when it was committed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stamp {
    pub step: u64,
    pub sim_time: f64,
}

/// One slot's words beside its value, 32 bytes of their own (a cache line holds two slots'
/// words, so a reader or writer of a slot touches one line besides `current`): its sequence
/// number, the generation it holds and its [`Stamp`], all written and read inside the
/// slot's seqlock.
#[repr(C, align(32))]
#[derive(Debug)]
pub struct SlotWords {
    pub seq: AtomicU64,
    /// The generation the slot holds, so that a reader lapped between loading `current` and
    /// its copy still reports the right one.
    pub gen: AtomicU64,
    pub step: AtomicU64,
    /// The simulated time's bits.
    pub time: AtomicU64,
}

impl SlotWords {
    /// Zeroed words (in shared memory they are zero as mapped).
    pub fn new() -> SlotWords {
        SlotWords { seq: AtomicU64::new(0), gen: AtomicU64::new(0), step: AtomicU64::new(0), time: AtomicU64::new(0) }
    }
}

impl Default for SlotWords {
    fn default() -> Self {
        SlotWords::new()
    }
}

/// A view of one bucket in memory: the slots' words ([`SlotWords`]), the generation counter
/// (its low bits name the current slot) and the slots' values.
#[derive(Debug, Clone, Copy)]
pub struct Bucket<'a> {
    pub meta: &'a [SlotWords; SLOTS],
    pub current: &'a AtomicU64,
    pub slots: [&'a [AtomicU64]; SLOTS],
}

/// Copies `src` bytes into shared words (bytes past `src.len()` keep their value).
///
/// Outside the loom model this is one `memcpy`: word-by-word atomic stores cannot be
/// vectorised and cost three times as much on a large set. A reader racing with the copy
/// sees bytes of either value, exactly as a C seqlock does, and the slot's sequence number
/// makes it throw them away (see `docs/architecture.md`, "Why the copies are memcpy").
pub fn store_bytes(dst: &[AtomicU64], src: &[u8]) {
    let n = src.len().min(dst.len() * 8);
    #[cfg(not(tutti_loom))]
    // SAFETY: `dst` covers `dst.len() * 8` bytes of atomics (interior mutability, so
    // writing through a shared reference is allowed) and `src` is at least `n` long; the
    // two cannot overlap because `src` is a plain slice.
    unsafe {
        std::ptr::copy_nonoverlapping(src.as_ptr(), dst.as_ptr() as *mut u8, n);
    }
    #[cfg(tutti_loom)]
    {
        let src = &src[..n];
        let mut chunks = src.chunks_exact(8);
        for (word, chunk) in dst.iter().zip(&mut chunks) {
            word.store(u64::from_ne_bytes(chunk.try_into().unwrap_or([0; 8])), Ordering::Relaxed);
        }
        let rest = chunks.remainder();
        if !rest.is_empty() {
            if let Some(word) = dst.get(src.len() / 8) {
                let mut b = word.load(Ordering::Relaxed).to_ne_bytes();
                b[..rest.len()].copy_from_slice(rest);
                word.store(u64::from_ne_bytes(b), Ordering::Relaxed);
            }
        }
    }
}

/// Copies shared words into `dst` bytes (one `memcpy` outside the loom model, as for
/// [`store_bytes`]; a torn copy is detected by the caller's sequence check).
pub fn load_bytes(src: &[AtomicU64], dst: &mut [u8]) {
    let n = dst.len().min(src.len() * 8);
    #[cfg(not(tutti_loom))]
    // SAFETY: `src` covers `src.len() * 8` readable bytes and `dst` at least `n`; a plain
    // `&mut` slice cannot overlap shared atomics.
    unsafe {
        std::ptr::copy_nonoverlapping(src.as_ptr() as *const u8, dst.as_mut_ptr(), n);
    }
    #[cfg(tutti_loom)]
    {
        let dst = &mut dst[..n];
        let len = dst.len();
        let mut chunks = dst.chunks_exact_mut(8);
        for (word, chunk) in src.iter().zip(&mut chunks) {
            chunk.copy_from_slice(&word.load(Ordering::Relaxed).to_ne_bytes());
        }
        let rest = chunks.into_remainder();
        if !rest.is_empty() {
            if let Some(word) = src.get(len / 8) {
                let n = rest.len();
                rest.copy_from_slice(&word.load(Ordering::Relaxed).to_ne_bytes()[..n]);
            }
        }
    }
}

/// Stores `src` at byte `offset` of shared words, keeping the bytes around it (the caller
/// is the only writer). Bytes past the end of `dst` are dropped.
pub fn store_range(dst: &[AtomicU64], offset: usize, src: &[u8]) {
    let len = dst.len() * 8;
    if offset >= len {
        return;
    }
    let src = &src[..src.len().min(len - offset)];
    #[cfg(not(tutti_loom))]
    // SAFETY: `offset + src.len() <= dst.len() * 8` (clamped above); see `store_bytes`.
    unsafe {
        std::ptr::copy_nonoverlapping(src.as_ptr(), (dst.as_ptr() as *mut u8).add(offset), src.len());
    }
    #[cfg(tutti_loom)]
    {
        let end = offset + src.len();
        let mut w = offset / 8;
        while w * 8 < end {
            let Some(word) = dst.get(w) else { return };
            let lo = (w * 8).max(offset);
            let hi = (w * 8 + 8).min(end);
            let mut b =
                if lo == w * 8 && hi == w * 8 + 8 { [0u8; 8] } else { word.load(Ordering::Relaxed).to_ne_bytes() };
            b[lo - w * 8..hi - w * 8].copy_from_slice(&src[lo - offset..hi - offset]);
            word.store(u64::from_ne_bytes(b), Ordering::Relaxed);
            w += 1;
        }
    }
}

/// Copies `dst.len()` bytes from byte `offset` of shared words (a part of a set; the
/// caller has checked that the range lies inside it).
pub fn load_range(src: &[AtomicU64], offset: usize, dst: &mut [u8]) {
    let len = src.len() * 8;
    let n = dst.len().min(len.saturating_sub(offset));
    #[cfg(not(tutti_loom))]
    // SAFETY: `offset + n <= src.len() * 8`; see `load_bytes`.
    unsafe {
        std::ptr::copy_nonoverlapping((src.as_ptr() as *const u8).add(offset), dst.as_mut_ptr(), n);
    }
    #[cfg(tutti_loom)]
    for (i, b) in dst[..n].iter_mut().enumerate() {
        let at = offset + i;
        *b = src[at / 8].load(Ordering::Relaxed).to_ne_bytes()[at % 8];
    }
}

/// Lends the words of a slot being written as bytes, for a writer that computes a value in
/// place (no staging copy on the way). Outside the loom model the bytes are the shared
/// memory itself; the loom model goes through a buffer with the same effect.
pub fn with_bytes_mut<R>(words: &[AtomicU64], f: impl FnOnce(&mut [u8]) -> R) -> R {
    #[cfg(not(tutti_loom))]
    {
        // SAFETY: the words are atomics (interior mutability) covering `len * 8` bytes; the
        // caller is the slot's only writer while it is lent (the slot is not current, its
        // sequence number odd, so no reader trusts it), and the loan ends with `f`.
        let bytes = unsafe { std::slice::from_raw_parts_mut(words.as_ptr() as *mut u8, words.len() * 8) };
        f(bytes)
    }
    #[cfg(tutti_loom)]
    {
        let mut buf = vec![0u8; words.len() * 8];
        load_bytes(words, &mut buf);
        let r = f(&mut buf);
        store_bytes(words, &buf);
        r
    }
}

/// Lends the first `len` bytes of a slot for reading, in place outside the loom model (the
/// caller validates the slot's sequence number afterwards; see `read_in_place`).
pub fn with_bytes<R>(words: &[AtomicU64], len: usize, f: impl FnOnce(&[u8]) -> R) -> R {
    let len = len.min(words.len() * 8);
    #[cfg(not(tutti_loom))]
    {
        // SAFETY: the words cover `words.len() * 8 >= len` bytes of atomics; a writer of
        // another process (or thread) may change them meanwhile, which the caller's sequence
        // check detects, and `f` only reads bytes, never trusting them.
        let bytes = unsafe { std::slice::from_raw_parts(words.as_ptr() as *const u8, len) };
        f(bytes)
    }
    #[cfg(tutti_loom)]
    {
        let mut buf = vec![0u8; len];
        load_bytes(words, &mut buf);
        f(&buf)
    }
}

/// Copies one slot's words into another (the writer carrying the previous value over).
pub fn copy_words(dst: &[AtomicU64], src: &[AtomicU64]) {
    #[cfg(not(tutti_loom))]
    // SAFETY: two distinct slots of one bucket never overlap; the length is the shorter one.
    unsafe {
        std::ptr::copy_nonoverlapping(src.as_ptr() as *const u8, dst.as_ptr() as *mut u8, dst.len().min(src.len()) * 8);
    }
    #[cfg(tutti_loom)]
    for (p, n) in src.iter().zip(dst) {
        n.store(p.load(Ordering::Relaxed), Ordering::Relaxed);
    }
}

impl Bucket<'_> {
    /// Writes a new value stamped `stamp`: `fill(previous, next)` is called with the current
    /// slot's words and the slot being written; it typically copies the previous value and
    /// overlays changes. Returns the new generation. The caller guarantees there is one
    /// writer at a time.
    pub fn write_with(&self, stamp: Stamp, fill: impl FnOnce(&[AtomicU64], &[AtomicU64])) -> u64 {
        let generation = self.try_write_with(|prev, next| {
            fill(prev, next);
            Some(stamp)
        });
        generation.unwrap_or_else(|| self.current.load(Ordering::Relaxed))
    }

    /// [`write_with`](Self::write_with) whose `fill` may give up (returns `None`) or else
    /// names the value's stamp once it has filled the slot: given up, the slot is abandoned,
    /// not made current, and `None` is returned.
    pub fn try_write_with(&self, fill: impl FnOnce(&[AtomicU64], &[AtomicU64]) -> Option<Stamp>) -> Option<u64> {
        let generation = self.current.load(Ordering::Relaxed);
        let cur = generation as usize % SLOTS;
        let next = (cur + 1) % SLOTS;
        let seq = &self.meta[next].seq;
        let s = seq.load(Ordering::Relaxed);
        // Odd: writing. (A writer that died mid-write left it odd; start from the next odd.)
        let writing = if s & 1 == 1 { s.wrapping_add(2) } else { s.wrapping_add(1) };
        seq.store(writing, Ordering::Relaxed);
        fence(Ordering::Release);
        self.meta[next].gen.store(generation.wrapping_add(1), Ordering::Relaxed);
        let filled = fill(self.slots[cur], self.slots[next]);
        if let Some(stamp) = filled {
            self.meta[next].step.store(stamp.step, Ordering::Relaxed);
            self.meta[next].time.store(stamp.sim_time.to_bits(), Ordering::Relaxed);
        }
        seq.store(writing.wrapping_add(1), Ordering::Release);
        // Not current when given up, so no reader takes it; its sequence is even again for
        // the next writer.
        filled?;
        self.current.store(generation.wrapping_add(1), Ordering::Release);
        Some(generation.wrapping_add(1))
    }

    /// Writes `src` as the new value stamped `stamp` (bytes past `src.len()` keep the
    /// previous value).
    pub fn write(&self, src: &[u8], stamp: Stamp) -> u64 {
        self.write_with(stamp, |prev, next| {
            if src.len() < next.len() * 8 {
                copy_words(next, prev);
            }
            store_bytes(next, src);
        })
    }

    /// One attempt at a consistent copy: `Some(generation)` when `dst` holds a whole value.
    pub fn try_read(&self, dst: &mut [u8]) -> Option<u64> {
        self.try_read_at(0, dst)
    }

    /// One attempt at a consistent copy of the `dst.len()` bytes at byte `offset` of the
    /// latest value (one item rather than the whole set).
    pub fn try_read_at(&self, offset: usize, dst: &mut [u8]) -> Option<u64> {
        self.try_read_stamped_at(offset, dst).map(|(generation, _)| generation)
    }

    /// [`try_read_at`](Self::try_read_at), with the value's [`Stamp`].
    pub fn try_read_stamped_at(&self, offset: usize, dst: &mut [u8]) -> Option<(u64, Stamp)> {
        let read = self.try_with(|words| {
            if offset == 0 {
                load_bytes(words, dst);
            } else {
                load_range(words, offset, dst);
            }
        });
        read.map(|(generation, stamp, ())| (generation, stamp))
    }

    /// The seqlock read, once: `f` runs on the current slot's words, and its result comes
    /// back with the slot's generation only if the slot's sequence number was even and
    /// unchanged across the call (otherwise whatever `f` saw may be torn), and the slot's stamp.
    fn try_with<R>(&self, f: impl FnOnce(&[AtomicU64]) -> R) -> Option<(u64, Stamp, R)> {
        let generation = self.current.load(Ordering::Acquire);
        let slot = generation as usize % SLOTS;
        let meta = &self.meta[slot];
        let s1 = meta.seq.load(Ordering::Acquire);
        if s1 & 1 == 1 {
            return None;
        }
        let held = meta.gen.load(Ordering::Relaxed);
        let stamp = Stamp {
            step: meta.step.load(Ordering::Relaxed),
            sim_time: f64::from_bits(meta.time.load(Ordering::Relaxed)),
        };
        let r = f(self.slots[slot]);
        fence(Ordering::Acquire);
        let s2 = meta.seq.load(Ordering::Relaxed);
        (s1 == s2).then_some((held, stamp, r))
    }

    /// A consistent copy of the latest value; returns its generation. Retries while a
    /// writer laps the reader; `None` after `max_tries` failed attempts (only a writer that
    /// commits continuously faster than one copy, or a corrupted segment, does that).
    pub fn read(&self, dst: &mut [u8], max_tries: u32) -> Option<u64> {
        self.read_at(0, dst, max_tries)
    }

    /// [`read`](Self::read) of the `dst.len()` bytes at byte `offset` only.
    pub fn read_at(&self, offset: usize, dst: &mut [u8], max_tries: u32) -> Option<u64> {
        self.read_stamped_at(offset, dst, max_tries).map(|(generation, _)| generation)
    }

    /// [`read_at`](Self::read_at), with the value's [`Stamp`].
    pub fn read_stamped_at(&self, offset: usize, dst: &mut [u8], max_tries: u32) -> Option<(u64, Stamp)> {
        for _ in 0..max_tries {
            if let Some(read) = self.try_read_stamped_at(offset, dst) {
                return Some(read);
            }
            spin_hint();
        }
        None
    }

    /// Runs `f` on the latest value where it lies, without copying it, and returns the value's
    /// generation with `f`'s result once the slot's sequence number shows that the value did
    /// not change while `f` ran. Otherwise `f` runs again on the newer value, so it may see
    /// a torn value first and must only compute from the bytes (copy, convert, serialise),
    /// never trust them. `None` after `max_tries` attempts, as for [`read`](Self::read). The
    /// value's [`Stamp`] comes with it.
    pub fn read_in_place<R>(
        &self,
        mut f: impl FnMut(&[u8]) -> R,
        len: usize,
        max_tries: u32,
    ) -> Option<(u64, Stamp, R)> {
        for _ in 0..max_tries {
            if let Some(read) = self.try_with(|words| with_bytes(words, len, &mut f)) {
                return Some(read);
            }
            spin_hint();
        }
        None
    }

    /// After the writer died mid-write: make the abandoned slot's sequence even again. The
    /// slot was not current, so no reader trusted its contents.
    pub fn recover(&self) {
        for seq in self.meta.iter().map(|m| &m.seq) {
            let s = seq.load(Ordering::Relaxed);
            if s & 1 == 1 {
                seq.store(s.wrapping_add(1), Ordering::Release);
            }
        }
    }
}

#[cfg(all(test, not(tutti_loom)))]
mod tests {
    use super::*;

    fn words(n: usize) -> Vec<AtomicU64> {
        (0..n).map(|_| AtomicU64::new(0)).collect()
    }

    #[test]
    fn bytes_round_trip_through_words_with_tails() {
        let w = words(2);
        store_bytes(&w, &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]);
        let mut out = [0u8; 11];
        load_bytes(&w, &mut out);
        assert_eq!(out, [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]);
        // A short store keeps the bytes after it.
        store_bytes(&w, &[0xaa; 9]);
        load_bytes(&w, &mut out);
        assert_eq!(out, [0xaa, 0xaa, 0xaa, 0xaa, 0xaa, 0xaa, 0xaa, 0xaa, 0xaa, 10, 11]);
    }

    #[test]
    fn ranges_are_stored_without_touching_neighbours() {
        let w = words(3);
        store_bytes(&w, &[0x11; 24]);
        store_range(&w, 5, &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
        let mut out = [0u8; 24];
        load_bytes(&w, &mut out);
        let mut want = [0x11u8; 24];
        want[5..17].copy_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
        assert_eq!(out, want);
        let mut part = [0u8; 7];
        load_range(&w, 3, &mut part);
        assert_eq!(part, want[3..10]);
        // A range running past the end is cut at the end.
        let mut tail = [0xffu8; 4];
        load_range(&w, 22, &mut tail);
        assert_eq!(tail, [0x11, 0x11, 0xff, 0xff]);
    }

    #[test]
    fn writes_alternate_slots_and_reads_see_the_latest() {
        let meta: [SlotWords; SLOTS] = std::array::from_fn(|_| SlotWords::new());
        let current = AtomicU64::new(0);
        let w: Vec<Vec<AtomicU64>> = (0..SLOTS).map(|_| words(1)).collect();
        let bucket = Bucket { meta: &meta, current: &current, slots: std::array::from_fn(|i| w[i].as_slice()) };
        let mut out = [0u8; 8];
        let at = |step| Stamp { step, sim_time: step as f64 * 0.5 };
        assert_eq!(bucket.write(&7u64.to_ne_bytes(), at(3)), 1);
        assert_eq!(bucket.read(&mut out, 10), Some(1));
        assert_eq!(u64::from_ne_bytes(out), 7);
        bucket.write(&9u64.to_ne_bytes(), at(4));
        assert_eq!(bucket.read_stamped_at(0, &mut out, 10), Some((2, at(4))), "the value comes with its own stamp");
        assert_eq!(u64::from_ne_bytes(out), 9);
        // A write given up leaves the value and its stamp as they were.
        assert_eq!(
            bucket.try_write_with(|_, next| {
                store_bytes(next, &[1; 8]);
                None
            }),
            None
        );
        assert_eq!(bucket.read_stamped_at(0, &mut out, 10), Some((2, at(4))));
        assert_eq!(u64::from_ne_bytes(out), 9);
        // A writer that died mid-write: the next slot stays odd until recovered.
        meta[3].seq.store(5, Ordering::Relaxed);
        current.store(3, Ordering::Relaxed);
        assert_eq!(bucket.try_read(&mut out), None);
        bucket.recover();
        assert!(bucket.try_read(&mut out).is_some());
    }
}
