//! One session's measurement frame fitted to its rows at a fixed geometry (the session block
//! of [`super::sessions`]): closed-form start, then Gauss–Newton over six parameters.

use super::options::IdentificationOptions;
use crate::math::{pose, Pose, Vec3};
use crate::measurement::{Measurement, Observation};
use nalgebra::{Matrix3, Matrix6, UnitQuaternion, Vector6};

/// Fits one session's frame block: `session_from_first` minimising
/// `Σ wᵢ·‖Wᵢ·(measuredᵢ ⊖ T·predictedᵢ)‖²` (rows divided by their σ's, `weights` per row, empty:
/// all 1), from a closed-form (Kabsch) start on the positions, by Gauss–Newton over the six
/// parameters with a minimum-norm step (directions the rows cannot see stay where the start
/// put them). Returns the frame and how many directions the rows determine.
pub fn fit_session_frame(
    predicted: &[Pose],
    measured: &[&Measurement],
    weights: &[f64],
    options: &IdentificationOptions,
) -> (Pose, usize) {
    let weight = |i: usize| weights.get(i).copied().unwrap_or(1.0);
    let used: Vec<usize> = (0..measured.len()).filter(|&i| weight(i) > 0.0).collect();
    let points = |i: &usize| predicted[*i].translation.vector;
    let (from, to): (Vec<Vec3>, Vec<Vec3>) = used
        .iter()
        .filter_map(|i| {
            Some((
                points(i),
                super::initial_guess::measured_position(measured[*i])?,
            ))
        })
        .unzip();
    let mut frame = super::initial_guess::fit_rigid_transform(&from, &to)
        .unwrap_or_else(|| mean_translation(&from, &to));
    let centre = to.iter().sum::<Vec3>() / to.len().max(1) as f64;
    let sigma = [options.position_sigma, options.rotation_sigma];
    let cost_at = |frame: &Pose| -> f64 {
        used.iter()
            .map(|&i| weight(i) * weighted_error(measured[i], &(frame * predicted[i]), sigma).1)
            .sum()
    };
    let mut cost = cost_at(&frame);
    let mut determined = 0;
    for _ in 0..20 {
        let mut normal = Matrix6::zeros();
        let mut gradient = Vector6::zeros();
        for &i in &used {
            let predicted = frame * predicted[i];
            let (error, _) = weighted_error(measured[i], &predicted, sigma);
            let jacobian = block_jacobian(&predicted, &centre, measured[i], sigma);
            normal += weight(i) * jacobian.transpose() * jacobian;
            gradient += weight(i) * jacobian.transpose() * error;
        }
        let svd = normal.svd(true, true);
        let largest = svd.singular_values.max();
        determined = svd
            .singular_values
            .iter()
            .filter(|&&s| s > 1e-10 * largest && s > 0.0)
            .count();
        let Ok(step) = svd.solve(&gradient, 1e-10 * largest) else {
            break;
        };
        let trial = moved(&frame, &centre, &step);
        let trial_cost = cost_at(&trial);
        // Also stops on a NaN cost.
        if trial_cost.partial_cmp(&cost) != Some(std::cmp::Ordering::Less) {
            break;
        }
        let done = cost - trial_cost <= 1e-14 * cost || step.norm() < 1e-14;
        frame = trial;
        cost = trial_cost;
        if done {
            break;
        }
    }
    (frame, determined)
}

/// A pure translation between the point sets' means (too few points for a rotation).
fn mean_translation(from: &[Vec3], to: &[Vec3]) -> Pose {
    let n = from.len().max(1) as f64;
    let shift = (to.iter().sum::<Vec3>() - from.iter().sum::<Vec3>()) / n;
    pose(shift, UnitQuaternion::identity())
}

/// `measured ⊖ predicted` divided by the σ's (rows of a position: 3, the rest 0) and its
/// squared norm.
pub(super) fn weighted_error(
    measured: &Measurement,
    predicted: &Pose,
    sigma: [f64; 2],
) -> (Vector6<f64>, f64) {
    let mut error = match &measured.observation {
        Observation::Pose(p) => crate::math::pose_error(p, predicted),
        Observation::Position(p) => {
            let d = p - predicted.translation.vector;
            Vector6::new(d.x, d.y, d.z, 0.0, 0.0, 0.0)
        }
        // A contact is not in a session's measurement frame: no rows in the session block.
        Observation::Contact(_) => Vector6::zeros(),
    };
    for k in 0..6 {
        error[k] /= sigma[k / 3];
    }
    (error, error.norm_squared())
}

/// The derivative of the predicted pose (position; rotation for poses) with respect to the
/// block's parameters `δ = (δt, δω)` of `T ← Trans(c + δt)·Rot(δω)·Trans(−c)·T`, rows divided
/// by the σ's: `∂p = δt + δω × (p − c)`, `∂ω = δω`.
fn block_jacobian(
    predicted: &Pose,
    centre: &Vec3,
    measured: &Measurement,
    sigma: [f64; 2],
) -> Matrix6<f64> {
    let arm = predicted.translation.vector - centre;
    let mut jacobian = Matrix6::zeros();
    jacobian
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(Matrix3::identity() / sigma[0]));
    jacobian
        .fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-arm.cross_matrix() / sigma[0]));
    if let Observation::Pose(_) = measured.observation {
        jacobian
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(Matrix3::identity() / sigma[1]));
    }
    jacobian
}

/// `Trans(c + δt)·Rot(δω)·Trans(−c)·frame`: the block moved by `step` about `centre`.
fn moved(frame: &Pose, centre: &Vec3, step: &Vector6<f64>) -> Pose {
    let rotation = UnitQuaternion::from_scaled_axis(step.fixed_rows::<3>(3).into_owned());
    let translation = centre + step.fixed_rows::<3>(0) - rotation * centre;
    pose(translation, rotation) * frame
}
