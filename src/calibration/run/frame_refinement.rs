//! The measurement frame refined by variable projection, for a calibration with exact
//! flexibility compensation.

use super::input::CalibrationInput;
use crate::calibration::outcome::FrameRefinement;
use crate::calibration::predictor::Deflected;
use crate::calibration::{calibrate, CalibrationReport, Compensation};
use crate::error::Result;
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::math::Pose;
use crate::measurement::Measurement;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

pub(super) struct Refined {
    pub(super) report: CalibrationReport,
    pub(super) summary: FrameRefinement,
}

/// Rigid kinematics cannot tell the measurement frame from the MCPC parameters (the model is
/// complete: any frame error is absorbed by them), but the deflections can: gravity and the
/// lever arms of the loads are fixed in space, and the absorbed parametrisation places joints
/// and masses differently. A frame fitted to the nominal model (off by the geometric errors)
/// therefore leaves a systematic error of the order of deflection × relative geometric error.
/// This refines the six frame parameters by variable projection: Gauss–Newton on the weighted
/// residual *after* calibrating the parameters at each trial frame, with forward-difference
/// derivatives (each a warm-started calibration) and a Gaussian prior centred on the closed-form
/// frame ([`FRAME_PRIOR_LENGTH`], [`FRAME_PRIOR_ANGLE`]) for the directions the data leave free.
pub(super) fn refine_measurement_frame(
    input: &CalibrationInput<'_>,
    flexibility: &FlexibilityModel,
    measurements: &[Measurement],
    start: &CalibrationReport,
) -> Result<Refined> {
    let predictor = Deflected {
        tree: input.tree,
        flexibility,
    };
    let residual_of = |report: &CalibrationReport| {
        crate::calibration::linearise::weighted_residual(
            &report.model,
            measurements,
            &predictor,
            input.options,
        )
    };
    let calibrate_at = |from: &McpcModel, frame: &Pose| -> Result<CalibrationReport> {
        let mut model = from.clone();
        model.set_world_from_base(frame);
        calibrate(
            input.branches,
            &model,
            measurements,
            Compensation::Exact(predictor),
            input.plan,
            input.options,
        )
    };
    const STEP: f64 = 1e-4;
    const MAX_ITERATIONS: usize = 10;
    let initial_frame = start.model.world_from_base();
    let correction_of = |frame: &Pose| correction(frame, &initial_frame);
    let prior = prior_scales();
    let total_cost = |residual: &DVector<f64>, frame: &Pose| -> f64 {
        0.5 * residual.norm_squared()
            + 0.5 * correction_of(frame).component_mul(&prior).norm_squared()
    };
    let mut current = start.clone();
    let mut residual = residual_of(&current)?;
    let initial_cost = 0.5 * residual.norm_squared();
    let mut iterations = 0;
    let mut determined = 0;
    let mut damping = 0.0;
    while iterations < MAX_ITERATIONS {
        let frame = current.model.world_from_base();
        // The six columns are independent calibrations: run them on all cores.
        let columns: Vec<DVector<f64>> = (0..6)
            .into_par_iter()
            .map(|k| -> Result<DVector<f64>> {
                let mut delta = [0.0; 6];
                delta[k] = STEP;
                let shifted = calibrate_at(&current.model, &moved(&frame, &delta))?;
                Ok((residual_of(&shifted)? - &residual) / STEP)
            })
            .collect::<Result<_>>()?;
        let jacobian = DMatrix::from_columns(&columns);
        crate::limits::ensure_finite(
            jacobian.iter().chain(residual.iter()),
            "measurement frame refinement: the Jacobian",
        )?;
        determined = determined_directions(&jacobian);
        let cost = total_cost(&residual, &frame);
        let weights = prior.component_mul(&prior);
        let normal = jacobian.tr_mul(&jacobian) + DMatrix::from_diagonal(&weights);
        let gradient = jacobian.tr_mul(&residual) + correction_of(&frame).component_mul(&weights);
        let mut accepted = false;
        let mut converged = false;
        for _ in 0..10 {
            let damped = &normal + DMatrix::identity(6, 6) * damping;
            let Some(cholesky) = damped.cholesky() else {
                break;
            };
            let step = -cholesky.solve(&gradient);
            let trial_frame = moved(&frame, step.as_slice());
            let trial = calibrate_at(&current.model, &trial_frame)?;
            let trial_residual = residual_of(&trial)?;
            let trial_cost = total_cost(&trial_residual, &trial_frame);
            if trial_cost < cost {
                current = trial;
                residual = trial_residual;
                damping *= 0.1;
                accepted = true;
                iterations += 1;
                // Past the noise floor the cost creeps along the valley the data leave
                // free; a relative decrease of 1e-5 is far below what noise tells apart.
                converged = step.norm() < 1e-9 || cost - trial_cost <= 1e-5 * cost;
                break;
            }
            damping = if damping == 0.0 {
                1e-6 * normal.diagonal().max()
            } else {
                damping * 10.0
            };
        }
        if !accepted || converged {
            break;
        }
    }
    Ok(finish(
        current,
        residual,
        initial_cost,
        iterations,
        determined,
        &initial_frame,
    ))
}

