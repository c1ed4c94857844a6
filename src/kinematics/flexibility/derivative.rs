//! How the deflected tool poses change with the MCPC parameters: the deflections change with
//! the geometry through the lever arms of the loads, which a Jacobian on the deflected chain
//! leaves out. Analytic (docs/flexibility.md §11): the deflected chain's analytic Jacobian
//! with every inserted deformation held, plus each deformation's own change (in closed form,
//! `load_change.rs`; or a forward difference of the loads and deformations only, not of the
//! chain) carried to the tools as a small rigid motion.

use super::apply::Deflection;
use super::compliance::{left_jacobian, right_jacobian};
use super::load_change::{Change, Reach, Scratch};
use super::loads::Evaluation;
use super::model::FlexibilityModel;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::{pose_error, Mat3, Pose, Transform, Vec3};
use crate::tree::KinematicTree;
use nalgebra::Vector6;

/// A small rigid motion in the base frame: rotation `omega` and the velocity `linear` of the
/// point at the base origin, so that a point x moves by `linear + omega × x`.
#[derive(Debug, Clone, Copy)]
struct Motion {
    omega: Vec3,
    linear: Vec3,
}

impl Motion {
    fn zero() -> Motion {
        Motion {
            omega: Vec3::zeros(),
            linear: Vec3::zeros(),
        }
    }

    /// Rotation `omega` about point `through`, plus translation `shift`.
    fn about(omega: Vec3, through: &Vec3, shift: Vec3) -> Motion {
        Motion {
            omega,
            linear: shift - omega.cross(through),
        }
    }

    fn add(&self, other: &Motion) -> Motion {
        Motion {
            omega: self.omega + other.omega,
            linear: self.linear + other.linear,
        }
    }
}

/// How a deformation's change with a parameter is had.
#[derive(Debug, Clone, Copy)]
enum LoadChange {
    /// In closed form (`load_change.rs`), where the parameter is a frame's or a tool's.
    Analytic,
    /// A forward difference of the loads and deformations.
    Differenced,
}

/// Segment `index`'s inserted transform `S = (R_s, t_s)` in its proximal nominal moved frame
/// (see `deflected_frames`), by its parts: the free end `e`, the translation `L·u` and the
/// rotation vector `ψ` (`R_s = Exp(ψ)`, `t_s = e + L·u − R_s·e`).
fn segment_parts(model: &FlexibilityModel, evaluation: &Evaluation, index: usize) -> [Vec3; 3] {
    let segment = &evaluation.deformations.segments[index];
    let frame = &evaluation.moved[model.segments[index].frame];
    let to_local = frame.rotation.transpose();
    [
        to_local * (segment.end - frame.translation),
        to_local * segment.translation,
        to_local * segment.rotation,
    ]
}

impl FlexibilityModel {
    /// Per parameter of `parameters` (indices of [`McpcModel::parameters`]), the change of
    /// every deflected tool pose ([`Self::deflected_tool_poses`]) per unit parameter at
    /// configuration `q`, `[dp; δθ]` in the convention of [`pose_error`].
    ///
    /// Analytic (docs/flexibility.md §11): the analytic Jacobian of the deflected chain with
    /// every deformation held, plus the change of each joint's and segment's deformation in
    /// closed form (the loads' change with the geometry) as a small rigid motion of what
    /// follows it. Agrees with central differences of [`Self::deflected_tool_poses`] to
    /// ~1e-7 relative (1e-9 with joint compliance alone; `tests/flexibility_derivative.rs`).
    /// `step` is the forward-difference step of the loads for the parameters that are not a
    /// frame's or a tool's (joint errors, the measurement frame); with a reference link (the
    /// measurement frame on a moving link) every column is the forward difference of the
    /// whole deflected chain.
    pub fn deflected_pose_derivatives(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
        parameters: &[usize],
        step: f64,
    ) -> Result<Vec<Vec<Vector6<f64>>>> {
        self.pose_derivatives(tree, model, q, parameters, step, LoadChange::Analytic)
    }

