//! Provenance in every output folder (provenance.yaml, `crate::io::provenance`): a workflow
//! notes when it started, and at its end records its settings, inputs and seeds; report.json
//! refers to the file (`"provenance"`).

use super::report_json::ReportParts;
use crate::error::Result;
use crate::io::{input_file, utc_iso8601, Program, ProvenanceRecord, RunFacts};
use std::path::PathBuf;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

pub use crate::io::PROVENANCE_FILE;

/// When a run started (wall clock and monotonic).
#[derive(Debug, Clone, Copy)]
pub struct Started {
    at: SystemTime,
    clock: Instant,
}

impl Started {
    /// The wall-clock seconds since the start.
    pub fn elapsed_s(&self) -> f64 {
        self.clock.elapsed().as_secs_f64()
    }

    /// Now.
    pub fn now() -> Self {
        Self {
            at: SystemTime::now(),
            clock: Instant::now(),
        }
    }
}

/// The record of a run of `command` with `settings` (the config as resolved, every default
/// written out), reading the files `inputs` (hashed now) and drawing from `seeds`.
pub fn record(
    command: &str,
    settings: String,
    inputs: &[PathBuf],
    seeds: &[(&str, u64)],
    started: Started,
) -> Result<ProvenanceRecord> {
    let commit = crate::io::GIT_COMMIT;
    Ok(ProvenanceRecord {
        program: Program {
            name: "treecal",
            version: env!("CARGO_PKG_VERSION"),
            commit: crate::io::commit_description(commit, false),
            dirty: (!commit.is_empty()).then_some(crate::io::GIT_DIRTY),
        },
        command: command.to_owned(),
        settings,
        inputs: inputs
            .iter()
            .map(|p| input_file(p))
            .collect::<Result<Vec<_>>>()?,
        outputs: Vec::new(),
        seeds: seeds.iter().map(|(n, s)| ((*n).to_owned(), *s)).collect(),
        run: RunFacts {
            started_utc: utc_iso8601(
                started
                    .at
                    .duration_since(UNIX_EPOCH)
                    .map_or(0, |d| d.as_secs()),
            ),
            duration_s: started.elapsed_s(),
            threads: rayon::current_num_threads(),
        },
    })
}

/// The settings of a config as text: its `Debug` form, every field written out (a source of
/// measurement arrays by its origin only, so that the record stays small).
pub fn settings_text<T: std::fmt::Debug>(config: &T) -> String {
    format!("{config:#?}")
}

/// Adds provenance.yaml to `files` and `"provenance": "provenance.yaml"` to the JSON report
/// `file` among them (and to `report`, its value without its typed `parts`). The record lists
/// every file of `files` with its SHA-256 (a report.json rendered later, when it is not among
/// them, is not listed).
pub(super) fn attach(
    record: &ProvenanceRecord,
    file: &str,
    (report, parts): (&mut serde_json::Value, &ReportParts),
    files: &mut Vec<(String, Vec<u8>)>,
) -> Result<()> {
    let reference = serde_json::Value::String(PROVENANCE_FILE.into());
    super::postures::set_report_key(report, parts, files, file, "provenance", reference)?;
    let record = ProvenanceRecord {
        outputs: crate::io::output_files(files),
        ..record.clone()
    };
    files.push((PROVENANCE_FILE.into(), record.to_yaml()?.into_bytes()));
    Ok(())
}

/// The provenance of a calibration: its settings (measurement arrays by their origin), every
/// input file, the hold-out seed.
pub(super) fn calibrate_record(
    config: &super::calibrate_config::CalibrateConfig,
    started: Started,
) -> Result<ProvenanceRecord> {
    use super::source::MeasurementSource;
    let by_origin = |source: &MeasurementSource| match source {
        MeasurementSource::Table(table) => MeasurementSource::Csv(PathBuf::from(&table.origin)),
        other => other.clone(),
    };
    let mut settings = config.clone();
    settings.measurements = by_origin(&config.measurements);
    settings.validation = config.validation.as_ref().map(by_origin);
    let inputs: Vec<PathBuf> = config.inputs().into_iter().map(Into::into).collect();
    record(
        "calibrate",
        settings_text(&settings),
        &inputs,
        &[("hold_out", config.seed)],
        started,
    )
}
