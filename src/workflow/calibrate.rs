//! `calibrate`: identified parameters with uncertainties, errors before and after per arm, the
//! verdict and a corrected URDF, from measurements (a CSV or arrays).
//!
//! [`calibrate`] computes everything and writes nothing; [`Calibration::write`] writes the
//! files. A failed verdict is an outcome, not an error: the CLI exits 1 after writing.

use super::calibrate_outputs::outputs;
use super::calibrate_steps::{check_config, export_calibrated, identify, read_data, Loaded};
use super::checks::{check_outputs, Output};
use super::model_choice::{ModelChoice, ParameterPatterns};
use super::note::Note;
use super::source::{MeasurementSource, PlanSource, RobotSource, StiffnessSource};
use crate::calibration::{
    ParameterEstimate, RobustLoss, Verdict, DEFAULT_POSITION_SIGMA, DEFAULT_ROTATION_SIGMA,
};
use crate::error::{Error, Result};
use crate::io::{check_output_folder, replace_folder, write_atomically, AngleUnit, LengthUnit};
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

/// How the measurement frame is found.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum MeasurementFrameChoice {
    /// Fitted in closed form, or the robot's root frame when that explains the data.
    #[default]
    Auto,
    /// The tracker's own frame, fitted and kept.
    Fit,
    /// The data are already in the robot's root link frame.
    Base,
    /// A registration file (YAML: the robot base in the tracker frame).
    File(PathBuf),
}

/// How the rotation rows are weighed against the position rows (`--noise`; docs/identification.md,
/// "Noise model from the data").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum NoiseChoice {
    /// The declared σ's; when the model is chosen by cross-validation, the σ ratio the
    /// residuals show is one more candidate (`geometry+estimated noise (corrections ≥ 2σ)`).
    #[default]
    Adaptive,
    /// Always the σ ratio the residuals show (variance components; the position σ kept).
    Estimated,
    /// Always the declared σ's.
    Declared,
}

/// The frame the stiffness file's gravity vector is given in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum GravityFrame {
    /// The measurement (tracker) frame: a levelled tracker.
    #[default]
    Measurement,
    /// The robot's root link frame: a level robot base.
    Base,
}

/// Everything a calibration needs; `Default` holds the CLI's defaults (the measurements must
/// be set).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateConfig {
    /// The robot [default: the built-in Robonaut].
    pub robot: RobotSource,
    /// The identification measurements.
    pub measurements: MeasurementSource,
    /// Validation measurements [default: a seeded fifth of the configurations held out].
    pub validation: Option<MeasurementSource>,
    /// Stiffness and payloads: compensate the deflections under gravity [default: rigid].
    pub stiffness: Option<StiffnessSource>,
    /// Tool links ending the arms [default: the measured tools].
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole, a mobile base) [default: the root].
    pub reference_link: Option<String>,
    /// The calibration plan.
    pub plan: PlanSource,
    /// Unit of lengths in the measurements [default: as stated, else m].
    pub length_unit: Option<LengthUnit>,
    /// Unit of revolute joint values [default: as stated, else rad].
    pub angle_unit: Option<AngleUnit>,
    /// Unit of prismatic joint values [default: the length unit].
    pub joint_length_unit: Option<LengthUnit>,
    /// Columns to skip (CSV only).
    pub ignore_columns: Vec<String>,
    /// A joint value outside its URDF limits is an error (else a warning).
    pub strict: bool,
    /// How the measurement frame is found.
    pub measurement_frame: MeasurementFrameChoice,
    /// Expected position noise of a measurement (m).
    pub position_sigma: f64,
    /// Expected rotation noise of a measured frame (rad).
    pub rotation_sigma: f64,
    /// Seed of the held-out validation fifth.
    pub seed: u64,
    /// Robust estimation.
    pub robust: RobustLoss,
    /// Identify the compliances jointly with the geometry (the stiffness is the prior).
    pub identify_stiffness: bool,
    /// Relative uncertainty of the prior stiffness (0.5: ±50 %).
    pub stiffness_prior: f64,
    /// The frame of the stiffness file's gravity vector.
    pub gravity_frame: GravityFrame,
    /// Add `<tool>_calibrated` links where a tool origin cannot be exported (docs/export.md).
    pub add_tool_links: bool,
    /// Which parameters describe the robot (`--model`).
    pub model: ModelChoice,
    /// First-harmonic joint-angle errors as parameters (`--joint-errors harmonics`).
    pub harmonics: bool,
    /// Backlash as parameters (`--joint-errors backlash`).
    pub backlash: bool,
    /// The default Gaussian prior on the nominal values (`--prior`).
    pub prior: bool,
    /// The prior's σ times this (`--prior-scale`; 1: the documented defaults).
    pub prior_scale: f64,
    /// Keep only the corrections of at least this many standard deviations (`--significant`).
    pub significant: Option<f64>,
    /// How the rotation rows are weighed against the position rows (`--noise`).
    pub noise: NoiseChoice,
    /// `--freeze` and `--free` patterns.
    pub patterns: ParameterPatterns,
    /// Cross-validate the model candidates over this many folds (`--cv`); `--model auto`
    /// uses [`super::cross_validation::DEFAULT_FOLDS`] without it.
    pub cv: Option<usize>,
    /// Fold assignments of the cross-validation (`--cv-repeats`, seeds `seed` …), whose
    /// squared held-out errors are averaged ([`super::cross_validation::REPEATS`] by default).
    pub cv_repeats: usize,
    /// Offer per-joint harmonics and backlash to the cross-validation by forward steps
    /// (`--cv-joint-steps`, [`super::cross_validation::joint_steps`]).
    pub cv_joint_steps: bool,
}

