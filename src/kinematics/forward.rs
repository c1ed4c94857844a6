//! Forward kinematics of the MCPC model (paper eq. (3)–(4)).

use super::mcpc::McpcModel;
use crate::error::Result;
use crate::math::{pose, rot_z, Pose, Vec3};
use crate::tree::KinematicTree;

/// Moves `pose` by the joint motion Q(θ) of frame `frame` (right-multiplies it).
#[inline]
fn apply_motion(model: &McpcModel, frame: usize, value: f64, pose_in: &Pose) -> Pose {
    match model.frames()[frame].kind {
        super::FrameKind::Revolute => pose_in * pose(Vec3::zeros(), rot_z(value)),
        super::FrameKind::Prismatic => {
            let mut moved = *pose_in;
            moved.translation.vector += pose_in.rotation * Vec3::new(0.0, 0.0, value);
            moved
        }
    }
}

impl McpcModel {
    /// Pose of every MCPC frame Σᵢ in the base (root link) frame at configuration `q`,
    /// before its own joint's motion. `q` has one value per independent tree joint.
    pub fn frame_poses(&self, q: &[f64]) -> Vec<Pose> {
        let mut base_from_frame: Vec<Pose> = Vec::with_capacity(self.frames().len());
        for (index, frame) in self.frames().iter().enumerate() {
            let pose = match frame.parent {
                Some(p) => {
                    apply_motion(self, p, self.joint_value(p, q), &base_from_frame[p])
                        * self.frame_constant(index)
                }
                None => *self.frame_constant(index),
            };
            base_from_frame.push(pose);
        }
        base_from_frame
    }

    /// Pose of tool `tool` in the base frame at configuration `q` (eq. (3)), walking only its
    /// own chain.
    pub fn tool_pose(&self, tool: usize, q: &[f64]) -> Pose {
        let mut base_from_current = Pose::identity();
        let mut previous: Option<usize> = None;
        for &frame in self.tool_chain(tool) {
            if let Some(p) = previous {
                base_from_current =
                    apply_motion(self, p, self.joint_value(p, q), &base_from_current);
            }
            base_from_current *= self.frame_constant(frame);
            previous = Some(frame);
        }
        if let Some(p) = previous {
            base_from_current = apply_motion(self, p, self.joint_value(p, q), &base_from_current);
        }
        base_from_current * self.tool_constant(tool)
    }

    /// Poses of all tools, in [`McpcModel::tools`] order.
    pub fn tool_poses(&self, q: &[f64]) -> Vec<Pose> {
        (0..self.tools().len())
            .map(|t| self.tool_pose(t, q))
            .collect()
    }

    /// Pose of the URDF child link of every frame's joint, from the MCPC model: Σᵢ·Q(θᵢ)·(frame_from_link).
    pub fn link_poses(&self, q: &[f64]) -> Vec<Pose> {
        self.frame_poses(q)
            .iter()
            .enumerate()
            .map(|(i, p)| {
                apply_motion(self, i, self.joint_value(i, q), p) * self.frames()[i].frame_from_link
            })
            .collect()
    }

    /// Checks `q` against the tree the model was built from, then returns the tool poses.
    pub fn checked_tool_poses(&self, tree: &KinematicTree, q: &[f64]) -> Result<Vec<Pose>> {
        tree.check_configuration(q)?;
        Ok(self.tool_poses(q))
    }
}
