//! The byte mutator of the fuzz tests: edits a valid input (a DDF, a config file, a
//! recording) into a damaged one. Each fuzz test draws the edits it wants (its own ranges,
//! tokens and values, with proptest) and applies them with [`Mutation::apply`].

/// One edit of a byte string. Positions are taken modulo the input's length, so that any
/// drawn number is a position in it; a length runs at most to the end.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Mutation {
    /// XORs the byte at `at` with `mask`.
    Flip { at: usize, mask: u8 },
    /// Sets the byte at `at` to `byte`.
    Set { at: usize, byte: u8 },
    /// Cuts the input at `at`.
    Truncate { at: usize },
    /// Removes `len` bytes from `at` on.
    Delete { at: usize, len: usize },
    /// Inserts a copy of the `len` bytes from `at` on, at `at`.
    Duplicate { at: usize, len: usize },
    /// Inserts `bytes` at `at` (modulo the length plus one: the end is a place too).
    Insert { at: usize, bytes: Vec<u8> },
    /// Writes `bytes` over the input from `at` on, as far as the input goes (a huge length
    /// field, wherever it is).
    Overwrite { at: usize, bytes: Vec<u8> },
}

impl Mutation {
    /// Applies the edit to `bytes`; an empty input stays empty.
    pub fn apply(&self, bytes: &mut Vec<u8>) {
        let n = bytes.len();
        if n == 0 {
            return;
        }
        match self {
            Mutation::Flip { at, mask } => bytes[at % n] ^= mask,
            Mutation::Set { at, byte } => bytes[at % n] = *byte,
            Mutation::Truncate { at } => bytes.truncate(at % n),
            Mutation::Delete { at, len } => {
                let at = at % n;
                bytes.drain(at..(at + len).min(n));
            }
            Mutation::Duplicate { at, len } => {
                let at = at % n;
                let slice = bytes[at..(at + len).min(n)].to_vec();
                bytes.splice(at..at, slice);
            }
            Mutation::Insert { at, bytes: text } => {
                let at = at % (n + 1);
                bytes.splice(at..at, text.iter().copied());
            }
            Mutation::Overwrite { at, bytes: v } => {
                let at = at % n;
                let end = (at + v.len()).min(n);
                bytes[at..end].copy_from_slice(&v[..end - at]);
            }
        }
    }
}

/// Applies `edits` to `bytes`, one after the other.
pub fn apply_all(bytes: &mut Vec<u8>, edits: &[Mutation]) {
    for m in edits {
        m.apply(bytes);
    }
}
