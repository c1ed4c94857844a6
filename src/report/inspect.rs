//! `treecal inspect`: the tree, the detected branches and the MCPC table of a robot.

use crate::kinematics::{FrameKind, McpcModel};
use crate::tree::{Actuation, BranchRole, Branches, JointKind, KinematicTree};
use serde::Serialize;
use std::fmt::Write;

/// The `schema_version` of `inspect --format json` / `yaml` (docs/file-formats.md).
pub const INSPECT_SCHEMA: &str = "treecal.inspect/1";

/// Everything `inspect` shows; serialises to YAML/JSON, renders to text.
#[derive(Debug, Clone, Serialize)]
pub struct InspectReport {
    /// [`INSPECT_SCHEMA`].
    pub schema_version: &'static str,
    /// Robot name.
    pub robot: String,
    /// Root link.
    pub root: String,
    /// Link count.
    pub links: usize,
    /// Joint counts by type.
    pub joints: JointCounts,
    /// Independent joint variables.
    pub degrees_of_freedom: usize,
    /// Loader warnings.
    pub warnings: Vec<String>,
    /// The tree, one entry per link in depth-first order.
    pub tree: Vec<TreeEntry>,
    /// The detected branches.
    pub branches: BranchesReport,
    /// Every limb of the tree with its role, whatever the tools (what a whole-body calibration
    /// could measure).
    pub limbs: Vec<LimbEntry>,
    /// The MCPC table.
    pub mcpc: McpcReport,
}

/// Joint counts by type.
#[derive(Debug, Clone, Default, Serialize)]
pub struct JointCounts {
    /// Revolute joints.
    pub revolute: usize,
    /// Continuous joints.
    pub continuous: usize,
    /// Prismatic joints.
    pub prismatic: usize,
    /// Fixed joints.
    pub fixed: usize,
    /// Movable joints that mimic another.
    pub mimic: usize,
}

/// One line of the tree.
#[derive(Debug, Clone, Serialize)]
pub struct TreeEntry {
    /// Depth below the root.
    pub depth: usize,
    /// Link name.
    pub link: String,
    /// Joint that carries it (none for the root).
    pub joint: Option<String>,
    /// Joint type.
    pub joint_type: Option<&'static str>,
    /// Mimic description, e.g. `-1·l_finger_left + 0`.
    pub mimic: Option<String>,
    /// The branch the joint belongs to, if any.
    pub branch: Option<String>,
}

/// One limb of the tree ([`crate::tree::limbs`]).
#[derive(Debug, Clone, Serialize)]
pub struct LimbEntry {
    /// The link it ends at.
    pub end: String,
    /// Role from the names: coupled, arm, leg, head or other.
    pub role: BranchRole,
    /// Movable joints, root side first.
    pub joints: Vec<String>,
    /// Movable joints beyond it (fingers, grippers) counted with it.
    pub beyond: usize,
}

/// The branches and why.
#[derive(Debug, Clone, Serialize)]
pub struct BranchesReport {
    /// The link fixed in the world while measuring (the root unless chosen).
    pub reference_link: String,
    /// What that reference makes invisible, in words (none for the root).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_note: Option<String>,
    /// How the tools were chosen.
    pub selection_rule: String,
    /// How left and right were decided.
    pub side_rule: String,
    /// Link where the arms diverge.
    pub divergence_link: String,
    /// Each branch.
    pub list: Vec<BranchEntry>,
}

/// One branch.
#[derive(Debug, Clone, Serialize)]
pub struct BranchEntry {
    /// Name.
    pub name: String,
    /// Role.
    pub role: BranchRole,
    /// Movable joints, root side first.
    pub joints: Vec<String>,
    /// Tool link.
    pub tool: Option<String>,
}

/// The MCPC table in degrees and millimetres (paper Table 1 layout).
#[derive(Debug, Clone, Serialize)]
pub struct McpcReport {
    /// Rows, branch by branch.
    pub rows: Vec<McpcRow>,
    /// Total parameter count.
    pub parameter_count: usize,
    /// How the count is made up, e.g. `4·13 + 2·0 + 6·2 = 64`.
    pub parameter_formula: String,
}

