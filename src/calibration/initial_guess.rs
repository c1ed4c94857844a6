//! A closed-form start for the iteration: where the measurement frame is relative to the
//! robot base, and where each measured tool frame is relative to its arm's last joint.
//!
//! A laser tracker measures in its own frame, and the frame it reports for a tool (for
//! example the three-target frame of the paper's section 5.3.1) can be hundreds of
//! millimetres and tens of degrees away from the URDF tool link. Linearising that far from
//! the truth can fail, so before iterating: (1) fit the measurement frame to the measured
//! positions by the Kabsch/Horn method, (2) fit each tool's constant transform by averaging
//! `last_frame⁻¹ · measured` over its measurements, and repeat a few times, since each fit
//! improves the other.

use super::linearise::map_rows_in_order;
use super::observation::kind_of;
use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, McpcTool};
use crate::math::{pose, Mat3, Pose, Rotation, Vec3};
use crate::measurement::Measurement;
use nalgebra::{Rotation3, UnitQuaternion};
use rayon::prelude::*;
use std::ops::Range;

/// What the initial guess changed.
#[derive(Debug, Clone)]
pub struct InitialGuess {
    /// The model to start the iteration from.
    pub model: McpcModel,
    /// The estimated pose of the robot base in the measurement frame.
    pub world_from_base: Pose,
    /// RMS distance between measured and predicted positions before the guess (m).
    pub rms_before: f64,
    /// The same after the guess (m).
    pub rms_after: f64,
}

/// The tool positions `model` predicts in its base frame (the measurement frame set to
/// identity) and the measured positions, in measurement order: the point sets that the
/// closed-form frame fits compare.
pub(crate) fn base_frame_positions(
    model: &McpcModel,
    measurements: &[Measurement],
) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut in_base = model.clone();
    in_base.set_world_from_base(&Pose::identity());
    // Only kinds that measure the tool's origin take part (all of today's). In parallel, in
    // measurement order.
    let pairs: Vec<Option<(Vec3, Vec3)>> = measurements
        .par_iter()
        .map(|m| {
            let measured = measured_position(m)?;
            Some((in_base.tool_pose(m.tool, &m.q).translation.vector, measured))
        })
        .collect();
    pairs.into_iter().flatten().unzip()
}

/// The measured position of the tool's origin, when the observation's kind measures it
/// (a pose's origin, a point: [`crate::calibration::MeasurementKind::measured_point`]).
pub(crate) fn measured_position(m: &Measurement) -> Option<Vec3> {
    kind_of(&m.observation).measured_point()
}

/// The rows' squares in parallel, summed in measurement order (the same sum on any number of
/// threads).
fn position_rms(model: &McpcModel, measurements: &[Measurement]) -> f64 {
    let squares = |range: Range<usize>| -> Result<Vec<Option<f64>>> {
        Ok(measurements[range]
            .iter()
            .map(|m| {
                let measured = measured_position(m)?;
                Some((model.tool_pose(m.tool, &m.q).translation.vector - measured).norm_squared())
            })
            .collect())
    };
    let mut sum = 0.0;
    // `squares` cannot fail.
    let _ = map_rows_in_order(measurements.len(), squares, |value| {
        if let Some(value) = value {
            sum += value;
        }
    });
    (sum / measurements.len().max(1) as f64).sqrt()
}

/// The rotation closest (Frobenius) to `m`, via SVD; `None` if `m` is degenerate.
fn nearest_rotation(m: &Mat3) -> Option<Rotation> {
    // The SVD of a non-finite matrix never ends.
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Mat3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    Some(UnitQuaternion::from_rotation_matrix(
        &Rotation3::from_matrix_unchecked(u * d * v_t),
    ))
}

/// Two paired point sets about their centroids.
struct Centred {
    from_mean: Vec3,
    to_mean: Vec3,
    /// `Σ (to_i − to_mean)(from_i − from_mean)ᵀ`.
    covariance: Mat3,
    /// `Σ ‖from_i − from_mean‖²`.
    spread: f64,
}

/// [`Centred`] of `from` and `to`; `None` for fewer than three pairs, sets of unequal length,
/// or non-finite sums (the SVD of a non-finite matrix never ends).
fn centred(from: &[Vec3], to: &[Vec3]) -> Option<Centred> {
    if from.len() < 3 || from.len() != to.len() {
        return None;
    }
    let n = from.len() as f64;
    let from_mean = from.iter().sum::<Vec3>() / n;
    let to_mean = to.iter().sum::<Vec3>() / n;
    let mut covariance = Mat3::zeros();
    let mut spread = 0.0;
    for (a, b) in from.iter().zip(to) {
        covariance += (b - to_mean) * (a - from_mean).transpose();
        spread += (a - from_mean).norm_squared();
    }
    let finite = covariance.iter().all(|v| v.is_finite()) && spread.is_finite();
    finite.then_some(Centred {
        from_mean,
        to_mean,
        covariance,
        spread,
    })
}

/// Kabsch/Horn: the rigid transform `T` minimising `Σ ‖T·from_i − to_i‖²`; `None` when the
/// points do not fix a rotation (fewer than three, or all on a line).
pub fn fit_rigid_transform(from: &[Vec3], to: &[Vec3]) -> Option<Pose> {
    let Centred {
        from_mean,
        to_mean,
        covariance,
        ..
    } = centred(from, to)?;
    let singular = covariance.singular_values();
    if singular[1] <= 1e-12 * singular[0].max(f64::MIN_POSITIVE) {
        return None;
    }
    let rotation = nearest_rotation(&covariance)?;
    Some(pose(to_mean - rotation * from_mean, rotation))
}

