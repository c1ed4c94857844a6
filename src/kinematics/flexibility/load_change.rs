//! The closed-form change of the loads and deformations with one MCPC parameter
//! (docs/flexibility.md §11): a parameter of frame f turns and shifts everything after Σ_f's
//! parent rigidly (a parameter of a tool, that tool alone), so every mass it carries moves by
//! one twist; the weights stay, their moments change, and the segments whose ends move change
//! length, beam frame and the stations of their self-weight. First order, at one evaluation:
//! no per-parameter evaluation of the loads.

use super::beam::point_load_deflection_change;
use super::loads::{beam_frame, Evaluation};
use super::model::{FlexibilityModel, Place, SegmentEnd};
use crate::kinematics::McpcModel;
use crate::math::{Mat3, Transform, Vec3};
use nalgebra::Vector6;

/// How one MCPC parameter moves the nominal chain, per unit parameter: what it reaches turns
/// by `omega`, and a point x of it moves by `linear + omega × x`.
pub(super) struct Reach {
    omega: Vec3,
    linear: Vec3,
    /// Per MCPC frame: whether Σᵢ and its moved frame move.
    frames: Vec<bool>,
    /// Per tool: whether the tool frame moves.
    tools: Vec<bool>,
}

impl Reach {
    /// Parameter `p`'s reach at the nominal frames of `evaluation` (`root`: the frame the
    /// root-side frames hang from); `None` for a parameter that is not a frame's or a tool's
    /// (joint errors, the measurement frame), which the caller differences.
    pub(super) fn of(
        model: &McpcModel,
        evaluation: &Evaluation,
        root: &Transform,
        p: usize,
    ) -> Option<Reach> {
        let before = |parent: Option<usize>| parent.map_or(*root, |i| evaluation.moved[i]);
        let frame_count = model.frames().len();
        for (f, frame) in model.frames().iter().enumerate() {
            let k = p.wrapping_sub(model.frame_parameter_offset(f));
            if k >= frame.kind.parameter_count() {
                continue;
            }
            // α and β turn about axes through P's origin, x and y shift along Σ_f's axes: the
            // identification Jacobian's columns (kinematics/jacobian.rs).
            let previous = before(frame.parent);
            let (omega, linear) = if k < 2 {
                let axis = previous.rotation * model.frame_axes(f)[k];
                (axis, -axis.cross(&previous.translation))
            } else {
                let axes = &evaluation.frames[f].rotation;
                (Vec3::zeros(), axes.column(k - 2).into_owned())
            };
            // Frames come parents first.
            let mut frames = vec![false; frame_count];
            for (j, other) in model.frames().iter().enumerate() {
                frames[j] = j == f || other.parent.is_some_and(|i| frames[i]);
            }
            let tools = model
                .tools()
                .iter()
                .map(|t| t.parent.is_some_and(|i| frames[i]))
                .collect();
            return Some(Reach {
                omega,
                linear,
                frames,
                tools,
            });
        }
        for (t, tool) in model.tools().iter().enumerate() {
            let k = p.wrapping_sub(model.tool_parameter_offset(t));
            if k >= 6 {
                continue;
            }
            let previous = before(tool.parent);
            let (omega, linear) = if k < 3 {
                let axis = previous.rotation * model.tool_axes(t)[k];
                (axis, -axis.cross(&previous.translation))
            } else {
                let axes = &evaluation.tools[t].rotation;
                (Vec3::zeros(), axes.column(k - 3).into_owned())
            };
            let mut tools = vec![false; model.tools().len()];
            tools[t] = true;
            return Some(Reach {
                omega,
                linear,
                frames: vec![false; frame_count],
                tools,
            });
        }
        None
    }

    fn velocity(&self, x: &Vec3) -> Vec3 {
        self.linear + self.omega.cross(x)
    }

    /// The rotation rate of frame `i` (zero outside the reach).
    fn turning(&self, i: usize) -> Vec3 {
        if self.frames[i] {
            self.omega
        } else {
            Vec3::zeros()
        }
    }