    /// [`Self::deflected_pose_derivatives`] with every deformation's change a forward
    /// difference (step `step`) of the loads and deformations: the semi-analytic derivative
    /// the analytic one is checked against (`tests/flexibility_derivative.rs`).
    pub fn deflected_pose_derivatives_by_load_differences(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
        parameters: &[usize],
        step: f64,
    ) -> Result<Vec<Vec<Vector6<f64>>>> {
        self.pose_derivatives(tree, model, q, parameters, step, LoadChange::Differenced)
    }

    fn pose_derivatives(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
        parameters: &[usize],
        step: f64,
        how: LoadChange,
    ) -> Result<Vec<Vec<Vector6<f64>>>> {
        self.check(tree, model, q)?;
        let tree_poses = if self.uses_tree {
            tree.link_poses(q)?
        } else {
            Vec::new()
        };
        if model.reference.is_some() {
            return Ok(self.forward_differences(model, q, &tree_poses, parameters, step));
        }
        let deflection =
            self.deflect_evaluated(model, q, self.evaluate_with(model, q, &tree_poses));
        let chain = model.jacobians_on(&deflection.chain);
        let tips: Vec<Vec3> = deflection
            .chain
            .tools
            .iter()
            .map(|t| t.translation)
            .collect();
        let base = BaseParts::new(self, &deflection);
        let root = model.world_from_root_transform(q);
        let values = model.parameters();
        let mut shifted = model.clone();
        let mut columns = Vec::with_capacity(parameters.len());
        let (mut scratch, mut change) = (Scratch::default(), Change::default());
        let (mut frame_motions, mut tools) = (Vec::new(), Vec::new());
        for &p in parameters {
            let analytic = match how {
                LoadChange::Analytic => Reach::of(model, &deflection.evaluation, &root, p),
                LoadChange::Differenced => None,
            };
            match analytic {
                Some(reach) => self.load_change(
                    model,
                    &deflection.evaluation,
                    &reach,
                    &mut scratch,
                    &mut change,
                ),
                None => {
                    shifted.set_parameter(p, values[p] + step)?;
                    let evaluation = self.evaluate_with(&shifted, q, &tree_poses);
                    shifted.set_parameter(p, values[p])?;
                    change = base.differences(self, &evaluation, step);
                }
            }
            self.deformation_motions(
                model,
                &deflection,
                &base,
                &change,
                (&mut frame_motions, &mut tools),
            );
            columns.push(
                tools
                    .iter()
                    .zip(&tips)
                    .zip(&chain)
                    .map(|((motion, tip), tool)| {
                        let moved = motion.linear + motion.omega.cross(tip);
                        let held = tool.jacobian.column(p);
                        Vector6::new(
                            held[0] + moved.x,
                            held[1] + moved.y,
                            held[2] + moved.z,
                            held[3] + motion.omega.x,
                            held[4] + motion.omega.y,
                            held[5] + motion.omega.z,
                        )
                    })
                    .collect(),
            );
        }
        Ok(columns)
    }

    /// Per tool, the rigid motion that `change` (per unit parameter, from the deformations at
    /// `deflection`) gives it along its path.
    fn deformation_motions(
        &self,
        model: &McpcModel,
        deflection: &Deflection,
        base: &BaseParts,
        change: &Change,
        (frames, tools): (&mut Vec<Motion>, &mut Vec<Motion>),
    ) {
        let segment_motion = |index: usize| -> Motion {
            let [d_end, d_shift, d_psi] = &change.segments[index];
            if [d_end, d_shift, d_psi].iter().all(|d| **d == Vec3::zeros()) {
                // A segment the parameter leaves alone (the analytic change is exactly zero).
                return Motion::zero();
            }
            let [end0, shift0, _] = &base.segments[index];
            let (jacobian, rotation) = &base.segment_exp[index];
            let omega_local = jacobian * d_psi;
            let rotated_end = rotation * end0;
            // t_s = e + L·u − R_s·e, so dt_s = de + d(L·u) − ω × (R_s·e) − R_s·de.
            let d_translation =
                d_end + d_shift - omega_local.cross(&rotated_end) - rotation * d_end;
            let translation = end0 + shift0 - rotated_end;
            // A point y (after S, in D's coordinates) moves by ω × (y − t_s) + dt_s.
            let frame = &deflection.deflected[self.segments[index].frame];
            Motion::about(
                frame.rotation * omega_local,
                &(frame.rotation * translation + frame.translation),
                frame.rotation * d_translation,
            )
        };
        frames.clear();
        for (i, frame) in model.frames().iter().enumerate() {
            let mut motion = match frame.parent {
                Some(p) => frames[p],
                None => Motion::zero(),
            };
            if let Some(index) = self.segment_to_frame[i] {
                motion = motion.add(&segment_motion(index));
            }
            if change.joints[i] != Vec3::zeros() {
                let after = &deflection.deflected[i];
                let omega = after.rotation * (base.joint_jacobians[i] * change.joints[i]);
                motion = motion.add(&Motion::about(omega, &after.translation, Vec3::zeros()));
            }
            frames.push(motion);
        }
        tools.clear();
        tools.extend((0..model.tools().len()).map(|t| {
            let motion = self.tool_parent[t].map_or(Motion::zero(), |p| frames[p]);
            match self.segment_to_tool[t] {
                Some(index) => motion.add(&segment_motion(index)),
                None => motion,
            }
        }));
    }

