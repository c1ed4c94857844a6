//! Building the flexibility model: bodies, segments and masses of a robot, with its stiffness.

use super::beam::BeamCompliance;
use super::names::{Membership, Names};
use super::stiffness::{LinkStiffness, Stiffness};
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::math::{Pose, Vec3};
use crate::tree::{JointKind, KinematicTree, LinkId};

/// Where a link segment ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SegmentEnd {
    /// At the origin of MCPC frame Σⱼ (index in [`McpcModel::frames`]).
    Frame(usize),
    /// At the origin of a tool frame (index in [`McpcModel::tools`]).
    Tool(usize),
}

/// A link segment: a straight cantilever from a joint origin to the next joint or tool origin.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// The MCPC frame whose body the segment is; it is clamped at that joint's origin.
    pub frame: usize,
    /// Where it ends.
    pub end: SegmentEnd,
    /// Its rigidities.
    pub stiffness: LinkStiffness,
    /// Compliances (scaled by [`FlexibilityModel::scaled`]).
    pub(crate) compliance: BeamCompliance,
    /// The column (0 = x, 1 = y, 2 = z) of the proximal moved frame that, made perpendicular to
    /// the segment, is the beam's z axis.
    pub(crate) reference_axis: usize,
}

/// Where a mass sits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Place {
    /// Fixed to MCPC frame `frame`'s body: the point in that frame's moved frame Σ·Q(θ).
    Body(usize, Vec3),
    /// At a tool: the point in the tool frame (a payload).
    Tool(usize, Vec3),
    /// A link fixed to a tool link (or the tool link itself): the point in the tool frame. It
    /// moves with the tool frame, as the exported URDF moves it, but loads its body's segment
    /// like any link's weight.
    ToolBody(usize, Vec3),
    /// Behind joints outside the model: the point in URDF link `link`, placed relative to the
    /// body link `body_link` of MCPC frame `frame` with the tree's forward kinematics.
    Tree {
        frame: usize,
        body_link: LinkId,
        link: LinkId,
        point: Vec3,
    },
    /// Behind joints outside the model below tool link `tool_link`: the point in URDF link
    /// `link`, placed relative to tool `tool`'s frame with the tree's forward kinematics.
    ToolTree {
        tool: usize,
        tool_link: LinkId,
        link: LinkId,
        point: Vec3,
    },
}

/// A point mass that loads the structure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Mass {
    /// kg.
    pub(crate) mass: f64,
    pub(crate) place: Place,
    /// The MCPC frame whose subtree carries it.
    pub(crate) frame: usize,
    /// The segment it loads along its length (self-weight), as built; `None` for payloads,
    /// which load their tool's segment at its tip. Evaluation loads the body's segment nearest
    /// to it at the current geometry (the same one unless the geometry moved it closer to
    /// another).
    pub(crate) segment: Option<usize>,
}

/// The flexibility error model of a robot (paper section 3): gravity loads, joint and link
/// compliance, and what they do to the tools. Built once; evaluated per configuration.
#[derive(Debug, Clone)]
pub struct FlexibilityModel {
    pub(crate) gravity: Vec3,
    /// Whether `gravity` is given in the measurement frame (a levelled tracker) rather than
    /// in the robot's root frame.
    pub(crate) gravity_in_measurement_frame: bool,
    /// Per MCPC frame: (bending, torsion) compliance, rad/(N·m).
    pub(crate) joint_compliance: Vec<(f64, f64)>,
    pub(crate) segments: Vec<Segment>,
    pub(crate) masses: Vec<Mass>,
    /// Per MCPC frame: the segment that ends at its origin (`None` on the base).
    pub(crate) segment_to_frame: Vec<Option<usize>>,
    /// Per tool: the segment that ends at its origin (`None` on the base).
    pub(crate) segment_to_tool: Vec<Option<usize>>,
    /// Whether some mass needs the tree's forward kinematics.
    pub(crate) uses_tree: bool,
    pub(crate) link_count: usize,
    /// Per tool: the MCPC frame that carries it (`None` on the base).
    pub(crate) tool_parent: Vec<Option<usize>>,
}

