//! `plan`: choose collision-free configurations that make the parameters best observable
//! (greedy pick + DETMAX exchanges on an observability index), per calibration stage. The
//! chosen and a random set are then analysed exactly as `check` analyses a pose file, so
//! `plan` and `check` report the same O1 for the same poses.

use super::check::stage_analysis;
use super::checker::{collision_checker, collision_statement};
use super::checks::{check_outputs, count, sigmas, Output};
use super::source::{NominalRobot, RobotSource};
use super::{no_progress, Note, Progress, ProgressFn};
use crate::calibration::DEFAULT_CONDITION_LIMIT;
use crate::calibration::{
    Criterion, IdentifiabilityReport, ObservationKind, ParameterSet, PoseRow,
    DEFAULT_POSITION_SIGMA, DEFAULT_ROTATION_SIGMA,
};
use crate::io::{planned_poses_to_csv, write_atomically};
use crate::limits;
use crate::math::Vec3;
use crate::measurement::TARGET_SPACING;
use crate::sim::CollisionCheck;
use crate::sim::{plan_poses, PlanReport, PlannedPose, PlanningOptions, PlanningStage};
use crate::sim::{NoiseModel, Targets};
use crate::tree::{Branches, KinematicTree};
use crate::{Error, McpcModel, Result};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Which calibration stage the poses are for.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum PlanStage {
    /// Every parameter at once (the simultaneous plan).
    #[default]
    All,
    /// The arms, the torso held.
    Arms,
    /// The torso, the arms locked.
    Torso,
    /// The paper's staging: a torso set (`torso_poses`), then an arms set (`poses`).
    Staged,
}

/// Settings of [`plan`]; `Default` is `treecal plan --poses 20`.
#[derive(Debug, Clone)]
pub struct PlanConfig {
    /// The robot.
    pub robot: RobotSource,
    /// Folders searched for `package://` collision meshes, before `ROS_PACKAGE_PATH`.
    pub package_paths: Vec<PathBuf>,
    /// Which collision shapes the poses are checked against (stated in the CSV's header).
    pub collision_check: CollisionCheck,
    /// Tool links ending the arms [default: detected].
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole, a mobile base) [default: the root].
    pub reference_link: Option<String>,
    /// Configurations to choose (for `Staged`: the arms set).
    pub poses: usize,
    /// Configurations of the torso set for `Staged`.
    pub torso_poses: usize,
    /// Collision-free candidates to choose from.
    pub candidates: usize,
    /// The observability index maximised.
    pub criterion: Criterion,
    /// Targets per tool: 3 (a frame) or 1 (a position).
    pub targets: u8,
    /// Which stage the poses are for.
    pub stage: PlanStage,
    /// Box every tool origin must lie in (base frame, m): xmin,ymin,zmin,xmax,ymax,zmax.
    pub workspace: Option<Vec<f64>>,
    /// Position σ the rows are weighted by (m), as in `check` and `calibrate`.
    pub position_sigma: f64,
    /// Rotation σ the rows are weighted by (rad), as in `check` and `calibrate`.
    pub rotation_sigma: f64,
    /// Tracker noise (as `simulate`) that sets both σ instead, when given.
    pub noise: Option<String>,
    /// Seed of the candidate draws.
    pub seed: u64,
}

impl Default for PlanConfig {
    fn default() -> Self {
        Self {
            robot: RobotSource::BuiltIn,
            package_paths: Vec::new(),
            collision_check: CollisionCheck::Meshes,
            tools: None,
            reference_link: None,
            poses: 20,
            torso_poses: 10,
            candidates: 5000,
            criterion: Criterion::O1,
            targets: 3,
            stage: PlanStage::All,
            workspace: None,
            position_sigma: DEFAULT_POSITION_SIGMA,
            rotation_sigma: DEFAULT_ROTATION_SIGMA,
            noise: None,
            seed: 0,
        }
    }
}

