//! Identification of MCPC parameters from measurements (paper section 4, done robustly).
//!
//! - [`solver`]: the iterative least-squares identification of eq. (26)–(29) with row
//!   weighting, column scaling, an SVD rank decision and Levenberg–Marquardt damping.

pub mod solver;

pub use solver::{
    identify, Combination, IdentificationOptions, IdentificationReport, Predictor, Rigid,
    Termination,
};
