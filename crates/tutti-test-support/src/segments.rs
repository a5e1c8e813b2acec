//! The shared-memory segments a test leaves in /dev/shm.

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

/// Removes the segments of namespace `.0` when dropped: a test's cleanup, which runs even
/// when the test fails or a framework it started was killed.
#[derive(Debug)]
pub struct RemoveSegments(pub String);

impl Drop for RemoveSegments {
    fn drop(&mut self) {
        for name in segments_of(&self.0) {
            let _ = std::fs::remove_file(format!("/dev/shm/{name}"));
        }
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
