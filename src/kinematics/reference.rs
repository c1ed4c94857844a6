//! The reference link: the link fixed in the world while measuring (a sole on the floor, a
//! mobile base), when it is not the URDF root.
//!
//! The model still describes the URDF's own joints in the URDF's direction (every frame's
//! parameters place the URDF joint origin, and export writes the URDF's own structure), but
//! what it predicts is relative to the reference link:
//!
//! ```text
//! world_from_tool(q) = world_from_reference · reference_from_root(q) · root_from_tool(q)
//! reference_from_root(q) = root_from_reference(q)⁻¹
//! ```
//!
//! where `root_from_reference(q)` is the forward kinematics of the reference link's own chain
//! of MCPC frames followed by a constant (the link's nominal placement after its last frame,
//! not a parameter: any error in it is absorbed by the world-fixed `world_from_reference`).
//! With no reference link, `world_from_root` is the constant measurement frame.
//!
//! A parameter of the reference chain moves the reference link by a twist ξ in the world;
//! holding the reference fixed moves every tool by −ξ instead, so its identification Jacobian
//! column is the negated column the reference link would have as a tool. Joints on the common
//! root path of the reference and a tool cancel exactly and are unobservable; the model built
//! by [`McpcModel::from_tree`] leaves them out. See `docs/mcpc.md`, "Reference link".

use super::mcpc::{FrameKind, McpcModel};
use super::model_extras::{inverse, ReferenceChain, ReferenceLink};
use crate::error::{Error, Result};
use crate::math::{Pose, Transform, Vec3};

impl McpcModel {
    /// Fixes `reference` in the world instead of the root (`None`: the root). Forward
    /// kinematics and Jacobians are then relative to the reference link, whose pose in the
    /// measurement frame is [`McpcModel::world_from_base`].
    ///
    /// With a reference link behind a movable joint the measurement frame becomes six parameters
    /// ([`McpcModel::with_frame_parameters`], appended last): the reference
    /// link's own placement after its last joint is not a parameter, so the world-fixed frame
    /// is what absorbs it (the reference end of the chain plays the part a tool frame plays
    /// at a tool). Without it the ankle axis of a sole would be pinned where the closed-form
    /// frame put it. The root link's placement between the chains is then a six-dimensional
    /// gauge freedom, which `crate::calibration::gauge` fixes.
    pub fn set_reference(&mut self, reference: Option<ReferenceLink>) -> Result<()> {
        let Some(reference) = reference else {
            self.reference = None;
            return Ok(());
        };
        let mut chain = Vec::new();
        let mut current = reference.parent;
        while let Some(frame) = current {
            if frame >= self.frames().len() {
                return Err(Error::InvalidTable {
                    origin: "MCPC model".into(),
                    message: format!(
                        "the reference link names frame {frame}, which does not exist"
                    ),
                });
            }
            chain.push(frame);
            current = self.frames()[frame].parent;
        }
        chain.reverse();
        if !chain.is_empty() && self.frame_parameters.is_none() {
            *self = self.with_frame_parameters();
        }
        self.reference = Some(ReferenceChain {
            last_from_link: Transform::from_pose(&reference.last_from_link),
            reference,
            chain,
        });
        Ok(())
    }

    /// The reference link, if it is not the root.
    pub fn reference(&self) -> Option<&ReferenceLink> {
        self.reference.as_ref().map(|r| &r.reference)
    }

    /// The frames from the root to the reference link, root side first (empty without one).
    pub fn reference_chain(&self) -> &[usize] {
        self.reference.as_ref().map_or(&[], |r| &r.chain)
    }

    /// Where the root link is in the measurement frame at configuration `q`: the constant
    /// [`McpcModel::world_from_base`] without a reference link, else
    /// `world_from_reference · root_from_reference(q)⁻¹`.
    pub fn world_from_root(&self, q: &[f64]) -> Pose {
        self.world_from_root_transform(q).to_pose()
    }

    /// [`McpcModel::world_from_root`] in the fast form (bit for bit the measurement frame
    /// without a reference link).
    pub(crate) fn world_from_root_transform(&self, q: &[f64]) -> Transform {
        match &self.reference {
            None => *self.world_from_base_transform(),
            Some(reference) => {
                let root_from_reference = self.root_from_reference(reference, q);
                self.world_from_base_transform()
                    .then(&inverse(&root_from_reference))
            }
        }
    }

    /// The reference link in the root frame at `q`, through its own chain of MCPC frames.
    fn root_from_reference(&self, reference: &ReferenceChain, q: &[f64]) -> Transform {
        let mut current = Transform::identity();
        let mut previous: Option<usize> = None;
        for &frame in &reference.chain {
            if let Some(p) = previous {
                current = self.moved(p, q, &current);
            }
            current = current.then(self.frame_constant(frame));
            previous = Some(frame);
        }
        if let Some(p) = previous {
            current = self.moved(p, q, &current);
        }
        current.then(&reference.last_from_link)
    }

    /// Adds the Jacobian columns of the reference chain's frames to a tool's columns (6 ×
    /// parameter_count, column-major in `data`): the negated twist each parameter gives the
    /// reference link, seen at the tool's tip (`previous`, `frames`: the chain's frames in the
    /// measurement frame, as in [`super::ChainFrames`]; `factors`: the joint-error factors).
    pub(crate) fn add_reference_columns(
        &self,
        tip: &Vec3,
        previous: &[Transform],
        frames: &[Transform],
        factors: &[[f64; 4]],
        data: &mut [f64],
    ) {
        let mut add = |column: usize, values: [f64; 6]| {
            for (slot, value) in data[6 * column..6 * column + 6].iter_mut().zip(values) {
                *slot -= value;
            }
        };
        let rotation = |axis: Vec3, through: &Vec3| {
            let linear = axis.cross(&(tip - through));
            [linear.x, linear.y, linear.z, axis.x, axis.y, axis.z]
        };
        let translation = |d: Vec3| [d.x, d.y, d.z, 0.0, 0.0, 0.0];
        let error_indices = if self.joint_errors.is_active() {
            self.joint_error_indices()
        } else {
            Vec::new()
        };
        for &frame in self.reference_chain() {
            let before = &previous[frame];
            let [alpha_axis, beta_axis] = self.frame_axes(frame);
            let offset = self.frame_parameter_offset(frame);
            add(
                offset,
                rotation(before.rotation * alpha_axis, &before.translation),
            );
            add(
                offset + 1,
                rotation(before.rotation * beta_axis, &before.translation),
            );
            if self.frames()[frame].kind == FrameKind::Revolute {
                let axes = &frames[frame].rotation;
                add(offset + 2, translation(axes.column(0).into_owned()));
                add(offset + 3, translation(axes.column(1).into_owned()));
            }
            let Some(indices) = error_indices.get(frame) else {
                continue;
            };
            let axis: Vec3 = frames[frame].rotation.column(2).into_owned();
            let twist = rotation(axis, &frames[frame].translation);
            let factor = factors.get(frame).copied().unwrap_or([0.0; 4]);
            for (k, index) in indices.iter().enumerate() {
                if let Some(index) = index {
                    add(*index, twist.map(|v| v * factor[k]));
                }
            }
        }
    }
}