/// One row: a joint frame or a tool frame.
#[derive(Debug, Clone, Serialize)]
pub struct McpcRow {
    /// Branch name.
    pub branch: String,
    /// Row number within the branch (0 = the branch's first joint frame).
    pub row: usize,
    /// Joint name, or the tool link for tool rows.
    pub name: String,
    /// `revolute`, `prismatic` or `tool`.
    pub kind: &'static str,
    /// Constant rotation about the previous joint axis (deg).
    pub phi_deg: f64,
    /// Whether this row was moved off the singularity.
    pub reparametrised: bool,
    /// α (deg).
    pub alpha_deg: f64,
    /// β (deg).
    pub beta_deg: f64,
    /// γ (deg), tools only.
    pub gamma_deg: Option<f64>,
    /// x (mm), absent for prismatic rows.
    pub x_mm: Option<f64>,
    /// y (mm), absent for prismatic rows.
    pub y_mm: Option<f64>,
    /// z (mm), tools only.
    pub z_mm: Option<f64>,
}

/// Builds the inspect report.
pub fn inspect(
    tree: &KinematicTree,
    warnings: &[String],
    branches: &Branches,
    model: &McpcModel,
) -> InspectReport {
    let counts = joint_counts(tree);
    let entries = tree_entries(tree, branches);
    let branch_entries = branches
        .all()
        .map(|b| BranchEntry {
            name: b.name.clone(),
            role: b.role,
            joints: b
                .joints
                .iter()
                .map(|j| tree.joint(*j).name.clone())
                .collect(),
            tool: b.tool.map(|t| tree.link(t).name.clone()),
        })
        .collect();

    let rows = mcpc_rows(tree, branches, model);
    let revolute = model
        .frames()
        .iter()
        .filter(|f| f.kind == FrameKind::Revolute)
        .count();
    let prismatic = model.frames().len() - revolute;
    let count = model.parameter_count();
    InspectReport {
        schema_version: INSPECT_SCHEMA,
        robot: tree.name().to_owned(),
        root: tree.link(tree.root()).name.clone(),
        links: tree.links().len(),
        joints: counts,
        degrees_of_freedom: tree.dof_count(),
        warnings: warnings.to_vec(),
        tree: entries,
        limbs: limb_entries(tree),
        branches: BranchesReport {
            reference_link: tree.link(branches.reference).name.clone(),
            reference_note: branches.reference_summary(tree),
            selection_rule: branches.selection.to_string(),
            side_rule: branches.sides.to_string(),
            divergence_link: tree.link(branches.divergence).name.clone(),
            list: branch_entries,
        },
        mcpc: McpcReport {
            rows,
            parameter_count: count,
            parameter_formula: format!(
                "4·{revolute} revolute + 2·{prismatic} prismatic + 6·{} tools = {count}",
                model.tools().len()
            ),
        },
    }
}

/// How many joints of each kind the tree has.
fn joint_counts(tree: &KinematicTree) -> JointCounts {
    let mut counts = JointCounts::default();
    for joint in tree.joints() {
        match joint.kind {
            JointKind::Revolute => counts.revolute += 1,
            JointKind::Continuous => counts.continuous += 1,
            JointKind::Prismatic => counts.prismatic += 1,
            JointKind::Fixed => counts.fixed += 1,
        }
        if matches!(joint.actuation, Actuation::Mimic { .. }) {
            counts.mimic += 1;
        }
    }
    counts
}

/// The tree depth first, each link with the joint above it.
fn tree_entries(tree: &KinematicTree, branches: &Branches) -> Vec<TreeEntry> {
    let branch_of = |joint: crate::tree::JointId| -> Option<String> {
        branches
            .all()
            .find(|b| b.joints.contains(&joint))
            .map(|b| b.name.clone())
    };
    let mut entries = Vec::new();
    let mut stack = vec![(tree.root(), 0usize)];
    while let Some((link, depth)) = stack.pop() {
        let parent_joint = tree.link(link).parent_joint;
        let mimic = parent_joint.and_then(|j| match tree.joint(j).actuation {
            Actuation::Mimic {
                master,
                multiplier,
                offset,
            } => Some(format!(
                "{multiplier}·{} + {offset}",
                tree.joint(tree.dofs()[master.0]).name
            )),
            _ => None,
        });
        entries.push(TreeEntry {
            depth,
            link: tree.link(link).name.clone(),
            joint: parent_joint.map(|j| tree.joint(j).name.clone()),
            joint_type: parent_joint.map(|j| tree.joint(j).kind.urdf_name()),
            mimic,
            branch: parent_joint.and_then(branch_of),
        });
        for &child in tree.link(link).child_joints.iter().rev() {
            stack.push((tree.joint(child).child, depth + 1));
        }
    }
    entries
}

