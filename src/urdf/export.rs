//! Calibrated MCPC model → URDF, by editing the original file in place.
//!
//! Only the `<origin xyz rpy>` (inserted where missing) and `<axis xyz>` of the joints whose
//! placement changes are rewritten; every other byte of the file stays as it was, so
//! `<transmission>`, `<gazebo>`, comments, limits, mimic tags and formatting survive. The
//! math is in `docs/export.md`: every link on the modelled chains gets its calibrated pose at
//! zero joint values, every other link keeps its pose relative to its parent link, and a
//! changed joint's origin is `parent_pose⁻¹ · child_pose`. The measurement frame
//! ([`McpcModel::world_from_base`]) is not part of a URDF and is not exported.

use super::export_options::{
    added_links_xml, AddedReason, AddedToolLink, DroppedOffset, ExportOptions,
};
use super::xml::{position, scan, unescape, Element};
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::math::{pose, rpy_from_rotation, Pose, Rotation, Vec3};
use crate::tree::{Joint, JointKind, KinematicTree, Link, LinkId};

/// A joint origin change smaller than this (m, and rad as twice the relative quaternion's
/// vector part) is left out: the joint keeps its text exactly. A picometre is far below
/// anything a calibration can resolve, and it keeps a nominal export byte-identical.
pub const UNCHANGED_TOLERANCE: f64 = 1e-12;

pub use super::export_options::ON_AXIS_TOLERANCE;

/// One joint whose `<origin>` or `<axis>` was rewritten.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct JointChange {
    /// The joint's URDF name.
    pub joint: String,
    /// The original origin translation (m).
    pub old_xyz: [f64; 3],
    /// The exported origin translation (m).
    pub new_xyz: [f64; 3],
    /// The original origin roll, pitch, yaw (rad).
    pub old_rpy: [f64; 3],
    /// The exported origin roll, pitch, yaw (rad).
    pub new_rpy: [f64; 3],
    /// The original axis (unit), if the axis was rewritten.
    pub old_axis: Option<[f64; 3]>,
    /// The exported axis (unit), if the axis was rewritten.
    pub new_axis: Option<[f64; 3]>,
}

/// The exported URDF text and what changed in it.
#[derive(Debug, Clone)]
pub struct ExportReport {
    /// The new URDF document.
    pub urdf: String,
    /// The joints whose origin or axis changed, in tree order.
    pub changes: Vec<JointChange>,
    /// Tool offsets left out because they are within the calibration's uncertainty.
    pub dropped: Vec<DroppedOffset>,
    /// Links added at exact calibrated tool frames ([`ExportOptions::add_tool_links`]).
    pub added_links: Vec<AddedToolLink>,
}

/// Writes the calibrated `model` into the URDF text `original` (from which `tree` was
/// imported; `origin` names it in messages) and returns the edited text.
///
/// `model` is [`McpcModel::from_tree`] of `tree` with calibrated parameters set. The exported
/// file reproduces the model's tool and link poses in the base (root link) frame at every
/// configuration; `world_from_base` is not exported.
pub fn export_urdf(
    original: &str,
    origin: &str,
    tree: &KinematicTree,
    model: &McpcModel,
) -> Result<ExportReport> {
    export_urdf_with(original, origin, tree, model, &ExportOptions::default())
}

