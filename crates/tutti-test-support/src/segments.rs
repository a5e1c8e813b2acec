//! The shared-memory segments a test leaves in /dev/shm.

use std::path::{Path, PathBuf};

/// The shared-memory segments of namespace `ns` now in /dev/shm (their file names).
pub fn segments_of(ns: &str) -> Vec<String> {
    let prefix = format!("tutti.{ns}.");
    std::fs::read_dir("/dev/shm")
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&prefix))
        .collect()
}

/// Removes the segments of namespace `.0` when dropped, and its run's control socket
/// (`tutti-ctl.NS`, beside them): a test's cleanup, which runs even when the test fails or a
/// framework it started was killed.
#[derive(Debug)]
pub struct RemoveSegments(pub String);

impl Drop for RemoveSegments {
    fn drop(&mut self) {
        for name in segments_of(&self.0) {
            let _ = std::fs::remove_file(format!("/dev/shm/{name}"));
        }
        let _ = std::fs::remove_file(format!("/dev/shm/tutti-ctl.{}", self.0));
    }
}

/// A file of /dev/shm removed when dropped: a segment a test crafts by hand (damaged,
/// foreign, a directory in its place), which no framework will remove. [`RemoveSegments`]
/// removes a whole namespace's instead.
#[derive(Debug)]
pub struct ShmFile(pub PathBuf);

impl ShmFile {
    /// The segment of `domain` in namespace `ns` (`/dev/shm/tutti.NS.DOMAIN`); nothing is
    /// created.
    pub fn segment(ns: &str, domain: &str) -> ShmFile {
        ShmFile(PathBuf::from(format!("/dev/shm/tutti.{ns}.{domain}")))
    }

    /// Its path.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for ShmFile {
    fn drop(&mut self) {
        // A file, or a directory a test made in its place.
        let _ = std::fs::remove_file(&self.0);
        let _ = std::fs::remove_dir(&self.0);
    }
}

/// Shrinks the segment of `domain` in namespace `ns` to `len` bytes, as a hostile process
/// would (`ftruncate` through a file handle of its own: the mappings do not know the
/// difference).
pub fn shrink_segment(ns: &str, domain: &str, len: u64) {
    let path = format!("/dev/shm/tutti.{ns}.{domain}");
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap_or_else(|e| panic!("opening {path}: {e}"));
    f.set_len(len).unwrap_or_else(|e| panic!("shrinking {path}: {e}"));
}