/// The MCPC parameters of every branch in the paper's Table 1 layout (deg, mm).
fn mcpc_rows(tree: &KinematicTree, branches: &Branches, model: &McpcModel) -> Vec<McpcRow> {
    let mut rows = Vec::new();
    for branch in branches.all() {
        let mut row = 0;
        for joint in &branch.joints {
            let Some(index) = model.frame_of_joint(*joint) else {
                continue;
            };
            let frame = &model.frames()[index];
            let revolute = frame.kind == FrameKind::Revolute;
            rows.push(McpcRow {
                branch: branch.name.clone(),
                row,
                name: tree.joint(*joint).name.clone(),
                kind: if revolute { "revolute" } else { "prismatic" },
                phi_deg: clean(frame.phi.to_degrees()),
                reparametrised: frame.reparametrised,
                alpha_deg: clean(frame.alpha.to_degrees()),
                beta_deg: clean(frame.beta.to_degrees()),
                gamma_deg: None,
                x_mm: revolute.then(|| clean(frame.x * 1e3)),
                y_mm: revolute.then(|| clean(frame.y * 1e3)),
                z_mm: None,
            });
            row += 1;
        }
        if let Some(index) = branch.tool.and_then(|t| model.tool_of_link(t)) {
            let tool = &model.tools()[index];
            rows.push(McpcRow {
                branch: branch.name.clone(),
                row,
                name: tree.link(tool.link).name.clone(),
                kind: "tool",
                phi_deg: clean(tool.phi.to_degrees()),
                reparametrised: tool.reparametrised,
                alpha_deg: clean(tool.alpha.to_degrees()),
                beta_deg: clean(tool.beta.to_degrees()),
                gamma_deg: Some(clean(tool.gamma.to_degrees())),
                x_mm: Some(clean(tool.x * 1e3)),
                y_mm: Some(clean(tool.y * 1e3)),
                z_mm: Some(clean(tool.z * 1e3)),
            });
        }
    }
    rows
}

/// The tree's limbs with their roles.
fn limb_entries(tree: &KinematicTree) -> Vec<LimbEntry> {
    crate::tree::limbs(tree)
        .into_iter()
        .map(|limb| LimbEntry {
            end: tree.link(limb.end).name.clone(),
            role: limb.role,
            joints: limb
                .joints
                .iter()
                .map(|j| tree.joint(*j).name.clone())
                .collect(),
            beyond: limb.beyond,
        })
        .collect()
}

/// Rounds away float noise (1e-9 of a degree or millimetre) so tables read cleanly.
fn clean(value: f64) -> f64 {
    let rounded = (value * 1e9).round() / 1e9;
    if rounded == 0.0 {
        0.0
    } else {
        rounded
    }
}

fn cell(value: Option<f64>) -> String {
    match value {
        Some(v) => fixed(v),
        None => "\\".into(),
    }
}

/// Three decimals, without the "-0.000" that tiny negative values would print as.
fn fixed(value: f64) -> String {
    let text = format!("{value:.3}");
    if text == "-0.000" {
        "0.000".into()
    } else {
        text
    }
}

