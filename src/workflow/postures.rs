//! The identification postures a calibration used, recorded in its report.json
//! (`"identification_postures"`) so that `treecal verify` judges fresh rows against the same
//! calibrated ranges, with the same code ([`ChainPostures::stratum`]), months later.

pub use super::report_json::POSTURES_KEY;
use super::report_json::{ReportParts, ToolPostures};
use crate::calibration::{chain_postures, ChainPostures};
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::measurement::Measurement;
use crate::tree::KinematicTree;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One joint of a tool's chain and its calibrated range.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedJoint {
    /// The joint's URDF name.
    pub name: String,
    /// `revolute` (rad) or `prismatic` (m).
    pub kind: String,
    /// The smallest identification value (rad, m).
    pub min: f64,
    /// The largest identification value (rad, m).
    pub max: f64,
}

/// One tool's identification postures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedTool {
    /// The tool link.
    pub tool: String,
    /// The independent joints of its chain, with their calibrated ranges.
    pub joints: Vec<RecordedJoint>,
    /// Per identification row, the value of each joint of `joints` (rad, m).
    pub postures: Vec<RecordedPosture>,
}

/// One recorded posture: the joint values by joint name (what `calibrate` writes: report.json
/// is labelled, no positional arrays), or in the order of [`RecordedTool::joints`] (read too).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum RecordedPosture {
    /// The values in the order of the tool's `joints`.
    Values(Vec<f64>),
    /// The values by joint name (older reports).
    Named(BTreeMap<String, f64>),
}

impl RecordedPosture {
    /// The value of joint `name`, the `index`-th of its tool's `joints`.
    pub fn value(&self, index: usize, name: &str) -> Option<f64> {
        match self {
            Self::Values(values) => values.get(index).copied(),
            Self::Named(values) => values.get(name).copied(),
        }
    }
}

/// Every tool's postures (report.json `"identification_postures"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedPostures {
    /// `rad` and `m`.
    pub units: String,
    /// Per model tool.
    pub tools: Vec<RecordedTool>,
}

/// The record of `identification` for `model` of `tree`.
pub fn record(
    tree: &KinematicTree,
    model: &McpcModel,
    identification: &[Measurement],
) -> RecordedPostures {
    let chains = chain_postures(model, identification);
    let tools = model
        .tools()
        .iter()
        .zip(&chains)
        .map(|(tool, chain)| {
            let joints = recorded_joints(tree, chain);
            let postures = chain
                .postures
                .iter()
                .map(|posture| {
                    RecordedPosture::Named(
                        joints
                            .iter()
                            .zip(posture)
                            .map(|(joint, &value)| (joint.name.clone(), value))
                            .collect(),
                    )
                })
                .collect();
            RecordedTool {
                tool: tree.link(tool.link).name.clone(),
                joints,
                postures,
            }
        })
        .collect();
    RecordedPostures {
        units: UNITS.into(),
        tools,
    }
}

/// [`RecordedPostures::units`].
const UNITS: &str = "revolute joints rad, prismatic joints m";

/// The joints of `chain` with their calibrated ranges.
fn recorded_joints(tree: &KinematicTree, chain: &ChainPostures) -> Vec<RecordedJoint> {
    chain
        .dofs
        .iter()
        .zip(chain.ranges())
        .map(|(&(dof, angle), (min, max))| RecordedJoint {
            name: tree.joint(tree.dofs()[dof]).name.clone(),
            kind: if angle { "revolute" } else { "prismatic" }.into(),
            min,
            max,
        })
        .collect()
}