impl FlexibilityModel {
    /// The flexibility model of `model`'s branches of `tree`, loaded and stiffened as
    /// `stiffness` says. Fails on bad numbers and on names that do not fit the robot.
    pub fn new(tree: &KinematicTree, model: &McpcModel, stiffness: &Stiffness) -> Result<Self> {
        stiffness.validate()?;
        let bad = |message: String| Error::InvalidData {
            origin: "stiffness".into(),
            message,
        };
        let names = Names::new(tree, model);
        let frame_count = model.frames().len();

        let mut joint_stiffness = vec![None; frame_count];
        for (name, value) in &stiffness.joint_overrides {
            let frame = names.joint(name).map_err(&bad)?;
            if joint_stiffness[frame].replace(*value).is_some() {
                return Err(bad(format!("joint '{name}' is given twice")));
            }
        }
        let joint_compliance = joint_stiffness
            .iter()
            .map(|s| {
                let s = s.unwrap_or(stiffness.joint_default);
                (s.bending.recip(), s.torsion.recip())
            })
            .collect();

        let mut body_stiffness: Vec<Option<(&str, LinkStiffness)>> = vec![None; frame_count];
        for (name, value) in &stiffness.link_overrides {
            let frame = names.body(name).map_err(&bad)?;
            if let Some((other, _)) = body_stiffness[frame].replace((name, *value)) {
                return Err(bad(format!(
                    "'{other}' and '{name}' name the same body; give its stiffness once"
                )));
            }
        }

        // Segments: from each frame's origin to each child frame's and each tool's origin.
        let mut segments = Vec::new();
        let mut segment_to_frame = vec![None; frame_count];
        let mut segment_to_tool = vec![None; model.tools().len()];
        let ends = model
            .frames()
            .iter()
            .enumerate()
            .filter_map(|(j, f)| f.parent.map(|p| (p, SegmentEnd::Frame(j))))
            .chain(
                model
                    .tools()
                    .iter()
                    .enumerate()
                    .filter_map(|(t, tool)| tool.parent.map(|p| (p, SegmentEnd::Tool(t)))),
            );
        for (frame, end) in ends {
            let (slot, offset) = match end {
                SegmentEnd::Frame(j) => (
                    &mut segment_to_frame[j],
                    model.frame_constant(j).translation,
                ),
                SegmentEnd::Tool(t) => {
                    (&mut segment_to_tool[t], model.tool_constant(t).translation)
                }
            };
            *slot = Some(segments.len());
            let stiffness = body_stiffness[frame].map_or(stiffness.link_default, |(_, s)| s);
            segments.push(Segment {
                frame,
                end,
                stiffness,
                compliance: BeamCompliance::from_stiffness(&stiffness),
                reference_axis: reference_axis(&offset),
            });
        }

        let masses = collect_masses(tree, model, stiffness, &names, &segments)?;
        let uses_tree = masses
            .iter()
            .any(|m| matches!(m.place, Place::Tree { .. } | Place::ToolTree { .. }));
        Ok(Self {
            gravity: stiffness.gravity,
            gravity_in_measurement_frame: false,
            joint_compliance,
            segments,
            masses,
            segment_to_frame,
            segment_to_tool,
            uses_tree,
            link_count: tree.links().len(),
            tool_parent: model.tools().iter().map(|t| t.parent).collect(),
        })
    }

    /// A copy with every compliance (joint and link) multiplied by `factor` ≥ 0: 0 is rigid,
    /// 1.1 is "10 % softer". Deflections scale with it (exactly for [`Self::tool_deflections`]).
    pub fn scaled(&self, factor: f64) -> Result<Self> {
        if !(factor.is_finite() && factor >= 0.0) {
            return Err(Error::InvalidData {
                origin: "compliance scale".into(),
                message: format!("factor {factor} is not a finite non-negative number"),
            });
        }
        let mut scaled = self.clone();
        for (bending, torsion) in &mut scaled.joint_compliance {
            *bending *= factor;
            *torsion *= factor;
        }
        for segment in &mut scaled.segments {
            segment.compliance = segment.compliance.scaled(factor);
        }
        Ok(scaled)
    }

