//! Type aliases and small geometric helpers used everywhere.
//!
//! Units inside treecal are SI: metres, radians, kilograms, newtons. Conversions from
//! millimetres and degrees happen only where files are read or written.
//!
//! Frames are named `a_from_b`: the pose of frame `b` expressed in frame `a`, so that
//! `world_from_base * base_from_tool` reads right and yields `world_from_tool`.

mod trig;

pub use trig::{sin_cos, sin_cos_all};

use nalgebra::{Isometry3, Matrix3, Translation3, Unit, UnitQuaternion, Vector3};

/// A rigid transform (rotation + translation), metres.
pub type Pose = Isometry3<f64>;
/// A 3-vector, metres or unitless.
pub type Vec3 = Vector3<f64>;
/// A rotation.
pub type Rotation = UnitQuaternion<f64>;
/// A 3×3 matrix.
pub type Mat3 = Matrix3<f64>;

/// Rotation about the X axis by `angle` radians.
pub fn rot_x(angle: f64) -> Rotation {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), angle)
}

/// Rotation about the Y axis by `angle` radians.
pub fn rot_y(angle: f64) -> Rotation {
    UnitQuaternion::from_axis_angle(&Vector3::y_axis(), angle)
}

/// Rotation about the Z axis by `angle` radians.
pub fn rot_z(angle: f64) -> Rotation {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle)
}

/// Rotation about an arbitrary unit axis.
pub fn rot_axis(axis: &Unit<Vector3<f64>>, angle: f64) -> Rotation {
    UnitQuaternion::from_axis_angle(axis, angle)
}

/// A pose from a translation and a rotation.
pub fn pose(translation: Vec3, rotation: Rotation) -> Pose {
    Isometry3::from_parts(Translation3::from(translation), rotation)
}

/// A pure translation.
pub fn translation(x: f64, y: f64, z: f64) -> Pose {
    Isometry3::translation(x, y, z)
}

/// URDF roll-pitch-yaw: `R = Rz(yaw) · Ry(pitch) · Rx(roll)` (fixed axes X, Y, Z).
pub fn rotation_from_rpy(roll: f64, pitch: f64, yaw: f64) -> Rotation {
    UnitQuaternion::from_euler_angles(roll, pitch, yaw)
}

/// The URDF roll, pitch, yaw of a rotation (inverse of [`rotation_from_rpy`]).
///
/// Accurate to rounding everywhere, gimbal lock included: the usual `pitch = −asin(r31)`
/// loses half the digits near pitch = ±90° (1e-8 rad), which is where MCPC-generated joints
/// often sit. Yaw comes from the first column, the yaw is undone, and roll and pitch are read
/// from well-conditioned entries of what remains, so the three angles reproduce the rotation
/// even where yaw and roll are not separately determined.
pub fn rpy_from_rotation(rotation: &Rotation) -> [f64; 3] {
    let m = *rotation.to_rotation_matrix().matrix();
    let yaw = if m[(1, 0)] == 0.0 && m[(0, 0)] == 0.0 {
        0.0
    } else {
        m[(1, 0)].atan2(m[(0, 0)])
    };
    // Ry(pitch)·Rx(roll) = Rz(−yaw)·R.
    let rest = *rot_z(-yaw).to_rotation_matrix().matrix() * m;
    let pitch = (-rest[(2, 0)]).atan2(rest[(0, 0)]);
    let roll = (-rest[(1, 2)]).atan2(rest[(1, 1)]);
    [wrap_angle(roll), pitch, wrap_angle(yaw)]
}

