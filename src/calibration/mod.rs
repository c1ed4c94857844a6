//! Identification of MCPC parameters from measurements (paper section 4, done robustly).
//!
//! - `observation`: the observation seam: what a kind of measurement predicts, its
//!   residual, Jacobian and noise model ([`MeasurementKind`]); positions and poses today.
//! - `identifiability`: rank, condition number, observability indices O1–O5 and the
//!   unidentifiable parameter combinations of a set of configurations, before measuring.
//! - `frame`: which measurement frame (root, fitted, known), and the unit-scale check.
//! - `gauge`: the root's placement, invisible from a reference link, and the parameters
//!   that fix it.
//! - `initial_guess`: closed-form measurement frame and tool frames to start from.
//! - `run`: a calibration from measured data end to end (hold-out, initial guess, plan,
//!   uncertainties, errors before and after per arm).
//! - `plan`: staged (paper section 5.3.1) and simultaneous calibration plans.
//! - `solver`: the iterative least-squares identification of eq. (26)–(29) with row
//!   weighting, column scaling, an SVD rank decision and Levenberg–Marquardt damping.
//! - `stiffness`: compliance scale factors identified jointly with the MCPC parameters
//!   (`--identify-stiffness`), and what a set of measurements can determine of them.
//! - `robust`: robust estimation (Huber or Cauchy by IRLS): blunders named and left out.
//! - `baseline`: the fair "before": the nominal robot registered like the calibrated one.
//! - `validation`: where validation configurations lie (repeat, inside, outside the
//!   identification ranges).
//! - `columns`: joint columns that look swapped or shifted, named by joint, and the
//!   findings that follow from them marked as probable consequences.
//! - `sessions`: one measurement frame per measurement session (a nuisance block per
//!   session), fitted with the geometry; validation in the training frame and re-registered.
//! - `checks`: the checks of a finished calibration (redundancy, rank, σ̂, conditioning,
//!   validation) that feed the verdict.
//! - `verdict`: the `ok` / `warning` / `failed` verdict that ends every calibration.

pub(crate) mod baseline;
pub(crate) mod checks;
mod coarse_to_fine;
pub(crate) mod columns;
pub(crate) mod frame;
pub(crate) mod gauge;
mod hold_out;
pub(crate) mod identifiability;
pub(crate) mod initial_guess;
mod linear_algebra;
mod linearise;
mod loss;
pub(crate) mod noise_components;
mod normal_equations;
mod observability;
pub(crate) mod observation;
mod options;
mod outcome;
pub(crate) mod plan;
mod predictor;
pub(crate) mod prior;
mod repeatability;
pub(crate) mod robust;
pub(crate) mod robust_frame;
pub(crate) mod run;
mod session_findings;
mod session_frame;
pub(crate) mod sessions;
pub(crate) mod solver;
mod solver_analysis;
mod solver_report;
pub(crate) mod stiffness;
#[cfg(test)]
mod test_problems;
pub(crate) mod validation;
pub(crate) mod verdict;

