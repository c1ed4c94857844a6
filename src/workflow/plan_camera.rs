//! `plan --camera cameras.yaml`: choose collision-free configurations in which the cameras see
//! the boards (every corner in the image and in front, the board facing the camera, no line of
//! sight through the robot's collision shapes) and which make the pixel Jacobian most
//! informative ([`crate::sim::camera_planning`]). Computes everything and writes nothing
//! ([`CameraPosePlan::write`] writes the CSV). See `docs/camera.md` section 7.

use super::checker::{collision_checker, collision_statement};
use super::checks::{check_outputs, Output};
use super::simulate_camera::with_camera_links;
use super::source::{branches, RobotSource};
use super::{Note, Progress, ProgressFn};
use crate::calibration::Criterion;
use crate::camera::Rig;
use crate::camera::View;
use crate::error::{Error, Result};
use crate::io::read_camera_file;
use crate::io::write_atomically;
use crate::sim::CollisionCheck;
use crate::sim::{plan_camera_poses, CameraPlanReport, CameraPlanningOptions};
use crate::sim::{Sight, VisibilityRules};
use crate::tree::KinematicTree;
use crate::McpcModel;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Settings of [`plan_camera`].
#[derive(Debug, Clone)]
pub struct CameraPlanConfig {
    /// The robot.
    pub robot: RobotSource,
    /// Folders searched for `package://` collision meshes.
    pub package_paths: Vec<PathBuf>,
    /// Which collision shapes the configurations are checked against (self-collision and
    /// lines of sight).
    pub collision_check: CollisionCheck,
    /// Tool links ending the arms [default: detected, plus a camera's link moved by joints on
    /// no branch].
    pub tools: Option<Vec<String>>,
    /// The camera file (cameras and targets).
    pub camera_file: PathBuf,
    /// Configurations to choose.
    pub poses: usize,
    /// Candidates (configurations showing a target) to choose from.
    pub candidates: usize,
    /// The criterion the sets are scored by.
    pub criterion: Criterion,
    /// Pixel noise σ (px).
    pub pixel_sigma: f64,
    /// Largest angle between a board's face normal and the direction to the camera (rad).
    pub max_view_angle: f64,
    /// Seed of the candidate draws.
    pub seed: u64,
}

/// What [`plan_camera`] chose.
#[derive(Debug, Clone)]
pub struct CameraPosePlan {
    /// What the CLI prints on stderr, in order.
    pub notes: Vec<Note>,
    /// The planner's outcome.
    pub report: CameraPlanReport,
    /// The configurations CSV (`id,targets,<joints>`, radians and metres).
    pub csv: String,
    /// The summary the CLI prints on stdout.
    pub text: String,
    /// The summary as JSON.
    pub json: serde_json::Value,
}

impl CameraPosePlan {
    /// Writes the configurations CSV to `out`, atomically.
    pub fn write(&self, out: &Path) -> Result<()> {
        write_atomically(out, self.csv.as_bytes())
    }
}

/// Refuses an output that cannot be written or would replace an input.
pub fn check_camera_plan_output(config: &CameraPlanConfig, out: &Path) -> Result<()> {
    let inputs: Vec<&Path> = config
        .robot
        .path()
        .into_iter()
        .chain(std::iter::once(config.camera_file.as_path()))
        .collect();
    check_outputs(&[Output::File(out)], &inputs)
}