/// [`export_urdf`] with `options`: a tool link carried by a revolute joint whose calibrated
/// origin lies off the joint axis is moved onto the axis when the offset is within
/// [`ExportOptions::tolerance`] ([`ExportReport::dropped`]), else gets a fixed child link at the
/// exact tool frame when [`ExportOptions::add_tool_links`] is set
/// ([`ExportReport::added_links`]), else the export fails with an error saying both.
pub fn export_urdf_with(
    original: &str,
    origin: &str,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &ExportOptions,
) -> Result<ExportReport> {
    let mut dropped = Vec::new();
    let mut added_links = Vec::new();
    let document = Document::new(original, origin)?;
    // Links of the tree that the text does not declare: marker links added at load time
    // (fixed leaves on a link of the text). Any other link counts as in the text, so that a
    // text the tree was not loaded from fails on its first joint.
    let in_text: Vec<bool> = tree
        .links()
        .iter()
        .map(|l| {
            let marker = l.child_joints.is_empty()
                && l.parent_joint.is_some_and(|j| {
                    let joint = tree.joint(j);
                    joint.kind == JointKind::Fixed
                        && document.has_link(&tree.link(joint.parent).name)
                });
            document.has_link(&l.name) || !marker
        })
        .collect();
    let placements = calibrated_placements(
        tree,
        model,
        options,
        &in_text,
        &mut dropped,
        &mut added_links,
    )?;
    for added in &added_links {
        if document.has_link(&added.link) {
            return Err(Error::InvalidRobot {
                origin: origin.to_owned(),
                message: format!(
                    "the robot already has a link '{}', which the export would add below link '{}'; remove that link (and its fixed joint) from the URDF, or rename it, and export again",
                    added.link, added.parent
                ),
            });
        }
    }
    let mut edits: Vec<(usize, usize, String)> = Vec::new();
    let mut changes = Vec::new();
    for (index, placement) in placements.iter().enumerate() {
        let Some(placement) = placement else { continue };
        let joint = &tree.joints()[index];
        let element = document.joint(&joint.name)?;
        let parent_from_joint = placement
            .parent_from_joint
            .unwrap_or(joint.parent_from_joint);
        let new_rpy = rpy_from_rotation(&parent_from_joint.rotation);
        let new_xyz: [f64; 3] = parent_from_joint.translation.vector.into();
        if placement.parent_from_joint.is_some() {
            document.set_origin(element, &joint.name, new_xyz, new_rpy, &mut edits)?;
        }
        let (old_axis, new_axis) = match placement.axis {
            Some(axis) => {
                document.set_axis(element, &joint.name, axis, &mut edits)?;
                (Some(joint.axis.into_inner().into()), Some(axis.into()))
            }
            None => (None, None),
        };
        changes.push(JointChange {
            joint: joint.name.clone(),
            old_xyz: joint.parent_from_joint.translation.vector.into(),
            new_xyz,
            old_rpy: rpy_from_rotation(&joint.parent_from_joint.rotation),
            new_rpy,
            old_axis,
            new_axis,
        });
    }
    if !added_links.is_empty() {
        edits.push(document.before_root_end(&added_links)?);
    }
    let urdf = apply_edits(original, edits);
    Ok(ExportReport {
        urdf,
        changes,
        dropped,
        added_links,
    })
}

/// `original` with the `(start, end, replacement)` edits applied (non-overlapping ranges).
pub(super) fn apply_edits(original: &str, mut edits: Vec<(usize, usize, String)>) -> String {
    edits.sort_by_key(|(start, _, _)| std::cmp::Reverse(*start));
    let mut text = original.to_owned();
    for (start, end, replacement) in edits {
        text.replace_range(start..end, &replacement);
    }
    text
}

/// A joint's new placement: its origin and, where it changes, its axis (in the joint frame).
#[derive(Debug, Clone, Copy)]
struct Placement {
    /// The new origin, if it moved.
    parent_from_joint: Option<Pose>,
    /// The new axis, if it turned.
    axis: Option<Vec3>,
}

/// Twice the vector part of the relative quaternion: the rotation angle for small angles,
/// without the acos that makes `angle_to` blind below about 1e-8 rad.
pub(super) fn rotation_gap(a: &Rotation, b: &Rotation) -> f64 {
    2.0 * (a.inverse() * b).quaternion().imag().norm()
}

/// A calibrated tool frame that goes into a link the export adds (docs/export.md).
struct PendingLink {
    tool: String,
    link: String,
    parent: LinkId,
    reason: AddedReason,
    base_from_link: Pose,
    /// [`AddedReason::OffAxis`]: how far the calibrated tool origin lies off the joint axis
    /// (m), the link's reported offset.
    off_axis: Option<f64>,
}

/// Whether link `link` is a fixed leaf child of link `parent`: a marker link a previous export
/// added, whose joint origin may be rewritten.
fn is_fixed_leaf_below(tree: &KinematicTree, link: LinkId, parent: LinkId) -> bool {
    let l = tree.link(link);
    l.child_joints.is_empty()
        && l.parent_joint.is_some_and(|j| {
            let joint = tree.joint(j);
            joint.kind == JointKind::Fixed && joint.parent == parent
        })
}

