//! What the deformations do to the tools: the linear map D_f = J_f·d_f (paper eq. (20),
//! (22)–(24)) and the deflected forward kinematics that inserts them as rigid transforms.

use super::loads::Evaluation;
use super::model::FlexibilityModel;
use crate::error::Result;
use crate::kinematics::{ChainFrames, McpcModel};
use crate::math::{Mat3, Pose, Transform, Vec3};
use crate::tree::KinematicTree;
use nalgebra::Vector6;

impl FlexibilityModel {
    /// The flexibility error `D_f` of every tool at configuration `q`, in [`McpcModel::tools`]
    /// order (eq. (23)–(24)): `[dp; δθ]` in the base frame, metres and radians, the convention
    /// of [`crate::math::pose_error`]`(deflected, nominal)` and of the identification Jacobian.
    ///
    /// Each joint rotation δ about origin o adds `[δ × (p − o); δ]` and each segment whose free
    /// end e moves by (u, ψ) adds `[u + ψ × (p − e); ψ]`, for tool position p: the columns of
    /// J_f times d_f. "Base frame" is the frame the model's poses are in (the measurement frame
    /// if [`McpcModel::set_world_from_base`] was used); gravity is turned into it. Costs one MCPC
    /// forward kinematics plus O(frames + masses + segments + tools × chain length).
    pub fn tool_deflections(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
    ) -> Result<Vec<Vector6<f64>>> {
        let evaluation = self.evaluate(tree, model, q)?;
        let joints = &evaluation.deformations.joints;
        let segments = &evaluation.deformations.segments;
        Ok(evaluation
            .tools
            .iter()
            .enumerate()
            .map(|(tool, transform)| {
                let tip = transform.translation;
                let mut position = Vec3::zeros();
                let mut rotation = Vec3::zeros();
                // The tool's own chain moves it; the reference link's chain moves the
                // reference, which is held fixed instead: the opposite motion of everything.
                let chains = [
                    (model.tool_chain(tool), 1.0),
                    (model.reference_chain(), -1.0),
                ];
                for (chain, sign) in chains {
                    for &frame in chain {
                        let joint = &joints[frame];
                        position += sign * joint.rotation.cross(&(tip - joint.origin));
                        rotation += sign * joint.rotation;
                    }
                    let on_path = chain
                        .iter()
                        .filter_map(|&frame| self.segment_to_frame[frame]);
                    for index in on_path {
                        let segment = &segments[index];
                        position += sign
                            * (segment.translation + segment.rotation.cross(&(tip - segment.end)));
                        rotation += sign * segment.rotation;
                    }
                }
                if let Some(index) = self.segment_to_tool[tool] {
                    let segment = &segments[index];
                    position += segment.translation + segment.rotation.cross(&(tip - segment.end));
                    rotation += segment.rotation;
                }
                Vector6::new(
                    position.x, position.y, position.z, rotation.x, rotation.y, rotation.z,
                )
            })
            .collect())
    }

    /// The tool poses at configuration `q` with every deformation inserted into the chain as
    /// an exact small rigid transform: each joint's rotation right after its motion, each
    /// segment's (translation, rotation) at its free end. Agrees with
    /// [`Self::tool_deflections`] to first order in the compliances.
    pub fn deflected_tool_poses(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
    ) -> Result<Vec<Pose>> {
        let evaluation = self.evaluate(tree, model, q)?;
        let poses = self
            .deflected_tools_evaluated(model, q, &evaluation)
            .iter()
            .map(Transform::to_pose)
            .collect();
        evaluation.recycle();
        Ok(poses)
    }

    /// The whole deflected chain at configuration `q` (see [`Self::deflected_tool_poses`]):
    /// what the identification Jacobian needs to stay accurate on a bending robot.
    pub fn deflected_chain(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
    ) -> Result<ChainFrames> {
        let deflection = self.deflect(tree, model, q)?;
        deflection.evaluation.recycle();
        Ok(deflection.chain)
    }

    /// The deflected chain with the deflected moved frames `Σᵢ'·Q(θᵢ)·Exp(d_joint,i)` and the
    /// evaluation it was built from (for the compliance derivatives).
    pub(super) fn deflect(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
    ) -> Result<Deflection> {
        Ok(self.deflect_evaluated(model, q, self.evaluate(tree, model, q)?))
    }

