//! What a calibration from data is run on and how.

use crate::calibration::options::IdentificationOptions;
use crate::calibration::MeasurementFrame;
use crate::calibration::Plan;
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::tree::{Branches, KinematicTree};

/// What a calibration is run on and how.
#[derive(Debug, Clone, Copy)]
pub struct CalibrationInput<'a> {
    /// The robot.
    pub tree: &'a KinematicTree,
    /// Its coupled branch and arms.
    pub branches: &'a Branches,
    /// The nominal MCPC model of `branches`.
    pub nominal: &'a McpcModel,
    /// The flexibility model, for exact compensation; `None` calibrates a rigid robot.
    pub flexibility: Option<&'a FlexibilityModel>,
    /// The stages.
    pub plan: &'a Plan,
    /// Row weights, tolerances.
    pub options: &'a IdentificationOptions,
    /// Where the measurements are: fitted, the root frame, a known registration, or `Auto`
    /// (see [`MeasurementFrame`]); the tool frames are always fitted.
    pub measurement_frame: MeasurementFrame,
    /// When the residuals are far above the noise, look for swapped or shifted joint columns
    /// (a registered nominal fit per rearrangement). The user's run does; the folds of a
    /// cross-validation do not (the same columns, diagnosed once by the run they choose for:
    /// at TIAGo's σ̂ the diagnosis was 94 % of a default run's CPU).
    pub diagnose_columns: bool,
}
