//! A checkpoint of a run ([`Checkpoint`]) and its file (docs/run.md, "Checkpoints").
//!
//! The file is a zip archive of two stored (uncompressed) entries: `manifest.json`, which
//! says what the checkpoint holds and where each part lies, and `data.bin`, the parts' bytes
//! one after the other. The archive's CRC-32 of each entry finds a damaged or truncated file,
//! the manifest's `format` and `version` a file that is not one or comes from another version,
//! and each domain's name and layout hash a checkpoint of another DDF: any of them refuses the
//! file with its reason before anything of the run is touched.
//!
//! Zip and JSON rather than a format of our own: any unzip and any JSON reader look inside a
//! checkpoint, and both come from maintained crates (`zip`, `serde_json`).

use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use tutti_core::ddf::Model;

/// The manifest's `format`.
pub const FORMAT: &str = "tutti-checkpoint";
/// The version of the file this library writes and reads.
pub const VERSION: u32 = 1;
/// A checkpoint file's extension, as `checkpoint: { dir }` names them.
pub const EXTENSION: &str = "tutti-checkpoint";

/// A run at a step boundary: the framework's time, every domain's sets, and each
/// component's state.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// The DDF's name, for messages.
    pub ddf: String,
    /// The simulated time of one step, seconds.
    pub step_seconds: f64,
    /// The index of the next step (its simulated time over the step).
    pub next_index: u64,
    /// Steps made so far (a step limit counts from them).
    pub steps: u64,
    pub domains: Vec<DomainState>,
    /// Components' states, each by its domain and name.
    pub components: Vec<ComponentState>,
    /// Components that keep no state and were left out (named in the file).
    pub skipped: Vec<Skipped>,
}

/// A domain at the boundary.
#[derive(Debug, Clone, PartialEq)]
pub struct DomainState {
    pub name: String,
    pub layout_hash: u64,
    /// The PUBLISH set the next step publishes (connections' values included).
    pub publish: Vec<u8>,
    /// The SUBSCRIBE set as the last step read it.
    pub subscribe: Vec<u8>,
    /// The PUBLISH set of the last step (event-driven domains compare the next with it).
    pub last_publish: Option<Vec<u8>>,
    pub seeded: bool,
    /// Event-driven: from which index each connection is next due, by its name.
    pub due: Vec<(String, u64)>,
}

/// One component's state in one domain.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentState {
    pub domain: String,
    pub name: String,
    pub state: Vec<u8>,
    /// The gateway's link to another site with a lookahead (its answers on their way), not a
    /// component of this run: a restore waits for it to connect, and finds it by its domain.
    pub remote: bool,
}

/// A component left out of a checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Skipped {
    pub domain: String,
    pub name: String,
    /// `stateless` (declared so) or `keeps no state` (told to skip it).
    pub why: String,
}

/// Why a checkpoint could not be written, read, taken or put back.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: not a tutti checkpoint: {reason}", path.display())]
    NotACheckpoint { path: PathBuf, reason: String },
    #[error("{}: checkpoint file version {found}; this tutti reads version {VERSION}", path.display())]
    Version { path: PathBuf, found: u32 },
    #[error("{}: the checkpoint is damaged: {reason}", path.display())]
    Damaged { path: PathBuf, reason: String },
    #[error("{what} is a checkpoint of another DDF: {reason}")]
    OtherDdf { what: String, reason: String },
    #[error("cannot checkpoint: {} keep no state that a checkpoint can save (give their components a state handler, or `stateless: true` in the launch file, or skip them: tutti ctl save --skip-stateless)", list(.0))]
    KeepsNoState(Vec<(String, String)>),
    #[error("cannot checkpoint: two connections of domain '{domain}' are named '{name}': name each component (TUTTI_COMPONENT)")]
    SameName { domain: String, name: String },
    #[error("component '{name}' of domain '{domain}' could not {what} its state: {why}")]
    Component { domain: String, name: String, what: &'static str, why: String },
    #[error("cannot restore: {0}")]
    Mismatch(String),
    #[error("cannot checkpoint: domain '{domain}' is joined to another site with a lookahead of {lookahead} steps, and its gateway does not keep the answers on their way over the link (one older than this tutti): they would be missing from the checkpoint (docs/run.md, \"Checkpoints\")")]
    Lookahead { domain: String, lookahead: u64 },
    #[error("domain '{domain}': {source}")]
    Domain { domain: String, source: tutti_core::shm::ShmError },
}

fn list(names: &[(String, String)]) -> String {
    let all: Vec<String> = names.iter().map(|(d, n)| format!("'{n}' (domain '{d}')")).collect();
    all.join(", ")
}

impl CheckpointError {
    /// Whether the file or the request was at fault (exit 2), not the run.
    pub fn is_invalid(&self) -> bool {
        !matches!(self, CheckpointError::Io { .. } | CheckpointError::Domain { .. })
    }
}