    /// The velocity of point `x` of frame `i` (zero outside the reach).
    fn of_frame(&self, i: usize, x: &Vec3) -> Vec3 {
        if self.frames[i] {
            self.velocity(x)
        } else {
            Vec3::zeros()
        }
    }
}

/// What a parameter changes, per unit: each joint's local rotation `[Δα, Δβ, Δθ]`, and each
/// segment's parts in its proximal nominal moved frame (free end, translation, rotation; see
/// `derivative.rs`).
#[derive(Debug, Default)]
pub(super) struct Change {
    pub(super) joints: Vec<Vec3>,
    pub(super) segments: Vec<[Vec3; 3]>,
}

/// The buffers of [`FlexibilityModel::load_change`], reused from one parameter to the next.
#[derive(Default)]
pub(super) struct Scratch {
    /// Per mass: its velocity (zero outside the reach).
    velocities: Vec<Vec3>,
    /// Per frame and per tool: the change of the subtree's moment about the base origin.
    torque: Vec<Vec3>,
    tool_torque: Vec<Vec3>,
    /// Per segment: whether anything of it changes (an end, its frame, a load on it).
    touched: Vec<bool>,
    /// Per segment: its beam's change (touched segments only) and the change of `d_link`.
    beams: Vec<Option<Beam>>,
    d_local: Vec<Vector6<f64>>,
}

/// A segment's beam at the evaluation and its change: clamp, length, axis and beam frame.
struct Beam {
    /// Whether the beam itself stays (no end moves, its frame does not turn): then only its
    /// tip load changes, and a mass that stays adds nothing.
    still: bool,
    start: Vec3,
    d_start: Vec3,
    d_end: Vec3,
    length: f64,
    d_length: f64,
    axis: Vec3,
    d_axis: Vec3,
    frame: Mat3,
    d_frame: Mat3,
}

impl FlexibilityModel {
    /// The change of every deformation with the parameter of `reach`, in closed form, into
    /// `change`. What the parameter leaves alone (another arm's joints and segments) is zero
    /// without arithmetic.
    pub(super) fn load_change(
        &self,
        model: &McpcModel,
        evaluation: &Evaluation,
        reach: &Reach,
        scratch: &mut Scratch,
        change: &mut Change,
    ) {
        let Scratch {
            velocities,
            torque,
            tool_torque,
            touched,
            ..
        } = scratch;
        velocities.clear();
        velocities.extend(
            self.masses
                .iter()
                .zip(&evaluation.positions)
                .map(|(mass, position)| {
                    let moves = match mass.place {
                        Place::Body(frame, _) | Place::Tree { frame, .. } => reach.frames[frame],
                        Place::Tool(tool, _)
                        | Place::ToolBody(tool, _)
                        | Place::ToolTree { tool, .. } => reach.tools[tool],
                    };
                    if moves {
                        reach.velocity(position)
                    } else {
                        Vec3::zeros()
                    }
                }),
        );
        // The weights stay; their moments about the base origin change by v × w.
        reset(torque, model.frames().len(), Vec3::zeros());
        reset(tool_torque, model.tools().len(), Vec3::zeros());
        reset(touched, self.segments.len(), false);
        for (k, (mass, velocity)) in self.masses.iter().zip(velocities.iter()).enumerate() {
            if *velocity == Vec3::zeros() {
                continue;
            }
            let moment = velocity.cross(&(evaluation.gravity * mass.mass));
            torque[mass.frame] += moment;
            if let Place::Tool(tool, _) = mass.place {
                tool_torque[tool] += moment;
            }
            if let Some(index) = evaluation.mass_segments[k] {
                touched[index] = true;
            }
        }
        for i in (0..torque.len()).rev() {
            if let Some(p) = model.frames()[i].parent {
                let t = torque[i];
                torque[p] += t;
            }
        }
        change.joints.clear();
        change.joints.extend((0..torque.len()).map(|i| {
            if !reach.frames[i] && torque[i] == Vec3::zeros() {
                return Vec3::zeros();
            }
            let moved = &evaluation.moved[i];
            let joint = &evaluation.deformations.joints[i];
            // τ = N − o × F in the moved frame: dτ_local = Rᵀ(dN − do × F − ω × τ).
            let d_moment = torque[i] - reach.of_frame(i, &moved.translation).cross(&joint.force);
            let local =
                moved.rotation.transpose() * (d_moment - reach.turning(i).cross(&joint.moment));
            let (bending, torsion) = self.joint_compliance[i];
            Vec3::new(bending * local.x, bending * local.y, torsion * local.z)
        }));
        self.segment_changes(evaluation, reach, scratch, change);
    }

