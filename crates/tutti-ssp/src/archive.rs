//! The `.ssp` archive: a zip with `SystemStructure.ssd` at its root, the FMUs and SSV files
//! it names, read in place and extracted into a directory for the run.

use std::fs::File;
use std::io::Read as _;
use std::path::{Path, PathBuf};

use crate::SspError;

/// The SSD every SSP archive has at its root.
pub const SSD: &str = "SystemStructure.ssd";

/// An opened SSP archive.
#[derive(Debug)]
pub struct Archive {
    pub path: PathBuf,
    zip: zip::ZipArchive<File>,
}

impl Archive {
    /// Opens `path` and checks that it is a zip with `SystemStructure.ssd` at its root.
    pub fn open(path: &Path) -> Result<Archive, SspError> {
        let file = File::open(path).map_err(|e| SspError::io(path, e))?;
        let zip = zip::ZipArchive::new(file).map_err(|e| SspError::Archive {
            file: path.display().to_string(),
            reason: format!("not an SSP archive: not a zip archive ({e})"),
        })?;
        let archive = Archive { path: path.to_path_buf(), zip };
        if !archive.has(SSD) {
            return Err(SspError::Archive {
                file: path.display().to_string(),
                reason: format!("not an SSP archive: it has no {SSD} at its root"),
            });
        }
        Ok(archive)
    }

    /// How a file inside the archive is named in messages: `SYSTEM.ssp!NAME`.
    pub fn label(&self, name: &str) -> String {
        format!("{}!{name}", self.path.display())
    }

    /// Whether the archive holds the file `name`.
    pub fn has(&self, name: &str) -> bool {
        self.zip.index_for_name(name).is_some()
    }

    /// The names of its files, in archive order.
    pub fn names(&self) -> Vec<String> {
        self.zip.file_names().filter(|n| !n.ends_with('/')).map(String::from).collect()
    }

    /// The text of the file `name` (UTF-8).
    pub fn read_text(&mut self, name: &str) -> Result<String, SspError> {
        let label = self.label(name);
        let mut entry = self
            .zip
            .by_name(name)
            .map_err(|e| SspError::Archive { file: label.clone(), reason: format!("not in the archive ({e})") })?;
        let mut text = String::new();
        entry
            .read_to_string(&mut text)
            .map_err(|e| SspError::Archive { file: label, reason: format!("cannot be read as UTF-8 text ({e})") })?;
        Ok(text)
    }

    /// Extracts every file into `dir`; a name that would land outside it (`../x`, an
    /// absolute path) is refused before anything is written.
    pub fn extract(&mut self, dir: &Path) -> Result<(), SspError> {
        let mut plan = Vec::new();
        for i in 0..self.zip.len() {
            let entry = self.zip.by_index(i).map_err(|e| broken(&self.path, e))?;
            let Some(rel) = entry.enclosed_name() else {
                return Err(SspError::Archive {
                    file: self.path.display().to_string(),
                    reason: format!("'{}' would be extracted outside its directory", entry.name()),
                });
            };
            plan.push((i, rel, entry.is_dir()));
        }
        for (i, rel, is_dir) in plan {
            let to = dir.join(&rel);
            if is_dir {
                std::fs::create_dir_all(&to).map_err(|e| SspError::io(&to, e))?;
                continue;
            }
            if let Some(parent) = to.parent() {
                std::fs::create_dir_all(parent).map_err(|e| SspError::io(parent, e))?;
            }
            let mut entry = self.zip.by_index(i).map_err(|e| broken(&self.path, e))?;
            let mut out = File::create(&to).map_err(|e| SspError::io(&to, e))?;
            std::io::copy(&mut entry, &mut out).map_err(|e| SspError::io(&to, e))?;
        }
        Ok(())
    }
}

fn broken(path: &Path, e: zip::result::ZipError) -> SspError {
    SspError::Archive { file: path.display().to_string(), reason: format!("a broken entry ({e})") }
}

/// `base` joined with the URI `source` of an SSD (relative to the SSD, which is at the
/// archive's root), normalised: `./resources/a.fmu` → `resources/a.fmu`. None for a URI
/// with a scheme (`file:`, `http:`) or one that leaves the archive.
pub fn resolve_source(source: &str) -> Option<String> {
    if source.contains("://") || source.starts_with('/') || source.contains(':') {
        return None;
    }
    let mut parts: Vec<&str> = Vec::new();
    for p in source.split('/') {
        match p {
            "" | "." => {}
            ".." => {
                parts.pop()?;
            }
            p => parts.push(p),
        }
    }
    (!parts.is_empty()).then(|| parts.join("/"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_stay_inside_the_archive() {
        assert_eq!(resolve_source("resources/a.fmu").as_deref(), Some("resources/a.fmu"));
        assert_eq!(resolve_source("./resources/../a.fmu").as_deref(), Some("a.fmu"));
        assert_eq!(resolve_source("../a.fmu"), None);
        assert_eq!(resolve_source("/etc/passwd"), None);
        assert_eq!(resolve_source("file:///a.fmu"), None);
    }
}
