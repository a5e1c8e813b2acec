//! What can go wrong reading an SSP archive and making a run of it.

use std::path::PathBuf;

/// A reason an SSP archive cannot be read or run. Each names the file (inside the archive:
/// `SYSTEM.ssp!SystemStructure.ssd`) and, for what it says, the line and column.
#[derive(Debug, thiserror::Error)]
pub enum SspError {
    #[error("{file}: {reason}")]
    Archive { file: String, reason: String },
    #[error("{file}:{line}:{col}: {message}")]
    At { file: String, line: u32, col: u32, message: String },
    #[error("{file}:{line}:{col}: {what} is not supported (docs/ssp.md, What is supported)")]
    Unsupported { file: String, line: u32, col: u32, what: String },
    #[error("{path}: {reason}")]
    Io { path: PathBuf, reason: String },
}

impl SspError {
    pub(crate) fn io(path: &std::path::Path, e: impl std::fmt::Display) -> SspError {
        SspError::Io { path: path.to_path_buf(), reason: e.to_string() }
    }
}