    /// Every segment's change of parts, from its tip load and its self-weight loads.
    fn segment_changes(
        &self,
        evaluation: &Evaluation,
        reach: &Reach,
        scratch: &mut Scratch,
        change: &mut Change,
    ) {
        let loads = &evaluation.loads;
        let Scratch {
            velocities,
            torque,
            tool_torque,
            touched,
            beams,
            d_local,
        } = scratch;
        beams.clear();
        d_local.clear();
        for (index, segment) in self.segments.iter().enumerate() {
            let (force, tip_torque, d_tip_torque, end_moves) = match segment.end {
                SegmentEnd::Frame(j) => {
                    (loads.force[j], loads.torque[j], torque[j], reach.frames[j])
                }
                SegmentEnd::Tool(t) => (
                    loads.tool_force[t],
                    loads.tool_torque[t],
                    tool_torque[t],
                    reach.tools[t],
                ),
            };
            touched[index] |=
                end_moves || reach.frames[segment.frame] || d_tip_torque != Vec3::zeros();
            if !touched[index] {
                beams.push(None);
                d_local.push(Vector6::zeros());
                continue;
            }
            let beam = self.beam_change(evaluation, reach, index);
            let placed = &evaluation.deformations.segments[index];
            let moment = tip_torque - placed.end.cross(&force);
            let d_moment = d_tip_torque - beam.d_end.cross(&force);
            d_local.push(beam.deflection_change(
                &segment.compliance,
                beam.length,
                beam.d_length,
                &force,
                (&moment, &d_moment),
            ));
            beams.push(Some(beam));
        }
        for (k, (mass, position)) in self.masses.iter().zip(&evaluation.positions).enumerate() {
            let Some(index) = evaluation.mass_segments[k] else {
                continue;
            };
            let Some(beam) = &beams[index] else {
                continue;
            };
            let velocity = &velocities[k];
            if beam.still && *velocity == Vec3::zeros() {
                continue;
            }
            let raw = (position - beam.start).dot(&beam.axis);
            let (station, d_station) = if raw <= 0.0 {
                (0.0, 0.0)
            } else if raw >= beam.length {
                (beam.length, beam.d_length)
            } else {
                let d_raw = (velocity - beam.d_start).dot(&beam.axis)
                    + (position - beam.start).dot(&beam.d_axis);
                (raw, d_raw)
            };
            let on_axis = beam.start + beam.axis * station;
            let d_on_axis = beam.d_start + beam.d_axis * station + beam.axis * d_station;
            let weight = evaluation.gravity * mass.mass;
            let moment = (position - on_axis).cross(&weight);
            let d_moment = (velocity - d_on_axis).cross(&weight);
            d_local[index] += beam.deflection_change(
                &self.segments[index].compliance,
                station,
                d_station,
                &weight,
                (&moment, &d_moment),
            );
        }
        change.segments.clear();
        change
            .segments
            .extend(self.segments.iter().enumerate().map(|(index, segment)| {
                let Some(beam) = &beams[index] else {
                    return [Vec3::zeros(); 3];
                };
                let placed = &evaluation.deformations.segments[index];
                let d_local = &d_local[index];
                let to_local = evaluation.moved[segment.frame].rotation.transpose();
                let turning = reach.turning(segment.frame);
                // The deformation in the base frame is B·local; in the moved frame Rᵀ·(B·local).
                let in_moved = |rows: usize, value: &Vec3| -> Vec3 {
                    let local = placed.local.fixed_rows::<3>(rows);
                    let d = d_local.fixed_rows::<3>(rows);
                    let change = beam.d_frame * local + beam.frame * d;
                    to_local * (change - turning.cross(value))
                };
                let along = placed.end - placed.start;
                [
                    to_local * (beam.d_end - beam.d_start - turning.cross(&along)),
                    in_moved(0, &placed.translation),
                    in_moved(3, &placed.rotation),
                ]
            }));
    }