    /// The link segments, in the order of [`super::Deformations::segments`].
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// The gravity vector, m/s², in the root frame or, after
    /// [`Self::with_gravity_in_measurement_frame`], in the measurement frame.
    pub fn gravity(&self) -> Vec3 {
        self.gravity
    }

    /// A copy whose gravity vector is fixed in the measurement frame (see
    /// [`crate::McpcModel::set_world_from_base`]) instead of the root frame: right for a
    /// levelled laser tracker. A calibration that fits the measurement frame absorbs part of
    /// the robot's geometric error into it, so gravity tied to the fitted root frame would be
    /// tilted by that error (docs/flexibility.md).
    pub fn with_gravity_in_measurement_frame(&self) -> Self {
        let mut copy = self.clone();
        copy.gravity_in_measurement_frame = true;
        copy
    }

    /// A copy in which every tool (not fixed to the base) carries a payload of `mass` kg: the
    /// file's payload at that tool gets this mass (several there: the first, the others none),
    /// and a tool without one gets it at its origin. For measurements taken at several
    /// payloads (docs/flexibility.md, section 12).
    pub fn with_payload_at_every_tool(&self, mass: f64) -> Result<Self> {
        if let Some(message) = super::stiffness::mass_problem(mass) {
            return Err(Error::InvalidData {
                origin: "payload".into(),
                message: format!("mass {message}"),
            });
        }
        let mut copy = self.clone();
        let mut given = vec![false; self.segment_to_tool.len()];
        for m in &mut copy.masses {
            if let Place::Tool(tool, _) = m.place {
                m.mass = if given[tool] { 0.0 } else { mass };
                given[tool] = true;
            }
        }
        for (tool, done) in given.iter().enumerate() {
            let Some(frame) = self.tool_parent[tool] else {
                continue;
            };
            if !done {
                copy.masses.push(Mass {
                    mass,
                    place: Place::Tool(tool, Vec3::zeros()),
                    frame,
                    segment: None,
                });
            }
        }
        Ok(copy)
    }

    /// The model for one measurement row: this one when the row states no payload, else a
    /// copy with `payload` kg at every tool ([`Self::with_payload_at_every_tool`]).
    pub fn for_payload(&self, payload: Option<f64>) -> Result<std::borrow::Cow<'_, Self>> {
        match payload {
            None => Ok(std::borrow::Cow::Borrowed(self)),
            Some(mass) => self
                .with_payload_at_every_tool(mass)
                .map(std::borrow::Cow::Owned),
        }
    }

    /// Total mass that loads the structure (links when self-weight is on, and payloads), kg.
    pub fn total_mass(&self) -> f64 {
        self.masses.iter().map(|m| m.mass).sum()
    }
}

/// The moved-frame axis (0 = x, 1 = y, 2 = z) most nearly perpendicular to a segment along
/// `offset`: z (the joint axis) unless the segment runs closer to it than to x or y.
fn reference_axis(offset: &Vec3) -> usize {
    let direction = offset.try_normalize(1e-12).unwrap_or_else(Vec3::x);
    [2, 0, 1]
        .into_iter()
        .min_by(|&a, &b| direction[a].abs().total_cmp(&direction[b].abs()))
        .unwrap_or(2)
}