/// Intrinsic X-Y-Z angles `(a, b, c)` with `R = Rx(a) · Ry(b) · Rz(c)`, the MCPC tool
/// convention (paper eq. (2)). `b` lies in [−π/2, π/2]; near |b| = π/2 the split between
/// `a` and `c` is arbitrary, which is why MCPC frames are re-parametrised away from there.
pub fn xyz_angles_from_rotation(rotation: &Rotation) -> [f64; 3] {
    // As in `rpy_from_rotation`: c from the first row, then a and b from R·Rz(−c) = Rx(a)·Ry(b).
    let m = *rotation.to_rotation_matrix().matrix();
    let c = if m[(0, 1)] == 0.0 && m[(0, 0)] == 0.0 {
        0.0
    } else {
        (-m[(0, 1)]).atan2(m[(0, 0)])
    };
    let rest = m * *rot_z(-c).to_rotation_matrix().matrix();
    let b = rest[(0, 2)].atan2(rest[(0, 0)]);
    let a = rest[(2, 1)].atan2(rest[(1, 1)]);
    [wrap_angle(a), b, wrap_angle(c)]
}

/// The root mean square of `values`; `None` when there are none.
pub fn root_mean_square(values: &[f64]) -> Option<f64> {
    (!values.is_empty())
        .then(|| (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt())
}

/// The angle in radians of the rotation that takes `a` to `b`.
pub fn rotation_distance(a: &Rotation, b: &Rotation) -> f64 {
    a.angle_to(b)
}

/// Wraps an angle to (−π, π].
pub fn wrap_angle(angle: f64) -> f64 {
    let wrapped = angle.rem_euclid(std::f64::consts::TAU);
    if wrapped > std::f64::consts::PI {
        wrapped - std::f64::consts::TAU
    } else {
        wrapped
    }
}

/// Skew-symmetric matrix `[v]×` with `[v]× w = v × w`.
pub fn skew(v: &Vec3) -> Mat3 {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn rpy_matches_urdf_convention() {
        let (r, p, y) = (0.3, -0.7, 1.9);
        let expected = rot_z(y) * rot_y(p) * rot_x(r);
        assert_relative_eq!(rotation_from_rpy(r, p, y), expected, epsilon = 1e-15);
        let back = rpy_from_rotation(&expected);
        assert_relative_eq!(back[0], r, epsilon = 1e-12);
        assert_relative_eq!(back[1], p, epsilon = 1e-12);
        assert_relative_eq!(back[2], y, epsilon = 1e-12);
    }

    /// Near and at gimbal lock the angles still reproduce the rotation to rounding.
    #[test]
    fn angle_extraction_is_accurate_at_gimbal_lock() {
        let half_pi = std::f64::consts::FRAC_PI_2;
        for offset in [0.0, 1e-12, 1e-9, 1e-7, 1e-4, -1e-9] {
            for (r, y) in [(0.3, -1.1), (2.0, 0.0), (-3.0, 3.0)] {
                let rotation = rotation_from_rpy(r, half_pi + offset, y);
                let [r2, p2, y2] = rpy_from_rotation(&rotation);
                assert!(
                    rotation.angle_to(&rotation_from_rpy(r2, p2, y2)) < 1e-14,
                    "{offset}"
                );
                let rotation = rot_x(r) * rot_y(-half_pi + offset) * rot_z(y);
                let [a, b, c] = xyz_angles_from_rotation(&rotation);
                assert!(
                    rotation.angle_to(&(rot_x(a) * rot_y(b) * rot_z(c))) < 1e-14,
                    "{offset}"
                );
            }
        }
    }

    #[test]
    fn xyz_angles_round_trip() {
        let (a, b, c) = (-1.2, 0.4, 2.5);
        let rotation = rot_x(a) * rot_y(b) * rot_z(c);
        let [a2, b2, c2] = xyz_angles_from_rotation(&rotation);
        assert_relative_eq!(a2, a, epsilon = 1e-12);
        assert_relative_eq!(b2, b, epsilon = 1e-12);
        assert_relative_eq!(c2, c, epsilon = 1e-12);
    }

    #[test]
    fn wrap_angle_range() {
        assert_relative_eq!(wrap_angle(3.0 * std::f64::consts::PI), std::f64::consts::PI);
        assert_relative_eq!(wrap_angle(-0.5), -0.5);
        assert_relative_eq!(
            wrap_angle(7.0),
            7.0 - std::f64::consts::TAU,
            epsilon = 1e-15
        );
    }
}

/// A rigid transform stored as a rotation matrix and a translation: the fast form used inside
/// forward kinematics, where a joint rotation about z touches only two columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// Rotation matrix.
    pub rotation: Mat3,
    /// Translation.
    pub translation: Vec3,
}