/// The recorded postures of each tool of `model` (of `tree`), in `model`'s configuration
/// indices; `None` for a tool the record does not have. An error names a recorded joint the
/// robot lacks.
pub fn chains_of(
    recorded: &RecordedPostures,
    tree: &KinematicTree,
    model: &McpcModel,
    origin: &str,
) -> Result<Vec<Option<ChainPostures>>> {
    model
        .tools()
        .iter()
        .map(|tool| {
            let name = &tree.link(tool.link).name;
            let Some(record) = recorded.tools.iter().find(|t| &t.tool == name) else {
                return Ok(None);
            };
            let dofs = record
                .joints
                .iter()
                .map(|joint| {
                    let dof = tree
                        .dofs()
                        .iter()
                        .position(|&j| tree.joint(j).name == joint.name)
                        .ok_or_else(|| Error::InvalidData {
                            origin: format!("{origin}: {POSTURES_KEY}"),
                            message: format!(
                                "joint '{}' of tool '{name}' is not a joint of the robot verified: verify the calibration's own URDF",
                                joint.name
                            ),
                        })?;
                    Ok((dof, joint.kind == "revolute"))
                })
                .collect::<Result<Vec<_>>>()?;
            let postures = record
                .postures
                .iter()
                .map(|posture| {
                    record
                        .joints
                        .iter()
                        .enumerate()
                        .map(|(index, joint)| {
                            posture.value(index, &joint.name).ok_or_else(|| Error::InvalidData {
                                origin: format!("{origin}: {POSTURES_KEY}"),
                                message: format!(
                                    "a posture of tool '{name}' has no value of joint '{}'",
                                    joint.name
                                ),
                            })
                        })
                        .collect::<Result<Vec<f64>>>()
                })
                .collect::<Result<Vec<_>>>()?;
            Ok(Some(ChainPostures { dofs, postures }))
        })
        .collect()
}

/// Sets `key` of the report.json object `report` to `value`, before its `stiffness` block
/// (which stays last).
pub(super) fn insert_key(report: &mut serde_json::Value, key: &str, value: serde_json::Value) {
    if let serde_json::Value::Object(map) = report {
        let stiffness = map.shift_remove("stiffness");
        map.insert(key.to_owned(), value);
        if let Some(stiffness) = stiffness {
            map.insert("stiffness".into(), stiffness);
        }
    }
}

/// Sets `key` to `value` in `report` and renders the JSON file `file` among `files` from it
/// with its typed `parts` ([`super::report_json::render`]: never parsed back, which at 10⁵ rows
/// would hold a second copy of a report of hundreds of MB).
pub(super) fn set_report_key(
    report: &mut serde_json::Value,
    parts: &ReportParts,
    files: &mut [(String, Vec<u8>)],
    file: &str,
    key: &str,
    value: serde_json::Value,
) -> Result<()> {
    insert_key(report, key, value);
    if let Some((_, bytes)) = files.iter_mut().find(|(name, _)| name == file) {
        *bytes = super::report_json::render(report, parts)?.into_bytes();
    }
    Ok(())
}

/// Records the identification postures of a calibration in its report.json value: the tools
/// and their joints there, the postures themselves returned typed (the file is rendered with
/// them once, when the report is complete).
pub(super) fn add_to_report(
    tree: &KinematicTree,
    model: &McpcModel,
    identification: &[Measurement],
    report: &mut serde_json::Value,
) -> Result<Vec<ToolPostures>> {
    let chains = chain_postures(model, identification);
    let mut parts = Vec::with_capacity(chains.len());
    let mut tools = Vec::with_capacity(chains.len());
    for (tool, chain) in model.tools().iter().zip(chains) {
        let joints = recorded_joints(tree, &chain);
        let names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
        parts.push(ToolPostures::new(&names, chain.postures));
        tools.push(RecordedTool {
            tool: tree.link(tool.link).name.clone(),
            joints,
            postures: Vec::new(),
        });
    }
    let record = RecordedPostures {
        units: UNITS.into(),
        tools,
    };
    let value = serde_json::to_value(record).map_err(|e| Error::InvalidData {
        origin: "report.json".into(),
        message: e.to_string(),
    })?;
    insert_key(report, POSTURES_KEY, value);
    Ok(parts)
}
