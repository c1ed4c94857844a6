//! Pose-set CSV files: joint columns as in a joint CSV, plus an optional `tool` column (the
//! tool link measured in that row) and an optional `stage` column (`torso` or `arms`). Read by
//! `treecal check --poses`; written by `treecal plan` (one row per tool per configuration,
//! `[stage,]tool,<joint names…>` in metres and radians, ready to be completed with the measured
//! columns of the measurement CSV).

use super::csv_fields::CsvTable;
use super::joints_csv::{configurations, ColumnMapping};
use crate::calibration::PoseRow;
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::sim::PlannedPose;
use crate::tree::KinematicTree;

/// The stage labels a pose row may carry (those of the staged plan).
pub const STAGES: [&str; 2] = ["torso", "arms"];

/// The pose rows of a pose-set CSV and how its columns were read.
#[derive(Debug, Clone)]
pub struct PoseSet {
    /// One row per measured tool and configuration: a CSV row without a `tool` column (or
    /// with an empty tool) stands for every tool of the model, in model order.
    pub rows: Vec<PoseRow>,
    /// Whether the file has a `stage` column.
    pub has_stage: bool,
    /// The joint columns; `unmatched` excludes `tool` and `stage`.
    pub mapping: ColumnMapping,
}

/// Reads the pose rows of `table` for `model` (built from `tree`). `angle_scale` converts
/// angle columns to radians; joints without a column are 0.
pub fn pose_rows(
    table: &CsvTable,
    tree: &KinematicTree,
    model: &McpcModel,
    angle_scale: f64,
    origin: &str,
) -> Result<PoseSet> {
    let (qs, mut mapping) = configurations(table, tree, angle_scale, origin)?;
    let column = |name: &str| table.headers.iter().position(|h| h == name);
    let tool_column = column("tool");
    let stage_column = column("stage");
    mapping
        .unmatched
        .retain(|&c| Some(c) != tool_column && Some(c) != stage_column);
    let tool_names: Vec<&str> = model
        .tools()
        .iter()
        .map(|t| tree.link(t.link).name.as_str())
        .collect();
    let mut rows = Vec::with_capacity(qs.len() * tool_names.len());
    for ((line, fields), q) in table.records.iter().zip(qs) {
        let stage = match stage_column.map(|c| fields[c].as_str()) {
            None | Some("") => None,
            Some(text) => match STAGES.iter().find(|s| s.eq_ignore_ascii_case(text)) {
                Some(stage) => Some((*stage).to_owned()),
                None => {
                    return Err(Error::InvalidData {
                        origin: format!("{origin}:{line}:stage"),
                        message: format!(
                        "'{}' is not a stage; use torso (arms locked) or arms, or leave it empty",
                        crate::limits::cut(text)
                    ),
                    })
                }
            },
        };
        let tools: Vec<usize> = match tool_column.map(|c| fields[c].as_str()) {
            None | Some("") => (0..tool_names.len()).collect(),
            Some(text) => match tool_names.iter().position(|n| *n == text) {
                Some(tool) => vec![tool],
                None => {
                    return Err(Error::InvalidData {
                        origin: format!("{origin}:{line}:tool"),
                        message: format!(
                            "'{text}' is not a tool of '{}'; use one of {} (or `tools` to choose others)",
                            tree.name(),
                            tool_names.join(", ")
                        ),
                    })
                }
            },
        };
        rows.extend(tools.into_iter().map(|tool| PoseRow {
            tool,
            q: q.clone(),
            stage: stage.clone(),
        }));
    }
    if rows.is_empty() {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: "no pose rows below the header; add one configuration per row".into(),
        });
    }
    Ok(PoseSet {
        rows,
        has_stage: stage_column.is_some(),
        mapping,
    })
}

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
