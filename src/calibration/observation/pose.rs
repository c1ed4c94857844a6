//! A full tool frame (six rows: position x, y, z (m), then the rotation vector x, y, z (rad),
//! in the measurement frame): a tracker's 6-DoF probe, or the three-target frame of the
//! paper's section 5.3.1, which the reader turns into a pose
//! ([`crate::measurement::frame_from_targets`]).

use super::{MeasurementKind, RobotState, RowKind};
use crate::error::Result;
use crate::math::{pose_error, Pose, Vec3};
use crate::measurement::Observation;
use nalgebra::{DMatrix, DMatrixViewMut, Translation3, UnitQuaternion, Vector3};

/// The rows of a pose: three coordinates (m), then three rotation components (rad).
const ROWS: [RowKind; 6] = [
    RowKind::Position,
    RowKind::Position,
    RowKind::Position,
    RowKind::Rotation,
    RowKind::Rotation,
    RowKind::Rotation,
];

/// The measured frame is its own kind: `pose_error(measured, predicted tool pose)`.
impl MeasurementKind for Pose {
    fn name(&self) -> &'static str {
        "pose"
    }

    fn row_kinds(&self) -> &'static [RowKind] {
        &ROWS
    }

    fn is_finite(&self) -> bool {
        self.translation
            .vector
            .iter()
            .chain(self.rotation.coords.iter())
            .all(|v| v.is_finite())
    }

    fn residual(&self, at: &RobotState<'_>, out: &mut [f64]) -> Result<()> {
        let mut error = pose_error(self, at.tool_pose(at.tool)?);
        if let Some(offset) = at.offset {
            error -= offset;
        }
        for (value, e) in out.iter_mut().zip(error.iter()) {
            *value = *e;
        }
        Ok(())
    }

    fn jacobian(
        &self,
        at: &RobotState<'_>,
        columns: &[usize],
        out: &mut DMatrixViewMut<'_, f64>,
    ) -> Result<()> {
        copy_tool_rows(at, columns, 6, out)
    }

    fn tool_motion_jacobian(&self, at: &RobotState<'_>, tool: usize) -> DMatrix<f64> {
        if tool == at.tool {
            DMatrix::identity(6, 6)
        } else {
            DMatrix::zeros(6, 6)
        }
    }

    fn measured_point(&self) -> Option<Vec3> {
        Some(self.translation.vector)
    }

    fn measured_frame(&self) -> Option<Pose> {
        Some(*self)
    }

    fn in_frame(&self, new_from_old: &Pose) -> Observation {
        Observation::Pose(new_from_old * self)
    }

    fn noise_free(&self, at: &RobotState<'_>) -> Result<Observation> {
        let predicted = at.tool_pose(at.tool)?;
        let Some(offset) = at.offset else {
            return Ok(Observation::Pose(*predicted));
        };
        // The pose whose `pose_error` from the prediction is the offset exactly.
        let rotation =
            UnitQuaternion::from_scaled_axis(Vector3::new(offset[3], offset[4], offset[5]));
        Ok(Observation::Pose(Pose::from_parts(
            Translation3::from(predicted.translation.vector + offset.fixed_rows::<3>(0)),
            rotation * predicted.rotation,
        )))
    }
}

/// The first `rows` rows of the measured tool's Jacobian, at the model's parameters among
/// `columns`; nuisance columns (past the model's parameters) are zero: today's kinds have
/// their nuisance (measurement frame, tool offsets) inside the model.
pub(super) fn copy_tool_rows(
    at: &RobotState<'_>,
    columns: &[usize],
    rows: usize,
    out: &mut DMatrixViewMut<'_, f64>,
) -> Result<()> {
    let tool = at.tool_jacobian(at.tool)?;
    let (stride, model_columns) = tool.jacobian.shape();
    let from = tool.jacobian.as_slice();
    for (column, &parameter) in columns.iter().enumerate() {
        let mut to = out.column_mut(column);
        // A column of the view is contiguous: copied as a slice (nalgebra's view iterators
        // and indexing step element by element).
        let to = &mut to.as_mut_slice()[..rows];
        if parameter < model_columns {
            to.copy_from_slice(&from[parameter * stride..][..rows]);
        } else {
            to.fill(0.0);
        }
    }
    Ok(())
}