/// Where a part lies in `data.bin`: offset and length.
type Span = (u64, u64);

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    format: String,
    version: u32,
    /// The tutti that wrote it.
    tutti: String,
    ddf: String,
    step_seconds: f64,
    next_index: u64,
    steps: u64,
    domains: Vec<ManifestDomain>,
    components: Vec<ManifestComponent>,
    skipped: Vec<Skipped>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestDomain {
    name: String,
    /// Hexadecimal, as `tutti status` shows it.
    layout_hash: String,
    publish: Span,
    subscribe: Span,
    last_publish: Option<Span>,
    seeded: bool,
    due: Vec<(String, u64)>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestComponent {
    domain: String,
    name: String,
    state: Span,
    /// A link's queue ([`ComponentState::remote`]); absent for a component.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    remote: bool,
}

impl Checkpoint {
    /// The checkpoint as a file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut data = Vec::new();
        let mut put = |bytes: &[u8]| {
            let span = (data.len() as u64, bytes.len() as u64);
            data.extend_from_slice(bytes);
            span
        };
        let domains = self
            .domains
            .iter()
            .map(|d| ManifestDomain {
                name: d.name.clone(),
                layout_hash: format!("{:016x}", d.layout_hash),
                publish: put(&d.publish),
                subscribe: put(&d.subscribe),
                last_publish: d.last_publish.as_deref().map(&mut put),
                seeded: d.seeded,
                due: d.due.clone(),
            })
            .collect();
        let components = self
            .components
            .iter()
            .map(|c| ManifestComponent {
                domain: c.domain.clone(),
                name: c.name.clone(),
                state: put(&c.state),
                remote: c.remote,
            })
            .collect();
        let manifest = Manifest {
            format: FORMAT.into(),
            version: VERSION,
            tutti: env!("CARGO_PKG_VERSION").into(),
            ddf: self.ddf.clone(),
            step_seconds: self.step_seconds,
            next_index: self.next_index,
            steps: self.steps,
            domains,
            components,
            skipped: self.skipped.clone(),
        };
        let json = serde_json::to_vec_pretty(&manifest).expect("a manifest is plain data");
        let mut out = std::io::Cursor::new(Vec::with_capacity(data.len() + json.len() + 512));
        {
            let mut zip = zip::ZipWriter::new(&mut out);
            let opts = zip::write::SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Stored)
                .large_file(data.len() as u64 >= u32::MAX as u64);
            // Writing to memory fails only for want of memory.
            zip.start_file("manifest.json", opts).expect("in memory");
            zip.write_all(&json).expect("in memory");
            zip.start_file("data.bin", opts).expect("in memory");
            zip.write_all(&data).expect("in memory");
            zip.finish().expect("in memory");
        }
        out.into_inner()
    }

    /// Writes the checkpoint to `path`: to a file beside it first, renamed into place, so
    /// that a crash meanwhile leaves the old file or none, never half a checkpoint.
    pub fn write(&self, path: &Path) -> Result<(), CheckpointError> {
        let io = |source| CheckpointError::Io { path: path.to_path_buf(), source };
        let mut part = path.as_os_str().to_owned();
        part.push(".part");
        let part = PathBuf::from(part);
        let result = (|| {
            let mut f = std::fs::File::create(&part)?;
            f.write_all(&self.to_bytes())?;
            f.sync_all()?;
            std::fs::rename(&part, path)
        })();
        if result.is_err() {
            let _ = std::fs::remove_file(&part);
        }
        result.map_err(io)
    }

    /// Reads the checkpoint at `path`.
    pub fn read(path: &Path) -> Result<Checkpoint, CheckpointError> {
        let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io { path: path.to_path_buf(), source })?;
        Checkpoint::from_bytes(&bytes, path)
    }

    /// Reads a checkpoint from a file's bytes (`path` names it in errors). Every offset is
    /// checked: a damaged file is an error, never a panic or a part taken from elsewhere.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Checkpoint, CheckpointError> {
        let not = |reason: String| CheckpointError::NotACheckpoint { path: path.to_path_buf(), reason };
        let damaged = |reason: String| CheckpointError::Damaged { path: path.to_path_buf(), reason };
        let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes))
            .map_err(|e| not(format!("not a zip archive, or a truncated one ({e})")))?;
        let manifest = read_entry(&mut zip, "manifest.json", 16 << 20).map_err(|e| match e {
            EntryError::Missing => not("no manifest.json".into()),
            EntryError::Bad(why) => damaged(format!("manifest.json: {why}")),
        })?;
        let format: serde_json::Value =
            serde_json::from_slice(&manifest).map_err(|e| damaged(format!("manifest.json: {e}")))?;
        if format.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
            return Err(not(format!("manifest.json does not say \"format\": \"{FORMAT}\"")));
        }
        let version = format.get("version").and_then(|v| v.as_u64()).unwrap_or(0);
        if version != u64::from(VERSION) {
            return Err(CheckpointError::Version {
                path: path.to_path_buf(),
                found: version.min(u32::MAX as u64) as u32,
            });
        }
        let m: Manifest = serde_json::from_value(format).map_err(|e| damaged(format!("manifest.json: {e}")))?;
        let data = read_entry(&mut zip, "data.bin", bytes.len() as u64).map_err(|e| match e {
            EntryError::Missing => damaged("no data.bin".into()),
            EntryError::Bad(why) => damaged(format!("data.bin: {why}")),
        })?;
        let part = |what: &str, (off, len): Span| -> Result<Vec<u8>, CheckpointError> {
            off.checked_add(len)
                .filter(|&end| end <= data.len() as u64)
                .map(|end| data[off as usize..end as usize].to_vec())
                .ok_or_else(|| damaged(format!("{what} lies outside data.bin ({off}+{len} of {})", data.len())))
        };
        if !(m.step_seconds.is_finite() && m.step_seconds > 0.0) {
            return Err(damaged(format!("step_seconds {} is not a positive time", m.step_seconds)));
        }
        let mut domains = Vec::with_capacity(m.domains.len());
        for d in m.domains {
            let layout_hash = u64::from_str_radix(&d.layout_hash, 16).map_err(|_| {
                damaged(format!("domain '{}': layout_hash '{}' is not hexadecimal", d.name, d.layout_hash))
            })?;
            let what = |set: &str| format!("domain '{}': its {set} set", d.name);
            domains.push(DomainState {
                layout_hash,
                publish: part(&what("PUBLISH"), d.publish)?,
                subscribe: part(&what("SUBSCRIBE"), d.subscribe)?,
                last_publish: d.last_publish.map(|s| part(&what("last PUBLISH"), s)).transpose()?,
                seeded: d.seeded,
                due: d.due,
                name: d.name,
            });
        }
        let mut components = Vec::with_capacity(m.components.len());
        for c in m.components {
            let state = part(&format!("component '{}' of domain '{}'", c.name, c.domain), c.state)?;
            components.push(ComponentState { domain: c.domain, name: c.name, state, remote: c.remote });
        }
        Ok(Checkpoint {
            ddf: m.ddf,
            step_seconds: m.step_seconds,
            next_index: m.next_index,
            steps: m.steps,
            domains,
            components,
            skipped: m.skipped,
        })
    }

    /// Checks that the checkpoint is one of `model`'s runs: the same domains, each with the
    /// same layout (its hash), each set of the size the layout gives. `what` names the
    /// checkpoint in the error.
    pub fn check_model(&self, model: &Model, what: &str) -> Result<(), CheckpointError> {
        let layouts = model.domains.iter().map(|d| {
            (d.name.as_str(), d.layout_hash, d.publish.layout.size as usize, d.subscribe.layout.size as usize)
        });
        self.check_layouts(layouts, what)
    }

    /// [`check_model`](Self::check_model) over each domain's (name, layout hash, PUBLISH
    /// size, SUBSCRIBE size).
    pub fn check_layouts<'a>(
        &self,
        layouts: impl Iterator<Item = (&'a str, u64, usize, usize)>,
        what: &str,
    ) -> Result<(), CheckpointError> {
        let other = |reason: String| CheckpointError::OtherDdf { what: what.to_string(), reason };
        let mut count = 0;
        for (i, (name, hash, publish, subscribe)) in layouts.enumerate() {
            count += 1;
            let Some(saved) = self.domain(i, name) else {
                return Err(other(format!("it has no domain '{name}'")));
            };
            if saved.layout_hash != hash {
                return Err(other(format!(
                    "domain '{name}' has layout hash {:016x} there and {hash:016x} here (its items differ)",
                    saved.layout_hash
                )));
            }
            let last = saved.last_publish.as_ref().map_or(publish, Vec::len);
            let sizes = [
                ("PUBLISH", saved.publish.len(), publish),
                ("SUBSCRIBE", saved.subscribe.len(), subscribe),
                ("last PUBLISH", last, publish),
            ];
            for (set, got, want) in sizes {
                if got != want {
                    return Err(CheckpointError::Damaged {
                        path: PathBuf::from(what),
                        reason: format!("domain '{name}': its {set} set is {got} bytes, its layout says {want}"),
                    });
                }
            }
        }
        // Every domain of the run was found, each once (names are unique in a DDF): any more
        // in the checkpoint are not the run's.
        if self.domains.len() != count {
            let mut names: Vec<&str> = self.domains.iter().map(|d| d.name.as_str()).collect();
            names.sort_unstable();
            let extra = names.windows(2).find(|w| w[0] == w[1]).map_or_else(
                || format!("it has {} domains, this DDF {count}", self.domains.len()),
                |w| format!("its domain '{}' appears twice", w[0]),
            );
            return Err(other(extra));
        }
        Ok(())
    }
}