/// The point masses: link centres of mass (with self-weight on) and payloads.
fn collect_masses(
    tree: &KinematicTree,
    model: &McpcModel,
    stiffness: &Stiffness,
    names: &Names,
    segments: &[Segment],
) -> Result<Vec<Mass>> {
    let zero = tree.link_poses(&tree.zero_configuration())?;
    let under_tool = links_under_tools(tree, model);
    let mut masses = Vec::new();
    if stiffness.self_weight {
        for (index, link) in tree.links().iter().enumerate() {
            let Membership::Body { frame, rigid } = names.membership()[index] else {
                continue;
            };
            let Some(inertial) = link.inertial.as_ref().filter(|i| i.mass > 0.0) else {
                continue;
            };
            let body_link = tree.joint(model.frames()[frame].joint).child;
            let frame_from_body_link: Pose = model.frames()[frame].frame_from_link;
            // At the zero configuration; constant for links fixed to the body.
            let in_frame = frame_from_body_link
                * zero[body_link.0].inverse()
                * zero[index]
                * nalgebra::Point3::from(inertial.center_of_mass());
            let place = if let Some((tool, tool_rigid)) = under_tool[index] {
                // At or below a tool link without children: it follows the tool frame (the
                // exported URDF moves such a tool link to the calibrated tool pose, and what
                // hangs from it along).
                let tool_link = model.tools()[tool].link;
                if tool_rigid {
                    let in_tool = zero[tool_link.0].inverse()
                        * zero[index]
                        * nalgebra::Point3::from(inertial.center_of_mass());
                    Place::ToolBody(tool, in_tool.coords)
                } else {
                    Place::ToolTree {
                        tool,
                        tool_link,
                        link: LinkId(index),
                        point: inertial.center_of_mass(),
                    }
                }
            } else if rigid {
                Place::Body(frame, in_frame.coords)
            } else {
                Place::Tree {
                    frame,
                    body_link,
                    link: LinkId(index),
                    point: inertial.center_of_mass(),
                }
            };
            masses.push(Mass {
                mass: inertial.mass,
                place,
                frame,
                segment: nearest_segment(model, segments, frame, &in_frame.coords),
            });
        }
    }
    let names_error = |message: String| Error::InvalidData {
        origin: "stiffness".into(),
        message,
    };
    for payload in &stiffness.payloads {
        let tool = names.tool(&payload.link).map_err(names_error)?;
        // A tool fixed to the base: its payload loads nothing that deflects.
        let Some(frame) = model.tools()[tool].parent else {
            continue;
        };
        masses.push(Mass {
            mass: payload.mass,
            place: Place::Tool(tool, payload.center_of_mass),
            frame,
            segment: None,
        });
    }
    Ok(masses)
}

/// Per link: the tool whose tool link is the link itself or an ancestor reached without a
/// calibrated joint, and whether only fixed joints lie in between. A tool link with child
/// links carries none: the export keeps such a link at its nominal place on the calibrated
/// chain (the measured frame goes into an added marker link), so its weight and its
/// children's stay with the body instead of following the measured frame.
fn links_under_tools(tree: &KinematicTree, model: &McpcModel) -> Vec<Option<(usize, bool)>> {
    let mut under: Vec<Option<(usize, bool)>> = vec![None; tree.links().len()];
    // Links are in topological order, so a link's parent is assigned before the link.
    for (index, link) in tree.links().iter().enumerate() {
        let id = LinkId(index);
        if let Some(tool) = model.tool_of_link(id) {
            if model.tools()[tool].parent.is_some() && link.child_joints.is_empty() {
                under[index] = Some((tool, true));
            }
            continue;
        }
        let Some(joint_id) = link.parent_joint else {
            continue;
        };
        if model.frame_of_joint(joint_id).is_some() {
            continue;
        }
        let joint = tree.joint(joint_id);
        under[index] = under[joint.parent.0]
            .map(|(tool, rigid)| (tool, rigid && joint.kind == JointKind::Fixed));
    }
    under
}

/// The segment of frame `frame`'s body closest to `point` (in the moved frame), first on ties.
fn nearest_segment(
    model: &McpcModel,
    segments: &[Segment],
    frame: usize,
    point: &Vec3,
) -> Option<usize> {
    let distance = |segment: &Segment| {
        let end = match segment.end {
            SegmentEnd::Frame(j) => model.frame_constant(j).translation,
            SegmentEnd::Tool(t) => model.tool_constant(t).translation,
        };
        let length_squared = end.norm_squared();
        let along = if length_squared > 0.0 {
            (point.dot(&end) / length_squared).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (point - end * along).norm()
    };
    segments
        .iter()
        .enumerate()
        .filter(|(_, s)| s.frame == frame)
        .min_by(|(_, a), (_, b)| distance(a).total_cmp(&distance(b)))
        .map(|(index, _)| index)
}
