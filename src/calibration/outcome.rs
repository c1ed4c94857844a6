//! What a calibration from measured data found ([`CalibrationRun`]): the parameters with their
//! uncertainties, the errors before and after per arm, the findings, the robust and session
//! reports. `run` produces it, `checks` reads it.

use super::frame::FrameDecision;
use super::initial_guess::InitialGuess;
use super::plan::CalibrationReport;
use super::robust::{Outlier, RobustReport};
use super::sessions::SessionsReport;
use super::verdict::Finding;
use crate::kinematics::McpcModel;
use serde::Serialize;

/// One MCPC parameter before and after, with its uncertainty: a row of the paper's Table 2.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParameterEstimate {
    /// Name as [`McpcModel::parameter_name`] gives it, e.g. `left_joint1 alpha`.
    pub name: String,
    /// The joint (joint frames) or tool link (tool frames) it belongs to.
    pub owner: String,
    /// `alpha`, `beta`, `gamma`, `x`, `y` or `z`.
    pub kind: String,
    /// `rad` or `m`.
    pub unit: String,
    /// Nominal value (from the URDF).
    pub nominal: f64,
    /// Where the fit started: the nominal value, except for tools, whose measured frame is
    /// first fitted in closed form (the initial guess).
    pub start: f64,
    /// Calibrated value.
    pub calibrated: f64,
    /// `calibrated − nominal`.
    pub change: f64,
    /// Standard deviation from the residuals (`σ̂²·(JᵀWJ)⁺`), if the stage that identified it
    /// has redundant data.
    pub std_dev: Option<f64>,
    /// Whether the data determine it on its own.
    pub identifiable: bool,
}

/// RMS, maximum and mean errors over a set of observations of one tool.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorSummary {
    /// Root-mean-square position error (mm): the headline figure.
    pub rms_position_mm: f64,
    /// Largest position error (mm).
    pub max_position_mm: f64,
    /// Mean position error (mm).
    pub mean_position_mm: f64,
    /// Root-mean-square orientation error (deg); `None` for position-only data.
    pub rms_orientation_deg: Option<f64>,
    /// Largest orientation error (deg); `None` for position-only data.
    pub max_orientation_deg: Option<f64>,
    /// Mean orientation error (deg); `None` for position-only data.
    pub mean_orientation_deg: Option<f64>,
}

impl ErrorSummary {
    /// The summary of per-observation errors (mm, deg; no orientation: empty).
    pub fn of(position_mm: &[f64], orientation_deg: &[f64]) -> Self {
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let rms = |v: &[f64]| crate::math::root_mean_square(v).unwrap_or(0.0);
        let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        let some = |v: f64| (!orientation_deg.is_empty()).then_some(v);
        Self {
            rms_position_mm: rms(position_mm),
            max_position_mm: max(position_mm),
            mean_position_mm: mean(position_mm),
            rms_orientation_deg: some(rms(orientation_deg)),
            max_orientation_deg: some(max(orientation_deg)),
            mean_orientation_deg: some(mean(orientation_deg)),
        }
    }
}

/// Errors of one arm's tool on one data set, before and after calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArmResiduals {
    /// The arm (branch name).
    pub arm: String,
    /// The arm's tool link.
    pub tool: String,
    /// Per observation, its index in the data set the run was given (outliers included), so
    /// that reports can name the row by its id.
    pub rows: Vec<usize>,
    /// Observations of this arm's tool in the set.
    pub observations: usize,
    /// Before: the nominal robot registered like the calibrated one (measurement frame when
    /// fitted, tool frames), rigid ([`CalibrationRun::baseline`]).
    pub before: ErrorSummary,
    /// After calibration.
    pub after: ErrorSummary,
    /// % of the RMS position error removed.
    pub position_removed_percent: f64,
    /// % of the RMS orientation error removed (pose observations only).
    pub orientation_removed_percent: Option<f64>,
    /// Position error per observation (mm): before, after (JSON: `before`, `after`).
    #[serde(serialize_with = "crate::serde_labels::before_after")]
    pub position_mm: [Vec<f64>; 2],
    /// Orientation error per observation (deg): before, after (empty for positions; JSON:
    /// `before`, `after`).
    #[serde(serialize_with = "crate::serde_labels::before_after")]
    pub orientation_deg: [Vec<f64>; 2],
}

