//! Files under the studio's root: every path a request names is resolved (symlinks too)
//! and must stay under the root; a save is atomic (temp file in the same folder, fsync,
//! then a hard link for a new file, which fails when the name exists, or a rename over an
//! existing one), so that no one ever sees a half-written file, and two creations of one
//! name cannot both win.

use std::io::{Read, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::ApiError;

/// The root folder, canonical.
#[derive(Debug, Clone)]
pub struct Root {
    dir: PathBuf,
}

impl Root {
    /// The root `dir`, resolved (it must exist and be a folder).
    pub fn new(dir: &Path) -> std::io::Result<Root> {
        let dir = dir.canonicalize()?;
        if !dir.is_dir() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("{} is not a folder", dir.display()),
            ));
        }
        Ok(Root { dir })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// `path` relative to the root, for showing (`/` separated).
    pub fn relative(&self, path: &Path) -> String {
        path.strip_prefix(&self.dir).unwrap_or(path).to_string_lossy().into_owned()
    }

    fn outside(&self, asked: &str) -> ApiError {
        ApiError::forbidden(format!("'{asked}' is outside the studio's root {}: refused", self.dir.display()))
    }

    fn check_name(asked: &str) -> Result<(), ApiError> {
        if asked.trim().is_empty() {
            return Err(ApiError::bad_request("no file name given"));
        }
        if asked.contains('\0') {
            return Err(ApiError::bad_request("a file name may not contain a NUL byte"));
        }
        Ok(())
    }

    /// An existing file named by `asked` (relative to the root, or absolute), resolved; it
    /// must be under the root.
    pub fn existing(&self, asked: &str) -> Result<PathBuf, ApiError> {
        Self::check_name(asked)?;
        let joined = self.dir.join(asked);
        let real = match joined.canonicalize() {
            Ok(p) => p,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                // Say "outside" for a path that leaves the root even when it does not exist.
                if !lexically_inside(&joined, &self.dir) {
                    return Err(self.outside(asked));
                }
                return Err(ApiError::not_found(format!("'{asked}': no such file under {}", self.dir.display())));
            }
            Err(e) => return Err(ApiError::bad_request(format!("'{asked}': {e}"))),
        };
        if !real.starts_with(&self.dir) {
            return Err(self.outside(asked));
        }
        if !real.is_file() {
            return Err(ApiError::bad_request(format!("'{asked}' is not a file")));
        }
        Ok(real)
    }

    /// Where a file named by `asked` is written: an existing file resolved as in
    /// [`Root::existing`], or a new file in an existing folder under the root.
    pub fn for_write(&self, asked: &str) -> Result<PathBuf, ApiError> {
        Self::check_name(asked)?;
        let joined = self.dir.join(asked);
        if joined.symlink_metadata().is_ok() {
            return self.existing(asked);
        }
        let (Some(parent), Some(Component::Normal(name))) = (joined.parent(), joined.components().next_back()) else {
            return Err(ApiError::bad_request(format!("'{asked}' does not name a file")));
        };
        let parent = parent.canonicalize().map_err(|_| {
            if !lexically_inside(&joined, &self.dir) {
                self.outside(asked)
            } else if let Some(file) = self.file_in_the_way(&joined) {
                self.not_a_folder(asked, &file)
            } else {
                ApiError::not_found(format!("'{asked}': its folder does not exist under {}", self.dir.display()))
            }
        })?;
        if !parent.starts_with(&self.dir) {
            return Err(self.outside(asked));
        }
        if !parent.is_dir() {
            return Err(self.not_a_folder(asked, &parent));
        }
        Ok(parent.join(name))
    }

    /// The deepest existing folder of `path` that is a file, not a folder (`a.ddf` of
    /// `a.ddf/x.ddf`), if there is one.
    fn file_in_the_way(&self, path: &Path) -> Option<PathBuf> {
        let existing = path.ancestors().skip(1).find(|p| p.symlink_metadata().is_ok())?;
        (!existing.is_dir()).then(|| existing.to_path_buf())
    }

    fn not_a_folder(&self, asked: &str, file: &Path) -> ApiError {
        ApiError::conflict(
            "not-a-folder",
            format!("'{asked}': {} is a file, not a folder: not saved", self.relative(file)),
        )
    }

    /// The DDFs under the root (`*.ddf`, hidden folders skipped), relative, sorted; at most
    /// `limit`, at most 8 folders deep.
    pub fn list_ddfs(&self, limit: usize) -> Vec<String> {
        self.list_ending(".ddf", limit)
    }

    /// The files under the root whose names end with `suffix` (hidden files and folders and
    /// `target` skipped; symlinks not followed), relative, sorted; at most `limit`, at most 8
    /// folders deep.
    pub fn list_ending(&self, suffix: &str, limit: usize) -> Vec<String> {
        let mut out = Vec::new();
        let mut stack = vec![(self.dir.clone(), 0)];
        while let Some((dir, depth)) = stack.pop() {
            let Ok(entries) = std::fs::read_dir(&dir) else { continue };
            for e in entries.flatten() {
                let name = e.file_name();
                let name = name.to_string_lossy();
                if name.starts_with('.') || name == "target" {
                    continue;
                }
                let Ok(ft) = e.file_type() else { continue };
                if ft.is_dir() && depth < 8 {
                    stack.push((e.path(), depth + 1));
                } else if ft.is_file() && name.ends_with(suffix) && out.len() < limit {
                    out.push(self.relative(&e.path()));
                }
            }
        }
        out.sort();
        out
    }
}