/// The new placement of every joint whose origin or axis changes (`None`: keep the text).
/// `in_text[l]`: whether link `l` is declared in the URDF text (not a marker added at load).
fn calibrated_placements(
    tree: &KinematicTree,
    model: &McpcModel,
    options: &ExportOptions,
    in_text: &[bool],
    dropped: &mut Vec<DroppedOffset>,
    added_links: &mut Vec<AddedToolLink>,
) -> Result<Vec<Option<Placement>>> {
    let frames = model.frames();
    let (base_from_frame, mut target) = frame_targets(tree, model);
    let mut new_axis: Vec<Option<Vec3>> = vec![None; tree.joints().len()];
    let mut pending: Vec<PendingLink> = Vec::new();
    for tool in model.tools() {
        let previous = tool
            .parent
            .map_or_else(Pose::identity, |p| base_from_frame[p]);
        let last_from_tool = tool.constant_transform();
        let link = tree.link(tool.link);
        let Some(joint_id) = link.parent_joint else {
            return Err(Error::InvalidRobot {
                origin: tree.name().to_owned(),
                message: format!(
                    "tool link '{}' is the root link, which a URDF cannot move; choose a tool below a joint",
                    link.name
                ),
            });
        };
        let joint = tree.joint(joint_id);
        if !in_text[tool.link.0] {
            // A measured point added at load time: the text gets the link.
            pending.push(PendingLink {
                tool: link.name.clone(),
                link: link.name.clone(),
                parent: joint.parent,
                reason: AddedReason::Point,
                base_from_link: previous * last_from_tool,
                off_axis: None,
            });
            continue;
        }
        let has_children = link
            .child_joints
            .iter()
            .any(|&j| in_text[tree.joint(j).child.0]);
        if has_children {
            // The measured frame must not drag the links below the tool along: the tool link
            // keeps its nominal place on the calibrated chain, a marker link takes the frame.
            let name = format!("{}_marker", link.name);
            match tree.link_id(&name) {
                Ok(existing) if is_fixed_leaf_below(tree, existing, tool.link) => {
                    target[existing.0] = Some(previous * last_from_tool);
                }
                _ => pending.push(PendingLink {
                    tool: link.name.clone(),
                    link: name,
                    parent: tool.link,
                    reason: AddedReason::Marker,
                    base_from_link: previous * last_from_tool,
                    off_axis: None,
                }),
            }
            continue;
        }
        // Where the calibrated chain puts the link at its nominal offset (a frame's child).
        let on_chain = target[tool.link.0];
        target[tool.link.0] = Some(previous * last_from_tool);
        if !joint.kind.is_movable() {
            continue;
        }
        // The tool link is the moved frame's child itself: its frame must follow the tool
        // frame at every joint value, so the axis in the link frame is link_from_moved · z.
        if tool.parent.map(|p| frames[p].joint) != Some(joint_id) {
            return Err(Error::InvalidRobot {
                origin: tree.name().to_owned(),
                message: format!(
                    "tool link '{}' is carried by joint '{}', which is not the last joint of its chain in the model",
                    link.name, joint.name
                ),
            });
        }
        match on_axis_pose(
            tree,
            (link, joint),
            (tool.link, &previous, &last_from_tool),
            options,
            dropped,
            &mut pending,
        )? {
            Some(link_pose) => {
                target[tool.link.0] = Some(previous * link_pose);
                new_axis[joint_id.0] = Some(link_pose.rotation.inverse() * Vec3::z());
            }
            // A marker link takes the frame: the tool link keeps its place, axis untouched.
            None => target[tool.link.0] = on_chain,
        }
    }

    let (placements, exported) = placements_of(tree, &target, &new_axis, in_text);
    added_links.extend(added_tool_links(tree, pending, &exported));
    Ok(placements)
}