/// Everything a calibration found.
#[derive(Debug, Clone)]
pub struct CalibrationRun {
    /// The closed-form start: measurement frame and tool frames.
    pub guess: InitialGuess,
    /// Which measurement frame was used and why.
    pub frame: FrameDecision,
    /// With flexibility compensation and a fitted measurement frame: how the frame was
    /// refined jointly with the parameters (`None` otherwise).
    pub frame_refinement: Option<FrameRefinement>,
    /// The plan's outcome (the calibrated model is `report.model`).
    pub report: CalibrationReport,
    /// Every MCPC parameter, in [`McpcModel::parameters`] order.
    pub parameters: Vec<ParameterEstimate>,
    /// Errors on the identification data, per arm.
    pub identification: Vec<ArmResiduals>,
    /// Errors on the validation data, per arm (empty without validation data).
    pub validation: Vec<ArmResiduals>,
    /// Predicted RMS position error at the validation configurations from the parameter
    /// covariance alone (mm): what the noise of the identification data leaves.
    pub predicted_validation_rms_mm: Option<f64>,
    /// The predicted position error distribution per validation observation: the standard
    /// deviation `√trace(J_p·C·J_pᵀ)` (mm), in validation order.
    pub predicted_validation_sd_mm: Vec<f64>,
    /// What the checks of this run found (frame choice, rank, σ̂, validation, …), in order;
    /// [`Verdict::from_findings`](super::verdict::Verdict::from_findings) turns them into
    /// the verdict.
    pub findings: Vec<Finding>,
    /// What the robust estimation did (loss, scale, weights and residuals of the
    /// identification data).
    pub robust: RobustReport,
    /// The measurements named as outliers, identification then validation: identification
    /// outliers are left out of the fit and of `identification`; validation outliers are
    /// only marked (every validation row counts in `validation`).
    pub outliers: Vec<Outlier>,
    /// The fair "before": the nominal robot with its measurement frame (when fitted) and tool
    /// frames fitted by least squares to the rows and weights of the fit
    /// ([`super::baseline::registered_nominal`]).
    pub baseline: McpcModel,
    /// Per validation measurement (in order): where it lies relative to the identification
    /// configurations.
    pub validation_strata: Vec<super::validation::Stratum>,
    /// Validation rows that repeat an identification posture compared with it, without a
    /// model ([`super::repeatability`]); `None` with too few repeats.
    pub repeatability: Option<super::repeatability::Repeatability>,
    /// The measurement sessions, when the data name any (`session` column): each training
    /// session's frame, and each validation session's figures in the training frame and
    /// re-registered.
    pub sessions: Option<SessionsReport>,
}

/// How the measurement frame was refined (see [`super::run::run_calibration`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameRefinement {
    /// Gauss–Newton iterations over the six frame parameters.
    pub iterations: usize,
    /// Weighted cost ½‖r‖² with the closed-form frame, and after refinement (JSON:
    /// `before`, `after`).
    #[serde(serialize_with = "crate::serde_labels::before_after")]
    pub cost: [f64; 2],
    /// Rotation (rad) and translation (m) of the frame correction (JSON: `rotation_rad`,
    /// `translation_m`).
    #[serde(serialize_with = "correction_json")]
    pub correction: [f64; 2],
    /// How many of the six frame directions the data determine (the rest are only fixed
    /// by the rigid kinematics, which cannot tell them from the parameters).
    pub determined: usize,
}

fn correction_json<S: serde::Serializer>(
    correction: &[f64; 2],
    serializer: S,
) -> std::result::Result<S::Ok, S::Error> {
    crate::serde_labels::labelled(correction, ["rotation_rad", "translation_m"], serializer)
}
