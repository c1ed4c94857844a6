//! Forward kinematics of the MCPC model (paper eq. (3)–(4)).
//!
//! Internally frames are [`Transform`]s (rotation matrix + translation): a joint's motion
//! about z then touches two columns, which is what makes this fast.

use super::mcpc::{FrameKind, McpcModel};
use crate::error::Result;
use crate::math::{sin_cos_all, Pose, Transform};
use crate::tree::KinematicTree;

/// Reusable buffers of [`McpcModel::tool_transforms_into`].
#[derive(Debug, Clone, Default)]
pub struct ForwardFrames {
    /// Each MCPC frame moved by its own joint, Σᵢ·Q(θᵢ), in the measurement frame.
    pub moved: Vec<Transform>,
    /// Each tool frame in the measurement frame, in [`McpcModel::tools`] order.
    pub tools: Vec<Transform>,
    motions: JointMotions,
}

thread_local! {
    /// The buffers of [`McpcModel::tool_poses`] (not reentrant: nothing it calls uses them).
    static SCRATCH: std::cell::RefCell<ForwardFrames> = std::cell::RefCell::default();
}

/// The joint value of every MCPC frame at one configuration, with its sine and cosine, all
/// computed in one vectorised pass ([`sin_cos_all`]; reusable buffers).
#[derive(Debug, Clone, Default)]
pub(crate) struct JointMotions {
    values: Vec<f64>,
    sines: Vec<f64>,
    cosines: Vec<f64>,
    /// Work space of [`Self::fill_frames`]: the chosen frames' values, sines and cosines.
    picked: [Vec<f64>; 3],
}

impl JointMotions {
    /// The joint values of `model`'s frames at `q`.
    pub(crate) fn fill(&mut self, model: &McpcModel, q: &[f64]) {
        self.values.clear();
        self.values
            .extend((0..model.frames().len()).map(|frame| model.joint_value(frame, q)));
        sin_cos_all(&self.values, &mut self.sines, &mut self.cosines);
    }

    /// [`Self::fill`] for `frames` only (the same values for those; the other frames keep
    /// what they held): one tool's chain needs the sines of its own joints, not the others'.
    pub(crate) fn fill_frames(&mut self, model: &McpcModel, q: &[f64], frames: &[&[usize]]) {
        let count = model.frames().len();
        for buffer in [&mut self.values, &mut self.sines, &mut self.cosines] {
            buffer.resize(count, 0.0);
        }
        let [values, sines, cosines] = &mut self.picked;
        values.clear();
        values.extend(
            frames
                .iter()
                .flat_map(|f| f.iter())
                .map(|&frame| model.joint_value(frame, q)),
        );
        sin_cos_all(values, sines, cosines);
        for (k, &frame) in frames.iter().flat_map(|f| f.iter()).enumerate() {
            self.values[frame] = values[k];
            self.sines[frame] = sines[k];
            self.cosines[frame] = cosines[k];
        }
    }

