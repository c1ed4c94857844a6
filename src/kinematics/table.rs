//! An MCPC parameter table in the layout of the paper's Table 1: branches of rows, each row
//! the MCPC frame of one joint, each arm ending in a tool row. Values in SI units.

use super::mcpc::{frame_transform, tool_transform, FrameKind};
use crate::error::{Error, Result};
use crate::math::Pose;

/// One joint row: the frame of joint `joint`, placed relative to the previous row's moved frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TableRow {
    /// Joint name in the generated URDF.
    pub joint: String,
    /// Name of the link the joint moves.
    pub link: String,
    /// Revolute or prismatic.
    pub kind: FrameKind,
    /// Constant rotation about the previous joint axis (rad); 0 in the paper's tables.
    pub phi: f64,
    /// α (rad).
    pub alpha: f64,
    /// β (rad).
    pub beta: f64,
    /// x (m), 0 for prismatic rows.
    pub x: f64,
    /// y (m), 0 for prismatic rows.
    pub y: f64,
    /// Joint limits (rad or m).
    pub limits: (f64, f64),
}

impl TableRow {
    /// `Rz(φ)·Rx(α)·Ry(β)·Trans(x, y, 0)`: the previous moved frame to this joint's frame.
    pub fn transform(&self) -> Pose {
        frame_transform(self.phi, self.alpha, self.beta, self.x, self.y)
    }
}

/// A tool row (six parameters).
#[derive(Debug, Clone, PartialEq)]
pub struct TableTool {
    /// Tool link name.
    pub link: String,
    /// Constant rotation about the last joint axis (rad); 0 in the paper's tables.
    pub phi: f64,
    /// α (rad).
    pub alpha: f64,
    /// β (rad).
    pub beta: f64,
    /// γ (rad).
    pub gamma: f64,
    /// x (m).
    pub x: f64,
    /// y (m).
    pub y: f64,
    /// z (m).
    pub z: f64,
}

impl TableTool {
    /// `Rz(φ)·Rx(α)·Ry(β)·Rz(γ)·Trans(x, y, z)`.
    pub fn transform(&self) -> Pose {
        tool_transform(
            self.phi, self.alpha, self.beta, self.gamma, self.x, self.y, self.z,
        )
    }
}

/// A branch of the table: joint rows in order and an optional tool.
#[derive(Debug, Clone, PartialEq)]
pub struct TableBranch {
    /// Branch name (`torso`, `left`, `right`, …).
    pub name: String,
    /// The branch it hangs from (its last row's moved frame); `None`: the base link.
    pub parent: Option<String>,
    /// Joint rows.
    pub rows: Vec<TableRow>,
    /// The tool row, if the branch ends in a tool. Its link may be the last row's link (the
    /// tool link is then the child link of the branch's last joint, as a palm on a wrist).
    pub tool: Option<TableTool>,
}

impl TableBranch {
    /// The tool, if its link is the link the branch's last joint moves (not a link of its own).
    pub fn carried_tool(&self) -> Option<&TableTool> {
        self.tool
            .as_ref()
            .filter(|t| self.rows.last().is_some_and(|r| r.link == t.link))
    }
}

/// A whole MCPC table.
#[derive(Debug, Clone, PartialEq)]
pub struct McpcTable {
    /// Robot name in the generated URDF.
    pub robot: String,
    /// Root link name.
    pub base_link: String,
    /// Branches, parents before children.
    pub branches: Vec<TableBranch>,
}

