//! The analytic identification Jacobian of the MCPC model (paper section 2.3, eq. (5)–(17)).
//!
//! For a tool pose `T` and a parameter `e`, the column `∂T/∂e` is a twist in the base frame:
//! the first three rows are the change of the tool position (m per unit of `e`), the last
//! three the small rotation (rad per unit of `e`) with `R_measured ≈ (I + [δ]×)·R_model`. This
//! is eq. (14)–(17) of the paper written directly in the base frame: α of frame i rotates
//! everything after it about the x axis of `P·Rz(φ)`, β about the y axis of
//! `P·Rz(φ)·Rx(α)` — both through the origin of `P`, the frame the constant part of frame i is
//! applied to (the previous frame moved by its joint) — and x, y translate along the frame's
//! own x and y. Tool parameters work the same way, with γ about the tool's z and x, y, z along
//! the tool's axes. The same formulas hold on a deflected chain ([`ChainFrames`] from the
//! flexibility model), which keeps the Jacobian accurate when the robot bends.
//! See `docs/identification.md`.

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

/// The frames of one configuration that the Jacobian is built from, in the measurement frame.
#[derive(Debug, Clone)]
pub struct ChainFrames {
    /// For each MCPC frame, the frame its constant part is applied to (`P`: the previous frame
    /// moved by its joint, and by any deformation).
    pub previous: Vec<Transform>,
    /// Each MCPC frame Σᵢ = P·constant.
    pub frames: Vec<Transform>,
    /// For each tool, the frame its constant part is applied to.
    pub tool_previous: Vec<Transform>,
    /// Each tool frame.
    pub tools: Vec<Transform>,
}

impl McpcModel {
    /// The rigid chain at configuration `q`.
    pub fn chain_frames(&self, q: &[f64]) -> ChainFrames {
        let frames = self.frame_transforms(q);
        let moved_parent = |parent: Option<usize>| match parent {
            Some(p) => self.moved(p, q, &frames[p]),
            None => *self.world_from_base_transform(),
        };
        let previous: Vec<Transform> = self
            .frames()
            .iter()
            .map(|f| moved_parent(f.parent))
            .collect();
        let tool_previous: Vec<Transform> = self
            .tools()
            .iter()
            .map(|t| moved_parent(t.parent))
            .collect();
        let tools = tool_previous
            .iter()
            .enumerate()
            .map(|(t, p)| p.then(self.tool_constant(t)))
            .collect();
        ChainFrames {
            previous,
            frames,
            tool_previous,
            tools,
        }
    }

    /// Writes the Jacobian columns of tool `tool` into `jacobian` (6 × parameter_count, zeroed
    /// by the caller).
    fn fill_tool_jacobian(&self, tool: usize, chain: &ChainFrames, jacobian: &mut DMatrix<f64>) {
        let tip = chain.tools[tool].translation;
        let mut rotation_column = |column: usize, axis: Vec3, through: Vec3| {
            let linear = axis.cross(&(tip - through));
            for row in 0..3 {
                jacobian[(row, column)] = linear[row];
                jacobian[(row + 3, column)] = axis[row];
            }
        };
        for &frame in self.tool_chain(tool) {
            let previous = &chain.previous[frame];
            let [alpha_axis, beta_axis] = self.frame_axes(frame);
            let offset = self.frame_parameter_offset(frame);
            rotation_column(offset, previous.rotation * alpha_axis, previous.translation);
            rotation_column(
                offset + 1,
                previous.rotation * beta_axis,
                previous.translation,
            );
        }
        let last = &chain.tool_previous[tool];
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
                    let direction = chain.frames[frame].rotation.column(k);
                    for row in 0..3 {
                        jacobian[(row, column)] = direction[row];
                    }
                }
            }
        }
        for k in 0..3 {
            let direction = chain.tools[tool].rotation.column(k);
            for row in 0..3 {
                jacobian[(row, offset + 3 + k)] = direction[row];
            }
        }
    }

    /// Tool poses and identification Jacobians of every tool on a given chain.
    pub fn jacobians_on(&self, chain: &ChainFrames) -> Vec<ToolJacobian> {
        (0..self.tools().len())
            .map(|tool| {
                let mut jacobian = DMatrix::zeros(6, self.parameter_count());
                self.fill_tool_jacobian(tool, chain, &mut jacobian);
                ToolJacobian {
                    pose: chain.tools[tool].to_pose(),
                    jacobian,
                }
            })
            .collect()
    }

    /// Tool pose and identification Jacobian of tool `tool` at configuration `q`.
    pub fn tool_jacobian(&self, tool: usize, q: &[f64]) -> ToolJacobian {
        let chain = self.chain_frames(q);
        let mut jacobian = DMatrix::zeros(6, self.parameter_count());
        self.fill_tool_jacobian(tool, &chain, &mut jacobian);
        ToolJacobian {
            pose: chain.tools[tool].to_pose(),
            jacobian,
        }
    }

    /// Poses and Jacobians of every tool at configuration `q`; shared frames computed once
    /// (eq. (16): the coupled branch's columns are shared by the arms).
    pub fn tool_jacobians(&self, q: &[f64]) -> Vec<ToolJacobian> {
        self.jacobians_on(&self.chain_frames(q))
    }
}