    /// [`Self::deflect`] from the deformations at `q` (`evaluation`).
    pub(super) fn deflect_evaluated(
        &self,
        model: &McpcModel,
        q: &[f64],
        evaluation: Evaluation,
    ) -> Deflection {
        let DeflectedFrames {
            deflected,
            previous,
            frames,
            tool_previous,
            tools,
        } = self.deflected_frames(model, q, &evaluation, true);
        Deflection {
            chain: ChainFrames {
                previous,
                frames,
                tool_previous,
                tools,
                joint_error_factors: {
                    let mut factors = Vec::new();
                    model.joint_error_factors(q, &mut factors);
                    factors
                },
                ..ChainFrames::default()
            },
            deflected,
            evaluation,
        }
    }

    /// The deflected tool frames alone from the deformations at `q` (`evaluation`): the
    /// tools of [`Self::deflect_evaluated`], bit for bit, without the rest of the chain (what
    /// predictions and the finite differences of the geometry need).
    pub(super) fn deflected_tools_evaluated(
        &self,
        model: &McpcModel,
        q: &[f64],
        evaluation: &Evaluation,
    ) -> Vec<Transform> {
        let DeflectedFrames {
            deflected, tools, ..
        } = self.deflected_frames(model, q, evaluation, false);
        // A thread being torn down just drops it.
        let _ = SPARE_DEFLECTED.try_with(|spare| *spare.borrow_mut() = deflected);
        tools
    }

    /// The deflected frames; `previous` and `frames` (Σᵢ' before the motion) only if `whole`,
    /// else empty.
    fn deflected_frames(
        &self,
        model: &McpcModel,
        q: &[f64],
        evaluation: &Evaluation,
        whole: bool,
    ) -> DeflectedFrames {
        let Evaluation {
            deformations,
            moved,
            ..
        } = evaluation;
        // A segment's deformation as a transform in its proximal moved frame (nominal axes).
        let segment_transform = |index: usize| -> Transform {
            let segment = &deformations.segments[index];
            let frame = &moved[self.segments[index].frame];
            let to_local = frame.rotation.transpose();
            let end = to_local * (segment.end - frame.translation);
            let rotation = exp(&(to_local * segment.rotation));
            Transform {
                rotation,
                translation: end + to_local * segment.translation - rotation * end,
            }
        };
        let count = model.frames().len();
        let kept = if whole { count } else { 0 };
        let world_from_root = model.world_from_root_transform(q);
        // Predictions (not `whole`) hand their `deflected` buffer back (`SPARE_DEFLECTED`).
        let mut deflected: Vec<Transform> = if whole {
            Vec::with_capacity(count)
        } else {
            let mut spare = SPARE_DEFLECTED
                .try_with(|spare| std::mem::take(&mut *spare.borrow_mut()))
                .unwrap_or_default();
            spare.clear();
            spare
        };
        let mut previous: Vec<Transform> = Vec::with_capacity(kept);
        let mut frames: Vec<Transform> = Vec::with_capacity(kept);
        for (i, frame) in model.frames().iter().enumerate() {
            // Without a segment, the parent's frame as it is (`then` with the identity gives
            // the same values).
            let before = match (frame.parent, self.segment_to_frame[i]) {
                (Some(p), Some(index)) => deflected[p].then(&segment_transform(index)),
                (Some(p), None) => deflected[p],
                (None, _) => world_from_root,
            };
            let sigma = before.then(model.frame_constant(i));
            // The evaluation's sines and cosines: it was made for this model at `q`.
            let after_motion = evaluation.motions.apply(model, i, &sigma);
            let local = deformations.joints[i].local.fixed_rows::<3>(3).into_owned();
            deflected.push(after_motion.then(&Transform {
                rotation: exp(&local),
                translation: Vec3::zeros(),
            }));
            if whole {
                previous.push(before);
                frames.push(sigma);
            }
        }
        let tool_before = |t: usize| match (model.tools()[t].parent, self.segment_to_tool[t]) {
            (Some(p), Some(index)) => deflected[p].then(&segment_transform(index)),
            (Some(p), None) => deflected[p],
            (None, _) => world_from_root,
        };
        let tool_count = model.tools().len();
        // `tool_previous` only if `whole`: a prediction needs the tools alone.
        let tool_previous: Vec<Transform> = (0..if whole { tool_count } else { 0 })
            .map(tool_before)
            .collect();
        let tools: Vec<Transform> = (0..tool_count)
            .map(|t| {
                let before = tool_previous
                    .get(t)
                    .copied()
                    .unwrap_or_else(|| tool_before(t));
                before.then(model.tool_constant(t))
            })
            .collect();
        // A reference link other than the root deflects with its chain; it is held fixed, so
        // everything moves back by its deflection.
        let mut all = [deflected, previous, frames, tool_previous, tools];
        if let Some(reference) = &model.reference {
            let moved = match reference.reference.parent {
                Some(p) => all[0][p],
                None => world_from_root,
            };
            let deflected_reference = moved.then(&reference.last_from_link);
            let back =
                model
                    .world_from_base_transform()
                    .then(&crate::kinematics::model_extras::inverse(
                        &deflected_reference,
                    ));
            for transform in all.iter_mut().flatten() {
                *transform = back.then(transform);
            }
        }
        let [deflected, previous, frames, tool_previous, tools] = all;
        DeflectedFrames {
            deflected,
            previous,
            frames,
            tool_previous,
            tools,
        }
    }
}

