//! Static gravity loads from the tips inward, and the deformations they cause (paper eq. (18),
//! (19), (21)) at one configuration.
//!
//! Everything is computed in the base (root link) frame at the nominal, undeflected pose, and
//! expressed in a joint or beam frame only where a stiffness applies: first-order theory.

use super::beam::point_load_deflection;
use super::model::{FlexibilityModel, Place, SegmentEnd};
use crate::error::{Error, Result};
use crate::kinematics::forward::JointMotions;
use crate::kinematics::McpcModel;
use crate::math::{Mat3, Transform, Vec3};
use crate::tree::KinematicTree;
use nalgebra::Vector6;

/// The deflection of one joint (eq. (18)–(19)) and the load that causes it.
#[derive(Debug, Clone, PartialEq)]
pub struct JointDeformation {
    /// The joint origin (origin of Σᵢ·Q(θᵢ)) in the base frame, m.
    pub origin: Vec3,
    /// Weight of everything the joint carries, base frame, N.
    pub force: Vec3,
    /// Moment of that weight about the joint origin, base frame, N·m.
    pub moment: Vec3,
    /// `d_joint` of eq. (19) in the moved joint frame Σᵢ·Q(θᵢ): `[0, 0, 0, Δα, Δβ, Δθ]`.
    pub local: Vector6<f64>,
    /// The small rotation of everything after the joint, about the joint origin, base frame, rad.
    pub rotation: Vec3,
}

/// The deflection of one link segment (corrected eq. (21)).
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentDeformation {
    /// The clamped end (the proximal joint origin), base frame, m.
    pub start: Vec3,
    /// The free end, base frame, m.
    pub end: Vec3,
    /// The beam frame (x along the segment) in the base frame.
    pub base_from_beam: Mat3,
    /// `d_link` of eq. (21) in the beam frame: `[Δx, Δy, Δz, Δα, Δβ, Δγ]` of the free end.
    pub local: Vector6<f64>,
    /// Translation of the free end, base frame, m.
    pub translation: Vec3,
    /// Small rotation of the free end (about it), base frame, rad.
    pub rotation: Vec3,
}

/// The flexibility deformations `d_f` of eq. (23) at one configuration, placed in the base frame.
///
/// "Base frame" here and in the fields is the frame the MCPC model's poses are in: the root
/// link frame, or the measurement frame if [`McpcModel::set_world_from_base`] moved it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Deformations {
    /// One per MCPC frame, in [`McpcModel::frames`] order.
    pub joints: Vec<JointDeformation>,
    /// One per segment, in [`FlexibilityModel::segments`] order.
    pub segments: Vec<SegmentDeformation>,
}

/// Deformations with the nominal frames they were computed at.
#[derive(Default)]
pub(crate) struct Evaluation {
    pub(crate) deformations: Deformations,
    /// Σᵢ·Q(θᵢ) of every frame, base frame.
    pub(crate) moved: Vec<Transform>,
    /// Every tool frame, base frame.
    pub(crate) tools: Vec<Transform>,
    /// Σᵢ of every frame (before its joint's motion), base frame.
    pub(crate) frames: Vec<Transform>,
    /// Every mass's position, base frame (in `FlexibilityModel::masses` order).
    pub(crate) positions: Vec<Vec3>,
    /// The segment each mass's self-weight loads (`None`: none).
    pub(crate) mass_segments: Vec<Option<usize>>,
    /// The subtree loads the deformations come from.
    pub(crate) loads: Loads,
    /// Gravity in the base frame, m/s².
    pub(crate) gravity: Vec3,
    /// The joints' motions at the configuration (their sines and cosines), for the deflected
    /// chain built on these frames.
    pub(crate) motions: JointMotions,
}

thread_local! {
    /// A spent [`Evaluation`] whose buffers the next one on this thread reuses: predictions
    /// evaluate the loads once per configuration and iteration, and their dozen allocations
    /// were a noticeable part of `simulate` (docs/performance.md, issue 24, round ten).
    static SPARE: std::cell::RefCell<Option<Evaluation>> = const { std::cell::RefCell::new(None) };
}

impl Evaluation {
    /// Hands the buffers back for the next evaluation on this thread.
    pub(crate) fn recycle(self) {
        // A thread being torn down just drops it.
        let _ = SPARE.try_with(|spare| *spare.borrow_mut() = Some(self));
    }
}

