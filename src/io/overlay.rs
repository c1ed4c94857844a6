//! The deployable forms of a calibration besides the URDF: the joint-origin overlay
//! (`calibration_overlay.yaml`, for a xacro's `xacro.load_yaml`) and the joint zero offsets
//! (`joint_offsets.yaml`, for a controller). Layouts in docs/file-formats.md and
//! docs/export.md.
//!
//! Numbers are written with Rust's `{}` of f64: the shortest digits that read back to the same
//! bits, and never an exponent, which YAML 1.1 readers (PyYAML, so xacro) would take for a
//! string (`1e-07`).

use super::yaml::parse_yaml;
use crate::error::{Error, Result};
use crate::math::{pose, rotation_from_rpy, Vec3};
use crate::urdf::{AddedReason, AddedToolLink, JointOverlay, OverlayJoint};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt::Write;

/// The `format` of `calibration_overlay.yaml`.
pub const OVERLAY_FORMAT: &str = "treecal.overlay/1";

/// The `format` of `joint_offsets.yaml`.
pub const OFFSETS_FORMAT: &str = "treecal.joint_offsets/1";

/// A key as a YAML double-quoted string (JSON escaping is valid YAML).
fn key(name: &str) -> String {
    serde_json::to_string(name).unwrap_or_else(|_| format!("\"{name}\""))
}

/// `x: .., y: .., z: .., roll: .., pitch: .., yaw: ..` lines, indented by `indent`.
fn origin_lines(out: &mut String, indent: &str, xyz: [f64; 3], rpy: [f64; 3]) {
    for (name, value) in ["x", "y", "z"].iter().zip(xyz) {
        let _ = writeln!(out, "{indent}{name}: {value}");
    }
    for (name, value) in ["roll", "pitch", "yaw"].iter().zip(rpy) {
        let _ = writeln!(out, "{indent}{name}: {value}");
    }
}