/// The calibrated pose of every frame in the base frame at zero joint values (the URDF origin
/// is the child's pose at joint value 0; mimic offsets are joint values like any other, so
/// nothing to undo), and the target pose of every frame's child link (`None` for the others).
fn frame_targets(tree: &KinematicTree, model: &McpcModel) -> (Vec<Pose>, Vec<Option<Pose>>) {
    let frames = model.frames();
    let mut base_from_frame: Vec<Pose> = Vec::with_capacity(frames.len());
    for frame in frames {
        let previous = frame
            .parent
            .map_or_else(Pose::identity, |p| base_from_frame[p]);
        base_from_frame.push(previous * frame.constant_transform());
    }
    let mut target: Vec<Option<Pose>> = vec![None; tree.links().len()];
    for (frame, base_from) in frames.iter().zip(&base_from_frame) {
        let child = tree.joint(frame.joint).child;
        target[child.0] = Some(base_from * frame.frame_from_link);
    }
    (base_from_frame, target)
}

/// The pose (in its moved frame) a tool link that is its joint's child gets: the calibrated
/// `last_from_tool`, or, off a rotational joint's axis, the closest frame a URDF joint can
/// carry with the offset dropped (within the tolerance); `None` when the offset is larger and
/// `add_tool_links` is set: the tool link (which may carry meshes and inertia) stays where its
/// joint puts it on the calibrated chain, and a marker link `<tool>_marker` is added at the
/// exact tool frame, as for a tool link with children. Else an error.
fn on_axis_pose(
    tree: &KinematicTree,
    (link, joint): (&Link, &Joint),
    (tool_link, previous, last_from_tool): (LinkId, &Pose, &Pose),
    options: &ExportOptions,
    dropped: &mut Vec<DroppedOffset>,
    pending: &mut Vec<PendingLink>,
) -> Result<Option<Pose>> {
    let last_from_tool = *last_from_tool;
    let off_axis = last_from_tool.translation.vector.xy().norm();
    let mut link_pose = last_from_tool;
    if joint.kind.is_rotational() && off_axis > ON_AXIS_TOLERANCE {
        // The closest frame a URDF joint can carry: the same orientation, the origin
        // projected onto the axis.
        let along = Vec3::new(0.0, 0.0, last_from_tool.translation.vector.z);
        link_pose = pose(along, last_from_tool.rotation);
        let tolerance = options.tolerance(&link.name);
        if off_axis <= tolerance {
            dropped.push(DroppedOffset {
                tool: link.name.clone(),
                joint: joint.name.clone(),
                offset_mm: off_axis * 1e3,
                tolerance_mm: tolerance * 1e3,
            });
        } else if options.add_tool_links {
            pending.push(PendingLink {
                tool: link.name.clone(),
                link: format!("{}_marker", link.name),
                parent: tool_link,
                reason: AddedReason::OffAxis,
                base_from_link: previous * last_from_tool,
                off_axis: Some(off_axis),
            });
            return Ok(None);
        } else {
            return Err(Error::InvalidRobot {
                origin: tree.name().to_owned(),
                message: format!(
                    "tool link '{}' is the child link of joint '{}' and its calibrated origin lies {:.4} mm off the joint axis, which a URDF joint cannot express, and more than the calibration's uncertainty allows to drop ({:.4} mm); export with `add_tool_links` to keep the tool link where the calibrated joint puts it and add a fixed link '{}_marker' at the exact calibrated tool frame, or calibrate a tool link below a fixed joint (add a <link> and a fixed <joint> under '{}')",
                    link.name,
                    joint.name,
                    off_axis * 1e3,
                    tolerance * 1e3,
                    link.name,
                    link.name
                ),
            });
        }
    }
    Ok(Some(link_pose))
}

/// The links to add to the text (measured points, markers, off-axis tools), placed relative
/// to their parents' exported poses; a marker at its parent's place is not added.
fn added_tool_links(
    tree: &KinematicTree,
    pending: Vec<PendingLink>,
    exported: &[Pose],
) -> Vec<AddedToolLink> {
    let mut added = Vec::new();
    for link in pending {
        let parent_from_link = exported[link.parent.0].inverse() * link.base_from_link;
        let at_parent = parent_from_link.translation.vector.norm() <= UNCHANGED_TOLERANCE
            && rotation_gap(&parent_from_link.rotation, &Rotation::identity())
                <= UNCHANGED_TOLERANCE;
        if link.reason == AddedReason::Marker && at_parent {
            // The measured frame is the tool link itself (a nominal model): nothing to add.
            continue;
        }
        added.push(AddedToolLink {
            // For an off-axis tool: how far its origin lies off the axis.
            offset_mm: link
                .off_axis
                .unwrap_or_else(|| parent_from_link.translation.vector.norm())
                * 1e3,
            tool: link.tool,
            link: link.link,
            parent: tree.link(link.parent).name.clone(),
            reason: link.reason,
            xyz: parent_from_link.translation.vector.into(),
            rpy: rpy_from_rotation(&parent_from_link.rotation),
            parent_from_link,
        });
    }
    added
}