impl FlexibilityModel {
    /// The joint and link deformations `d_f` at configuration `q`, with their loads.
    pub fn deformations(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
    ) -> Result<Deformations> {
        Ok(self.evaluate(tree, model, q)?.deformations)
    }

    /// Checks that `tree` and `model` are the shape this model was built for.
    pub(super) fn check(&self, tree: &KinematicTree, model: &McpcModel, q: &[f64]) -> Result<()> {
        tree.check_configuration(q)?;
        let fits = tree.links().len() == self.link_count
            && model.frames().len() == self.joint_compliance.len()
            && model.tools().len() == self.segment_to_tool.len();
        if fits {
            Ok(())
        } else {
            Err(Error::InvalidData {
                origin: "flexibility model".into(),
                message: "the tree or MCPC model differs from the one the flexibility model was built from; build it again".into(),
            })
        }
    }

    /// The deformations at `q` with the nominal frames they were computed at.
    pub(crate) fn evaluate(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
    ) -> Result<Evaluation> {
        self.check(tree, model, q)?;
        // Only masses behind joints outside the model need the tree (head, fingers).
        let tree_poses = if self.uses_tree {
            tree.link_poses(q)?
        } else {
            Vec::new()
        };
        Ok(self.evaluate_with(model, q, &tree_poses))
    }

    /// [`Self::evaluate`] once checked, with the tree's link poses at `q` (empty unless the
    /// model uses the tree): what does not depend on the MCPC parameters, computed once for
    /// every parameter a finite difference shifts.
    pub(crate) fn evaluate_with(
        &self,
        model: &McpcModel,
        q: &[f64],
        tree_poses: &[crate::math::Pose],
    ) -> Evaluation {
        let mut evaluation = SPARE
            .try_with(|spare| spare.borrow_mut().take())
            .ok()
            .flatten()
            .unwrap_or_default();
        self.evaluate_into(model, q, tree_poses, &mut evaluation);
        evaluation
    }

    /// [`Self::evaluate_with`] into `evaluation`'s buffers (every field overwritten).
    fn evaluate_into(
        &self,
        model: &McpcModel,
        q: &[f64],
        tree_poses: &[crate::math::Pose],
        evaluation: &mut Evaluation,
    ) {
        let Evaluation {
            deformations: Deformations { joints, segments },
            moved,
            tools,
            frames,
            positions,
            mass_segments,
            loads,
            gravity,
            motions,
        } = evaluation;
        model.frame_and_moved_transforms_into(q, frames, moved, motions);
        tools.clear();
        tools.extend(model.tools().iter().enumerate().map(|(t, tool)| {
            match tool.parent {
                Some(p) => moved[p].then(model.tool_constant(t)),
                None => model
                    .world_from_root_transform(q)
                    .then(model.tool_constant(t)),
            }
        }));
        // Frames are in the model's measurement frame; gravity is given in the root frame
        // unless it was fixed in the measurement frame.
        *gravity = if self.gravity_in_measurement_frame {
            self.gravity
        } else {
            model.world_from_base_transform().rotation * self.gravity
        };
        self.mass_positions(model, moved, tools, tree_poses, positions);
        self.loads(model, gravity, positions, tools.len(), loads);
        self.joint_deformations(moved, loads, joints);
        self.segment_deformations(frames, moved, tools, loads, segments);
        self.add_self_weight(segments, positions, gravity, mass_segments);
        for segment in segments.iter_mut() {
            segment.translation = segment.base_from_beam * segment.local.fixed_rows::<3>(0);
            segment.rotation = segment.base_from_beam * segment.local.fixed_rows::<3>(3);
        }
    }

