//! The planned-pose CSV (see `docs/file-formats.md`): one row per tool per configuration,
//! `[stage,]tool,<joint names…>` in metres and radians, ready to be completed with the
//! measured `x,y,z[,qw,qx,qy,qz]` columns of the measurement CSV.

use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::sim::planning::PlannedPose;
use crate::tree::KinematicTree;

/// Writes pose sets as CSV; each set has an optional stage label (a `stage` column is written
/// when any set has one), rows in set order.
pub fn planned_poses_to_csv(
    tree: &KinematicTree,
    model: &McpcModel,
    sets: &[(Option<&str>, &[PlannedPose])],
) -> Result<String> {
    let staged = sets.iter().any(|(stage, _)| stage.is_some());
    let mut header: Vec<String> = Vec::new();
    if staged {
        header.push("stage".into());
    }
    header.push("tool".into());
    header.extend(tree.dofs().iter().map(|j| tree.joint(*j).name.clone()));
    let mut rows = vec![header];
    for (stage, poses) in sets {
        for pose in *poses {
            for &tool in &pose.tools {
                let link = model
                    .tools()
                    .get(tool)
                    .map(|t| tree.link(t.link).name.clone())
                    .ok_or_else(|| Error::InvalidData {
                        origin: "pose CSV".into(),
                        message: format!("tool {tool} of {}", model.tools().len()),
                    })?;
                let mut row = Vec::with_capacity(pose.q.len() + 2);
                if staged {
                    row.push(stage.unwrap_or_default().to_owned());
                }
                row.push(link);
                row.extend(pose.q.iter().map(|v| format!("{v}")));
                rows.push(row);
            }
        }
    }
    super::csv_text(&rows, "pose CSV")
}
