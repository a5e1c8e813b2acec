//! The Data Description File: parse (`raw`), validate (`validate`) into the [`Model`], and
//! lay out (`layout`). Both dialects (`docs/ddf.md`) read into the same model.
//!
//! ```
//! let model = tutti_core::ddf::parse_str(
//!     r#"<orchestra><domain name="d"><block name="d/Publish">
//!          <item name="x"><type>double</type></item></block></domain></orchestra>"#,
//!     "inline.ddf",
//! ).unwrap();
//! assert_eq!(model.domains[0].publish.layout.size, 8);
//! ```

use std::fmt;
use std::io::Read;
use std::path::Path;

use serde::Serialize;

pub mod layout;
pub mod model;
pub mod raw;
pub mod synth;
pub mod validate;
pub mod write;

pub use layout::SetLayout;
pub use model::{Connection, ConnectionKind, Domain, Flags, Item, ItemKind, Leaf, Model, Role, ScalarType, Set, Value};

/// Largest DDF accepted, in bytes.
pub const MAX_FILE_BYTES: u64 = 64 << 20;

/// A 1-based line and column in a DDF.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Pos {
    pub line: u32,
    pub col: u32,
}

/// One problem found in a DDF.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Diagnostic {
    pub pos: Pos,
    pub message: String,
}

/// Why a DDF could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum DdfError {
    /// The file could not be read at all.
    /// (The OS error is in the message, not the error's source: a caller that prints the
    /// chain, as `anyhow`'s `{:#}` does, would print it twice.)
    #[error("{path}: error: cannot read the file: {cause}")]
    Io { path: String, cause: std::io::Error },
    /// The file was read and found invalid; every problem is listed.
    #[error("{}", render(path, diagnostics))]
    Invalid { path: String, diagnostics: Vec<Diagnostic> },
}

impl DdfError {
    /// The diagnostics, one per line, compiler-style: `FILE:LINE:COL: error: MESSAGE`.
    pub fn diagnostics(&self) -> &[Diagnostic] {
        match self {
            DdfError::Io { .. } => &[],
            DdfError::Invalid { diagnostics, .. } => diagnostics,
        }
    }
}

fn render(path: &str, diagnostics: &[Diagnostic]) -> String {
    diagnostics.iter().map(|d| format!("{path}:{d}")).collect::<Vec<_>>().join("\n")
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: error: {}", self.pos.line, self.pos.col, self.message)
    }
}

/// Reads, parses and validates the DDF at `path`.
pub fn load(path: impl AsRef<Path>) -> Result<Model, DdfError> {
    let path = path.as_ref();
    let shown = path.display().to_string();
    let io = |cause| DdfError::Io { path: shown.clone(), cause };
    let file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    if len > MAX_FILE_BYTES {
        return Err(invalid(&shown, Pos { line: 1, col: 1 }, too_large(len)));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    // Read at most one byte past the limit, in case the file grew since `metadata`.
    file.take(MAX_FILE_BYTES + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(invalid(&shown, Pos { line: 1, col: 1 }, too_large(bytes.len() as u64)));
    }
    parse_bytes(&bytes, &shown)
}

fn too_large(len: u64) -> String {
    format!("the file is {len} bytes; a DDF may be at most {} MiB", MAX_FILE_BYTES >> 20)
}

fn invalid(path: &str, pos: Pos, message: String) -> DdfError {
    DdfError::Invalid { path: path.to_string(), diagnostics: vec![Diagnostic { pos, message }] }
}

/// Parses and validates DDF bytes; `source` names them in diagnostics.
pub fn parse_bytes(bytes: &[u8], source: &str) -> Result<Model, DdfError> {
    let text = match std::str::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let good = &bytes[..e.valid_up_to()];
            // `good` is valid UTF-8: it stops where `valid_up_to` says the first bad byte is.
            let good = std::str::from_utf8(good).unwrap_or_default();
            let pos = raw::LineIndex::new(good).pos(good.len());
            return Err(invalid(
                source,
                pos,
                format!("the file is not UTF-8 text (invalid byte at offset {}): is it a DDF?", e.valid_up_to()),
            ));
        }
    };
    if let Some(at) = text.find('\0') {
        let pos = raw::LineIndex::new(text).pos(at);
        return Err(invalid(source, pos, "the file contains NUL bytes: it is binary, not a DDF".into()));
    }
    parse_str(text, source)
}

/// Parses and validates DDF text; `source` names it in diagnostics.
pub fn parse_str(text: &str, source: &str) -> Result<Model, DdfError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let root = raw::parse(text).map_err(|e| invalid(source, e.pos, e.message))?;
    validate::validate(root.root(), source)
        .map_err(|diagnostics| DdfError::Invalid { path: source.to_string(), diagnostics })
}