    /// The forward differences of the whole deflected chain (`(pose(p + step) ⊖ pose(p)) /
    /// step`): for a model with a reference link.
    fn forward_differences(
        &self,
        model: &McpcModel,
        q: &[f64],
        tree_poses: &[Pose],
        parameters: &[usize],
        step: f64,
    ) -> Vec<Vec<Vector6<f64>>> {
        let poses = |model: &McpcModel| -> Vec<Pose> {
            let evaluation = self.evaluate_with(model, q, tree_poses);
            let tools = self.deflected_tools_evaluated(model, q, &evaluation);
            tools.iter().map(Transform::to_pose).collect()
        };
        let base = poses(model);
        let values = model.parameters();
        let mut shifted = model.clone();
        let mut columns = Vec::with_capacity(parameters.len());
        for &p in parameters {
            // A parameter index was checked by the caller's `set_parameter` on the main path;
            // here an out-of-range one is skipped by `get`.
            let Some(&value) = values.get(p) else {
                continue;
            };
            let _ = shifted.set_parameter(p, value + step);
            let at = poses(&shifted);
            let _ = shifted.set_parameter(p, value);
            columns.push(
                at.iter()
                    .zip(&base)
                    .map(|(a, b)| pose_error(a, b) / step)
                    .collect(),
            );
        }
        columns
    }
}

/// What the differences start from, per configuration: each joint's rotation vector and
/// `J_r` of it, each segment's parts and (`J_l(ψ)`, `Exp(ψ)`).
struct BaseParts {
    joints: Vec<nalgebra::Vector3<f64>>,
    joint_jacobians: Vec<Mat3>,
    segments: Vec<[Vec3; 3]>,
    segment_exp: Vec<(Mat3, Mat3)>,
}

impl BaseParts {
    /// The change from these parts to `evaluation`'s, per `step` (a forward difference).
    fn differences(&self, model: &FlexibilityModel, evaluation: &Evaluation, step: f64) -> Change {
        let joints = evaluation
            .deformations
            .joints
            .iter()
            .zip(&self.joints)
            .map(|(joint, base)| (joint.local.fixed_rows::<3>(3) - base) / step)
            .collect();
        let segments = self
            .segments
            .iter()
            .enumerate()
            .map(|(index, base)| {
                let parts = segment_parts(model, evaluation, index);
                [0, 1, 2].map(|k| (parts[k] - base[k]) / step)
            })
            .collect();
        Change { joints, segments }
    }

    fn new(model: &FlexibilityModel, deflection: &Deflection) -> Self {
        let evaluation = &deflection.evaluation;
        let joints: Vec<Vec3> = evaluation
            .deformations
            .joints
            .iter()
            .map(|j| j.local.fixed_rows::<3>(3).into_owned())
            .collect();
        let segments: Vec<[Vec3; 3]> = (0..model.segments.len())
            .map(|index| segment_parts(model, evaluation, index))
            .collect();
        BaseParts {
            joint_jacobians: joints.iter().map(right_jacobian).collect(),
            segment_exp: segments
                .iter()
                .map(|[_, _, psi]| (left_jacobian(psi), super::apply::exp(psi)))
                .collect(),
            joints,
            segments,
        }
    }
}
