//! The observation columns of a measurement CSV row turned into an [`Observation`]: a position,
//! a pose whose orientation is a quaternion, a rotation matrix or URDF roll-pitch-yaw, or three
//! targets (see `docs/file-formats.md`, section 4).

use crate::math::{rotation_from_rpy, Pose, Rotation, Vec3};
use crate::measurement::{frame_from_targets, targets_problem, Observation};
use nalgebra::{Matrix3, Quaternion, Rotation3, Translation3, UnitQuaternion};

/// What each row of a measurement CSV observes; the header's columns decide.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObservationKind {
    /// `x,y,z`: one target's position.
    Position,
    /// `x,y,z,qw,qx,qy,qz`: a full pose, the orientation a unit quaternion (the components are
    /// read by name, so `qx,qy,qz,qw` works too).
    Pose,
    /// `x,y,z,r11,…,r33`: a full pose, the orientation a rotation matrix (`r<row><column>`).
    RotationMatrix,
    /// `x,y,z,roll,pitch,yaw`: a full pose, the orientation URDF roll-pitch-yaw
    /// (`Rz(yaw)·Ry(pitch)·Rx(roll)`).
    RollPitchYaw,
    /// `ax,…,cz`: three targets A, B, C on the tool, turned into a pose (paper section 5.3.1)
    /// whose offset from the URDF tool frame is unknown and must be identified.
    ThreeTargets,
}

/// Every layout, in the order the header is matched against them.
pub(super) const KINDS: [ObservationKind; 5] = [
    ObservationKind::Position,
    ObservationKind::Pose,
    ObservationKind::RotationMatrix,
    ObservationKind::RollPitchYaw,
    ObservationKind::ThreeTargets,
];

/// Every observation column name (never a joint name).
pub(super) const OBSERVATION_COLUMNS: [&str; 28] = [
    "x", "y", "z", "qw", "qx", "qy", "qz", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32",
    "r33", "roll", "pitch", "yaw", "ax", "ay", "az", "bx", "by", "bz", "cx", "cy", "cz",
];

/// The accepted observation layouts, for messages.
pub(super) const LAYOUTS: &str = "x,y,z (a position); x,y,z with qw,qx,qy,qz (a pose, unit \
    quaternion, any column order), r11..r33 (a pose, rotation matrix) or roll,pitch,yaw (a pose, \
    URDF roll-pitch-yaw); or ax,ay,az,bx,by,bz,cx,cy,cz (three targets A, B, C)";

impl ObservationKind {
    /// The observation columns of this layout, in file order.
    pub fn columns(self) -> &'static [&'static str] {
        match self {
            ObservationKind::Position => &["x", "y", "z"],
            ObservationKind::Pose => &["x", "y", "z", "qw", "qx", "qy", "qz"],
            ObservationKind::RotationMatrix => &[
                "x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33",
            ],
            ObservationKind::RollPitchYaw => &["x", "y", "z", "roll", "pitch", "yaw"],
            ObservationKind::ThreeTargets => {
                &["ax", "ay", "az", "bx", "by", "bz", "cx", "cy", "cz"]
            }
        }
    }

    /// Whether rows of this layout observe a full pose.
    pub fn is_pose(self) -> bool {
        self != ObservationKind::Position
    }
}

/// What a value of observation column `name` is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ColumnQuantity {
    /// A position or target coordinate (the file's length unit).
    Length,
    /// A roll, pitch or yaw angle (the file's rotation unit).
    Angle,
    /// A quaternion component or rotation matrix entry.
    Plain,
}

/// The quantity of observation column `name`.
pub(super) fn column_quantity(name: &str) -> ColumnQuantity {
    match name {
        "roll" | "pitch" | "yaw" => ColumnQuantity::Angle,
        _ if name.starts_with('q') || name.starts_with('r') => ColumnQuantity::Plain,
        _ => ColumnQuantity::Length,
    }
}

/// How far a rotation matrix may be from orthonormal (largest entry of `RᵀR − I`): a matrix
/// printed with 4 significant digits is within 1e-3; a transposed or scaled one is far off.
pub const ROTATION_MATRIX_TOLERANCE: f64 = 1e-3;

/// The observation of `values` (SI, in [`ObservationKind::columns`] order), or what is wrong
/// with them and which columns say it.
pub(super) fn observation(
    kind: ObservationKind,
    values: &[f64],
) -> std::result::Result<Observation, (&'static str, String)> {
    let position = Translation3::new(values[0], values[1], values[2]);
    let pose =
        |rotation: UnitQuaternion<f64>| Observation::Pose(Pose::from_parts(position, rotation));
    match kind {
        ObservationKind::Position => Ok(Observation::Position(position.vector)),
        ObservationKind::Pose => {
            let raw = Quaternion::new(values[3], values[4], values[5], values[6]);
            let norm = raw.norm();
            if (norm - 1.0).abs() > 1e-3 {
                return Err((
                    "qw",
                    format!(
                        "the quaternion (qw,qx,qy,qz) = ({}, {}, {}, {}) has norm {norm:.6}, not 1; \
                         check the column names (qw is the scalar part; the columns are read by name, in any order) \
                         and that it is a unit quaternion",
                        values[3], values[4], values[5], values[6]
                    ),
                ));
            }
            Ok(pose(UnitQuaternion::from_quaternion(raw)))
        }
        ObservationKind::RotationMatrix => {
            let matrix = Matrix3::from_row_slice(&values[3..12]);
            let gap = (matrix.transpose() * matrix - Matrix3::identity())
                .abs()
                .max();
            if gap.is_nan() || gap > ROTATION_MATRIX_TOLERANCE || matrix.determinant() <= 0.0 {
                return Err((
                    "r11..r33",
                    format!(
                        "r11..r33 is not a rotation matrix (RᵀR differs from the identity by up \
                         to {gap:.2e}, determinant {:.4}); give the orientation's rotation matrix, \
                         r<row><column>, to at least 4 significant digits",
                        matrix.determinant()
                    ),
                ));
            }
            // The nearest rotation: printed digits make the matrix slightly non-orthonormal.
            let rotation = Rotation3::from_matrix_eps(&matrix, 1e-12, 100, Rotation3::identity());
            Ok(pose(UnitQuaternion::from_rotation_matrix(&rotation)))
        }
        ObservationKind::RollPitchYaw => {
            let rotation: Rotation = rotation_from_rpy(values[3], values[4], values[5]);
            Ok(pose(rotation))
        }
        ObservationKind::ThreeTargets => {
            let [a, b, c] = [0, 3, 6].map(|i| Vec3::new(values[i], values[i + 1], values[i + 2]));
            // The tolerance check comes first: it also rules out `None` from the frame.
            let frame = match targets_problem(&a, &b, &c) {
                None => frame_from_targets(&a, &b, &c)
                    .ok_or_else(|| "the targets define no frame".to_owned()),
                Some(why) => Err(why),
            };
            frame.map(Observation::Pose).map_err(|why| {
                (
                    "ax..cz",
                    format!(
                        "collinear or coincident targets: {why}; A, B and C must be three \
                         distinct reflectors on the tool, not on one line"
                    ),
                )
            })
        }
    }
}