    /// `transform · Q(θ)` for the joint of frame `frame` (the same bits as
    /// [`McpcModel::moved`]).
    #[inline(always)]
    pub(crate) fn apply(
        &self,
        model: &McpcModel,
        frame: usize,
        transform: &Transform,
    ) -> Transform {
        match model.frames()[frame].kind {
            FrameKind::Revolute => transform.rotated_z_by(self.sines[frame], self.cosines[frame]),
            FrameKind::Prismatic => transform.translated_z(self.values[frame]),
        }
    }
}

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
        let world_from_root = self.world_from_root_transform(q);
        let mut base_from_frame: Vec<Transform> = Vec::with_capacity(self.frames().len());
        for (index, frame) in self.frames().iter().enumerate() {
            let transform = match frame.parent {
                Some(p) => self
                    .moved(p, q, &base_from_frame[p])
                    .then(self.frame_constant(index)),
                None => world_from_root.then(self.frame_constant(index)),
            };
            base_from_frame.push(transform);
        }
        base_from_frame
    }

    /// [`Self::frame_transforms`] and every frame after its own joint's motion, Σᵢ·Q(θᵢ):
    /// the same values, each joint's motion applied once (a parent's moved frame is shared by
    /// its children); written into `frames` and `moved` (cleared first: their buffers are
    /// reused). The joints' sines and cosines are left in `motions` (all at once, the same
    /// bits as one by one) for whatever else moves the same joints at `q`.
    pub(crate) fn frame_and_moved_transforms_into(
        &self,
        q: &[f64],
        frames: &mut Vec<Transform>,
        moved: &mut Vec<Transform>,
        motions: &mut JointMotions,
    ) {
        let world_from_root = self.world_from_root_transform(q);
        motions.fill(self, q);
        frames.clear();
        moved.clear();
        for (index, frame) in self.frames().iter().enumerate() {
            let transform = match frame.parent {
                Some(p) => moved[p].then(self.frame_constant(index)),
                None => world_from_root.then(self.frame_constant(index)),
            };
            moved.push(motions.apply(self, index, &transform));
            frames.push(transform);
        }
    }

    /// Pose of every MCPC frame Σᵢ in the base (root link) frame at configuration `q`,
    /// before its own joint's motion. `q` has one value per independent tree joint.
    pub fn frame_poses(&self, q: &[f64]) -> Vec<Pose> {
        self.frame_transforms(q)
            .iter()
            .map(Transform::to_pose)
            .collect()
    }

    /// Pose of tool `tool` in the base frame at configuration `q` (eq. (3)), walking only its
    /// own chain.
    pub fn tool_pose(&self, tool: usize, q: &[f64]) -> Pose {
        let mut current = self.world_from_root_transform(q);
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
    /// branch) are computed once, each joint's motion is applied once.
    pub fn tool_poses(&self, q: &[f64]) -> Vec<Pose> {
        SCRATCH.with(|scratch| {
            let mut frames = scratch.borrow_mut();
            self.tool_transforms_into(q, &mut frames);
            frames.tools.iter().map(Transform::to_pose).collect()
        })
    }

    /// Forward kinematics of every tool into reusable buffers, in the fast form (rotation
    /// matrix + translation, the form Pinocchio's frame placements have): no allocation once
    /// `frames` has its size. `frames.tools` ends up holding the same poses as
    /// [`Self::tool_poses`] (bit for bit: the same products in the same order).
    pub fn tool_transforms_into(&self, q: &[f64], frames: &mut ForwardFrames) {
        let world_from_root = self.world_from_root_transform(q);
        self.moved_frames_into(q, &world_from_root, &mut frames.moved, &mut frames.motions);
        frames
            .tools
            .resize(self.tools().len(), Transform::identity());
        for (tool, target) in frames.tools.iter_mut().enumerate() {
            *target = self.tool_from_moved(tool, &world_from_root, &frames.moved);
        }
    }

    /// Every frame moved by its own joint, Σᵢ·Q(θᵢ), in the measurement frame.
    fn moved_frames_into(
        &self,
        q: &[f64],
        world_from_root: &Transform,
        moved: &mut Vec<Transform>,
        motions: &mut JointMotions,
    ) {
        motions.fill(self, q);
        moved.resize(self.frames().len(), Transform::identity());
        // The frame just computed, kept in registers: reading a parent back from `moved`
        // right after writing it stalls on the store, and in a chain the parent is usually
        // the frame just before.
        let mut last: Option<(usize, Transform)> = None;
        for (index, frame) in self.frames().iter().enumerate() {
            let parent = match (frame.parent, &last) {
                (Some(p), Some((l, transform))) if *l == p => transform,
                (Some(p), _) => &moved[p],
                (None, _) => world_from_root,
            };
            let placed = motions.apply(self, index, &parent.then(self.frame_constant(index)));
            moved[index] = placed;
            last = Some((index, placed));
        }
    }

    /// Tool `tool` from the moved frames of [`Self::moved_frames_into`].
    #[inline]
    fn tool_from_moved(
        &self,
        tool: usize,
        world_from_root: &Transform,
        moved: &[Transform],
    ) -> Transform {
        match self.tools()[tool].parent {
            Some(last) => moved[last].then(self.tool_constant(tool)),
            None => world_from_root.then(self.tool_constant(tool)),
        }
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