/// `overlay` as `calibration_overlay.yaml`, with `comment` (lines) at the top.
pub fn overlay_to_yaml(overlay: &JointOverlay, comment: &str) -> String {
    let mut out = String::new();
    for line in comment.lines() {
        let _ = writeln!(out, "# {line}");
    }
    let _ = writeln!(out, "format: {OVERLAY_FORMAT}");
    let _ = writeln!(out, "robot: {}", key(&overlay.robot));
    out.push_str("units: {length: m, angle: rad}\n");
    if overlay.joints.is_empty() {
        out.push_str("joints: {}\n");
    } else {
        out.push_str("joints:\n");
    }
    for joint in &overlay.joints {
        let _ = writeln!(out, "  {}:", key(&joint.joint));
        origin_lines(&mut out, "    ", joint.xyz, joint.rpy);
        if let Some(axis) = joint.axis {
            let _ = writeln!(out, "    axis: [{}, {}, {}]", axis[0], axis[1], axis[2]);
        }
    }
    if overlay.added_links.is_empty() {
        out.push_str("added_links: {}\n");
    } else {
        out.push_str("added_links:\n");
    }
    for link in &overlay.added_links {
        let _ = writeln!(out, "  {}:", key(&link.link));
        let _ = writeln!(out, "    parent: {}", key(&link.parent));
        let _ = writeln!(out, "    joint: {}", key(&format!("{}_joint", link.link)));
        let _ = writeln!(out, "    tool: {}", key(&link.tool));
        let reason = match link.reason {
            AddedReason::OffAxis => "off_axis",
            AddedReason::Marker => "marker",
            AddedReason::Point => "point",
        };
        let _ = writeln!(out, "    reason: {reason}");
        origin_lines(&mut out, "    ", link.xyz, link.rpy);
    }
    out
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OverlayFile {
    format: String,
    robot: String,
    #[allow(dead_code)]
    units: BTreeMap<String, String>,
    joints: BTreeMap<String, JointEntry>,
    added_links: BTreeMap<String, LinkEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JointEntry {
    x: f64,
    y: f64,
    z: f64,
    roll: f64,
    pitch: f64,
    yaw: f64,
    axis: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LinkEntry {
    parent: String,
    joint: String,
    tool: String,
    reason: String,
    x: f64,
    y: f64,
    z: f64,
    roll: f64,
    pitch: f64,
    yaw: f64,
}

/// Parses `calibration_overlay.yaml` (`origin` names it in messages). Joints come back in
/// name order (a YAML mapping has none); the edits do not depend on it.
pub fn parse_overlay(text: &str, origin: &str) -> Result<JointOverlay> {
    let file: OverlayFile = parse_yaml(
        text,
        origin,
        "; an overlay holds `format`, `robot`, `units`, `joints` and `added_links` as treecal calibrate writes them (docs/export.md)",
    )?;
    let invalid = |message: String| Error::InvalidData {
        origin: origin.to_owned(),
        message,
    };
    if file.format != OVERLAY_FORMAT {
        return Err(invalid(format!(
            "format '{}' is not '{OVERLAY_FORMAT}'; write the overlay with this treecal version",
            file.format
        )));
    }
    let mut joints = Vec::new();
    for (name, j) in file.joints {
        let numbers = [j.x, j.y, j.z, j.roll, j.pitch, j.yaw];
        if !numbers
            .iter()
            .chain(j.axis.iter().flatten())
            .all(|v| v.is_finite())
        {
            return Err(invalid(format!(
                "joints.{name}: a value is not a finite number"
            )));
        }
        joints.push(OverlayJoint {
            joint: name,
            xyz: [j.x, j.y, j.z],
            rpy: [j.roll, j.pitch, j.yaw],
            axis: j.axis,
        });
    }
    let mut added_links = Vec::new();
    for (name, l) in file.added_links {
        let reason = match l.reason.as_str() {
            "off_axis" => AddedReason::OffAxis,
            "marker" => AddedReason::Marker,
            "point" => AddedReason::Point,
            other => {
                return Err(invalid(format!(
                    "added_links.{name}.reason '{other}' is not one of off_axis, marker, point"
                )))
            }
        };
        if l.joint != format!("{name}_joint") {
            return Err(invalid(format!(
                "added_links.{name}.joint is '{}'; treecal names it '{name}_joint'",
                l.joint
            )));
        }
        let (xyz, rpy) = ([l.x, l.y, l.z], [l.roll, l.pitch, l.yaw]);
        if !xyz.iter().chain(&rpy).all(|v| v.is_finite()) {
            return Err(invalid(format!(
                "added_links.{name}: a value is not a finite number"
            )));
        }
        let parent_from_link = pose(Vec3::from(xyz), rotation_from_rpy(rpy[0], rpy[1], rpy[2]));
        added_links.push(AddedToolLink {
            tool: l.tool,
            link: name,
            parent: l.parent,
            reason,
            offset_mm: parent_from_link.translation.vector.norm() * 1e3,
            parent_from_link,
            xyz,
            rpy,
        });
    }
    Ok(JointOverlay {
        robot: file.robot,
        joints,
        added_links,
    })
}

/// One joint's zero offset: the model's joint value is the reported one plus `offset`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct JointOffset {
    /// The joint's URDF name.
    pub joint: String,
    /// The offset (rad for a revolute joint, m for a prismatic one).
    pub offset: f64,
    /// Its standard deviation, when the calibration gives one.
    pub std_dev: Option<f64>,
    /// `rad` or `m`.
    pub unit: &'static str,
}

/// `joint_offsets.yaml`: the zero offsets, with `comment` (lines) at the top.
pub fn joint_offsets_to_yaml(robot: &str, offsets: &[JointOffset], comment: &str) -> String {
    let mut out = String::new();
    for line in comment.lines() {
        let _ = writeln!(out, "# {line}");
    }
    let _ = writeln!(out, "format: {OFFSETS_FORMAT}");
    let _ = writeln!(out, "robot: {}", key(robot));
    out.push_str("convention: q_urdf = q_reported + offset\n");
    if offsets.is_empty() {
        out.push_str("joints: {}\n");
    } else {
        out.push_str("joints:\n");
    }
    for o in offsets {
        let _ = write!(
            out,
            "  {}: {{offset: {}, unit: {}",
            key(&o.joint),
            o.offset,
            o.unit
        );
        if let Some(s) = o.std_dev {
            let _ = write!(out, ", std_dev: {s}");
        }
        out.push_str("}\n");
    }
    out
}