    /// Where every mass is, base frame.
    fn mass_positions(
        &self,
        model: &McpcModel,
        moved: &[Transform],
        tools: &[Transform],
        tree_poses: &[crate::math::Pose],
        positions: &mut Vec<Vec3>,
    ) {
        positions.clear();
        positions.extend(self.masses.iter().map(|m| match m.place {
            Place::Body(frame, point) => moved[frame].rotation * point + moved[frame].translation,
            Place::Tool(tool, point) | Place::ToolBody(tool, point) => {
                tools[tool].rotation * point + tools[tool].translation
            }
            Place::ToolTree {
                tool,
                tool_link,
                link,
                point,
            } => {
                let in_tool = tree_poses[tool_link.0].inverse()
                    * tree_poses[link.0]
                    * nalgebra::Point3::from(point);
                tools[tool].rotation * in_tool.coords + tools[tool].translation
            }
            Place::Tree {
                frame,
                body_link,
                link,
                point,
            } => {
                let body_from_link = tree_poses[body_link.0].inverse() * tree_poses[link.0];
                let in_frame = model.frames()[frame].frame_from_link
                    * body_from_link
                    * nalgebra::Point3::from(point);
                moved[frame].rotation * in_frame.coords + moved[frame].translation
            }
        }));
    }

    /// From the tips inward, the weight each joint carries as a force and a moment about the
    /// base origin (moved to any point p as N − p × F); and the same for the masses at each
    /// tool.
    fn loads(
        &self,
        model: &McpcModel,
        gravity: &Vec3,
        positions: &[Vec3],
        tool_count: usize,
        loads: &mut Loads,
    ) {
        let frame_count = model.frames().len();
        for (buffer, count) in [
            (&mut loads.force, frame_count),
            (&mut loads.torque, frame_count),
            (&mut loads.tool_force, tool_count),
            (&mut loads.tool_torque, tool_count),
        ] {
            buffer.clear();
            buffer.resize(count, Vec3::zeros());
        }
        for (mass, position) in self.masses.iter().zip(positions) {
            let weight = gravity * mass.mass;
            loads.force[mass.frame] += weight;
            loads.torque[mass.frame] += position.cross(&weight);
            if let Place::Tool(tool, _) = mass.place {
                loads.tool_force[tool] += weight;
                loads.tool_torque[tool] += position.cross(&weight);
            }
        }
        // Frames come parents first, so children are complete before they are added on.
        for i in (0..frame_count).rev() {
            if let Some(p) = model.frames()[i].parent {
                let (f, t) = (loads.force[i], loads.torque[i]);
                loads.force[p] += f;
                loads.torque[p] += t;
            }
        }
    }

    /// Eq. (18)–(19): each joint's deflection under the moment it carries.
    fn joint_deformations(
        &self,
        moved: &[Transform],
        loads: &Loads,
        joints: &mut Vec<JointDeformation>,
    ) {
        joints.clear();
        joints.extend((0..moved.len()).map(|i| {
            let origin = moved[i].translation;
            let moment = loads.torque[i] - origin.cross(&loads.force[i]);
            let rotation_matrix = moved[i].rotation;
            let local_moment = rotation_matrix.transpose() * moment;
            let (bending, torsion) = self.joint_compliance[i];
            let local_rotation = Vec3::new(
                bending * local_moment.x,
                bending * local_moment.y,
                torsion * local_moment.z,
            );
            JointDeformation {
                origin,
                force: loads.force[i],
                moment,
                local: Vector6::new(
                    0.0,
                    0.0,
                    0.0,
                    local_rotation.x,
                    local_rotation.y,
                    local_rotation.z,
                ),
                rotation: rotation_matrix * local_rotation,
            }
        }));
    }

    /// Corrected eq. (21): each segment's deflection under the load at its free end (the
    /// translation and rotation in the base frame are filled in later).
    fn segment_deformations(
        &self,
        frames: &[Transform],
        moved: &[Transform],
        tools: &[Transform],
        loads: &Loads,
        segments: &mut Vec<SegmentDeformation>,
    ) {
        segments.clear();
        segments.extend(self.segments.iter().map(|segment| {
            let start = moved[segment.frame].translation;
            let (end, tip_force, tip_torque) = match segment.end {
                SegmentEnd::Frame(j) => (frames[j].translation, loads.force[j], loads.torque[j]),
                SegmentEnd::Tool(t) => (
                    tools[t].translation,
                    loads.tool_force[t],
                    loads.tool_torque[t],
                ),
            };
            let base_from_beam = beam_frame(
                &(end - start),
                &moved[segment.frame].rotation,
                segment.reference_axis,
            );
            let length = (end - start).norm();
            let local = point_load_deflection(
                length,
                &segment.compliance,
                length,
                &(base_from_beam.transpose() * tip_force),
                &(base_from_beam.transpose() * (tip_torque - end.cross(&tip_force))),
            );
            SegmentDeformation {
                start,
                end,
                base_from_beam,
                local,
                translation: Vec3::zeros(),
                rotation: Vec3::zeros(),
            }
        }));
    }

