//! The recorders as a library: a framework run in-process (`tutti_host::Host`) with a
//! [`RecordingSink`], each format in turn. One suite runs over both formats: every step the
//! run made is in the file, once and in order, with the values the framework published.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use tutti_host::{Host, HostOptions, Summary};
use tutti_record::replay::Recording;
use tutti_record::{create, RecordingSink};

/// The recorded DDF: one asynchronous domain, `rec`, two items out and one in.
fn rec_ddf() -> String {
    tutti_test_support::ddf::one_domain("rec")
        .publish("x", "float64")
        .publish("n", "int32")
        .subscribe("y", "float64")
        .text()
}

/// The recording formats, as the file's extension chooses them.
#[derive(Debug, Clone, Copy)]
enum Format {
    Csv,
    Mcap,
}

impl Format {
    fn file(self) -> &'static str {
        match self {
            Format::Csv => "run.csv",
            Format::Mcap => "run.mcap",
        }
    }
}

/// Runs a framework of `rec` for a short while with `x = 2.5`, `n = 7` published, recording
/// into `dir` in `format`; returns the run's summary.
fn record(format: Format, dir: &Path) -> Summary {
    let model = tutti_core::ddf::parse_str(&rec_ddf(), "rec.ddf").unwrap();
    let ns = format!("reclib{}{format:?}", std::process::id()).to_lowercase();
    let opts = HostOptions {
        step: Duration::from_millis(2),
        speed: 1.0,
        duration: Some(Duration::from_millis(60)),
        namespace: Some(ns),
        sets: vec!["rec/x=2.5".into(), "rec/n=7".into()],
        ddf_name: "rec.ddf".into(),
        ..HostOptions::default()
    };
    let mut host = Host::new(&model, opts).unwrap();
    // The MCAP recording carries its DDF inside, read from the file.
    let ddf = dir.join("rec.ddf");
    std::fs::write(&ddf, rec_ddf()).unwrap();
    let recorder = create(&dir.join(format.file()), &model, &ddf).unwrap();
    host.add_sink(Box::new(RecordingSink(recorder)));
    let summary = host.run(&AtomicBool::new(false), |_| {}).unwrap();
    assert!(summary.started && summary.steps > 0, "the run made no step: {summary:?}");
    summary
}

/// The steps and the `x`, `n` values of every recorded step, read back.
fn read_back(format: Format, dir: &Path) -> Vec<(u64, f64, i32)> {
    let path = dir.join(format.file());
    match format {
        Format::Mcap => {
            let recording = Recording::read(&path).unwrap();
            assert_eq!(recording.ddf_name, "rec.ddf");
            assert_eq!(recording.domains.len(), 1);
            recording.domains[0]
                .steps
                .iter()
                .map(|s| {
                    let x = f64::from_ne_bytes(s.publish[0..8].try_into().unwrap());
                    let n = i32::from_ne_bytes(s.publish[8..12].try_into().unwrap());
                    (s.step, x, n)
                })
                .collect()
        }
        Format::Csv => {
            let text = std::fs::read_to_string(&path).unwrap();
            let mut lines = text.lines();
            let header: Vec<&str> = lines.next().expect("a header row").split(',').collect();
            let col =
                |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("{name} in {header:?}"));
            let (step, x, n) = (col("step"), col("publish.x"), col("publish.n"));
            lines
                .map(|l| {
                    let f: Vec<&str> = l.split(',').collect();
                    (f[step].parse().unwrap(), f[x].parse().unwrap(), f[n].parse().unwrap())
                })
                .collect()
        }
    }
}

fn every_step_is_recorded_once_in_order_with_its_values(format: Format) {
    let dir = tempfile::tempdir().unwrap();
    let summary = record(format, dir.path());
    let rows = read_back(format, dir.path());
    assert_eq!(rows.len() as u64, summary.steps, "{format:?}: one row per step of the run");
    let steps: Vec<u64> = rows.iter().map(|r| r.0).collect();
    assert!(steps.windows(2).all(|w| w[1] == w[0] + 1), "{format:?}: steps not consecutive: {steps:?}");
    for (step, x, n) in rows {
        assert_eq!((x, n), (2.5, 7), "{format:?}: step {step} carries other values");
    }
}

#[test]
fn csv_records_every_step_once_in_order_with_its_values() {
    every_step_is_recorded_once_in_order_with_its_values(Format::Csv);
}

#[test]
fn mcap_records_every_step_once_in_order_with_its_values() {
    every_step_is_recorded_once_in_order_with_its_values(Format::Mcap);
}