impl InspectReport {
    /// The text rendering printed by `treecal inspect`.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let j = &self.joints;
        let _ = writeln!(out, "robot '{}': root '{}', {} links, {} joints ({} revolute, {} continuous, {} prismatic, {} fixed; {} mimic), {} degrees of freedom",
            self.robot, self.root, self.links,
            j.revolute + j.continuous + j.prismatic + j.fixed,
            j.revolute, j.continuous, j.prismatic, j.fixed, j.mimic, self.degrees_of_freedom);
        for warning in &self.warnings {
            let _ = writeln!(out, "warning: {warning}");
        }
        self.write_tree(&mut out);
        self.write_limbs(&mut out);
        self.write_branches(&mut out);
        self.write_mcpc(&mut out);
        out
    }

    /// The tree, one link a line, indented by depth.
    fn write_tree(&self, out: &mut String) {
        let _ = writeln!(
            out,
            "\ntree (link ← joint [type], * = on a calibrated branch):"
        );
        for entry in &self.tree {
            let indent = "  ".repeat(entry.depth + 1);
            match (&entry.joint, entry.joint_type) {
                (Some(joint), Some(kind)) => {
                    let mark = if entry.branch.is_some() { " *" } else { "" };
                    let mimic = entry
                        .mimic
                        .as_ref()
                        .map(|m| format!(" mimic {m}"))
                        .unwrap_or_default();
                    let _ = writeln!(
                        out,
                        "{indent}{} ← {joint} [{kind}{mimic}]{mark}",
                        entry.link
                    );
                }
                _ => {
                    let _ = writeln!(out, "{indent}{}", entry.link);
                }
            }
        }
    }

    /// The limbs with their roles.
    fn write_limbs(&self, out: &mut String) {
        let _ = writeln!(
            out,
            "\nlimbs (roles from the names; any of them can be measured)"
        );
        for limb in &self.limbs {
            let beyond = if limb.beyond > 0 {
                format!(" (+{} movable joints beyond)", limb.beyond)
            } else {
                String::new()
            };
            let _ = writeln!(
                out,
                "  {:<8} {} joints up to '{}': {}{beyond}",
                limb.role.label(),
                limb.joints.len(),
                limb.end,
                limb.joints.join(", ")
            );
        }
    }

    /// The branches and how they were chosen.
    fn write_branches(&self, out: &mut String) {
        let b = &self.branches;
        let _ = writeln!(out, "\nbranches (diverging at '{}')", b.divergence_link);
        if b.reference_link != self.root {
            let _ = writeln!(
                out,
                "  reference link:  {} (fixed in the world)",
                b.reference_link
            );
        }
        if let Some(note) = &b.reference_note {
            let _ = writeln!(out, "  {note}");
        }
        let _ = writeln!(out, "  tools chosen by: {}", b.selection_rule);
        let _ = writeln!(out, "  left/right by:   {}", b.side_rule);
        for branch in &b.list {
            let tool = branch
                .tool
                .as_ref()
                .map(|t| format!(" → tool '{t}'"))
                .unwrap_or_default();
            let joints = if branch.joints.is_empty() {
                "(no movable joints)".to_owned()
            } else {
                branch.joints.join(", ")
            };
            let _ = writeln!(
                out,
                "  {:<10} {} joints: {joints}{tool} [{}]",
                branch.name,
                branch.joints.len(),
                branch.role.label()
            );
        }
    }

    /// The MCPC parameter table and its notes.
    fn write_mcpc(&self, out: &mut String) {
        let _ = writeln!(
            out,
            "\nMCPC parameters (paper Table 1 layout; angles in degrees, lengths in mm):"
        );
        let width = self
            .mcpc
            .rows
            .iter()
            .map(|r| r.name.chars().count())
            .max()
            .unwrap_or(4)
            // A longer name overflows its column (a format width above 65,535 panics).
            .clamp(5, 60);
        let _ = writeln!(
            out,
            "  {:<10} {:>3}  {:<width$} {:>9} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
            "branch", "row", "joint", "φ", "α", "β", "γ", "x", "y", "z"
        );
        for row in &self.mcpc.rows {
            let mark = if row.reparametrised { " *" } else { "" };
            let _ = writeln!(
                out,
                "  {:<10} {:>3}  {:<width$} {:>9} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}{mark}",
                row.branch,
                row.row,
                row.name,
                fixed(row.phi_deg),
                fixed(row.alpha_deg),
                fixed(row.beta_deg),
                cell(row.gamma_deg),
                cell(row.x_mm),
                cell(row.y_mm),
                cell(row.z_mm)
            );
        }
        let _ = writeln!(out, "  φ is a constant (not a parameter): the rotation about the previous joint axis chosen so that |β| ≤ 60°.");
        if self.mcpc.rows.iter().any(|r| r.reparametrised) {
            let _ = writeln!(out, "  * re-parametrised: the joint axis lies (nearly) along the previous X axis (β near ±90°, the MCPC");
            let _ = writeln!(out, "    singularity; for a tool row, the gimbal lock of its X-Y-Z angles), so φ turns the previous frame");
            let _ = writeln!(out, "    by 90°; later rows' φ undo the turn.");
        }
        let _ = writeln!(out, "  parameters: {}", self.mcpc.parameter_formula);
    }
}
