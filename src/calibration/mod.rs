//! Identification of MCPC parameters from measurements (paper section 4, done robustly).
//!
//! - [`initial_guess`](mod@initial_guess): closed-form measurement frame and tool frames to start from.
//! - [`plan`]: staged (paper section 5.3.1) and simultaneous calibration plans.
//! - [`solver`]: the iterative least-squares identification of eq. (26)–(29) with row
//!   weighting, column scaling, an SVD rank decision and Levenberg–Marquardt damping.

pub mod initial_guess;
pub mod plan;
pub mod solver;

pub use initial_guess::{fit_rigid_transform, initial_guess, InitialGuess};
pub use plan::{
    calibrate, CalibrationReport, Compensation, ParameterSet, Plan, Stage, StageReport,
};
pub use solver::{
    identify, Combination, Deflected, DeflectedWithDerivative, IdentificationOptions,
    IdentificationReport, Predictor, Rigid, Termination,
};