/// Plans the camera configurations; writes nothing.
pub fn plan_camera(config: &CameraPlanConfig, progress: ProgressFn<'_>) -> Result<CameraPosePlan> {
    let angle = config.max_view_angle;
    if !(angle > 0.0 && angle < std::f64::consts::FRAC_PI_2) {
        return Err(Error::InvalidSetting {
            setting: "max_view_angle".into(),
            message: format!("{angle} rad: give an angle between 0 and 90° (in degrees)"),
        });
    }
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
    let checker = collision_checker(
        &config.robot,
        tree,
        &config.package_paths,
        config.collision_check,
        &mut notes,
    )?;
    let rules = VisibilityRules {
        max_view_angle: angle,
        ..VisibilityRules::default()
    };
    let sight = Sight {
        rig: &rig,
        model: &augmented,
        tree,
        checker: Some(&checker),
        rules: &rules,
    };
    let options = CameraPlanningOptions {
        poses: config.poses,
        candidates: config.candidates,
        criterion: config.criterion,
        pixel_sigma: config.pixel_sigma,
        seed: config.seed,
    };
    let tick = |done: usize| {
        progress(Progress {
            stage: None,
            done,
            total: config.candidates,
            unit: "candidates",
        })
    };
    let report = plan_camera_poses(&sight, Some(&checker), &options, &tick)?;
    let collisions = collision_statement(config.collision_check, &checker);
    let text = summary(&rig, &report, &rules, &collisions);
    let json = summary_json(&rig, &report, &rules);
    let csv = configurations_csv(tree, &rig, &report.poses);
    Ok(CameraPosePlan {
        notes,
        report,
        csv,
        text,
        json,
    })
}

/// The names of the targets `views` show, `;`-separated.
fn seen(rig: &Rig, views: &[View]) -> String {
    views
        .iter()
        .map(|v| rig.targets[v.target].name.as_str())
        .collect::<Vec<_>>()
        .join(";")
}

/// One line per figure of the plan.
fn summary(
    rig: &Rig,
    report: &CameraPlanReport,
    rules: &VisibilityRules,
    collisions: &str,
) -> String {
    let mut text = String::new();
    let _ = writeln!(
        text,
        "camera plan: {} configurations from {} candidates showing a target ({} collision-free \
         draws, {} showing none: a target counts when every point is in the image and in \
         front, the board within {:.0}° of facing the camera, and no line of sight crosses \
         another link's collision shape; {collisions})",
        report.poses.len(),
        report.candidates,
        report.draws,
        report.hidden,
        rules.max_view_angle.to_degrees()
    );
    let _ = writeln!(
        text,
        "{:?} on the pixel Jacobian ({} of {} unknowns determined by the pool): planned {:.4e}, \
         random set of the same size {:.4e} ({} exchanges after the greedy pick)",
        report.criterion,
        report.pool_rank,
        report.unknowns,
        report.planned_value,
        report.random_value,
        report.exchanges
    );
    for (target, name) in rig.targets.iter().map(|t| &t.name).enumerate() {
        let count = |poses: &[(Vec<f64>, Vec<View>)]| {
            poses
                .iter()
                .filter(|(_, views)| views.iter().any(|v| v.target == target))
                .count()
        };
        let _ = writeln!(
            text,
            "  {name}: seen in {} planned, {} random configurations",
            count(&report.poses),
            count(&report.random_poses)
        );
    }
    text
}

fn summary_json(
    rig: &Rig,
    report: &CameraPlanReport,
    rules: &VisibilityRules,
) -> serde_json::Value {
    serde_json::json!({
        "poses": report.poses.len(),
        "candidates": report.candidates,
        "draws": report.draws,
        "hidden": report.hidden,
        "criterion": report.criterion,
        "planned_value": report.planned_value,
        "random_value": report.random_value,
        "unknowns": report.unknowns,
        "pool_rank": report.pool_rank,
        "exchanges": report.exchanges,
        "max_view_angle_deg": rules.max_view_angle.to_degrees(),
        "targets_seen": report.poses.iter().map(|(_, v)| seen(rig, v)).collect::<Vec<_>>(),
    })
}

/// `id,targets,<every independent joint>` (rad, m), one row per planned configuration.
fn configurations_csv(tree: &KinematicTree, rig: &Rig, poses: &[(Vec<f64>, Vec<View>)]) -> String {
    let joints: Vec<&str> = tree
        .dofs()
        .iter()
        .map(|&j| tree.joint(j).name.as_str())
        .collect();
    let mut csv = format!(
        "# units: length=m angle=rad\nid,targets,{}\n",
        joints.join(",")
    );
    for (k, (q, views)) in poses.iter().enumerate() {
        let values: Vec<String> = q.iter().map(|v| format!("{v:.9}")).collect();
        let _ = writeln!(csv, "c{k},{},{}", seen(rig, views), values.join(","));
    }
    csv
}
