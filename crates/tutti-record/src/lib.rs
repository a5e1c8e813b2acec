//! Recordings of a co-simulation: both sets of every domain at every step, in one of two
//! formats behind one interface ([`Recorder`]), chosen by the file's extension ([`create`]):
//!
//! * **CSV** ([`csv`]): one file per domain, a row per step, a column per element;
//! * **MCAP** ([`mcap`]): one file for the run, a channel per set named like its ROS 2 topic
//!   (`/DOMAIN/publish`, `/DOMAIN/subscribe`), messages in the gateway's CDR with a `ros2msg`
//!   schema equal to what `tutti idl` writes, zstd-compressed chunks with an index: it opens
//!   in Foxglove and plays with `ros2 bag play`. Connection and owner changes go on
//!   `/tutti/events`; the DDF travels inside as an attachment, so that `tutti replay` needs
//!   nothing but the file ([`replay`] reads it back).
//!
//! Recorders take a framework's steps as a sink of the runner ([`RecordingSink`] for a
//! `tutti_host::Host`, [`record_step`] for a loop of one's own). Two runs live here too: the
//! passive [`live::LiveRecorder`] of `tutti record`, and the framework of `tutti replay`
//! ([`replay::Replay`]).
//!
//! The crate sits above the core and the runner (`tutti-host`) and depends on no DDS crate.

use std::path::Path;

use tutti_core::ddf::Model;
use tutti_core::shm::Framework;
use tutti_host::{HostError, StepDone, StepSink};

pub mod csv;
pub mod live;
pub mod mcap;
pub mod replay;

/// What went wrong, with the file involved.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {detail}")]
    Format { path: String, detail: String },
    /// An MCAP file that is damaged (or not MCAP), with the byte offset where it is.
    #[error("{path}: {error}")]
    Mcap { path: String, error: mcap::read::ReadError },
    /// `--domain` names a domain that is not there.
    #[error("{path}: no {noun} '{domain}' ({noun}s: {known})")]
    UnknownDomain { path: String, noun: &'static str, domain: String, known: String },
    /// The framework of a replay.
    #[error(transparent)]
    Host(#[from] HostError),
}

impl RecordError {
    /// Whether the request was impossible (the CLI's exit status 2) rather than the run failing.
    pub fn is_invalid(&self) -> bool {
        match self {
            RecordError::Format { .. } | RecordError::Mcap { .. } | RecordError::UnknownDomain { .. } => true,
            RecordError::Host(e) => e.is_invalid(),
            RecordError::Io { .. } => false,
        }
    }
}

/// Keeps in `model` only the domains named in `names` (all of them when `names` is empty);
/// a name it lacks is an error that lists what it has. `path` and `noun` word the error
/// (`"domain"`, `"recorded domain"`).
pub fn keep_domains(model: &mut Model, names: &[String], path: &Path, noun: &'static str) -> Result<(), RecordError> {
    if let Some(missing) = names.iter().find(|n| model.domain(n).is_none()) {
        return Err(RecordError::UnknownDomain {
            path: path.display().to_string(),
            noun,
            domain: missing.clone(),
            known: model.domains.iter().map(|d| d.name.as_str()).collect::<Vec<_>>().join(", "),
        });
    }
    if !names.is_empty() {
        model.domains.retain(|d| names.contains(&d.name));
    }
    Ok(())
}

/// One step of one domain, as the framework saw it.
#[derive(Debug, Clone, Copy)]
pub struct Step<'a> {
    pub step: u64,
    /// Simulated time, seconds.
    pub sim_time: f64,
    /// Wall-clock time, nanoseconds since the Unix epoch.
    pub wall_ns: u64,
    /// Seconds since the run started.
    pub elapsed_s: f64,
    /// Connections of the domain during the step.
    pub connections: u32,
    /// The process that holds the SUBSCRIBE set exclusively, if one does.
    pub owner_pid: Option<u32>,
    /// The PUBLISH and SUBSCRIBE sets, in shared-memory layout.
    pub publish: &'a [u8],
    pub subscribe: &'a [u8],
}

/// A recording being written.
pub trait Recorder {
    /// Records step `s` of domain number `domain` (its index in the model).
    fn step(&mut self, domain: usize, s: &Step<'_>) -> Result<(), RecordError>;
    /// Writes what is buffered and closes the recording (an MCAP file gets its index here).
    fn finish(self: Box<Self>) -> Result<(), RecordError>;
}

/// The recording `path` of `model` (read from `ddf_path`, whose stem names the ROS 2
/// package): MCAP for `*.mcap`, else CSV (one file per domain when there are several:
/// `STEM-DOMAIN.csv`).
pub fn create(path: &Path, model: &Model, ddf_path: &Path) -> Result<Box<dyn Recorder>, RecordError> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("mcap")) {
        Ok(Box::new(mcap::McapRecorder::create(path, model, ddf_path)?))
    } else {
        Ok(Box::new(csv::CsvRecorder::create(path, model)?))
    }
}

/// Records in `recorder` the step every domain of `fw` just made (as `done` says, with the
/// PUBLISH sets it published).
pub fn record_step(recorder: &mut dyn Recorder, fw: &Framework, done: &StepDone<'_>) -> Result<(), RecordError> {
    let (wall_ns, elapsed_s) = (now_ns(), done.run_start.elapsed().as_secs_f64());
    for (i, (host, report)) in fw.domains.iter().zip(done.reports).enumerate() {
        let step = Step {
            step: report.step,
            sim_time: done.sim,
            wall_ns,
            elapsed_s,
            connections: host.connection_count(),
            owner_pid: host.segment().exclusive_owner_pid(),
            publish: &done.publish[i],
            subscribe: host.subscribe(),
        };
        recorder.step(i, &step)?;
    }
    Ok(())
}

/// A recording as a sink of a `tutti_host::Host`: it records every step of the run.
pub struct RecordingSink(pub Box<dyn Recorder>);

impl std::fmt::Debug for RecordingSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("RecordingSink")
    }
}

impl StepSink for RecordingSink {
    fn step(&mut self, fw: &Framework, done: &StepDone<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(record_step(self.0.as_mut(), fw, done)?)
    }

    fn finish(self: Box<Self>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(self.0.finish()?)
    }
}

/// Wall-clock time now, nanoseconds since the Unix epoch (for [`Step::wall_ns`]).
pub fn now_ns() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

pub(crate) fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> RecordError + '_ {
    move |source| RecordError::Io { path: path.display().to_string(), source }
}

/// Creates the directory of `path` if it has one.
pub(crate) fn create_parent(path: &Path) -> Result<(), RecordError> {
    match path.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(dir) => std::fs::create_dir_all(dir).map_err(io_error(dir)),
        None => Ok(()),
    }
}