impl CalibrateConfig {
    /// Every file the calibration reads (robot, measurements, validation, stiffness, plan,
    /// registration); no output may replace one.
    pub fn inputs(&self) -> Vec<&Path> {
        let frame = match &self.measurement_frame {
            MeasurementFrameChoice::File(path) => Some(path.as_path()),
            _ => None,
        };
        [
            self.robot.path(),
            self.measurements.path(),
            self.validation.as_ref().and_then(MeasurementSource::path),
            self.stiffness.as_ref().and_then(StiffnessSource::path),
            self.plan.path(),
            frame,
        ]
        .into_iter()
        .flatten()
        .collect()
    }

    /// Checks, before calibrating, that the folder `out` can receive the outputs and holds
    /// no input ([`check_outputs`], [`check_output_folder`]).
    pub fn check_output(&self, out: &Path) -> Result<()> {
        check_outputs(&[Output::Folder(out)], &self.inputs())?;
        check_output_folder(out, &is_output_file)
    }
}

impl Default for CalibrateConfig {
    fn default() -> Self {
        Self {
            robot: RobotSource::BuiltIn,
            measurements: MeasurementSource::default(),
            validation: None,
            stiffness: None,
            tools: None,
            reference_link: None,
            plan: PlanSource::Auto,
            length_unit: None,
            angle_unit: None,
            joint_length_unit: None,
            ignore_columns: Vec::new(),
            strict: false,
            measurement_frame: MeasurementFrameChoice::Auto,
            position_sigma: DEFAULT_POSITION_SIGMA,
            rotation_sigma: DEFAULT_ROTATION_SIGMA,
            seed: 0,
            robust: RobustLoss::Huber,
            identify_stiffness: false,
            stiffness_prior: 0.5,
            gravity_frame: GravityFrame::Measurement,
            add_tool_links: false,
            model: ModelChoice::Adaptive,
            harmonics: false,
            backlash: false,
            prior: false,
            prior_scale: 1.0,
            significant: None,
            noise: NoiseChoice::Adaptive,
            patterns: ParameterPatterns::default(),
            cv: None,
            cv_repeats: super::cross_validation::REPEATS,
            cv_joint_steps: false,
        }
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
    /// Every output file: `(name, bytes)`.
    pub files: Vec<(String, Vec<u8>)>,
    /// The input files it was computed from ([`CalibrateConfig::inputs`]): the writers refuse
    /// to replace or delete them.
    pub inputs: Vec<PathBuf>,
}

/// Calibrates: reads the inputs, identifies the parameters (and the stiffness if asked),
/// checks the result, exports the URDF and renders the reports. Writes nothing.
pub fn calibrate(config: &CalibrateConfig) -> Result<Calibration> {
    let started = super::provenance::Started::now();
    check_config(config)?;
    let loaded = Loaded::new(config)?;
    let mut notes = loaded.robot.notes();
    let data = read_data(config, &loaded, &mut notes)?;
    let (mut result, identified) = identify(config, &loaded, &data, &mut notes)?;
    let export = export_calibrated(config, &loaded, &mut result.run);
    let mut outputs = outputs(config, &loaded, &data, &mut result, export, identified)?;
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
    drop((data, result));
    let provenance = super::provenance::calibrate_record(config, started)?;
    super::provenance::attach(
        &provenance,
        "report.json",
        (&mut outputs.report, &outputs.report_parts),
        &mut outputs.files,
    )?;
    Ok(Calibration {
        verdict: outputs.verdict,
        notes,
        parameters,
        report_markdown: outputs.markdown,
        urdf: outputs.urdf,
        files: outputs.files,
        inputs: config.inputs().into_iter().map(Path::to_owned).collect(),
    })
}

impl Calibration {
    /// The content of report.json, parsed from the file's text (`files`): at 10⁵ rows a
    /// value of some hundreds of MB, so the calibration holds only the text.
    pub fn report(&self) -> serde_json::Value {
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
        replace_folder(out, &self.files)
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