    /// Self-weight: each link's weight at its centre of mass projected on its segment, with
    /// the moment of the offset (see docs/flexibility.md). Sets the segment each mass
    /// loads (`chosen`).
    fn add_self_weight(
        &self,
        segments: &mut [SegmentDeformation],
        positions: &[Vec3],
        gravity: &Vec3,
        chosen: &mut Vec<Option<usize>>,
    ) {
        chosen.clear();
        chosen.resize(self.masses.len(), None);
        for ((mass, position), chosen) in self.masses.iter().zip(positions).zip(chosen) {
            if mass.segment.is_none() {
                continue;
            }
            // The body's segment nearest to the mass at the current geometry, so that the
            // model follows the geometry being calibrated (and an exported URDF's).
            let Some(index) = nearest_segment(&self.segments, segments, mass.frame, position)
            else {
                continue;
            };
            *chosen = Some(index);
            let segment = &mut segments[index];
            let axis = segment.base_from_beam.column(0).into_owned();
            let length = (segment.end - segment.start).norm();
            // Not `clamp`, which panics on a NaN bound (a non-finite pose, from an overflow).
            let station = (position - segment.start).dot(&axis).max(0.0).min(length);
            let on_axis = segment.start + axis * station;
            let weight = gravity * mass.mass;
            let to_beam = segment.base_from_beam.transpose();
            segment.local += point_load_deflection(
                length,
                &self.segments[index].compliance,
                station,
                &(to_beam * weight),
                &(to_beam * (position - on_axis).cross(&weight)),
            );
        }
    }
}

/// The weight each joint carries, and the weight of the masses at each tool, as forces and
/// moments about the base origin, base frame (N, N·m).
#[derive(Default)]
pub(crate) struct Loads {
    pub(crate) force: Vec<Vec3>,
    pub(crate) torque: Vec<Vec3>,
    pub(crate) tool_force: Vec<Vec3>,
    pub(crate) tool_torque: Vec<Vec3>,
}

/// The segment of frame `frame`'s body nearest to `point` (base frame), the first on ties.
fn nearest_segment(
    model: &[super::model::Segment],
    placed: &[SegmentDeformation],
    frame: usize,
    point: &Vec3,
) -> Option<usize> {
    let distance = |placed: &SegmentDeformation| {
        let along = placed.end - placed.start;
        let length_squared = along.norm_squared();
        let t = if length_squared > 0.0 {
            ((point - placed.start).dot(&along) / length_squared).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (point - placed.start - along * t).norm()
    };
    // A body with one segment (all but a branching torso's): that one, no distance needed.
    let mut candidates = model.iter().enumerate().filter(|(_, s)| s.frame == frame);
    let first = candidates.next()?.0;
    if candidates.next().is_none() {
        return Some(first);
    }
    // Each distance once (the first of equal ones still wins).
    model
        .iter()
        .zip(placed)
        .enumerate()
        .filter(|(_, (s, _))| s.frame == frame)
        .map(|(index, (_, placed))| (index, distance(placed)))
        .min_by(|(_, a), (_, b)| a.total_cmp(b))
        .map(|(index, _)| index)
}

/// The beam frame of a segment along `along` (base frame): x along the segment, z the moved
/// frame's `reference` column made perpendicular to x, y = z × x. A zero-length segment gets
/// the moved frame itself (its deflection is zero anyway).
pub(super) fn beam_frame(along: &Vec3, moved: &Mat3, reference: usize) -> Mat3 {
    let Some(x) = along.try_normalize(1e-12) else {
        return *moved;
    };
    // The reference axis was chosen as the most perpendicular at build time; should a changed
    // model make it parallel, the next axis serves.
    let z = [reference, (reference + 1) % 3, (reference + 2) % 3]
        .into_iter()
        .find_map(|k| {
            let axis = moved.column(k).into_owned();
            (axis - x * axis.dot(&x)).try_normalize(1e-6)
        })
        .unwrap_or_else(|| moved.column(2).into_owned());
    Mat3::from_columns(&[x, z.cross(&x), z])
}
