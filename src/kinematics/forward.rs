//! Forward kinematics of the MCPC model (paper eq. (3)–(4)).
//!
//! Internally frames are [`Transform`]s (rotation matrix + translation): a joint's motion
//! about z then touches two columns, which is what makes this fast.

use super::mcpc::{FrameKind, McpcModel};
use crate::error::Result;
use crate::math::{Pose, Transform};
use crate::tree::KinematicTree;

impl McpcModel {
    /// `transform · Q(θ)` for the joint of frame `frame` at configuration `q`.
    #[inline]
    pub(crate) fn moved(&self, frame: usize, q: &[f64], transform: &Transform) -> Transform {
        let value = self.joint_value(frame, q);
        match self.frames()[frame].kind {
            FrameKind::Revolute => transform.rotated_z(value),
            FrameKind::Prismatic => transform.translated_z(value),
        }
    }

    /// Every frame Σᵢ in the measurement frame ([`McpcModel::world_from_base`], the base frame
    /// unless set), before its own joint's motion (fast form).
    pub fn frame_transforms(&self, q: &[f64]) -> Vec<Transform> {
        let mut base_from_frame: Vec<Transform> = Vec::with_capacity(self.frames().len());
        for (index, frame) in self.frames().iter().enumerate() {
            let transform = match frame.parent {
                Some(p) => self
                    .moved(p, q, &base_from_frame[p])
                    .then(self.frame_constant(index)),
                None => self
                    .world_from_base_transform()
                    .then(self.frame_constant(index)),
            };
            base_from_frame.push(transform);
        }
        base_from_frame
    }

    /// Pose of every MCPC frame Σᵢ in the base (root link) frame at configuration `q`,
    /// before its own joint's motion. `q` has one value per independent tree joint.
    pub fn frame_poses(&self, q: &[f64]) -> Vec<Pose> {
        self.frame_transforms(q)
            .iter()
            .map(Transform::to_pose)
            .collect()
    }

    /// The tool frame given the base_from_frame transforms of all frames.
    #[inline]
    fn tool_from_frames(&self, tool: usize, q: &[f64], frames: &[Transform]) -> Transform {
        match self.tools()[tool].parent {
            Some(last) => self
                .moved(last, q, &frames[last])
                .then(self.tool_constant(tool)),
            None => self
                .world_from_base_transform()
                .then(self.tool_constant(tool)),
        }
    }

    /// Pose of tool `tool` in the base frame at configuration `q` (eq. (3)), walking only its
    /// own chain.
    pub fn tool_pose(&self, tool: usize, q: &[f64]) -> Pose {
        let mut current = *self.world_from_base_transform();
        let mut previous: Option<usize> = None;
        for &frame in self.tool_chain(tool) {
            if let Some(p) = previous {
                current = self.moved(p, q, &current);
            }
            current = current.then(self.frame_constant(frame));
            previous = Some(frame);
        }
        if let Some(p) = previous {
            current = self.moved(p, q, &current);
        }
        current.then(self.tool_constant(tool)).to_pose()
    }

    /// Poses of all tools, in [`McpcModel::tools`] order (eq. (4)); shared frames (the coupled
    /// branch) are computed once.
    pub fn tool_poses(&self, q: &[f64]) -> Vec<Pose> {
        let frames = self.frame_transforms(q);
        (0..self.tools().len())
            .map(|t| self.tool_from_frames(t, q, &frames).to_pose())
            .collect()
    }

    /// Pose of the URDF child link of every frame's joint, from the MCPC model:
    /// Σᵢ·Q(θᵢ)·(frame_from_link).
    pub fn link_poses(&self, q: &[f64]) -> Vec<Pose> {
        self.frame_transforms(q)
            .iter()
            .enumerate()
            .map(|(i, t)| self.moved(i, q, t).to_pose() * self.frames()[i].frame_from_link)
            .collect()
    }

    /// Checks `q` against the tree the model was built from, then returns the tool poses.
    pub fn checked_tool_poses(&self, tree: &KinematicTree, q: &[f64]) -> Result<Vec<Pose>> {
        tree.check_configuration(q)?;
        Ok(self.tool_poses(q))
    }
}
