//! Files under the studio's root: every path a request names is resolved (symlinks too)
//! and must stay under the root; a save is atomic (temp file in the same folder, fsync,
//! rename) and refused when the file changed on disk since it was opened.

use std::io::{Read, Write};
use std::path::{Component, Path, PathBuf};

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
            if lexically_inside(&joined, &self.dir) {
                ApiError::not_found(format!("'{asked}': its folder does not exist under {}", self.dir.display()))
            } else {
                self.outside(asked)
            }
        })?;
        if !parent.starts_with(&self.dir) {
            return Err(self.outside(asked));
        }
        Ok(parent.join(name))
    }

    /// The DDFs under the root (`*.ddf`, hidden folders skipped), relative, sorted; at most
    /// `limit`, at most 8 folders deep.
    pub fn list_ddfs(&self, limit: usize) -> Vec<String> {
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
                } else if ft.is_file() && name.ends_with(".ddf") && out.len() < limit {
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

/// Writes `bytes` to `path` atomically: a temp file in the same folder, synced, renamed
/// over `path`. The temp file is removed when anything fails.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.studio-tmp", std::process::id()));
    let result = (|| {
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
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
