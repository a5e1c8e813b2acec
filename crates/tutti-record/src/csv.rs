//! CSV: one file per domain (`STEM-DOMAIN.csv` when the model has several), a header row,
//! then a row per step: `step,sim_time,wall_s,connections`, then every element of the
//! PUBLISH set (`publish.PATH`, arrays `publish.PATH[i]`) and of the SUBSCRIBE set.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use tutti_core::ddf::{Leaf, Model, Role};

use super::{create_parent, io_error, RecordError, Recorder, Step};

struct DomainFile {
    path: PathBuf,
    out: BufWriter<File>,
    leaves: Vec<(Role, Leaf)>,
}

/// The CSV files of a run.
pub struct CsvRecorder {
    files: Vec<DomainFile>,
}

impl std::fmt::Debug for CsvRecorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CsvRecorder").field("files", &self.files.iter().map(|d| &d.path).collect::<Vec<_>>()).finish()
    }
}

/// The file of `domain` for a recording asked for as `base`.
pub fn domain_path(base: &Path, domain: &str, several: bool) -> PathBuf {
    if !several {
        return base.to_path_buf();
    }
    let stem = base.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "record".into());
    base.with_file_name(format!("{stem}-{domain}.csv"))
}

impl CsvRecorder {
    pub fn create(base: &Path, model: &Model) -> Result<CsvRecorder, RecordError> {
        let several = model.domains.len() > 1;
        let mut files = Vec::with_capacity(model.domains.len());
        for d in &model.domains {
            let path = domain_path(base, &d.name, several);
            create_parent(&path)?;
            let file = File::create(&path).map_err(io_error(&path))?;
            let mut out = BufWriter::new(file);
            let leaves: Vec<(Role, Leaf)> = d.leaves().map(|(r, l)| (r, l.clone())).collect();
            let mut header = vec!["step".to_string(), "sim_time".into(), "wall_s".into(), "connections".into()];
            for (role, leaf) in &leaves {
                let prefix = role.lower();
                if leaf.length == 1 {
                    header.push(format!("{prefix}.{}", leaf.path));
                } else {
                    header.extend((0..leaf.length).map(|i| format!("{prefix}.{}[{i}]", leaf.path)));
                }
            }
            writeln!(out, "{}", header.join(",")).map_err(io_error(&path))?;
            files.push(DomainFile { path, out, leaves });
        }
        Ok(CsvRecorder { files })
    }
}

impl Recorder for CsvRecorder {
    fn step(&mut self, domain: usize, s: &Step<'_>) -> Result<(), RecordError> {
        let Some(f) = self.files.get_mut(domain) else { return Ok(()) };
        let mut row = format!("{},{:.6},{:.6},{}", s.step, s.sim_time, s.elapsed_s, s.connections);
        for (role, leaf) in &f.leaves {
            let buf = if *role == Role::Publish { s.publish } else { s.subscribe };
            let n = leaf.ty.size() as usize;
            let Some(bytes) = buf.get(leaf.range()) else { continue };
            for chunk in bytes.chunks_exact(n) {
                row.push(',');
                row.push_str(&leaf.ty.decode(chunk).to_string());
            }
        }
        writeln!(f.out, "{row}").map_err(io_error(&f.path))
    }

    fn finish(self: Box<Self>) -> Result<(), RecordError> {
        for mut f in self.files {
            f.out.flush().map_err(io_error(&f.path))?;
        }
        Ok(())
    }
}