thread_local! {
    /// The deflected frames' buffer of the latest prediction on this thread, for the next.
    static SPARE_DEFLECTED: std::cell::RefCell<Vec<Transform>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// The frames of a deflected chain (see [`ChainFrames`] for their meaning).
struct DeflectedFrames {
    deflected: Vec<Transform>,
    previous: Vec<Transform>,
    frames: Vec<Transform>,
    tool_previous: Vec<Transform>,
    tools: Vec<Transform>,
}

/// The deflected chain and what it was built from.
pub(super) struct Deflection {
    /// The deflected chain.
    pub(super) chain: ChainFrames,
    /// Per MCPC frame, the deflected moved frame `Σᵢ'·Q(θᵢ)·Exp(d_joint,i)`.
    pub(super) deflected: Vec<Transform>,
    /// The loads and deformations, at the nominal (undeflected) frames.
    pub(super) evaluation: Evaluation,
}

/// The rotation matrix of rotation vector `v` (axis · angle), by Rodrigues' formula
/// `cos θ·I + a·[v]× + b·v·vᵀ` with `a = sin θ/θ`, `b = (1 − cos θ)/θ²`. Deflections are small:
/// below 0.05 rad the series of `a`, `b` and `cos θ` to θ⁸ are exact to rounding and skip the
/// trigonometric calls.
pub(super) fn exp(v: &Vec3) -> Mat3 {
    let t = v.norm_squared();
    let (a, b, cos) = if t < 2.5e-3 {
        let a = 1.0 - t / 6.0 * (1.0 - t / 20.0 * (1.0 - t / 42.0 * (1.0 - t / 72.0)));
        let b = 0.5 * (1.0 - t / 12.0 * (1.0 - t / 30.0 * (1.0 - t / 56.0 * (1.0 - t / 90.0))));
        (a, b, 1.0 - t * b)
    } else {
        let angle = t.sqrt();
        let (sin, cos) = angle.sin_cos();
        (sin / angle, (1.0 - cos) / t, cos)
    };
    let (x, y, z) = (v.x, v.y, v.z);
    Mat3::new(
        cos + b * x * x,
        b * x * y - a * z,
        b * x * z + a * y,
        b * x * y + a * z,
        cos + b * y * y,
        b * y * z - a * x,
        b * x * z - a * y,
        b * y * z + a * x,
        cos + b * z * z,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn exp_matches_nalgebra_on_both_branches() {
        for &angle in &[0.0, 1e-9, 1e-4, 0.01, 0.0499, 0.0501, 0.3, 2.0, 3.1] {
            let v = Vec3::new(0.3, -0.5, 0.8).normalize() * angle;
            let expected = Rotation3::new(v).into_inner();
            assert!((exp(&v) - expected).amax() < 1e-15, "angle {angle}");
        }
    }
}
