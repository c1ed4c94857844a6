//! MCPC table → URDF text.
//!
//! Each joint row becomes a joint whose `<origin>` is `Rx(α)·Ry(β)·Trans(x, y, 0)` relative to
//! the previous row's link and whose axis is z, so every generated link frame is the MCPC frame
//! Σᵢ moved by its joint. Tool rows become fixed joints, except a tool that is the link of its
//! branch's last row (a palm moved by the wrist joint): that joint's child link is then the
//! tool link itself, at the tool frame, with the axis written in that frame; a URDF can do so
//! only while the tool origin lies on the joint axis, else the joint moves a `<tool>_mount`
//! link and the tool hangs below it on a fixed joint. Links get simple cylinders and plausible
//! masses so that later steps (gravity loads, self-collision) have something to work with.

use super::export_options::ON_AXIS_TOLERANCE;
use crate::kinematics::{FrameKind, McpcTable, TableBranch};
use crate::math::{pose, rpy_from_rotation, Pose, Rotation, Vec3};
use std::fmt::Write;

/// Radius of the link tubes (m).
const TUBE_RADIUS: f64 = 0.035;
/// Radius and length of the joint-module housings (m), visual only.
const HOUSING_RADIUS: f64 = 0.045;
const HOUSING_LENGTH: f64 = 0.09;
/// Collision cylinders stop this far short of each joint so that links meeting at a shared
/// joint origin do not touch (m).
const COLLISION_MARGIN: f64 = 0.05;
/// Mass of a joint module (kg) and of the tube per metre (kg/m): Schunk-class modules.
const MODULE_MASS: f64 = 1.8;
const TUBE_MASS_PER_METRE: f64 = 3.0;

/// Formats a number for URDF: shortest round-trip decimal, with values below 1e-15 as 0.
fn number(value: f64) -> String {
    if value.abs() < 1e-15 {
        "0".into()
    } else {
        format!("{value}")
    }
}

fn triple(v: [f64; 3]) -> String {
    format!("{} {} {}", number(v[0]), number(v[1]), number(v[2]))
}

fn origin_element(p: &Pose) -> String {
    let t = p.translation.vector;
    format!(
        "<origin xyz=\"{}\" rpy=\"{}\"/>",
        triple([t.x, t.y, t.z]),
        triple(rpy_from_rotation(&p.rotation))
    )
}

/// A cylinder from the link origin to `end` (link frame), as (pose of its centre, length).
fn segment(end: &Vec3, margin: f64) -> Option<(Pose, f64)> {
    let length = end.norm() - 2.0 * margin;
    if length < 0.01 {
        return None;
    }
    let direction = end.normalize();
    let rotation = Rotation::rotation_between(&Vec3::z(), &direction)
        .unwrap_or_else(|| Rotation::from_axis_angle(&Vec3::x_axis(), std::f64::consts::PI));
    Some((pose(end * 0.5, rotation), length))
}

fn cylinder(kind: &str, placement: &Pose, radius: f64, length: f64) -> String {
    format!(
        "    <{kind}>\n      {}\n      <geometry><cylinder radius=\"{}\" length=\"{}\"/></geometry>{}\n    </{kind}>\n",
        origin_element(placement),
        number(radius),
        number(length),
        if kind == "visual" { "\n      <material name=\"grey\"/>" } else { "" }
    )
}

