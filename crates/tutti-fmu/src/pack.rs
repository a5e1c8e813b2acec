//! Writing an FMU archive: for programs that build an FMU from source (the UAV demo builds
//! its AltitudeFilter this way).

use std::io::Write as _;
use std::path::Path;

/// Writes a zip at `path` with `entries` (archive path, bytes), uncompressed: an FMU is
/// `modelDescription.xml` plus `binaries/PLATFORM/ID.so` (and anything else it carries).
pub fn write_fmu(path: &Path, entries: &[(&str, &[u8])]) -> std::io::Result<()> {
    let file = std::fs::File::create(path)?;
    let mut zip = zip::ZipWriter::new(file);
    let opts = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, bytes) in entries {
        zip.start_file(*name, opts).map_err(std::io::Error::other)?;
        zip.write_all(bytes)?;
    }
    zip.finish().map_err(std::io::Error::other)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_written_archive_opens_as_an_fmu() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.fmu");
        let md = r#"<fmiModelDescription fmiVersion="3.0" modelName="M" instantiationToken="t">
            <CoSimulation modelIdentifier="m"/><ModelVariables/></fmiModelDescription>"#;
        super::write_fmu(&path, &[("modelDescription.xml", md.as_bytes()), ("binaries/x86_64-linux/m.so", b"")])
            .unwrap();
        let fmu = crate::Fmu::open(&path).unwrap();
        assert_eq!(fmu.binary_entry().unwrap(), "binaries/x86_64-linux/m.so");
    }
}
