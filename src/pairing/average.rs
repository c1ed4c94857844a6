//! Averages over a plateau: the joints' mean and standard deviation, the target's mean
//! position and RMS spread, the rigid body's mean orientation and RMS angle.

use super::plateau::{Plateau, PlateauStatus};
use super::{JointSeries, TrackerSeries};
use crate::math::{Rotation, Vec3};
use nalgebra::{Quaternion, UnitQuaternion};

/// The statistics of the samples of both logs within `interval`.
pub(super) fn measure(
    interval: (f64, f64),
    joints: &JointSeries,
    tracker: &TrackerSeries,
    status: PlateauStatus,
) -> Plateau {
    let inside = |t: &f64| (interval.0..=interval.1).contains(t);
    let joint_rows: Vec<&Vec<f64>> = joints
        .times
        .iter()
        .zip(&joints.values)
        .filter(|(t, _)| inside(t))
        .map(|(_, v)| v)
        .collect();
    let width = joints.values.first().map_or(0, Vec::len);
    let (joint_mean, joint_std): (Vec<f64>, Vec<f64>) = (0..width)
        .map(|d| mean_std(joint_rows.iter().map(|row| row[d])))
        .unzip();
    let indices: Vec<usize> = (0..tracker.times.len())
        .filter(|&i| inside(&tracker.times[i]))
        .collect();
    let (position, position_spread) = match indices.len() {
        0 => (None, None),
        n => {
            let mean = indices.iter().map(|&i| tracker.positions[i]).sum::<Vec3>() / n as f64;
            let square = indices
                .iter()
                .map(|&i| (tracker.positions[i] - mean).norm_squared())
                .sum::<f64>();
            (Some(mean), Some((square / n as f64).sqrt()))
        }
    };
    let (orientation, rotation_spread) = tracker
        .orientations
        .as_ref()
        .and_then(|all| mean_rotation(indices.iter().map(|&i| all[i])))
        .map_or((None, None), |(r, s)| (Some(r), Some(s)));
    Plateau {
        start: interval.0,
        end: interval.1,
        joint_mean,
        joint_std,
        joint_samples: joint_rows.len(),
        position,
        position_spread,
        orientation,
        rotation_spread,
        tracker_samples: indices.len(),
        status,
    }
}

/// Mean and (population) standard deviation; NaN for none.
fn mean_std(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = values.clone().count() as f64;
    let mean = values.clone().sum::<f64>() / n;
    let variance = values.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    (mean, variance.sqrt())
}

/// The normalised sign-aligned mean of rotations close to each other, and the RMS angle of
/// the rotations from it (rad); `None` for none.
fn mean_rotation(rotations: impl Iterator<Item = Rotation> + Clone) -> Option<(Rotation, f64)> {
    let first = rotations.clone().next()?;
    let sum = rotations
        .clone()
        .fold(Quaternion::new(0.0, 0.0, 0.0, 0.0), |acc, r| {
            let q = *r.quaternion();
            if q.dot(first.quaternion()) < 0.0 {
                acc - q
            } else {
                acc + q
            }
        });
    let mean = UnitQuaternion::try_new(sum, 1e-12)?;
    let (n, square) = rotations.fold((0usize, 0.0), |(n, s), r| {
        (n + 1, s + r.angle_to(&mean).powi(2))
    });
    Some((mean, (square / n as f64).sqrt()))
}
