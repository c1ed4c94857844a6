//! Identification of MCPC parameters from measurements (paper section 4, done robustly).
//!
//! - [`observation`]: the observation seam: what a kind of measurement predicts, its
//!   residual, Jacobian and noise model ([`MeasurementKind`]); positions and poses today.
//! - [`identifiability`]: rank, condition number, observability indices O1–O5 and the
//!   unidentifiable parameter combinations of a set of configurations, before measuring.
//! - [`frame`]: which measurement frame (root, fitted, known), and the unit-scale check.
//! - [`gauge`]: the root's placement, invisible from a reference link, and the parameters
//!   that fix it.
//! - [`initial_guess`](mod@initial_guess): closed-form measurement frame and tool frames to start from.
//! - [`run`]: a calibration from measured data end to end (hold-out, initial guess, plan,
//!   uncertainties, errors before and after per arm).
//! - [`plan`]: staged (paper section 5.3.1) and simultaneous calibration plans.
//! - [`solver`]: the iterative least-squares identification of eq. (26)–(29) with row
//!   weighting, column scaling, an SVD rank decision and Levenberg–Marquardt damping.
//! - [`stiffness`]: compliance scale factors identified jointly with the MCPC parameters
//!   (`--identify-stiffness`), and what a set of measurements can determine of them.
//! - [`robust`]: robust estimation (Huber or Cauchy by IRLS): blunders named and left out.
//! - [`baseline`]: the fair "before": the nominal robot registered like the calibrated one.
//! - [`validation`]: where validation configurations lie (repeat, inside, outside the
//!   identification ranges).
//! - [`columns`]: joint columns that look swapped or shifted, named by joint, and the
//!   findings that follow from them marked as probable consequences.
//! - [`sessions`]: one measurement frame per measurement session (a nuisance block per
//!   session), fitted with the geometry; validation in the training frame and re-registered.
//! - [`checks`]: the checks of a finished calibration (redundancy, rank, σ̂, conditioning,
//!   validation) that feed the verdict.
//! - [`verdict`]: the `ok` / `warning` / `failed` verdict that ends every calibration.

pub mod baseline;
pub mod checks;
pub mod columns;
pub mod frame;
pub mod gauge;
mod hold_out;
pub mod identifiability;
pub mod initial_guess;
mod linear_algebra;
mod linearise;
mod loss;
pub mod noise_components;
mod normal_equations;
mod observability;
pub mod observation;
mod options;
mod outcome;
pub mod plan;
mod predictor;
pub mod prior;
pub mod robust;
pub mod run;
mod session_findings;
pub mod sessions;
pub mod solver;
pub mod stiffness;
pub mod validation;
pub mod verdict;

pub use frame::{
    check_length_scale, choose_measurement_frame, ChosenFrame, FrameDecision, MeasurementFrame,
};
pub use identifiability::{
    analyse, criterion_value, observability_indices, Criterion, IdentifiabilityOptions,
    IdentifiabilityReport, NamedCombination, ObservabilityIndices, ObservationKind, PoseRow,
};
pub use initial_guess::{fit_rigid_transform, fit_similarity_scale, initial_guess, InitialGuess};
pub use observation::{kind_of, MeasurementKind, Noise, Nuisance, RobotState, RowKind};
pub use plan::{
    calibrate, CalibrationReport, Compensation, ParameterSet, Plan, Stage, StageReport,
};
pub use prior::Prior;
pub use robust::{calibrate_robust, RobustLoss, RobustReport};
pub use run::{
    assembled_covariance, hold_out, hold_out_indices, run_calibration, ArmResiduals,
    CalibrationInput, CalibrationRun, ErrorSummary, ParameterEstimate,
};
pub use sessions::{
    calibrate_sessions, SessionCalibration, SessionFrame, SessionValidation, Sessions,
    SessionsReport,
};
pub use solver::{
    identify, identify_with_nuisance, weighted_jacobian, Combination, Deflected,
    DeflectedWithDerivative, IdentificationOptions, IdentificationReport, Predictor, Rigid,
    Termination,
};
pub use stiffness::{
    analyse_compliance, calibrate_with_stiffness, identified_stiffness, identify_stiffness,
    without_outliers, ComplianceEstimate, ComplianceIdentifiability, Fitted, StiffnessOptions,
    StiffnessReport, StiffnessSequence,
};
pub use verdict::{Finding, Status, Verdict};

/// The expected position noise of a measurement (m) every command and the Python package
/// assume unless told otherwise: position rows are divided by it.
pub const DEFAULT_POSITION_SIGMA: f64 = 1e-4;

/// The expected rotation noise of a measured frame (rad) every command and the Python package
/// assume unless told otherwise: rotation rows are divided by it.
pub const DEFAULT_ROTATION_SIGMA: f64 = 1e-3;
