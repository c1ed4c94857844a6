//! "Calibrate, identify stiffness, calibrate again": the one sequence `calibrate
//! --identify-stiffness` and `simulate --identify-stiffness` both run.
//!
//! The stiffness fit is plain least squares, so it leaves out the rows the robust calibration
//! named as outliers, as that calibration's own last fit did: a blunder kept in would pull the
//! compliance scales (`tests/stiffness.rs`, `the_stiffness_fit_leaves_the_outliers_out`).

use super::{identify_stiffness, StiffnessOptions, StiffnessReport};
use crate::calibration::options::IdentificationOptions;
use crate::error::Result;
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::measurement::Measurement;
use crate::tree::KinematicTree;

/// What a calibration hands the stiffness fit: the calibrated model, the rows it fitted (in
/// the frame the model predicts in) and the indices of those it named as outliers.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The calibrated model (the stiffness fit's start).
    pub model: McpcModel,
    /// The rows of the calibration.
    pub measurements: Vec<Measurement>,
    /// Indices into `measurements` of the rows named as outliers.
    pub outliers: Vec<usize>,
}

/// The three steps' outcomes.
#[derive(Debug, Clone)]
pub struct StiffnessSequence<R> {
    /// The calibration with the prior flexibility.
    pub first: R,
    /// The stiffness fit (geometry and compliance scales jointly).
    pub stiffness: StiffnessReport,
    /// The calibration again, with the identified flexibility.
    pub again: R,
}

/// `measurements` without the rows at `outliers`.
pub fn without_outliers(measurements: &[Measurement], outliers: &[usize]) -> Vec<Measurement> {
    measurements
        .iter()
        .enumerate()
        .filter(|(index, _)| !outliers.contains(index))
        .map(|(_, m)| m.clone())
        .collect()
}

/// Calibrates (`calibrate` with `first`: the prior flexibility, or `None` for a rigid first
/// calibration), identifies the stiffness from the calibrated model with every geometric
/// parameter free and the outliers left out, and calibrates again with the identified
/// flexibility.
#[allow(clippy::too_many_arguments)]
pub fn calibrate_with_stiffness<R>(
    tree: &KinematicTree,
    prior: &FlexibilityModel,
    first: Option<&FlexibilityModel>,
    options: &IdentificationOptions,
    stiffness: &StiffnessOptions,
    mut calibrate: impl FnMut(Option<&FlexibilityModel>) -> Result<R>,
    fitted: impl Fn(&R) -> Fitted,
) -> Result<StiffnessSequence<R>> {
    let first = calibrate(first)?;
    let rows = fitted(&first);
    let free: Vec<usize> = (0..rows.model.parameter_count()).collect();
    let kept = without_outliers(&rows.measurements, &rows.outliers);
    let report = identify_stiffness(
        tree,
        &rows.model,
        prior,
        &kept,
        None,
        &free,
        options,
        stiffness,
    )?;
    let again = calibrate(Some(&report.flexibility))?;
    Ok(StiffnessSequence {
        first,
        stiffness: report,
        again,
    })
}
