//! `calibrate`: identified parameters with uncertainties, errors before and after per arm, the
//! verdict and a corrected URDF, from measurements (a CSV or arrays).
//!
//! [`calibrate`] computes everything and writes nothing; [`Calibration::write`] writes the
//! files. A failed verdict is an outcome, not an error: the CLI exits 1 after writing.

pub use super::calibrate_config::{
    CalibrateConfig, GravityFrame, MeasurementFrameChoice, NoiseChoice,
};
use super::calibrate_identify::identify;
use super::calibrate_outputs::outputs;
use super::calibrate_steps::{check_config, export_calibrated, read_data, Loaded};
use super::checks::{check_outputs, Output};
use super::note::Note;
use super::report_json::ReportParts;
use super::spelling::{spell_reports, spelled_markdown, Spelling};
use crate::calibration::{ParameterEstimate, Verdict};
use crate::error::{Error, Result};
use crate::io::{check_output_folder, replace_folder_streamed, write_atomically, StreamedFile};
use std::path::{Path, PathBuf};

/// The files [`Calibration::write`] writes besides the SVG plots.
pub const OUTPUT_FILES: [&str; 9] = [
    "calibrated.urdf",
    "params.yaml",
    "report.md",
    "report.json",
    "stiffness.yaml",
    super::calibrate_artifact::REGISTRATION_FILE,
    super::calibrate_artifact::COMPENSATED_URDF,
    "joint_errors.yaml",
    super::provenance::PROVENANCE_FILE,
];

/// Whether a file name is one `calibrate` writes (a previous output may be replaced).
pub fn is_output_file(name: &str) -> bool {
    OUTPUT_FILES.contains(&name)
        || super::calibrate_deploy::DEPLOY_FILES.contains(&name)
        || name.ends_with(".svg")
}

// The output check beside the output names (the settings are in `calibrate_config`).
impl CalibrateConfig {
    /// Checks, before calibrating, that the folder `out` can receive the outputs and holds
    /// no input ([`check_outputs`], [`check_output_folder`]).
    pub fn check_output(&self, out: &Path) -> Result<()> {
        check_outputs(&[Output::Folder(out)], &self.inputs())?;
        check_output_folder(out, &is_output_file)
    }
}

/// One parameter of the calibrated model (name, owner, kind, unit, nominal, calibrated,
/// change, std_dev, identifiable).
pub type ParameterRow = ParameterEstimate;

/// The outcome of a calibration.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// `ok`, `warning` or `failed`, with its reasons.
    pub verdict: Verdict,
    /// What the CLI prints on stderr, in order: loader and reading warnings, notes on the
    /// hold-out and the plan, then the verdict's reasons.
    pub notes: Vec<Note>,
    /// Every MCPC parameter.
    pub parameters: Vec<ParameterRow>,
    /// report.md.
    pub report_markdown: String,
    /// The calibrated URDF; `None` when the verdict failed or the model cannot be exported.
    pub urdf: Option<String>,
    /// Every output file: `(name, bytes)`; without report.json after
    /// [`calibrate_for_writing`] (then [`Calibration::write`] renders it into the folder).
    pub files: Vec<(String, Vec<u8>)>,
    /// The input files it was computed from ([`CalibrateConfig::inputs`]): the writers refuse
    /// to replace or delete them.
    pub inputs: Vec<PathBuf>,
    /// report.json not yet rendered ([`calibrate_for_writing`]): its value and typed rows.
    unrendered_report: Option<(serde_json::Value, ReportParts)>,
}

/// Calibrates: reads the inputs, identifies the parameters (and the stiffness if asked),
/// checks the result, exports the URDF and renders the reports. Writes nothing.
pub fn calibrate(config: &CalibrateConfig) -> Result<Calibration> {
    calibrate_rendering(config, true, None)
}

/// As [`calibrate`], with report.json left unrendered until [`Calibration::write`] streams it
/// into the folder: at 10⁶ configurations a text of about 900 MB never held in memory.
/// [`Calibration::files`] lacks report.json; [`Calibration::report`] still gives its value.
///
/// `spell` spells the settings report.md and report.html name as the front end does
/// ([`Spelling`]; the command line: `--model offsets` where the library says `` `model`
/// offsets ``); `None` keeps the library's names. report.json keeps them.
pub fn calibrate_for_writing(
    config: &CalibrateConfig,
    spell: Option<Spelling<'_>>,
) -> Result<Calibration> {
    calibrate_rendering(config, false, spell)
}