/// Umeyama: the scale `s` of the similarity transform `s·R·from + t` closest to `to` (least
/// squares), `s = trace(D·Σ)/σ²_from` with `Σ` the singular values of the cross-covariance and
/// `D` the reflection fix; `None` when `from` does not spread (fewer than three points, or all
/// at one place).
pub fn fit_similarity_scale(from: &[Vec3], to: &[Vec3]) -> Option<f64> {
    let centred = centred(from, to)?;
    let n = from.len() as f64;
    let covariance = centred.covariance / n;
    let spread = centred.spread / n;
    if spread <= 1e-18 {
        return None;
    }
    let svd = covariance.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let sign = if (u * v_t).determinant() < 0.0 {
        -1.0
    } else {
        1.0
    };
    let s = svd.singular_values;
    let scale = (s[0] + s[1] + sign * s[2]) / spread;
    (scale.is_finite() && scale > 0.0).then_some(scale)
}

/// Fits the measurement frame and every measured tool's frame in closed form (see the module
/// documentation); `rounds` alternations (3 is plenty).
pub fn initial_guess(
    model: &McpcModel,
    measurements: &[Measurement],
    rounds: usize,
) -> Result<InitialGuess> {
    require_measurements(measurements)?;
    let rms_before = position_rms(model, measurements);
    let mut current = model.clone();
    for _ in 0..rounds.max(1) {
        // (1) The measurement frame, from positions predicted in the base frame.
        let (predicted, measured) = base_frame_positions(&current, measurements);
        if let Some(world_from_base) = fit_rigid_transform(&predicted, &measured) {
            current.set_world_from_base(&world_from_base);
        }
        // (2) Each tool's transform from its last moved frame.
        current = fit_tools(&current, measurements)?;
    }
    let rms_after = position_rms(&current, measurements);
    Ok(InitialGuess {
        world_from_base: current.world_from_base(),
        model: current,
        rms_before,
        rms_after,
    })
}

/// Each measured tool's transform from its last moved frame, fitted in closed form with the
/// measurement frame of `current` kept.
fn fit_tools(current: &McpcModel, measurements: &[Measurement]) -> Result<McpcModel> {
    let mut tools = current.tools().to_vec();
    for (index, tool) in tools.iter_mut().enumerate() {
        let own: Vec<&Measurement> = measurements.iter().filter(|m| m.tool == index).collect();
        if own.is_empty() {
            continue;
        }
        let last_poses: Vec<Pose> = own
            .par_iter()
            .map(|m| match tool.parent {
                Some(f) => current
                    .moved(f, &m.q, &current.frame_transforms(&m.q)[f])
                    .to_pose(),
                None => current.world_from_root(&m.q),
            })
            .collect();
        let current_relative = tool.constant_transform();
        let poses: Vec<Pose> = own
            .iter()
            .zip(&last_poses)
            .filter_map(|(m, last)| {
                kind_of(&m.observation)
                    .measured_frame()
                    .map(|p| last.inverse() * p)
            })
            .collect();
        let relative = if poses.len() == own.len() {
            // Full poses: mean translation, chordal mean rotation.
            let translation =
                poses.iter().map(|p| p.translation.vector).sum::<Vec3>() / poses.len() as f64;
            let sum: Mat3 = poses
                .iter()
                .map(|p| *p.rotation.to_rotation_matrix().matrix())
                .sum();
            match nearest_rotation(&sum) {
                Some(rotation) => pose(translation, rotation),
                None => current_relative,
            }
        } else {
            // Positions: least-squares point in the last frame, orientation kept.
            let point = own
                .iter()
                .zip(&last_poses)
                .filter_map(|(m, last)| {
                    measured_position(m)
                        .map(|p| (last.inverse() * nalgebra::Point3::from(p)).coords)
                })
                .sum::<Vec3>()
                / own.len() as f64;
            pose(point, current_relative.rotation)
        };
        let twist = tool.parent.map_or(0.0, |f| current.frames()[f].twist);
        *tool = McpcTool::from_relative_pose(tool.link, tool.parent, twist, &relative);
    }
    let mut fitted = McpcModel::new(current.frames().to_vec(), tools)?;
    fitted.adopt_extra_parameters(current);
    fitted.set_world_from_base(&current.world_from_base());
    Ok(fitted)
}

/// The initial guess with the measurement frame of `model` kept (e.g. data already in the
/// root frame): only the measured tools' frames are fitted.
pub fn initial_tool_frames(
    model: &McpcModel,
    measurements: &[Measurement],
) -> Result<InitialGuess> {
    require_measurements(measurements)?;
    let rms_before = position_rms(model, measurements);
    let current = fit_tools(model, measurements)?;
    Ok(InitialGuess {
        world_from_base: current.world_from_base(),
        rms_before,
        rms_after: position_rms(&current, measurements),
        model: current,
    })
}

fn require_measurements(measurements: &[Measurement]) -> Result<()> {
    if measurements.is_empty() {
        return Err(Error::InvalidData {
            origin: "initial guess".into(),
            message: "no measurements".into(),
        });
    }
    Ok(())
}