/// The placements that reach the `target` poses, and the exported pose of every link: joint
/// by joint, so that an origin left unchanged (below the tolerance) is accounted for by the
/// joints after it instead of accumulating. Joints of links not in the text stay untouched.
fn placements_of(
    tree: &KinematicTree,
    target: &[Option<Pose>],
    new_axis: &[Option<Vec3>],
    in_text: &[bool],
) -> (Vec<Option<Placement>>, Vec<Pose>) {
    let mut exported: Vec<Pose> = Vec::with_capacity(tree.links().len());
    exported.push(Pose::identity());
    let mut placements = Vec::with_capacity(tree.joints().len());
    for (index, joint) in tree.joints().iter().enumerate() {
        let parent = exported[joint.parent.0];
        let child = target[joint.child.0].filter(|_| in_text[joint.child.0]);
        let Some(child) = child else {
            exported.push(parent * joint.parent_from_joint);
            placements.push(None);
            continue;
        };
        let parent_from_joint = parent.inverse() * child;
        let axis = new_axis[index].filter(|axis| {
            joint.kind != JointKind::Fixed
                && (axis - joint.axis.into_inner()).norm() > UNCHANGED_TOLERANCE
        });
        let moved = (parent_from_joint.translation.vector
            - joint.parent_from_joint.translation.vector)
            .norm()
            > UNCHANGED_TOLERANCE
            || rotation_gap(
                &parent_from_joint.rotation,
                &joint.parent_from_joint.rotation,
            ) > UNCHANGED_TOLERANCE;
        if moved || axis.is_some() {
            exported.push(parent * parent_from_joint);
            placements.push(Some(Placement {
                parent_from_joint: moved.then_some(parent_from_joint),
                axis,
            }));
        } else {
            exported.push(parent * joint.parent_from_joint);
            placements.push(None);
        }
    }
    (placements, exported)
}

/// Shortest text that reads back as exactly these numbers.
fn numbers(values: [f64; 3]) -> String {
    format!("{} {} {}", values[0], values[1], values[2])
}

/// The original text with its elements located.
pub(super) struct Document<'a> {
    text: &'a str,
    origin: &'a str,
    elements: Vec<Element>,
}

impl<'a> Document<'a> {
    pub(super) fn new(text: &'a str, origin: &'a str) -> Result<Self> {
        let elements = scan(text, origin)?;
        Ok(Self {
            text,
            origin,
            elements,
        })
    }

    fn invalid(&self, at: usize, message: String) -> Error {
        Error::InvalidRobot {
            origin: position(self.text, self.origin, at),
            message,
        }
    }

    /// The `<joint>` element called `name` directly under the root `<robot>` (joints inside
    /// `<transmission>` or `<gazebo>` are other things with the same tag).
    pub(super) fn joint(&self, name: &str) -> Result<usize> {
        let mut found = self.elements.iter().enumerate().filter(|(_, e)| {
            e.name == "joint"
                && e.parent.is_some_and(|p| self.elements[p].parent.is_none())
                && e.attribute("name")
                    .is_some_and(|a| unescape(&self.text[a.value.clone()]) == name)
        });
        match (found.next(), found.next()) {
            (Some((index, _)), None) => Ok(index),
            (Some(_), Some((_, second))) => Err(self.invalid(
                second.start,
                format!("joint '{name}' is declared twice; joint names must be unique"),
            )),
            (None, _) => Err(Error::InvalidRobot {
                origin: self.origin.to_owned(),
                message: format!(
                    "the text has no <joint name=\"{name}\"> under <robot>; pass the URDF the tree was loaded from"
                ),
            }),
        }
    }