impl Checkpoint {
    /// The saved domain `name`, which is the run's domain number `i`: looked for at that
    /// place first (a checkpoint lists its run's domains in the DDF's order), so that a run of
    /// thousands of domains is checked and restored in linear time.
    pub fn domain(&self, i: usize, name: &str) -> Option<&DomainState> {
        match self.domains.get(i) {
            Some(d) if d.name == name => Some(d),
            _ => self.domains.iter().find(|d| d.name == name),
        }
    }
}

/// Removes all but the newest `keep` checkpoints (by name: `step-NNNNNNNNN`) of `dir`.
pub fn keep_newest(dir: &Path, keep: usize) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|x| x == EXTENSION)
                && p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("step-"))
        })
        .collect();
    files.sort();
    let old = files.len().saturating_sub(keep);
    for f in &files[..old] {
        let _ = std::fs::remove_file(f);
    }
}

enum EntryError {
    Missing,
    Bad(String),
}

/// Reads entry `name` whole (its CRC checked by the reader), at most `limit` bytes.
fn read_entry<R: Read + Seek>(zip: &mut zip::ZipArchive<R>, name: &str, limit: u64) -> Result<Vec<u8>, EntryError> {
    let mut entry = match zip.by_name(name) {
        Ok(e) => e,
        Err(zip::result::ZipError::FileNotFound) => return Err(EntryError::Missing),
        Err(e) => return Err(EntryError::Bad(e.to_string())),
    };
    if entry.size() > limit {
        return Err(EntryError::Bad(format!("{} bytes, more than the file could hold", entry.size())));
    }
    let mut out = Vec::with_capacity(entry.size() as usize);
    entry.read_to_end(&mut out).map_err(|e| EntryError::Bad(e.to_string()))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Checkpoint {
        Checkpoint {
            ddf: "x.ddf".into(),
            step_seconds: 0.01,
            next_index: 500,
            steps: 500,
            domains: vec![DomainState {
                name: "d".into(),
                layout_hash: 0xdead_beef,
                publish: vec![1, 2, 3, 4],
                subscribe: vec![5, 6],
                last_publish: Some(vec![9, 9, 9, 9]),
                seeded: true,
                due: vec![("c".into(), 7)],
            }],
            components: vec![
                ComponentState { domain: "d".into(), name: "c".into(), state: vec![42; 100], remote: false },
                ComponentState {
                    domain: "d".into(),
                    name: "dds-writer 01 lookahead 4".into(),
                    state: vec![7; 9],
                    remote: true,
                },
            ],
            skipped: vec![Skipped { domain: "d".into(), name: "s".into(), why: "stateless".into() }],
        }
    }

    #[test]
    fn a_checkpoint_reads_back_as_written() {
        let c = sample();
        let back = Checkpoint::from_bytes(&c.to_bytes(), Path::new("c")).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn periodic_checkpoints_keep_the_newest_and_nothing_else_is_touched() {
        let dir = tempfile::tempdir().unwrap();
        for step in [500, 1000, 1500, 2000] {
            sample().write(&dir.path().join(format!("step-{step:09}.{EXTENSION}"))).unwrap();
        }
        std::fs::write(dir.path().join("warm.tutti-checkpoint"), b"mine").unwrap();
        std::fs::write(dir.path().join("notes.txt"), b"mine").unwrap();
        keep_newest(dir.path(), 2);
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(
            left,
            [
                "notes.txt",
                "step-000001500.tutti-checkpoint",
                "step-000002000.tutti-checkpoint",
                "warm.tutti-checkpoint"
            ]
        );
        // Written through a file beside it: nothing half-written is left.
        assert!(!left.iter().any(|f| f.ends_with(".part")));
    }

    #[test]
    fn a_truncated_or_altered_file_is_refused_with_its_reason() {
        let bytes = sample().to_bytes();
        for cut in [0, 10, bytes.len() / 2, bytes.len() - 1] {
            let e = Checkpoint::from_bytes(&bytes[..cut], Path::new("c")).unwrap_err();
            assert!(matches!(e, CheckpointError::NotACheckpoint { .. } | CheckpointError::Damaged { .. }), "{e}");
        }
        // A byte of data.bin changed: its CRC no longer matches.
        let mut altered = bytes.clone();
        let at = altered.windows(4).position(|w| w == [42, 42, 42, 42]).unwrap();
        altered[at] = 43;
        let e = Checkpoint::from_bytes(&altered, Path::new("c")).unwrap_err();
        assert!(e.to_string().contains("damaged"), "{e}");
    }
}