/// One link element; `segment_end` is the next joint's origin (or the tool point) in this frame.
fn link_element(name: &str, segment_ends: &[Vec3], with_housing: bool) -> String {
    let mut body = String::new();
    let mut mass = 0.0;
    let mut weighted = Vec3::zeros();
    let mut inertia_diagonal = Vec3::zeros();
    if with_housing {
        body += &cylinder("visual", &Pose::identity(), HOUSING_RADIUS, HOUSING_LENGTH);
        mass += MODULE_MASS;
    }
    for end in segment_ends {
        if let Some((placement, length)) = segment(end, 0.0) {
            body += &cylinder("visual", &placement, TUBE_RADIUS, length);
            let tube = TUBE_MASS_PER_METRE * length;
            mass += tube;
            weighted += placement.translation.vector * tube;
            // Solid-cylinder inertia about its own centre, summed as an isotropic bound below.
            let across = tube * (3.0 * TUBE_RADIUS * TUBE_RADIUS + length * length) / 12.0;
            inertia_diagonal += Vec3::repeat(across);
        }
        if let Some((placement, length)) = segment(end, COLLISION_MARGIN) {
            body += &cylinder("collision", &placement, TUBE_RADIUS, length);
        }
    }
    if mass == 0.0 {
        mass = 0.1;
    }
    let center = weighted / mass;
    // A diagonal inertia that bounds the true one (isotropic per segment plus the module).
    let module = MODULE_MASS * HOUSING_RADIUS * HOUSING_RADIUS / 2.0;
    let i = inertia_diagonal + Vec3::repeat(module.max(1e-4));
    format!(
        "  <link name=\"{name}\">\n    <inertial>\n      <origin xyz=\"{}\" rpy=\"0 0 0\"/>\n      <mass value=\"{}\"/>\n      <inertia ixx=\"{}\" ixy=\"0\" ixz=\"0\" iyy=\"{}\" iyz=\"0\" izz=\"{}\"/>\n    </inertial>\n{body}  </link>\n",
        triple([center.x, center.y, center.z]),
        number((mass * 1e6_f64).round() / 1e6),
        number((i.x * 1e9).round() / 1e9),
        number((i.y * 1e9).round() / 1e9),
        number((i.z * 1e9).round() / 1e9),
    )
}

/// How a tool that is its branch's last row's link ([`TableBranch::carried_tool`]) is written.
enum Carried<'a> {
    /// Not such a tool (or no tool).
    No,
    /// On the last joint's axis: the joint's child link is the tool link, placed at the tool
    /// frame, its axis turned into that frame.
    OnAxis(&'a crate::kinematics::TableTool),
    /// Off the axis, which a URDF joint cannot express: the joint moves a link called `mount`
    /// and the tool hangs below it on a fixed joint, as any other tool.
    OffAxis {
        /// A link name not used in the table.
        mount: String,
    },
}

fn carried_tool<'a>(table: &McpcTable, branch: &'a TableBranch) -> Carried<'a> {
    let Some(tool) = branch.carried_tool() else {
        return Carried::No;
    };
    let revolute = branch
        .rows
        .last()
        .is_some_and(|r| r.kind == FrameKind::Revolute);
    let off_axis = tool.transform().translation.vector.xy().norm();
    if !revolute || off_axis <= ON_AXIS_TOLERANCE {
        return Carried::OnAxis(tool);
    }
    let used = |name: &str| {
        name == table.base_link
            || table.branches.iter().any(|b| {
                b.rows.iter().any(|r| r.link == name)
                    || b.tool.as_ref().is_some_and(|t| t.link == name)
            })
    };
    let mut mount = format!("{}_mount", tool.link);
    while used(&mount) {
        mount.push('_');
    }
    Carried::OffAxis { mount }
}