    /// Whether a `<link name="…">` directly under the root declares link `name`.
    pub(super) fn has_link(&self, name: &str) -> bool {
        self.elements.iter().any(|e| {
            e.name == "link"
                && e.parent.is_some_and(|p| self.elements[p].parent.is_none())
                && e.attribute("name")
                    .is_some_and(|a| unescape(&self.text[a.value.clone()]) == name)
        })
    }

    /// The one child element `tag` of element `parent`, if any.
    fn child(&self, parent: usize, tag: &str, joint: &str) -> Result<Option<&Element>> {
        let mut found = self
            .elements
            .iter()
            .filter(|e| e.parent == Some(parent) && e.name == tag);
        match (found.next(), found.next()) {
            (first, None) => Ok(first),
            (Some(_), Some(second)) => Err(self.invalid(
                second.start,
                format!("joint '{joint}' has more than one <{tag}>; remove all but one"),
            )),
            (None, Some(_)) => unreachable!("an iterator yields in order"),
        }
    }

    /// Sets attributes of child `tag` of joint element `joint`, inserting the element (after
    /// the joint's start tag, on its own line) or the attributes where missing.
    fn set_child(
        &self,
        joint: usize,
        joint_name: &str,
        tag: &str,
        values: &[(&str, String)],
        edits: &mut Vec<(usize, usize, String)>,
    ) -> Result<()> {
        let element = &self.elements[joint];
        if element.self_closing {
            return Err(self.invalid(
                element.start,
                format!("joint '{joint_name}' is an empty element; it needs <parent> and <child>"),
            ));
        }
        match self.child(joint, tag, joint_name)? {
            Some(child) => {
                let mut missing = String::new();
                for (name, value) in values {
                    match child.attribute(name) {
                        Some(attribute) => {
                            edits.push((attribute.value.start, attribute.value.end, value.clone()))
                        }
                        None => missing.push_str(&format!(" {name}=\"{value}\"")),
                    }
                }
                if !missing.is_empty() {
                    edits.push((child.attributes_end, child.attributes_end, missing));
                }
            }
            None => {
                let line_start = self.text[..element.start].rfind('\n').map_or(0, |n| n + 1);
                let indent: String = self.text[line_start..element.start]
                    .chars()
                    .take_while(|c| c.is_whitespace())
                    .collect();
                let attributes: String = values
                    .iter()
                    .map(|(name, value)| format!(" {name}=\"{value}\""))
                    .collect();
                edits.push((
                    element.tag_end,
                    element.tag_end,
                    format!("\n{indent}  <{tag}{attributes}/>"),
                ));
            }
        }
        Ok(())
    }

    /// An edit that inserts the `added` links before the root's `</robot>`.
    pub(super) fn before_root_end(
        &self,
        added: &[AddedToolLink],
    ) -> Result<(usize, usize, String)> {
        let Some(end) = self.text.rfind("</robot") else {
            return Err(Error::InvalidRobot {
                origin: self.origin.to_owned(),
                message: "the text has no </robot> end tag to add the tool links before".into(),
            });
        };
        let indent = self
            .elements
            .iter()
            .find(|e| e.name == "link")
            .map(|e| {
                let line_start = self.text[..e.start].rfind('\n').map_or(0, |n| n + 1);
                self.text[line_start..e.start]
                    .chars()
                    .take_while(|c| c.is_whitespace())
                    .collect::<String>()
            })
            .unwrap_or_else(|| "  ".into());
        Ok((end, end, added_links_xml(added, &indent)))
    }

    pub(super) fn set_origin(
        &self,
        joint: usize,
        joint_name: &str,
        xyz: [f64; 3],
        rpy: [f64; 3],
        edits: &mut Vec<(usize, usize, String)>,
    ) -> Result<()> {
        let values = [("xyz", numbers(xyz)), ("rpy", numbers(rpy))];
        self.set_child(joint, joint_name, "origin", &values, edits)
    }

    pub(super) fn set_axis(
        &self,
        joint: usize,
        joint_name: &str,
        axis: Vec3,
        edits: &mut Vec<(usize, usize, String)>,
    ) -> Result<()> {
        let values = [("xyz", numbers(axis.into()))];
        self.set_child(joint, joint_name, "axis", &values, edits)
    }
}