impl Transform {
    /// The identity.
    pub fn identity() -> Self {
        Self {
            rotation: Mat3::identity(),
            translation: Vec3::zeros(),
        }
    }

    /// From a [`Pose`].
    pub fn from_pose(pose: &Pose) -> Self {
        Self {
            rotation: *pose.rotation.to_rotation_matrix().matrix(),
            translation: pose.translation.vector,
        }
    }

    /// To a [`Pose`].
    pub fn to_pose(&self) -> Pose {
        let rotation = nalgebra::Rotation3::from_matrix_unchecked(self.rotation);
        Isometry3::from_parts(
            Translation3::from(self.translation),
            UnitQuaternion::from_rotation_matrix(&rotation),
        )
    }

    /// `self · other`. Written out element by element (the same sums in the same order as
    /// nalgebra's product, which is not unrolled as well for 3 × 3): this and
    /// [`Self::rotated_z`] are all the arithmetic of forward kinematics.
    #[inline(always)]
    pub fn then(&self, other: &Transform) -> Transform {
        // Column-major: a[column][row].
        let a = &self.rotation.data.0;
        let b = &other.rotation.data.0;
        let t = &other.translation;
        let row = |i: usize, x: [f64; 3]| a[0][i] * x[0] + a[1][i] * x[1] + a[2][i] * x[2];
        let column = |x: &[f64; 3]| [row(0, *x), row(1, *x), row(2, *x)];
        let translation = [t.x, t.y, t.z];
        let moved = column(&translation);
        Transform {
            rotation: Mat3::from_data(nalgebra::ArrayStorage([
                column(&b[0]),
                column(&b[1]),
                column(&b[2]),
            ])),
            translation: Vec3::new(
                moved[0] + self.translation.x,
                moved[1] + self.translation.y,
                moved[2] + self.translation.z,
            ),
        }
    }

    /// `self · Rz(angle)`.
    #[inline]
    pub fn rotated_z(&self, angle: f64) -> Transform {
        let (s, c) = sin_cos(angle);
        self.rotated_z_by(s, c)
    }

    /// `self · Rz(θ)` given `sin θ` and `cos θ`.
    #[inline(always)]
    pub fn rotated_z_by(&self, s: f64, c: f64) -> Transform {
        let x = self.rotation.column(0).into_owned();
        let y = self.rotation.column(1).into_owned();
        let mut rotation = self.rotation;
        rotation.set_column(0, &(x * c + y * s));
        rotation.set_column(1, &(y * c - x * s));
        Transform {
            rotation,
            translation: self.translation,
        }
    }

    /// `self · Trans(0, 0, distance)`.
    #[inline]
    pub fn translated_z(&self, distance: f64) -> Transform {
        Transform {
            rotation: self.rotation,
            translation: self.translation + self.rotation.column(2) * distance,
        }
    }
}

/// The 6-vector pose error `[p_a − p_b; log(R_a·R_bᵀ)]` in the common (base) frame: metres,
/// then the rotation vector (axis · angle, rad) that takes `b`'s orientation to `a`'s. This is
/// the error the identification Jacobian predicts (not a difference of Euler angles).
pub fn pose_error(a: &Pose, b: &Pose) -> nalgebra::Vector6<f64> {
    let dp = a.translation.vector - b.translation.vector;
    let dr = (a.rotation * b.rotation.inverse()).scaled_axis();
    nalgebra::Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}
