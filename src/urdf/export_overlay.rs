//! The calibration as a joint-origin overlay: the numbers [`export_urdf_with`] writes into
//! `calibrated.urdf`, per changed joint, for robots whose URDF is generated from xacro.
//!
//! One source of truth: the overlay is built from the [`ExportReport`] of the export itself
//! (its [`JointChange`]s and [`AddedToolLink`]s), never recomputed from the model, so
//! [`apply_overlay`] on the nominal URDF gives back `calibrated.urdf` (the same edits, the same
//! number formatting). The YAML form and the xacro lines that load it are in `io::overlay`
//! and `docs/export.md`.
//!
//! [`export_urdf_with`]: super::export_urdf_with
//! [`JointChange`]: super::JointChange

use super::export::{apply_edits, rotation_gap, Document, ExportReport, UNCHANGED_TOLERANCE};
use super::export_options::AddedToolLink;
use super::import::parse_urdf;
use crate::error::{Error, Result};
use crate::math::{pose, rotation_from_rpy, Vec3};
use crate::tree::{JointKind, KinematicTree};

/// One joint's calibrated placement in URDF convention.
#[derive(Debug, Clone, PartialEq)]
pub struct OverlayJoint {
    /// The joint's URDF name.
    pub joint: String,
    /// Origin translation in the parent link frame (m).
    pub xyz: [f64; 3],
    /// Origin roll, pitch, yaw (rad; `R = Rz(yaw)·Ry(pitch)·Rx(roll)`).
    pub rpy: [f64; 3],
    /// The axis in the joint frame (unit), changed or not; `None` for a fixed joint.
    pub axis: Option<[f64; 3]>,
}

/// The joints a calibration changed and the links it adds, for a xacro or a URDF.
#[derive(Debug, Clone, PartialEq)]
pub struct JointOverlay {
    /// The robot's name.
    pub robot: String,
    /// Every joint whose origin or axis the export changed, in tree order.
    pub joints: Vec<OverlayJoint>,
    /// The fixed leaf links the export added (marker frames, measured points, off-axis tools).
    pub added_links: Vec<AddedToolLink>,
}

impl JointOverlay {
    /// The overlay of `export`, the export of a model of `tree`.
    pub fn of_export(tree: &KinematicTree, export: &ExportReport) -> Result<Self> {
        let joints = export
            .changes
            .iter()
            .map(|change| {
                let joint = tree.joint(tree.joint_id(&change.joint)?);
                let axis = match joint.kind {
                    JointKind::Fixed => None,
                    _ => Some(
                        change
                            .new_axis
                            .unwrap_or_else(|| joint.axis.into_inner().into()),
                    ),
                };
                Ok(OverlayJoint {
                    joint: change.joint.clone(),
                    xyz: change.new_xyz,
                    rpy: change.new_rpy,
                    axis,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            robot: tree.name().to_owned(),
            joints,
            added_links: export.added_links.clone(),
        })
    }
}

/// Applies `overlay` to the URDF text `original` (`origin` names it in messages): the origin
/// and axis of every joint it lists (left as they are where they already agree to
/// [`UNCHANGED_TOLERANCE`]) and its added links before `</robot>`. Applied to the URDF a
/// calibration exported from, it gives `calibrated.urdf` back; every other byte is kept.
pub fn apply_overlay(original: &str, origin: &str, overlay: &JointOverlay) -> Result<String> {
    let tree = parse_urdf(original, origin)?.tree;
    let document = Document::new(original, origin)?;
    let mut edits = Vec::new();
    for entry in &overlay.joints {
        let joint = tree.joint(tree.joint_id(&entry.joint).map_err(|_| Error::InvalidRobot {
            origin: origin.to_owned(),
            message: format!(
                "the overlay names joint '{}', which this URDF does not have; apply the overlay to the robot it was calibrated for (robot '{}')",
                entry.joint, overlay.robot
            ),
        })?);
        let element = document.joint(&entry.joint)?;
        let parent_from_joint = pose(
            Vec3::from(entry.xyz),
            rotation_from_rpy(entry.rpy[0], entry.rpy[1], entry.rpy[2]),
        );
        let moved = (parent_from_joint.translation.vector
            - joint.parent_from_joint.translation.vector)
            .norm()
            > UNCHANGED_TOLERANCE
            || rotation_gap(
                &parent_from_joint.rotation,
                &joint.parent_from_joint.rotation,
            ) > UNCHANGED_TOLERANCE;
        if moved {
            document.set_origin(element, &entry.joint, entry.xyz, entry.rpy, &mut edits)?;
        }
        if let Some(axis) = entry.axis.filter(|_| joint.kind != JointKind::Fixed) {
            let axis = Vec3::from(axis);
            if (axis - joint.axis.into_inner()).norm() > UNCHANGED_TOLERANCE {
                document.set_axis(element, &entry.joint, axis, &mut edits)?;
            }
        }
    }
    for added in &overlay.added_links {
        if document.has_link(&added.link) {
            return Err(Error::InvalidRobot {
                origin: origin.to_owned(),
                message: format!(
                    "the URDF already has a link '{}', which the overlay adds below link '{}'; apply the overlay to the nominal URDF, not to a calibrated one",
                    added.link, added.parent
                ),
            });
        }
        if tree.link_id(&added.parent).is_err() {
            return Err(Error::InvalidRobot {
                origin: origin.to_owned(),
                message: format!(
                    "the overlay adds link '{}' below link '{}', which this URDF does not have",
                    added.link, added.parent
                ),
            });
        }
    }
    if !overlay.added_links.is_empty() {
        edits.push(document.before_root_end(&overlay.added_links)?);
    }
    Ok(apply_edits(original, edits))
}