/// One planned set.
#[derive(Debug, Clone)]
pub struct PlannedSet {
    /// Its `stage` label in the CSV (`torso`, `arms`; none for the simultaneous set).
    pub label: Option<String>,
    /// What the planner chose; its `planned_value` / `random_value` are the criterion it
    /// maximised (columns scaled over the candidate pool, docs/planning.md).
    pub report: PlanReport,
    /// The chosen set analysed as `check` analyses it.
    pub planned: IdentifiabilityReport,
    /// The random comparison set analysed as `check` analyses it.
    pub random: IdentifiabilityReport,
}

/// What [`plan`] chose.
#[derive(Debug, Clone)]
pub struct PosePlan {
    /// What the CLI prints on stderr, in order.
    pub notes: Vec<Note>,
    /// The planned sets, torso first.
    pub sets: Vec<PlannedSet>,
    /// The criterion the sets were chosen and are reported by.
    pub criterion: Criterion,
    /// The poses CSV (`[stage,]tool,<joint columns>`).
    pub csv: String,
    /// One summary line per set, and its warnings (what the CLI prints on stdout).
    pub text: String,
    /// The sets as JSON: counts, rejections, and the reported criterion and O1–O5.
    pub json: serde_json::Value,
}

impl PosePlan {
    /// Writes the poses CSV to `out`, atomically.
    pub fn write(&self, out: &Path) -> Result<()> {
        write_atomically(out, self.csv.as_bytes())
    }
}

/// Refuses an output that cannot be written or would replace the robot: call before [`plan`].
pub fn check_output(config: &PlanConfig, out: &Path) -> Result<()> {
    check_outputs(
        &[Output::File(out)],
        &config.robot.path().into_iter().collect::<Vec<_>>(),
    )
}

/// Plans the poses; writes nothing.
pub fn plan(config: &PlanConfig) -> Result<PosePlan> {
    plan_with_progress(config, &no_progress)
}

/// [`plan`], calling `progress` as candidates are accepted.
pub fn plan_with_progress(config: &PlanConfig, progress: ProgressFn<'_>) -> Result<PosePlan> {
    let workspace = validate(config)?;
    let mut notes = Vec::new();
    let NominalRobot {
        import,
        branches,
        model,
    } = config.robot.nominal(
        config.tools.as_deref(),
        config.reference_link.as_deref(),
        &mut notes,
    )?;
    let tree = &import.tree;
    notes.extend(branches.roles_summary(tree).map(Note::info));
    notes.extend(branches.reference_summary(tree).map(Note::info));
    notes.extend(crate::calibration::gauge_summary(&model, tree).map(Note::info));
    let checker = collision_checker(
        &config.robot,
        tree,
        &config.package_paths,
        config.collision_check,
        &mut notes,
    )?;
    let collisions = collision_statement(config.collision_check, &checker);
    let base = PlanningOptions {
        poses: config.poses,
        candidates: config.candidates,
        criterion: config.criterion,
        targets: targets(config.targets),
        workspace,
        position_sigma: config.position_sigma,
        rotation_sigma: config.rotation_sigma,
        seed: config.seed,
        ..PlanningOptions::default()
    };
    let base = with_noise(config, base, &mut notes)?;
    let mut sets = Vec::new();
    for (index, (label, stage, poses)) in stages(config).into_iter().enumerate() {
        let options = PlanningOptions {
            stage,
            poses,
            // Each stage its own candidates.
            seed: base.seed.wrapping_add(index as u64),
            ..base.clone()
        };
        let tick = |done: usize| {
            progress(Progress {
                stage: Some(label.unwrap_or("all")),
                done,
                total: options.candidates,
                unit: "candidates",
            })
        };
        let report = plan_poses(tree, &branches, &model, Some(&checker), &options, &tick)?;
        let analyse =
            |poses: &[PlannedPose]| analyse_set(tree, &branches, &model, &options, label, poses);
        sets.push(PlannedSet {
            label: label.map(str::to_owned),
            planned: analyse(&report.poses)?,
            random: analyse(&report.random_poses)?,
            report,
        });
    }
    finish(notes, sets, config.criterion, &collisions, tree, &model)
}