    /// Segment `index`'s beam and its change with the parameter of `reach` (beam frame:
    /// normalisation of the axis, Gram–Schmidt of the reference column). A segment of zero
    /// length takes the one-sided change in the direction its end moves (as a forward
    /// difference would): the beam along that direction, its length the distance moved.
    fn beam_change(&self, evaluation: &Evaluation, reach: &Reach, index: usize) -> Beam {
        let segment = &self.segments[index];
        let placed = &evaluation.deformations.segments[index];
        let moved = &evaluation.moved[segment.frame];
        let d_start = reach.of_frame(segment.frame, &placed.start);
        let end_moves = match segment.end {
            SegmentEnd::Frame(j) => reach.frames[j],
            SegmentEnd::Tool(t) => reach.tools[t],
        };
        let d_end = if end_moves {
            reach.velocity(&placed.end)
        } else {
            Vec3::zeros()
        };
        let along = placed.end - placed.start;
        let d_along = d_end - d_start;
        let length = along.norm();
        if along.try_normalize(1e-12).is_none() {
            let frame = beam_frame(&d_along, &moved.rotation, segment.reference_axis);
            return Beam {
                still: false,
                start: placed.start,
                d_start,
                d_end,
                length,
                d_length: d_along.norm(),
                axis: frame.column(0).into_owned(),
                d_axis: Vec3::zeros(),
                frame,
                d_frame: Mat3::zeros(),
            };
        }
        let frame = placed.base_from_beam;
        let axis = frame.column(0).into_owned();
        let d_length = axis.dot(&d_along);
        let d_axis = (d_along - axis * d_length) / length;
        let turning = reach.turning(segment.frame);
        // z = (r − x(r·x)) / |…| for the moved frame's column r that `beam_frame` took.
        let reference = segment.reference_axis;
        let chosen = [reference, (reference + 1) % 3, (reference + 2) % 3]
            .into_iter()
            .find_map(|k| {
                let r = moved.rotation.column(k).into_owned();
                let u = r - axis * r.dot(&axis);
                u.try_normalize(1e-6).map(|_| (r, u.norm()))
            });
        let z = frame.column(2).into_owned();
        let d_z = match chosen {
            Some((r, size)) => {
                let d_r = turning.cross(&r);
                let d_u = d_r - d_axis * r.dot(&axis) - axis * (d_r.dot(&axis) + r.dot(&d_axis));
                (d_u - z * z.dot(&d_u)) / size
            }
            None => turning.cross(&z),
        };
        let d_y = d_z.cross(&axis) + z.cross(&d_axis);
        Beam {
            still: d_start == Vec3::zeros() && d_end == Vec3::zeros() && turning == Vec3::zeros(),
            start: placed.start,
            d_start,
            d_end,
            length,
            d_length,
            axis,
            d_axis,
            frame,
            d_frame: Mat3::from_columns(&[d_axis, d_y, d_z]),
        }
    }
}

/// `buffer` as `size` copies of `value`, in its own allocation.
fn reset<T: Clone>(buffer: &mut Vec<T>, size: usize, value: T) {
    buffer.clear();
    buffer.resize(size, value);
}

impl Beam {
    /// The change of the deflection under `force` and `moment` (base frame, with the
    /// moment's change; the force is a weight, constant) at `station`.
    fn deflection_change(
        &self,
        compliance: &super::beam::BeamCompliance,
        station: f64,
        d_station: f64,
        force: &Vec3,
        (moment, d_moment): (&Vec3, &Vec3),
    ) -> Vector6<f64> {
        let (to_beam, d_to_beam) = (self.frame.transpose(), self.d_frame.transpose());
        let local_force = to_beam * force;
        let local_moment = to_beam * moment;
        point_load_deflection_change(
            self.length,
            self.d_length,
            compliance,
            station,
            d_station,
            (&local_force, &(d_to_beam * force)),
            (&local_moment, &(d_to_beam * moment + to_beam * d_moment)),
        )
    }
}
