//! The position of one target fixed on a tool (a single laser-tracker reflector, a
//! motion-capture marker): 3 rows, x, y, z (m) in the measurement frame.

use super::{MeasurementKind, RobotState, RowKind};
use crate::error::Result;
use crate::math::{Pose, Vec3};
use crate::measurement::Observation;
use nalgebra::{DMatrix, DMatrixViewMut};

/// The rows of a position: three coordinates (m).
const ROWS: [RowKind; 3] = [RowKind::Position; 3];

/// The measured point is its own kind: `measured − predicted tool origin`.
impl MeasurementKind for Vec3 {
    fn name(&self) -> &'static str {
        "position"
    }

    fn row_kinds(&self) -> &'static [RowKind] {
        &ROWS
    }

    fn is_finite(&self) -> bool {
        self.iter().all(|v| v.is_finite())
    }

    fn residual(&self, at: &RobotState<'_>, out: &mut [f64]) -> Result<()> {
        let difference = self - at.tool_pose(at.tool)?.translation.vector;
        for (k, value) in out.iter_mut().take(3).enumerate() {
            *value = difference[k] - at.offset.map_or(0.0, |o| o[k]);
        }
        Ok(())
    }

    fn jacobian(
        &self,
        at: &RobotState<'_>,
        columns: &[usize],
        out: &mut DMatrixViewMut<'_, f64>,
    ) -> Result<()> {
        super::pose::copy_tool_rows(at, columns, 3, out)
    }

    fn tool_motion_jacobian(&self, at: &RobotState<'_>, tool: usize) -> DMatrix<f64> {
        if tool == at.tool {
            DMatrix::identity(3, 6)
        } else {
            DMatrix::zeros(3, 6)
        }
    }

    fn measured_point(&self) -> Option<Vec3> {
        Some(*self)
    }

    fn in_frame(&self, new_from_old: &Pose) -> Observation {
        Observation::Position(new_from_old.transform_point(&(*self).into()).coords)
    }

    fn noise_free(&self, at: &RobotState<'_>) -> Result<Observation> {
        let origin = at.tool_pose(at.tool)?.translation.vector;
        Ok(Observation::Position(match at.offset {
            Some(offset) => origin + offset.fixed_rows::<3>(0),
            None => origin,
        }))
    }
}
