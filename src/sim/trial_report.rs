//! What one simulated calibration trial reports: errors per arm, blunders found, the stages'
//! summary, the true joint errors.

use crate::calibration::{ComplianceEstimate, Termination};
use crate::kinematics::McpcModel;
use crate::measurement::Measurement;
use crate::tree::KinematicTree;
use serde::Serialize;

/// Maximum and mean errors over a set of configurations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Largest position error (mm).
    pub max_position_mm: f64,
    /// Mean position error (mm).
    pub mean_position_mm: f64,
    /// Largest orientation error (deg).
    pub max_orientation_deg: f64,
    /// Mean orientation error (deg).
    pub mean_orientation_deg: f64,
}

impl ErrorStats {
    pub(super) fn of(position_mm: &[f64], orientation_deg: &[f64]) -> Self {
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        Self {
            max_position_mm: max(position_mm),
            mean_position_mm: mean(position_mm),
            max_orientation_deg: max(orientation_deg),
            mean_orientation_deg: mean(orientation_deg),
        }
    }
}

/// Per-configuration errors of one arm against the true (deflected, noise-free) tool pose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArmErrors {
    /// The arm (branch name).
    pub arm: String,
    /// Nominal model.
    pub before: ErrorStats,
    /// Calibrated without flexibility compensation (rigid prediction).
    pub rigid: ErrorStats,
    /// Calibrated with compensation (deflected prediction).
    pub compensated: ErrorStats,
    /// % of the mean position error removed, rigid / compensated (JSON: `rigid`,
    /// `compensated`).
    #[serde(serialize_with = "crate::serde_labels::rigid_compensated")]
    pub position_removed_percent: [f64; 2],
    /// % of the mean orientation error removed, rigid / compensated (JSON: `rigid`,
    /// `compensated`).
    #[serde(serialize_with = "crate::serde_labels::rigid_compensated")]
    pub orientation_removed_percent: [f64; 2],
    /// Position errors per configuration (mm): before, rigid, compensated (JSON: keyed by
    /// those names).
    #[serde(serialize_with = "crate::serde_labels::before_rigid_compensated")]
    pub position_mm: [Vec<f64>; 3],
    /// Orientation errors per configuration (deg): before, rigid, compensated (JSON: keyed by
    /// those names).
    #[serde(serialize_with = "crate::serde_labels::before_rigid_compensated")]
    pub orientation_deg: [Vec<f64>; 3],
}

/// Blunders injected into a trial's measurements and the outliers the calibrations named
/// (indices into the measurements, torso stage then arms stage).
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct BlunderReport {
    /// The measurements turned into blunders.
    pub injected: Vec<usize>,
    /// The outliers named by the calibration without / with compensation (JSON: `rigid`,
    /// `compensated`).
    #[serde(serialize_with = "crate::serde_labels::rigid_compensated")]
    pub named: [Vec<usize>; 2],
}

impl BlunderReport {
    /// Blunders named, blunders missed and clean measurements named, by the calibration
    /// without (`0`) or with (`1`) compensation.
    pub fn counts(&self, run: usize) -> [usize; 3] {
        let named = &self.named[run];
        let hits = self.injected.iter().filter(|i| named.contains(i)).count();
        [hits, self.injected.len() - hits, named.len() - hits]
    }
}

/// The outcome of one calibration run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// Plan repetitions.
    pub cycles: usize,
    /// Per stage, in plan order.
    pub stages: Vec<StageSummary>,
}

/// How one stage of a calibration run went.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageSummary {
    /// The stage's name.
    pub name: String,
    /// Accepted solver iterations.
    pub iterations: usize,
    /// Why the solver stopped (JSON: snake_case, as in report.json).
    pub termination: Termination,
    /// Numerical rank of the scaled Jacobian at the solution.
    pub rank: usize,
    /// How many parameters were free.
    pub parameters: usize,
}

/// One joint's true joint-angle errors (`kinematics::joint_errors`; rad).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TruthJointError {
    /// The joint.
    pub joint: String,
    /// `a` of `a·sin q`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sine: Option<f64>,
    /// `b` of `b·cos q`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cosine: Option<f64>,
    /// Half the dead band.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub backlash: Option<f64>,
}

/// The joint-angle errors of `truth` by joint name.
pub(super) fn truth_joint_errors(tree: &KinematicTree, truth: &McpcModel) -> Vec<TruthJointError> {
    truth
        .frames()
        .iter()
        .enumerate()
        .filter_map(|(i, frame)| {
            let [_, sine, cosine, backlash] = truth.joint_error_values(i);
            (sine.is_some() || backlash.is_some()).then(|| TruthJointError {
                joint: tree.joint(frame.joint).name.clone(),
                sine,
                cosine,
                backlash,
            })
        })
        .collect()
}

/// One simulated calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrialReport {
    /// The trial's own seed.
    pub seed: u64,
    /// Errors on the arm-stage identification configurations, per arm.
    pub identification: Vec<ArmErrors>,
    /// Errors on the validation configurations, per arm.
    pub validation: Vec<ArmErrors>,
    /// RMS validation position error that the measurement noise alone predicts for the
    /// compensated calibration (mm): from σ²·(JᵀJ)⁻¹ propagated to the validation poses.
    pub noise_floor_position_mm: f64,
    /// How the rigid calibration went.
    pub rigid_run: RunSummary,
    /// How the compensated calibration went.
    pub compensated_run: RunSummary,
    /// With stiffness identification: every compliance parameter, its `scale` relative to the
    /// model's prior (the truth's scale is the model's stiffness over the truth's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<Vec<ComplianceEstimate>>,
    /// The blunders injected and the outliers each calibration named.
    pub blunders: BlunderReport,
    /// The true robot's joint-angle errors (rad), per revolute joint that has one.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub truth_joint_errors: Vec<TruthJointError>,
    /// The simulated measurements (torso stage, then arms stage).
    #[serde(skip)]
    pub measurements: Vec<Measurement>,
    /// Notes of how the plan ran (e.g. `empty-torso`: a torso stage skipped), in the words
    /// of [`crate::calibration::CalibrationReport::notes`].
    #[serde(skip)]
    pub notes: Vec<String>,
}