impl McpcTable {
    /// Checks names are unique and parents come first; `origin` names the source file.
    pub fn validate(&self, origin: &str) -> Result<()> {
        let bad = |message: String| Error::InvalidTable {
            origin: origin.to_owned(),
            message,
        };
        let mut links = vec![self.base_link.as_str()];
        let mut joints: Vec<&str> = Vec::new();
        for (index, branch) in self.branches.iter().enumerate() {
            if let Some(parent) = &branch.parent {
                let found = self.branches[..index].iter().find(|b| &b.name == parent);
                match found {
                    None => {
                        return Err(bad(format!(
                        "branch '{}' hangs from branch '{parent}', which is not listed before it",
                        branch.name
                    )))
                    }
                    Some(p) if p.rows.is_empty() => {
                        return Err(bad(format!(
                            "branch '{}' hangs from branch '{parent}', which has no joint rows",
                            branch.name
                        )))
                    }
                    Some(p) if p.carried_tool().is_some() => {
                        return Err(bad(format!(
                            "branch '{}' hangs from branch '{parent}', whose last link is its tool; give that tool a link of its own",
                            branch.name
                        )))
                    }
                    Some(_) => {}
                }
            }
            for row in &branch.rows {
                let values = [
                    row.alpha,
                    row.beta,
                    row.x,
                    row.y,
                    row.limits.0,
                    row.limits.1,
                ];
                if values.iter().any(|v| !v.is_finite()) {
                    return Err(bad(format!(
                        "row of joint '{}' has a non-finite value",
                        row.joint
                    )));
                }
                if row.limits.0 > row.limits.1 {
                    return Err(bad(format!(
                        "joint '{}' has lower limit above upper limit",
                        row.joint
                    )));
                }
                if joints.contains(&row.joint.as_str()) {
                    return Err(bad(format!("joint name '{}' is used twice", row.joint)));
                }
                joints.push(&row.joint);
                if links.contains(&row.link.as_str()) {
                    return Err(bad(format!("link name '{}' is used twice", row.link)));
                }
                links.push(&row.link);
            }
            if let Some(tool) = &branch.tool {
                let values = [
                    tool.phi, tool.alpha, tool.beta, tool.gamma, tool.x, tool.y, tool.z,
                ];
                if values.iter().any(|v| !v.is_finite()) {
                    return Err(bad(format!("tool '{}' has a non-finite value", tool.link)));
                }
                // A tool may be the link its branch's last joint moves (a palm on the wrist
                // joint): then the table names that link twice, in the last row and the tool.
                let carried = branch.rows.last().is_some_and(|r| r.link == tool.link);
                if !carried && links.contains(&tool.link.as_str()) {
                    return Err(bad(format!(
                        "link name '{}' is used twice (a tool may share a name only with its own branch's last row, when the last joint moves the tool link)",
                        tool.link
                    )));
                }
                if !carried {
                    links.push(&tool.link);
                }
            }
        }
        Ok(())
    }
}

impl McpcTable {
    /// The table of an MCPC model: one branch per detected branch, rows in chain order, φ
    /// where the model needed it. Generating a URDF from it reproduces the model's tool poses
    /// and joint frames (mimic relations and joints off the branches are not part of a table).
    pub fn from_model(
        tree: &crate::tree::KinematicTree,
        branches: &crate::tree::Branches,
        model: &super::McpcModel,
    ) -> Result<Self> {
        use crate::tree::JointKind;
        let mut out = Vec::new();
        let mut listed: Vec<usize> = Vec::new();
        for branch in branches.all() {
            let mut rows = Vec::new();
            for joint in &branch.joints {
                let index = model
                    .frame_of_joint(*joint)
                    .ok_or_else(|| Error::InvalidTable {
                        origin: "MCPC model".into(),
                        message: format!("joint '{}' has no MCPC frame", tree.joint(*joint).name),
                    })?;
                if listed.contains(&index) {
                    return Err(Error::InvalidTable {
                        origin: "MCPC model".into(),
                        message: format!(
                            "joint '{}' belongs to two arms; a table needs every arm to start at the torso",
                            tree.joint(*joint).name
                        ),
                    });
                }
                listed.push(index);
                let frame = &model.frames()[index];
                let source = tree.joint(*joint);
                let limits = match (source.kind, source.limits) {
                    (_, Some(l)) if l.lower.is_finite() && l.upper.is_finite() => {
                        (l.lower, l.upper)
                    }
                    (JointKind::Prismatic, _) => (-1.0, 1.0),
                    _ => (-std::f64::consts::PI, std::f64::consts::PI),
                };
                rows.push(TableRow {
                    joint: source.name.clone(),
                    link: tree.link(source.child).name.clone(),
                    kind: frame.kind,
                    phi: frame.phi,
                    alpha: frame.alpha,
                    beta: frame.beta,
                    x: frame.x,
                    y: frame.y,
                    limits,
                });
            }
            let tool = branch
                .tool
                .and_then(|t| model.tool_of_link(t))
                .map(|index| {
                    let t = &model.tools()[index];
                    TableTool {
                        link: tree.link(t.link).name.clone(),
                        phi: t.phi,
                        alpha: t.alpha,
                        beta: t.beta,
                        gamma: t.gamma,
                        x: t.x,
                        y: t.y,
                        z: t.z,
                    }
                });
            let parent = (branch.role != crate::tree::BranchRole::Coupled
                && !branches.coupled.joints.is_empty())
            .then(|| branches.coupled.name.clone());
            if rows.is_empty() && tool.is_none() {
                continue;
            }
            out.push(TableBranch {
                name: branch.name.clone(),
                parent,
                rows,
                tool,
            });
        }
        Ok(McpcTable {
            robot: tree.name().to_owned(),
            base_link: tree.link(tree.root()).name.clone(),
            branches: out,
        })
    }
}
