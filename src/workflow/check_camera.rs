//! `check --camera FILE --detections FILE`: what camera detections determine, before any
//! fit ([`crate::camera::camera_identifiability`]), with the unobservable combinations said
//! in words.

use super::simulate_camera::with_camera_links;
use super::source::{branches, RobotSource};
use super::Note;
use crate::camera::{camera_identifiability, CameraIdentifiability, CameraProblem, Rig};
use crate::io::read_camera_file;
use crate::io::read_detections;
use crate::io::StatedUnits;
use crate::{McpcModel, Result};
use std::path::PathBuf;

/// Settings of [`check_camera`].
#[derive(Debug, Clone)]
pub struct CameraCheckConfig {
    /// The robot.
    pub robot: RobotSource,
    /// Tool links ending the arms [default: detected, plus the links of cameras moved by
    /// joints on no branch].
    pub tools: Option<Vec<String>>,
    /// The camera file (cameras and targets, `docs/file-formats.md`).
    pub camera_file: PathBuf,
    /// The detections CSV.
    pub detections: PathBuf,
    /// Pixel noise σ of a detected point (px).
    pub pixel_sigma: f64,
}

/// What [`check_camera`] found.
#[derive(Debug, Clone)]
pub struct CameraCheck {
    /// What the CLI prints on stderr, in order.
    pub notes: Vec<Note>,
    /// The analysis.
    pub report: CameraIdentifiability,
    /// The text report.
    pub text: String,
}

/// Reads the robot, the camera file and the detections and says what the detections
/// determine.
pub fn check_camera(config: &CameraCheckConfig) -> Result<CameraCheck> {
    let mut notes = Vec::new();
    let robot = config.robot.load()?;
    notes.extend(robot.notes());
    let import = robot.import;
    let tree = &import.tree;
    let contents = read_camera_file(&config.camera_file, tree)?;
    let branches = with_camera_links(
        tree,
        branches(&import, config.tools.as_deref(), None)?,
        &contents.cameras,
        &mut notes,
    )?;
    let nominal = McpcModel::from_tree(tree, &branches)?;
    let (rig, augmented) = Rig::build(tree, &nominal, &contents.cameras, &contents.targets)?;
    let views = read_detections(&config.detections, tree, &rig, &StatedUnits::default())?;
    let problem = CameraProblem {
        rig: &rig,
        views: &views,
        tracker: &[],
        unknowns: rig.unknowns(&augmented, true),
        contacts: Default::default(),
    };
    let report = camera_identifiability(tree, &branches, &augmented, &problem, config.pixel_sigma)?;
    let text = text(&report, views.len());
    Ok(CameraCheck {
        notes,
        report,
        text,
    })
}

fn text(report: &CameraIdentifiability, views: usize) -> String {
    let mut text = format!(
        "camera detections: {views} image(s) of a target; {} unknowns, rank {}\n",
        report.unknowns, report.rank
    );
    if report.findings.is_empty() {
        text.push_str("every unknown is determined by these images\n");
    }
    for finding in &report.findings {
        text.push_str(&format!("- {finding}\n"));
    }
    text
}