pub use baseline::registered_nominal;
pub use checks::{
    assess, conditioning, convergence, joint_errors_plausible, position_only, rank, redundancy,
    residual_scale, stiffness_below_zero, unexplained_mm, validation_improves,
    validation_matches_prediction, validation_set_aside, CONDITION_WARNING, JOINT_ERROR_FAILED,
    JOINT_ERROR_WARNING, REDUNDANCY_WARNING, SIGMA_FAILED, SIGMA_WARNING, VALIDATION_FAILED,
    VALIDATION_WARNING,
};
pub use columns::{
    diagnose_columns, mark_consequences, CONSEQUENCES, CONSEQUENCE_PREFIX, DIAGNOSIS_ROWS,
    ROOT_CAUSES, ROOT_CAUSE_RATIO,
};
pub use frame::{
    check_length_scale, choose_measurement_frame, ChosenFrame, FrameDecision, MeasurementFrame,
};
pub use frame::{
    frame_explains, FRAME_EXTRA_RMS_FLOOR, FRAME_EXTRA_RMS_RATIO, FRAME_ROTATION_LIMIT,
    FRAME_TRANSLATION_LIMIT, LENGTH_SCALE_LIMIT,
};
pub use gauge::{gauge_summary, reference_gauge};
pub use identifiability::{
    analyse, criterion_value, observability_indices, Criterion, IdentifiabilityOptions,
    IdentifiabilityReport, NamedCombination, ObservabilityIndices, ObservationKind, PoseRow,
};
pub use identifiability::{
    describe_terms, scaled_jacobian, scaled_singular_values,
    weighted_jacobian as planned_weighted_jacobian, DEFAULT_CONDITION_LIMIT,
};
pub use initial_guess::initial_tool_frames;
pub use initial_guess::{fit_rigid_transform, fit_similarity_scale, initial_guess, InitialGuess};
pub use noise_components::{
    balanced_rotation_sigma, variance_components, NoiseComponent, MAX_NOISE_ROUNDS,
    NOISE_RATIO_TOLERANCE,
};
pub use observation::{
    contact_violation, norms_by_row_kind, squares_by_row_kind, standardized_norm, NuisanceBlock,
    Tools, DEFAULT_CONTACT_SIGMAS,
};
pub use observation::{kind_of, MeasurementKind, Noise, Nuisance, RobotState, RowKind};
pub use plan::{
    calibrate, CalibrationReport, Compensation, ParameterSet, Plan, Stage, StageReport,
};
pub use plan::{
    coupled_frames, locked_arm_model, position_only_orientations, stage_parameters,
    CYCLE_TOLERANCE, MAX_CYCLES,
};
pub use prior::Prior;
pub use prior::{
    DEFAULT_ANGLE_SIGMA, DEFAULT_JOINT_ERROR_SIGMA, DEFAULT_LENGTH_SIGMA, DEFAULT_OFFSET_SIGMA,
};
pub use repeatability::{repeatability, Repeatability, SessionLabels};
pub(crate) use robust::outlier_mask;
pub use robust::{calibrate_robust, RobustLoss, RobustReport};
pub use robust::{
    residuals, robust_scale, threshold, weights_of, DataSet, Outlier, Residual, MAX_ROUNDS,
    OUTLIER_WEIGHT, SCALE_FLOOR, WEIGHT_TOLERANCE,
};
pub use robust_frame::{
    fit_session_frame_robust, gross_blunders, gross_rows, RobustFrame, GROSS_FACTOR,
};
pub use run::{
    assembled_covariance, hold_out, hold_out_indices, run_calibration, ArmResiduals,
    CalibrationInput, CalibrationRun, ErrorSummary, ParameterEstimate,
};
pub use run::{removed_percent, FrameRefinement, FRAME_PRIOR_ANGLE, FRAME_PRIOR_LENGTH};
pub use session_frame::fit_session_frame;
pub use sessions::{
    calibrate_sessions, SessionCalibration, SessionFrame, SessionValidation, Sessions,
    SessionsReport,
};
pub use sessions::{
    finish_sessions, in_first_frame, predictions, session_findings, session_label,
    validate_sessions, validation_in_training_frames, FRAME_BLOCK_PARAMETERS, ROTATION_LENGTH,
    ROUND_TOLERANCE,
};
pub use solver::{
    identify, identify_with_nuisance, weighted_jacobian, Combination, Deflected,
    DeflectedWithDerivative, IdentificationOptions, IdentificationReport, Predictor, Rigid,
    Termination,
};
pub use solver::{weighted_residual, CORRECTION_RADIUS, IDENTIFIABLE_NULL_WEIGHT};
pub use stiffness::{
    analyse_compliance, calibrate_with_stiffness, identified_stiffness, identify_stiffness,
    without_outliers, ComplianceEstimate, ComplianceIdentifiability, Fitted, StiffnessOptions,
    StiffnessReport, StiffnessSequence,
};
pub use stiffness::{name, DETERMINED};
pub use validation::{
    chain_postures, strata, ChainPostures, PostureIndex, Stratum, INSIDE_MARGIN_ANGLE,
    INSIDE_MARGIN_LENGTH, REPEAT_ANGLE, REPEAT_LENGTH,
};
pub use verdict::{Finding, Status, Verdict};

/// The expected position noise of a measurement (m) every command and the Python package
/// assume unless told otherwise: position rows are divided by it.
pub const DEFAULT_POSITION_SIGMA: f64 = 1e-4;

/// The expected rotation noise of a measured frame (rad) every command and the Python package
/// assume unless told otherwise: rotation rows are divided by it.
pub const DEFAULT_ROTATION_SIGMA: f64 = 1e-3;