/// The outcome: the CSV, the summary text, the JSON, and each set's warnings as notes.
fn finish(
    mut notes: Vec<Note>,
    sets: Vec<PlannedSet>,
    criterion: Criterion,
    collisions: &str,
    tree: &KinematicTree,
    model: &McpcModel,
) -> Result<PosePlan> {
    let labelled: Vec<(Option<&str>, &[PlannedPose])> = sets
        .iter()
        .map(|s| (s.label.as_deref(), s.report.poses.as_slice()))
        .collect();
    // `check` and `calibrate` skip `#` lines: the header travels with the poses.
    let csv = format!(
        "# self-collision check: {collisions}\n{}",
        planned_poses_to_csv(tree, model, &labelled)?
    );
    let mut text = format!("self-collision check: {collisions}\n");
    for set in &sets {
        let label = set.label.as_deref().unwrap_or("all");
        let _ = writeln!(text, "{}", summary_line(label, set, criterion));
        for warning in set_warnings(set) {
            let _ = writeln!(text, "  warning: {warning}");
            notes.push(Note::warning(format!("{label}: {warning}")));
        }
    }
    let json = serde_json::json!({
        "robot": tree.name(),
        "criterion": criterion.to_string(),
        "collision_check": collisions,
        "sets": sets.iter().map(|s| set_json(s, criterion)).collect::<Vec<_>>(),
    });
    Ok(PosePlan {
        notes,
        sets,
        criterion,
        csv,
        text,
        json,
    })
}

/// `all: 20 poses from 5000 candidates (…); O1 over 64 parameters (as check computes it):
/// planned …, random …; 3 exchanges`.
fn summary_line(label: &str, set: &PlannedSet, criterion: Criterion) -> String {
    let report = &set.report;
    format!(
        "{label}: {} poses from {} candidates ({} rejected for self-collision, {} outside the \
         workspace); {} over {} parameters (as `treecal check` computes it): planned {:.3e}, \
         random {:.3e}; {} exchanges",
        report.poses.len(),
        report.candidates,
        report.rejected_collision,
        report.rejected_workspace,
        criterion_name(criterion),
        set.planned.parameter_count(),
        set.planned.criterion(criterion),
        set.random.criterion(criterion),
        report.exchanges
    )
}

fn criterion_name(criterion: Criterion) -> &'static str {
    match criterion {
        Criterion::O1 => "O1",
        Criterion::D => "D",
        Criterion::O3 => "O3",
    }
}

/// What `check` would warn about the planned set: fewer equations than identifiable
/// parameters, or a rank deficiency the observation type does not explain.
fn set_warnings(set: &PlannedSet) -> Vec<String> {
    if set.report.poses.is_empty() {
        return vec!["no poses were planned".into()];
    }
    set.planned.warnings()
}

fn set_json(set: &PlannedSet, criterion: Criterion) -> serde_json::Value {
    let report = &set.report;
    serde_json::json!({
        "stage": set.label.as_deref().unwrap_or("all"),
        "poses": report.poses.len(),
        "candidates": report.candidates,
        "rejected_collision": report.rejected_collision,
        "rejected_workspace": report.rejected_workspace,
        "parameters": set.planned.parameter_count(),
        "planned": { "criterion": set.planned.criterion(criterion), "indices": set.planned.indices },
        "random": { "criterion": set.random.criterion(criterion), "indices": set.random.indices },
        "pool_scaled": { "planned": report.planned_value, "random": report.random_value },
        "exchanges": report.exchanges,
    })
}

