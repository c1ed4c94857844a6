//! `export`: write calibrated MCPC parameters (a `params.yaml`) into the robot's URDF.

use super::note::Note;
use super::source::{branches, RobotSource};
use crate::calibration::Finding;
use crate::error::Result;
use crate::io::{read_parameter_file_robot, read_parameters, write_atomically};
use crate::kinematics::McpcModel;
use crate::urdf::{export_urdf_with, AddedReason, ExportOptions, ExportReport};
use std::path::{Path, PathBuf};

/// At most this many parameters missing from the file are named one by one.
const LISTED_MISSING: usize = 5;

/// What to export.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ExportConfig {
    /// The robot whose URDF is rewritten.
    pub robot: RobotSource,
    /// The parameter file (YAML, as `calibrate` writes `params.yaml`).
    pub parameters: PathBuf,
    /// Tool links ending the arms: the ones the parameters were calibrated with.
    pub tools: Option<Vec<String>>,
    /// The link the parameters were calibrated from (`None`: the URDF root). Needed when it is
    /// not the root: the paths from it (up a supporting leg) are part of the model only then.
    pub reference_link: Option<String>,
    /// Add a fixed `<tool>_marker` link at the tool frame where a tool origin cannot be
    /// expressed by its joint (docs/export.md) instead of failing.
    pub add_tool_links: bool,
}

/// An exported URDF with what the user should know about it.
#[derive(Debug, Clone)]
pub struct Export {
    /// The new URDF, the joints changed, the offsets dropped and the links added.
    pub report: ExportReport,
    /// Loader warnings, parameters missing from the file, and what the export dropped or
    /// added, in order.
    pub notes: Vec<Note>,
}

/// Sets the file's parameters on the robot's MCPC model and rewrites the joint origins (and
/// axes where needed) that change; every other byte of the URDF is kept.
pub fn export(config: &ExportConfig) -> Result<Export> {
    let mut robot = config.robot.load()?;
    let mut notes = robot.notes();
    // Measured points the calibration added as marker links: the model needs them again.
    let file_robot = read_parameter_file_robot(&config.parameters)?;
    for (link, parent) in &file_robot.points {
        if robot.tree().link_id(link).is_err() {
            let parent = robot.tree().link_id(parent)?;
            robot.import.tree.add_marker_link(link, parent)?;
        }
    }
    let tools = match &config.tools {
        None if !file_robot.points.is_empty() => Some(file_robot.tools.clone()),
        tools => tools.clone(),
    };
    let tree = robot.tree();
    let branches = branches(
        &robot.import,
        tools.as_deref(),
        config.reference_link.as_deref(),
    )?;
    let mut model = McpcModel::from_tree(tree, &branches)?;
    let parameters = read_parameters(&config.parameters, tree, &model)?;
    // A file for another branch selection misses every parameter: name a few, count the rest.
    notes.extend(
        parameters
            .warnings
            .iter()
            .take(LISTED_MISSING)
            .map(Note::warning),
    );
    if parameters.warnings.len() > LISTED_MISSING {
        notes.push(Note::warning(format!(
            "… and {} more parameters not listed keep their nominal values",
            parameters.warnings.len() - LISTED_MISSING
        )));
    }
    model.set_parameters(&parameters.values)?;
    let options =
        ExportOptions::with_uncertainty(tree, &model, &parameters.std_devs, config.add_tool_links);
    let report = export_urdf_with(&robot.text, &robot.origin, tree, &model, &options)?;
    notes.extend(export_notes(&report).iter().map(Note::from));
    Ok(Export { report, notes })
}

impl Export {
    /// The URDF text.
    pub fn urdf(&self) -> &str {
        &self.report.urdf
    }

    /// Writes the URDF to `out` (atomically).
    pub fn write(&self, out: &Path) -> Result<()> {
        write_atomically(out, self.report.urdf.as_bytes())
    }

    /// What changed, e.g. `3 joint origins changed, 1 axes`.
    pub fn summary(&self) -> String {
        let axes = self
            .report
            .changes
            .iter()
            .filter(|c| c.new_axis.is_some())
            .count();
        let axes = match axes {
            0 => String::new(),
            n => format!(", {n} axes"),
        };
        format!("{} joint origins changed{axes}", self.report.changes.len())
    }
}

/// Notes on what an export dropped or added (docs/export.md): notes of `export`, among the
/// verdict's reasons in `calibrate`.
pub fn export_notes(report: &ExportReport) -> Vec<Finding> {
    let dropped = report.dropped.iter().map(|d| {
        format!(
            "tool '{}' moved onto the axis of joint '{}' in the URDF: its calibrated origin lies {:.4} mm off the axis, within the calibration's uncertainty ({:.4} mm, 3σ); its orientation is exact",
            d.tool, d.joint, d.offset_mm, d.tolerance_mm
        )
    });
    let added = report.added_links.iter().map(|a| match a.reason {
        AddedReason::OffAxis => format!(
            "added link '{}' below tool '{}' at the exact calibrated tool frame, {:.4} mm off the axis of the joint that moves '{}' (which a URDF joint cannot carry): '{}' keeps its place on the calibrated arm, with its meshes and inertia; use '{}' for the measured frame",
            a.link, a.tool, a.offset_mm, a.tool, a.tool, a.link
        ),
        AddedReason::Marker => format!(
            "added link '{}' below tool '{}' at the calibrated measured (marker) frame, {:.1} mm from the tool link's origin: '{}' has child links, which keep their place on the calibrated arm; use '{}' for the measured frame",
            a.link, a.tool, a.offset_mm, a.tool, a.link
        ),
        AddedReason::Point => format!(
            "added link '{}' below '{}' at the calibrated position of the measured point ({:.1} mm from the link's origin)",
            a.link, a.parent, a.offset_mm
        ),
    });
    dropped
        .chain(added)
        .map(|message| Finding::note("urdf-export", message))
        .collect()
}