/// Frame perturbation: world_from_base ← exp(δ)·world_from_base, δ = (translation, rotation)
/// in the measurement frame.
fn moved(frame: &Pose, delta: &[f64]) -> Pose {
    let rotation = nalgebra::UnitQuaternion::from_scaled_axis(nalgebra::Vector3::new(
        delta[3], delta[4], delta[5],
    ));
    // Turned about the frame's own origin, not the measurement origin.
    let origin = frame.translation.vector + nalgebra::Vector3::new(delta[0], delta[1], delta[2]);
    Pose::from_parts(origin.into(), rotation * frame.rotation)
}

/// The correction of `frame` from the closed-form frame `initial_frame` as (translation,
/// rotation vector).
fn correction(frame: &Pose, initial_frame: &Pose) -> DVector<f64> {
    let t = frame.translation.vector - initial_frame.translation.vector;
    let r = (frame.rotation * initial_frame.rotation.inverse()).scaled_axis();
    DVector::from_column_slice(&[t.x, t.y, t.z, r.x, r.y, r.z])
}

/// The inverse scales of the frame's Gaussian prior, translation then rotation.
fn prior_scales() -> DVector<f64> {
    DVector::from_column_slice(&[
        1.0 / FRAME_PRIOR_LENGTH,
        1.0 / FRAME_PRIOR_LENGTH,
        1.0 / FRAME_PRIOR_LENGTH,
        1.0 / FRAME_PRIOR_ANGLE,
        1.0 / FRAME_PRIOR_ANGLE,
        1.0 / FRAME_PRIOR_ANGLE,
    ])
}

/// How many directions of the frame the data determine better than the prior does.
fn determined_directions(jacobian: &DMatrix<f64>) -> usize {
    let singular_values = jacobian.clone().svd(false, false).singular_values;
    let largest = singular_values.max();
    singular_values
        .iter()
        .filter(|&&s| s > 1.0 / FRAME_PRIOR_LENGTH.max(FRAME_PRIOR_ANGLE) && s > 1e-6 * largest)
        .count()
}

/// How far (m) the refined measurement frame is expected to be from the closed-form fit: the
/// scale of a Gaussian prior that keeps the directions the deflections hardly see (such as a
/// turn about the vertical) where the closed form put them.
pub const FRAME_PRIOR_LENGTH: f64 = 0.01;

/// The same for rotations (rad).
pub const FRAME_PRIOR_ANGLE: f64 = 0.01;

fn finish(
    report: CalibrationReport,
    residual: DVector<f64>,
    initial_cost: f64,
    iterations: usize,
    determined: usize,
    initial_frame: &Pose,
) -> Refined {
    let frame = report.model.world_from_base();
    let change = frame * initial_frame.inverse();
    Refined {
        summary: FrameRefinement {
            iterations,
            cost: [initial_cost, 0.5 * residual.norm_squared()],
            correction: [
                change.rotation.angle(),
                (frame.translation.vector - initial_frame.translation.vector).norm(),
            ],
            determined,
        },
        report,
    }
}