/// `poses` (every tool measured at each) analysed as `check` analyses the CSV rows of the
/// stage `label`: the same σ, parameters and observation.
fn analyse_set(
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    options: &PlanningOptions,
    label: Option<&str>,
    poses: &[PlannedPose],
) -> Result<IdentifiabilityReport> {
    let rows: Vec<PoseRow> = poses
        .iter()
        .flat_map(|pose| {
            pose.tools.iter().map(|&tool| PoseRow {
                tool,
                q: pose.q.clone(),
                stage: label.map(str::to_owned),
            })
        })
        .collect();
    let parameters = match options.stage {
        PlanningStage::Torso => ParameterSet::Coupled,
        PlanningStage::Arms => ParameterSet::Arms,
        PlanningStage::All => ParameterSet::All,
    };
    let observation = match options.targets {
        Targets::One => ObservationKind::Position,
        Targets::Three => ObservationKind::Pose,
    };
    stage_analysis(
        tree,
        branches,
        model,
        &rows,
        observation,
        parameters,
        (options.position_sigma, options.rotation_sigma),
        DEFAULT_CONDITION_LIMIT,
    )
}

/// The sets to plan: (CSV label, stage, poses).
fn stages(config: &PlanConfig) -> Vec<(Option<&'static str>, PlanningStage, usize)> {
    match config.stage {
        PlanStage::All => vec![(None, PlanningStage::All, config.poses)],
        PlanStage::Arms => vec![(Some("arms"), PlanningStage::Arms, config.poses)],
        PlanStage::Torso => vec![(Some("torso"), PlanningStage::Torso, config.poses)],
        PlanStage::Staged => vec![
            (Some("torso"), PlanningStage::Torso, config.torso_poses),
            (Some("arms"), PlanningStage::Arms, config.poses),
        ],
    }
}

fn targets(count: u8) -> Targets {
    if count == 1 {
        Targets::One
    } else {
        Targets::Three
    }
}

/// The σ's a tracker noise model implies (σ at the base; a three-target frame √2·σ / 0.1 m),
/// when one is given; `check` then needs the same σ's to report the same O1.
fn with_noise(
    config: &PlanConfig,
    mut options: PlanningOptions,
    notes: &mut Vec<Note>,
) -> Result<PlanningOptions> {
    let Some(text) = &config.noise else {
        return Ok(options);
    };
    let noise = NoiseModel::parse(text)?;
    if !noise.is_none() {
        let sigma = noise.sigma(&Vec3::zeros());
        options.position_sigma = sigma;
        options.rotation_sigma = std::f64::consts::SQRT_2 * sigma / TARGET_SPACING;
        notes.push(Note::info(format!(
            "rows weighted by the {text} noise: `position_sigma` {:e} `rotation_sigma` {:e} (give check the same to see the same O1)",
            options.position_sigma, options.rotation_sigma
        )));
    }
    Ok(options)
}

fn invalid(setting: &str, message: String) -> Error {
    Error::setting(setting, message)
}

/// The settings' ranges; the workspace box as two corners.
fn validate(config: &PlanConfig) -> Result<Option<(Vec3, Vec3)>> {
    count("poses", config.poses, limits::MAX_POSES)?;
    count("candidates", config.candidates, limits::MAX_CANDIDATES)?;
    if config.torso_poses > limits::MAX_POSES {
        count("torso_poses", config.torso_poses, limits::MAX_POSES)?;
    }
    sigmas(config.position_sigma, config.rotation_sigma)?;
    if !matches!(config.targets, 1 | 3) {
        return Err(invalid(
            "targets",
            "use 1 (a position) or 3 (a frame)".into(),
        ));
    }
    for value in config.workspace.iter().flatten() {
        if let Some(problem) = limits::magnitude_problem(*value, limits::Quantity::Length) {
            return Err(invalid("workspace", problem));
        }
    }
    match config.workspace.as_deref() {
        None => Ok(None),
        Some([x0, y0, z0, x1, y1, z1]) => {
            Ok(Some((Vec3::new(*x0, *y0, *z0), Vec3::new(*x1, *y1, *z1))))
        }
        Some(values) => Err(invalid(
            "workspace",
            format!(
                "give six numbers xmin,ymin,zmin,xmax,ymax,zmax (metres, base frame), not {}",
                values.len()
            ),
        )),
    }
}
