//! Loading the robot a command works on: a URDF path, or the built-in Robonaut.

use std::path::Path;
use treecal::io::read_measured_tool_names;
use treecal::urdf::{load_urdf, parse_urdf, UrdfImport};
use treecal::{detect_branches, Branches, Result};

/// The Robonaut generated from the paper's Table 1, built into the library so that the main
/// commands work from any directory.
pub const BUILT_IN_ROBONAUT: &str = treecal::workflow::source::BUILT_IN_ROBONAUT;

/// Loads `path`, or the built-in Robonaut when `None`; prints loader warnings on stderr.
pub fn load(path: Option<&Path>) -> Result<UrdfImport> {
    let import = match path {
        Some(path) => load_urdf(path)?,
        None => parse_urdf(BUILT_IN_ROBONAUT, "built-in robonaut.urdf")?,
    };
    for warning in &import.warnings {
        eprintln!("treecal: warning: {warning}");
    }
    Ok(import)
}

/// Detects branches, with the tool links named by the user if any.
pub fn branches(import: &UrdfImport, tools: Option<&[String]>) -> Result<Branches> {
    let tree = &import.tree;
    let tools = tools
        .map(|names| {
            names
                .iter()
                .map(|n| tree.link_id(n.trim()))
                .collect::<Result<Vec<_>>>()
        })
        .transpose()?;
    detect_branches(tree, tools.as_deref())
}

/// Detects branches from the tools the user named, else from the links the measurement CSV's
/// `tool` column names (the measured tools), so that automatic detection cannot pick others.
pub fn measured_branches(
    import: &UrdfImport,
    tools: Option<&[String]>,
    measurements: &Path,
) -> Result<Branches> {
    if tools.is_some() {
        return branches(import, tools);
    }
    let measured = read_measured_tool_names(measurements)?;
    let tree = &import.tree;
    let ids = measured
        .iter()
        .map(|name| {
            tree.link_id(name).map_err(|e| treecal::Error::InvalidData {
                origin: format!("{}: tool column", measurements.display()),
                message: format!("{e}; the tool column names the measured tool links"),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    detect_branches(tree, Some(&ids))
}

/// The URDF text of `path`, or of the built-in Robonaut, with the name to use in messages.
pub fn original_text(path: Option<&Path>) -> Result<(String, String)> {
    match path {
        Some(path) => Ok((
            treecal::limits::read_text(path, treecal::limits::MAX_URDF_BYTES)?,
            path.display().to_string(),
        )),
        None => Ok((
            BUILT_IN_ROBONAUT.to_owned(),
            "built-in robonaut.urdf".to_owned(),
        )),
    }
}

/// Notes on what an export dropped or added (docs/export.md): printed by `export`, among the
/// verdict's reasons in `calibrate`.
pub fn export_notes(report: &treecal::urdf::ExportReport) -> Vec<treecal::calibration::Finding> {
    let dropped = report.dropped.iter().map(|d| {
        format!(
            "tool '{}' moved onto the axis of joint '{}' in the URDF: its calibrated origin lies {:.4} mm off the axis, within the calibration's uncertainty ({:.4} mm, 3σ); its orientation is exact",
            d.tool, d.joint, d.offset_mm, d.tolerance_mm
        )
    });
    let added = report.added_links.iter().map(|a| {
        format!(
            "added link '{}' below tool '{}' at the exact calibrated tool frame ({:.4} mm off the joint axis, which the tool link itself cannot be)",
            a.link, a.tool, a.offset_mm
        )
    });
    dropped
        .chain(added)
        .map(|message| treecal::calibration::Finding::note("urdf-export", message))
        .collect()
}