fn calibrate_rendering(
    config: &CalibrateConfig,
    render_report: bool,
    spell: Option<Spelling<'_>>,
) -> Result<Calibration> {
    let started = super::provenance::Started::now();
    check_config(config)?;
    let loaded = Loaded::new(config)?;
    let mut notes = loaded.robot.notes();
    let data = read_data(config, &loaded, &mut notes)?;
    let (mut result, identified) = identify(config, &loaded, &data, &mut notes)?;
    let export = export_calibrated(config, &loaded, &mut result.run);
    // The inputs' digests (a large measurement file takes a second) on a thread of their own
    // beside the outputs, which stay on this thread (and its memory arena: on a worker's, the
    // peak memory of 10⁶ configurations rose by a fifth).
    let (outputs, provenance) = std::thread::scope(|scope| {
        let provenance = scope.spawn(|| super::provenance::calibrate_record(config, started));
        let outputs = outputs(config, &loaded, &data, &mut result, export, identified);
        (outputs, provenance.join())
    });
    let provenance = provenance.map_err(|_| Error::InvalidData {
        origin: "provenance".into(),
        message: "the thread reading the inputs' digests stopped".into(),
    })?;
    let (mut outputs, mut provenance) = (outputs?, provenance?);
    super::calibrate_steps::add_model_choice(
        loaded.robot.tree(),
        &result,
        &mut outputs,
        &mut notes,
    )?;
    notes.extend(outputs.verdict.reasons.iter().map(Note::from));
    // For `treecal verify`: the calibrated ranges, and where the folder came from.
    outputs.report_parts.postures = super::postures::add_to_report(
        loaded.robot.tree(),
        &result.run.report.model,
        &data.measurements,
        &mut outputs.report,
    )?;
    // report.json is rendered last and is the largest output: what only led to it goes first.
    let parameters = std::mem::take(&mut result.run.parameters);
    // Freed on a thread of their own (millions of small allocations at 10⁶ configurations)
    // while the reports are spelled and provenance attached.
    std::thread::spawn(move || drop((data, result)));
    provenance.run.duration_s = started.elapsed_s();
    if !render_report {
        outputs.files.retain(|(name, _)| name != "report.json");
    }
    if let Some(spell) = spell {
        outputs.markdown = spelled_markdown(&outputs.markdown, spell);
        spell_reports(&mut outputs.files, spell);
    }
    super::provenance::attach(
        &provenance,
        "report.json",
        (&mut outputs.report, &outputs.report_parts),
        &mut outputs.files,
    )?;
    let unrendered_report = (!render_report).then_some((outputs.report, outputs.report_parts));
    Ok(Calibration {
        verdict: outputs.verdict,
        notes,
        parameters,
        report_markdown: outputs.markdown,
        urdf: outputs.urdf,
        files: outputs.files,
        inputs: config.inputs().into_iter().map(Path::to_owned).collect(),
        unrendered_report,
    })
}

impl Calibration {
    /// The content of report.json, parsed from the file's text (`files`): at 10⁵ rows a
    /// value of some hundreds of MB, so the calibration holds only the text.
    pub fn report(&self) -> serde_json::Value {
        if let Some((report, parts)) = &self.unrendered_report {
            return super::report_json::value(report, parts).unwrap_or(serde_json::Value::Null);
        }
        self.files
            .iter()
            .find(|(name, _)| name == "report.json")
            .and_then(|(_, bytes)| serde_json::from_slice(bytes).ok())
            .unwrap_or(serde_json::Value::Null)
    }

    /// Whether the result may be used (verdict `ok` or `warning`).
    pub fn usable(&self) -> bool {
        self.verdict.usable()
    }

    /// Replaces the folder `out` with the output files; refuses a folder holding an input or
    /// files that are not a previous calibration output.
    pub fn write(&self, out: &Path) -> Result<()> {
        check_outputs(&[Output::Folder(out)], &self.input_paths())?;
        check_output_folder(out, &is_output_file)?;
        let render = |out: &mut dyn std::io::Write| match &self.unrendered_report {
            Some((report, parts)) => super::report_json::write(report, parts, out),
            None => Ok(()),
        };
        let streamed: Vec<StreamedFile<'_>> = match self.unrendered_report {
            Some(_) => vec![("report.json", &render)],
            None => Vec::new(),
        };
        replace_folder_streamed(out, &self.files, &streamed)
    }

    /// Writes the calibrated URDF to `path` (atomically); an error when there is none (a
    /// failed verdict) or `path` is an input.
    pub fn write_urdf(&self, path: &Path) -> Result<()> {
        let Some(urdf) = &self.urdf else {
            let why: Vec<&str> = self
                .verdict
                .reasons
                .iter()
                .filter(|r| r.status == crate::calibration::Status::Failed)
                .map(|r| r.message.as_str())
                .collect();
            return Err(Error::InvalidData {
                origin: "calibration".into(),
                message: format!(
                    "no calibrated URDF: the verdict is {}{}",
                    self.verdict.status,
                    if why.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", why.join("; "))
                    }
                ),
            });
        };
        check_outputs(&[Output::File(path)], &self.input_paths())?;
        write_atomically(path, urdf.as_bytes())
    }

    fn input_paths(&self) -> Vec<&Path> {
        self.inputs.iter().map(PathBuf::as_path).collect()
    }
}