/// Generates a URDF document from an MCPC table (SI units). The output is deterministic.
pub fn urdf_from_mcpc_table(table: &McpcTable, source_note: &str) -> String {
    // Names go into attributes and the note into a comment: escaped once, here.
    let table = &escaped_names(table);
    let source_note = source_note.replace("--", "- -");
    let mut out = String::new();
    let _ = writeln!(out, "<?xml version=\"1.0\"?>");
    let _ = writeln!(
        out,
        "<!-- Generated by treecal from-mcpc from {source_note}; do not edit by hand. -->"
    );
    let _ = writeln!(
        out,
        "<!-- Every link frame is the MCPC joint frame moved by its joint (z = joint axis). -->"
    );
    let _ = writeln!(out, "<robot name=\"{}\">", table.robot);
    let _ = writeln!(
        out,
        "  <material name=\"grey\"><color rgba=\"0.6 0.6 0.65 1\"/></material>"
    );

    // Where each branch's first row hangs from: the base, or another branch's last link.
    let last_link = |name: &str| -> Option<&str> {
        table
            .branches
            .iter()
            .find(|b| b.name == name)
            .and_then(|b| b.rows.last())
            .map(|r| r.link.as_str())
    };
    // For each link: its children's origins in its frame, for drawing segments.
    let mut ends: Vec<(String, Vec<Vec3>)> = vec![(table.base_link.clone(), Vec::new())];
    let mut joints = String::new();
    for branch in &table.branches {
        let mut parent = branch
            .parent
            .as_deref()
            .and_then(last_link)
            .unwrap_or(&table.base_link)
            .to_owned();
        let carried = carried_tool(table, branch);
        for (index, row) in branch.rows.iter().enumerate() {
            let last = index + 1 == branch.rows.len();
            // The last joint moves the tool link itself: its link frame is the tool frame.
            let (link, link_from_moved) = match (last, &carried) {
                (true, Carried::OnAxis(tool)) => (row.link.clone(), tool.transform()),
                (true, Carried::OffAxis { mount }) => (mount.clone(), Pose::identity()),
                _ => (row.link.clone(), Pose::identity()),
            };
            let placement = row.transform() * link_from_moved;
            let axis = link_from_moved.rotation.inverse() * Vec3::z();
            if let Some(entry) = ends.iter_mut().find(|(n, _)| *n == parent) {
                entry.1.push(placement.translation.vector);
            }
            let kind = match row.kind {
                FrameKind::Revolute => "revolute",
                FrameKind::Prismatic => "prismatic",
            };
            let _ = write!(
                joints,
                "  <joint name=\"{}\" type=\"{kind}\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{link}\"/>\n    {}\n    <axis xyz=\"{}\"/>\n    <limit lower=\"{}\" upper=\"{}\" effort=\"150\" velocity=\"1\"/>\n  </joint>\n",
                row.joint,
                origin_element(&placement),
                triple(axis.into()),
                number(row.limits.0),
                number(row.limits.1)
            );
            ends.push((link.clone(), Vec::new()));
            parent = link;
        }
        let tool = match carried {
            Carried::OnAxis(_) => None,
            _ => branch.tool.as_ref(),
        };
        if let Some(tool) = tool {
            let placement = tool.transform();
            if let Some(entry) = ends.iter_mut().find(|(n, _)| *n == parent) {
                entry.1.push(placement.translation.vector);
            }
            let _ = write!(
                joints,
                "  <joint name=\"{}_joint\" type=\"fixed\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{}\"/>\n    {}\n  </joint>\n",
                tool.link,
                tool.link,
                origin_element(&placement)
            );
            ends.push((tool.link.clone(), Vec::new()));
        }
    }
    let tools: Vec<&str> = table
        .branches
        .iter()
        .filter_map(|b| b.tool.as_ref().map(|t| t.link.as_str()))
        .collect();
    for (name, segment_ends) in &ends {
        if name == &table.base_link {
            // A pedestal below the base frame.
            let _ = write!(
                out,
                "  <link name=\"{name}\">\n    <inertial>\n      <origin xyz=\"0 0 -0.1\" rpy=\"0 0 0\"/>\n      <mass value=\"20\"/>\n      <inertia ixx=\"0.2\" ixy=\"0\" ixz=\"0\" iyy=\"0.2\" iyz=\"0\" izz=\"0.3\"/>\n    </inertial>\n{}{}  </link>\n",
                cylinder("visual", &pose(Vec3::new(0.0, 0.0, -0.1), Rotation::identity()), 0.15, 0.1),
                cylinder("collision", &pose(Vec3::new(0.0, 0.0, -0.1), Rotation::identity()), 0.15, 0.1),
            );
        } else if tools.contains(&name.as_str()) {
            let _ = write!(
                out,
                "  <link name=\"{name}\">\n    <inertial>\n      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n      <mass value=\"0.2\"/>\n      <inertia ixx=\"0.0001\" ixy=\"0\" ixz=\"0\" iyy=\"0.0001\" iyz=\"0\" izz=\"0.0001\"/>\n    </inertial>\n    <visual>\n      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n      <geometry><sphere radius=\"0.02\"/></geometry>\n      <material name=\"grey\"/>\n    </visual>\n  </link>\n"
            );
        } else {
            out += &link_element(name, segment_ends, true);
        }
    }
    out += &joints;
    out += "</robot>\n";
    out
}

/// `text` as an XML attribute value: `&`, `<`, `>`, `"` and `'` as entities.
fn xml_escaped(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// A copy of `table` with every name XML-escaped.
fn escaped_names(table: &McpcTable) -> McpcTable {
    let mut table = table.clone();
    table.robot = xml_escaped(&table.robot);
    table.base_link = xml_escaped(&table.base_link);
    for branch in &mut table.branches {
        branch.name = xml_escaped(&branch.name);
        branch.parent = branch.parent.as_deref().map(xml_escaped);
        for row in &mut branch.rows {
            row.joint = xml_escaped(&row.joint);
            row.link = xml_escaped(&row.link);
        }
        if let Some(tool) = &mut branch.tool {
            tool.link = xml_escaped(&tool.link);
        }
    }
    table
}
