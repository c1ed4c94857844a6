//! The analytic identification Jacobian of the MCPC model (paper section 2.3, eq. (5)–(17)).
//!
//! For a tool pose `T` and a parameter `e`, the column `∂T/∂e` is a twist in the base frame:
//! the first three rows are the change of the tool position (m per unit of `e`), the last
//! three the small rotation (rad per unit of `e`) with `R_measured ≈ (I + [δ]×)·R_model`. This
//! is eq. (14)–(17) of the paper written directly in the base frame: α of frame i rotates
//! everything after it about the x axis of `P·Rz(φ)`, β about the y axis of
//! `P·Rz(φ)·Rx(α)` — both through the origin of `P`, the previous frame moved by its joint —
//! and x, y translate along the frame's own x and y. Tool parameters work the same way, with
//! γ about the tool's z and x, y, z along the tool's axes. See `docs/identification.md`.

use super::mcpc::{FrameKind, McpcModel};
use crate::math::{Pose, Transform, Vec3};
use nalgebra::DMatrix;

/// A tool pose with its identification Jacobian.
#[derive(Debug, Clone)]
pub struct ToolJacobian {
    /// The tool pose in the base frame.
    pub pose: Pose,
    /// 6 × [`McpcModel::parameter_count`]: rows x, y, z (m) then rotation x, y, z (rad), in the
    /// base frame; zero columns for parameters off the tool's chain.
    pub jacobian: DMatrix<f64>,
}

impl McpcModel {
    /// The previous frame moved by its joint, `P = Σ_p·Q(θ_p)`, for frame or tool parent `parent`.
    fn moved_parent(&self, parent: Option<usize>, q: &[f64], frames: &[Transform]) -> Transform {
        match parent {
            Some(p) => self.moved(p, q, &frames[p]),
            None => *self.world_from_base_transform(),
        }
    }

    /// Writes the Jacobian columns of tool `tool` into `jacobian` (6 × parameter_count, zeroed
    /// by the caller) and returns the tool transform. `frames` are [`McpcModel::frame_transforms`].
    fn fill_tool_jacobian(
        &self,
        tool: usize,
        q: &[f64],
        frames: &[Transform],
        jacobian: &mut DMatrix<f64>,
    ) -> Transform {
        let last = self.moved_parent(self.tools()[tool].parent, q, frames);
        let tool_transform = last.then(self.tool_constant(tool));
        let tip = tool_transform.translation;
        let mut rotation_column = |column: usize, axis: Vec3, through: Vec3| {
            let linear = axis.cross(&(tip - through));
            for row in 0..3 {
                jacobian[(row, column)] = linear[row];
                jacobian[(row + 3, column)] = axis[row];
            }
        };
        for &frame in self.tool_chain(tool) {
            let previous = self.moved_parent(self.frames()[frame].parent, q, frames);
            let [alpha_axis, beta_axis] = self.frame_axes(frame);
            let offset = self.frame_parameter_offset(frame);
            rotation_column(offset, previous.rotation * alpha_axis, previous.translation);
            rotation_column(
                offset + 1,
                previous.rotation * beta_axis,
                previous.translation,
            );
        }
        let [alpha_axis, beta_axis, gamma_axis] = self.tool_axes(tool);
        let offset = self.tool_parameter_offset(tool);
        rotation_column(offset, last.rotation * alpha_axis, last.translation);
        rotation_column(offset + 1, last.rotation * beta_axis, last.translation);
        rotation_column(offset + 2, last.rotation * gamma_axis, last.translation);
        // Translations: along the frame's own x, y (revolute frames) and the tool's x, y, z.
        for &frame in self.tool_chain(tool) {
            if self.frames()[frame].kind == FrameKind::Revolute {
                let offset = self.frame_parameter_offset(frame);
                for (k, column) in [offset + 2, offset + 3].into_iter().enumerate() {
                    let direction = frames[frame].rotation.column(k);
                    for row in 0..3 {
                        jacobian[(row, column)] = direction[row];
                    }
                }
            }
        }
        for k in 0..3 {
            let direction = tool_transform.rotation.column(k);
            for row in 0..3 {
                jacobian[(row, offset + 3 + k)] = direction[row];
            }
        }
        tool_transform
    }

    /// Tool pose and identification Jacobian of tool `tool` at configuration `q`.
    pub fn tool_jacobian(&self, tool: usize, q: &[f64]) -> ToolJacobian {
        let frames = self.frame_transforms(q);
        let mut jacobian = DMatrix::zeros(6, self.parameter_count());
        let transform = self.fill_tool_jacobian(tool, q, &frames, &mut jacobian);
        ToolJacobian {
            pose: transform.to_pose(),
            jacobian,
        }
    }

    /// Poses and Jacobians of every tool at configuration `q`; shared frames computed once
    /// (eq. (16): the coupled branch's columns are shared by the arms).
    pub fn tool_jacobians(&self, q: &[f64]) -> Vec<ToolJacobian> {
        let frames = self.frame_transforms(q);
        (0..self.tools().len())
            .map(|tool| {
                let mut jacobian = DMatrix::zeros(6, self.parameter_count());
                let transform = self.fill_tool_jacobian(tool, q, &frames, &mut jacobian);
                ToolJacobian {
                    pose: transform.to_pose(),
                    jacobian,
                }
            })
            .collect()
    }
}