/// Whether `path`, with `.` and `..` applied as text, stays under `root`.
fn lexically_inside(path: &Path, root: &Path) -> bool {
    let mut parts: Vec<Component<'_>> = Vec::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                if parts.pop().is_none() {
                    return false;
                }
            }
            Component::CurDir => {}
            c => parts.push(c),
        }
    }
    parts.iter().collect::<PathBuf>().starts_with(root)
}

/// The version of a file's contents, as the page holds it to detect a change on disk: a
/// 64-bit FNV-1a hash of the bytes, in hex.
pub fn version(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Reads a file of at most `max` bytes.
pub fn read_limited(path: &Path, max: u64) -> Result<Vec<u8>, ApiError> {
    let file = std::fs::File::open(path).map_err(|e| ApiError::bad_request(format!("{}: {e}", path.display())))?;
    let mut bytes = Vec::new();
    file.take(max + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| ApiError::bad_request(format!("{}: {e}", path.display())))?;
    if bytes.len() as u64 > max {
        return Err(ApiError::bad_request(format!("{}: larger than {} MiB", path.display(), max >> 20)));
    }
    Ok(bytes)
}

/// A temp file beside `path`, created (never an existing one: a name is taken by another
/// save, or left by a process that died, gets the next), written and synced. The caller
/// links or renames it into place, and removes it.
fn temp_beside(path: &Path, bytes: &[u8]) -> std::io::Result<PathBuf> {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    loop {
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{name}.{}.{n}.studio-tmp", std::process::id()));
        let mut f = match std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        };
        let written = f.write_all(bytes).and_then(|()| f.sync_all());
        if let Err(e) = written {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
        return Ok(tmp);
    }
}

/// Syncs the folder of `path`, so that the name just linked or renamed there survives a crash.
fn sync_folder(path: &Path) {
    if let Some(dir) = path.parent() {
        // Best effort: some file systems cannot sync a folder; the file itself is synced.
        let _ = std::fs::File::open(dir).and_then(|d| d.sync_all());
    }
}

/// Writes `bytes` to `path` atomically: a temp file in the same folder, synced, renamed
/// over `path` (keeping its permissions). A reader sees the old contents or the new, never
/// a part; the temp file is removed when anything fails.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = temp_beside(path, bytes)?;
    let result = (|| {
        if let Ok(meta) = std::fs::metadata(path) {
            std::fs::set_permissions(&tmp, meta.permissions())?;
        }
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    sync_folder(path);
    result
}

/// Creates `path` with `bytes`, atomically and only if it does not exist: a temp file in the
/// same folder, synced, then hard-linked to `path`, which fails with
/// [`std::io::ErrorKind::AlreadyExists`] when the name is taken (by another save an instant
/// before, say). There is no moment when `path` exists with part of `bytes`. On a file
/// system without hard links the file is created exclusively (`O_EXCL`) and written in place.
pub fn create_new(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = temp_beside(path, bytes)?;
    let linked = std::fs::hard_link(&tmp, path);
    let _ = std::fs::remove_file(&tmp);
    match linked {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => return Err(e),
        Err(_) => {
            let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(path)?;
            f.write_all(bytes).and_then(|()| f.sync_all())?;
        }
    }
    sync_folder(path);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_stay_under_the_root() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("root")).unwrap();
        std::fs::write(dir.path().join("root/a.ddf"), "x").unwrap();
        std::fs::write(dir.path().join("secret"), "s").unwrap();
        std::os::unix::fs::symlink(dir.path().join("secret"), dir.path().join("root/link.ddf")).unwrap();
        let root = Root::new(&dir.path().join("root")).unwrap();
        assert!(root.existing("a.ddf").is_ok());
        assert!(root.existing("./sub/../a.ddf").is_err()); // sub does not exist
        for bad in ["../secret", "link.ddf", "../../etc/passwd", "/etc/passwd", "../nothing"] {
            let e = root.existing(bad).unwrap_err();
            assert!(e.message.contains("outside"), "{bad}: {}", e.message);
            let e = root.for_write(bad).unwrap_err();
            assert!(e.message.contains("outside"), "{bad}: {}", e.message);
        }
        assert_eq!(root.for_write("new.ddf").unwrap(), root.dir().join("new.ddf"));
        assert!(root.for_write("nofolder/new.ddf").unwrap_err().message.contains("folder"));
        assert_eq!(root.list_ddfs(10), vec!["a.ddf".to_string()]); // a symlink is not listed
    }

    #[test]
    fn a_path_under_a_file_is_a_conflict_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.ddf"), "x").unwrap();
        let root = Root::new(dir.path()).unwrap();
        for asked in ["a.ddf/x.ddf", "a.ddf/sub/x.ddf"] {
            let e = root.for_write(asked).unwrap_err();
            assert_eq!((e.status.as_u16(), e.code), (409, "not-a-folder"), "{asked}: {}", e.message);
            assert!(e.message.contains(": a.ddf is a file"), "{}", e.message);
            assert!(e.message.contains(asked), "{}", e.message);
        }
    }

    #[test]
    fn of_racing_creations_of_one_name_exactly_one_wins_and_the_file_is_whole() {
        let dir = tempfile::tempdir().unwrap();
        for round in 0..20 {
            let p = dir.path().join(format!("f{round}.ddf"));
            let barrier = std::sync::Barrier::new(2);
            let results: Vec<std::io::Result<()>> = std::thread::scope(|s| {
                let racers: Vec<_> = [b'a', b'b']
                    .map(|c| {
                        let (p, barrier) = (&p, &barrier);
                        s.spawn(move || {
                            barrier.wait();
                            create_new(p, &[c; 100_000])
                        })
                    })
                    .into_iter()
                    .collect();
                racers.into_iter().map(|t| t.join().unwrap()).collect()
            });
            let won = results.iter().filter(|r| r.is_ok()).count();
            assert_eq!(won, 1, "round {round}: {results:?}");
            let lost = results.iter().find_map(|r| r.as_ref().err()).unwrap();
            assert_eq!(lost.kind(), std::io::ErrorKind::AlreadyExists, "round {round}");
            let bytes = std::fs::read(&p).unwrap();
            assert!(bytes.len() == 100_000 && bytes.iter().all(|b| *b == bytes[0]), "round {round}: torn file");
        }
        // Only the 20 files: no temp file left.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 20);
    }

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.ddf");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert_ne!(version(b"one"), version(b"two"));
    }
}
