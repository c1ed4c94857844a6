//! What [`calibrate`](super::calibrate::calibrate) is asked to do: its settings and the
//! choices among them (the CLI and Python build it; provenance records it).

use super::model_choice::{ModelChoice, ParameterPatterns};
use super::source::{MeasurementSource, PlanSource, RobotSource, StiffnessSource};
use crate::calibration::{RobustLoss, DEFAULT_POSITION_SIGMA, DEFAULT_ROTATION_SIGMA};
use crate::io::{AngleUnit, LengthUnit};
use std::path::{Path, PathBuf};

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
    /// Add `<tool>_marker` links where a tool origin cannot be exported (docs/export.md)
    /// [default: true: a marker body on a leaf wrist link, the usual mocap set-up, lies off
    /// the wrist axis; false fails the export instead].
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
        let validation = self.validation.iter().flat_map(MeasurementSource::paths);
        let rest = [
            self.stiffness.as_ref().and_then(StiffnessSource::path),
            self.plan.path(),
            frame,
        ];
        self.robot
            .path()
            .into_iter()
            .chain(self.measurements.paths())
            .chain(validation)
            .chain(rest.into_iter().flatten())
            .collect()
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
            add_tool_links: true,
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
