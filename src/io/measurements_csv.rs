//! The measurement CSV (see `docs/file-formats.md`): one row per tool observation, with the
//! joint values of every independent joint, in metres and radians.

use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::measurement::{Measurement, Observation};
use crate::tree::KinematicTree;

/// Writes measurements as CSV: `id,stage,tool,<joint names…>,x,y,z[,qw,qx,qy,qz]`.
/// Full poses and single positions cannot be mixed in one file.
pub fn measurements_to_csv(
    tree: &KinematicTree,
    model: &McpcModel,
    measurements: &[Measurement],
) -> Result<String> {
    let poses = measurements
        .iter()
        .filter(|m| matches!(m.observation, Observation::Pose(_)))
        .count();
    if poses != 0 && poses != measurements.len() {
        return Err(Error::InvalidData {
            origin: "measurement CSV".into(),
            message: "full poses and single positions cannot be written to one file".into(),
        });
    }
    let mut header: Vec<String> = vec!["id".into(), "stage".into(), "tool".into()];
    header.extend(tree.dofs().iter().map(|j| tree.joint(*j).name.clone()));
    header.extend(["x", "y", "z"].map(String::from));
    if poses > 0 {
        header.extend(["qw", "qx", "qy", "qz"].map(String::from));
    }
    let mut rows = vec![header];
    for (index, m) in measurements.iter().enumerate() {
        let tool = model
            .tools()
            .get(m.tool)
            .map(|t| tree.link(t.link).name.clone())
            .ok_or_else(|| Error::InvalidData {
                origin: "measurement CSV".into(),
                message: format!(
                    "measurement {index} names tool {} of {}",
                    m.tool,
                    model.tools().len()
                ),
            })?;
        let mut row = vec![
            (index + 1).to_string(),
            m.stage.clone().unwrap_or_default(),
            tool,
        ];
        row.extend(m.q.iter().map(|v| format!("{v}")));
        match &m.observation {
            Observation::Pose(p) => {
                let t = p.translation.vector;
                let q = p.rotation.quaternion();
                row.extend(
                    [t.x, t.y, t.z, q.w, q.i, q.j, q.k]
                        .iter()
                        .map(|v| format!("{v}")),
                );
            }
            Observation::Position(p) => row.extend([p.x, p.y, p.z].iter().map(|v| format!("{v}"))),
        }
        rows.push(row);
    }
    super::csv_text(&rows, "measurement CSV")
}
