//! `inspect`, `to-mcpc` and `from-mcpc`: a robot's tree, branches and MCPC table, and the
//! table turned back into a URDF.

use super::note::Note;
use super::source::{branches, RobotSource};
use crate::error::Result;
use crate::io::{mcpc_table_to_yaml, read_mcpc_table};
use crate::kinematics::{McpcModel, McpcTable};
use crate::report::{inspect as inspect_report, InspectReport};
use crate::urdf::{parse_urdf, urdf_from_mcpc_table};
use std::path::Path;

/// A robot and, optionally, the tool links ending its arms.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ModelConfig {
    /// The robot.
    pub robot: RobotSource,
    /// Tool links ending the arms [default: detected].
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole, a mobile base) [default: the root].
    pub reference_link: Option<String>,
}

/// A robot's tree, branches and MCPC parameter table.
#[derive(Debug, Clone)]
pub struct Inspection {
    /// The report (text, YAML or JSON).
    pub report: InspectReport,
    /// The loader's warnings.
    pub notes: Vec<Note>,
}

/// Loads the robot, detects its branches and builds its MCPC model.
pub fn inspect(config: &ModelConfig) -> Result<Inspection> {
    let robot = config.robot.load()?;
    let branches = branches(
        &robot.import,
        config.tools.as_deref(),
        config.reference_link.as_deref(),
    )?;
    let model = McpcModel::from_tree(robot.tree(), &branches)?;
    let report = inspect_report(robot.tree(), &robot.import.warnings, &branches, &model);
    Ok(Inspection {
        report,
        notes: robot.notes(),
    })
}

/// A robot's MCPC table as YAML (the format `from-mcpc` reads).
#[derive(Debug, Clone, PartialEq)]
pub struct McpcTableText {
    /// The YAML text.
    pub yaml: String,
    /// The loader's warnings.
    pub notes: Vec<Note>,
}

/// The MCPC table of the detected (or named) branches, with the constant phi of every row.
pub fn to_mcpc(config: &ModelConfig) -> Result<McpcTableText> {
    let robot = config.robot.load()?;
    let branches = branches(
        &robot.import,
        config.tools.as_deref(),
        config.reference_link.as_deref(),
    )?;
    if branches.reference != robot.tree().root() {
        return Err(crate::error::Error::Branches(
            "an MCPC table is rooted at the URDF root; give no reference link".into(),
        ));
    }
    let model = McpcModel::from_tree(robot.tree(), &branches)?;
    let table = McpcTable::from_model(robot.tree(), &branches, &model)?;
    let source = match &config.robot {
        RobotSource::BuiltIn => "the built-in robonaut.urdf".to_owned(),
        RobotSource::File(path) => path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        ),
        RobotSource::Text { origin, .. } => origin.clone(),
    };
    let header = [
        format!("MCPC table of {source}, written by treecal to-mcpc (degrees, millimetres)."),
        "Rows: prev_from_frame = Q(prev) * Rz(phi) * Rx(alpha) * Ry(beta) * Trans(x, y, 0); phi is a constant, see docs/mcpc.md.".to_owned(),
    ];
    Ok(McpcTableText {
        yaml: mcpc_table_to_yaml(&table, &header),
        notes: robot.notes(),
    })
}

/// The URDF generated from an MCPC table file, checked to load.
pub fn from_mcpc(table: &Path) -> Result<String> {
    let parsed = read_mcpc_table(table)?;
    // Name the source by its file name only, so the output does not depend on where it ran.
    let source = table
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| table.display().to_string());
    let urdf = urdf_from_mcpc_table(&parsed, &source);
    parse_urdf(&urdf, "generated URDF")?;
    Ok(urdf)
}
