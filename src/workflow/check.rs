//! `check`: how well a pose set determines the parameters, per calibration stage — singular
//! values, rank, condition number, O1–O5 and the combinations the poses cannot determine.

use super::checks::{sigmas, unused_stage_rows};
use super::source::{
    add_measured_points, branches, measured_branches, MeasurementSource, PlanSource, RobotSource,
    StiffnessSource,
};
use super::Note;
use crate::calibration::{
    analyse, analyse_compliance, ComplianceIdentifiability, IdentifiabilityOptions,
    IdentifiabilityReport, IdentificationOptions, ObservationKind, ParameterSet, Plan, PoseRow,
    DEFAULT_POSITION_SIGMA, DEFAULT_ROTATION_SIGMA,
};
use crate::io::{
    parse_csv, pose_rows, read_plan, to_json, to_yaml, AngleUnit, LengthUnit,
    MeasurementReadOptions,
};
use crate::kinematics::{FlexibilityModel, Stiffness};
use crate::limits;
use crate::measurement::{Measurement, Observation};
use crate::report::{compliance_identifiability_markdown, CheckReport, StageCheck};
use crate::sim::staged_pose_set;
use crate::sim::CollisionChecker;
use crate::tree::{Branches, KinematicTree};
use crate::{Error, McpcModel, Result};
use std::path::{Path, PathBuf};

/// Size of the default pose set: arm configurations, torso configurations, locked arm
/// configurations (as `simulate`).
const DEFAULT_ARMS: usize = 20;
const DEFAULT_TORSO: usize = 10;
const DEFAULT_LOCKS: usize = 2;

/// Settings of [`check`]; `Default` is `treecal check` without flags (a seeded random set).
#[derive(Debug, Clone)]
pub struct CheckConfig {
    /// The robot.
    pub robot: RobotSource,
    /// Tool links ending the arms [default: detected, or the measured ones].
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole, a mobile base) [default: the root].
    pub reference_link: Option<String>,
    /// A pose CSV (joint columns, optional `tool` and `stage`), e.g. `plan`'s output.
    pub pose_file: Option<PathBuf>,
    /// Measurements (a CSV or arrays) whose configurations, tools and stages are analysed.
    pub measurements: Option<MeasurementSource>,
    /// Unit of lengths in `measurements` [default: its `# units:` comment, else m].
    pub length_unit: Option<LengthUnit>,
    /// Unit of prismatic joint values in `measurements` [default: the length unit].
    pub joint_length_unit: Option<LengthUnit>,
    /// Unit of revolute joint values [default: the file's `# units:` comment, else rad].
    pub angle_unit: Option<AngleUnit>,
    /// Columns of `measurements` to skip.
    pub ignore_columns: Vec<String>,
    /// Targets per tool without measurements: 3 (a pose) or 1 (a position).
    pub targets: u8,
    /// The plan whose stages are analysed (`Auto`: staged when the rows are labelled).
    pub plan: PlanSource,
    /// Expected position error of a measurement (m).
    pub position_sigma: f64,
    /// Expected rotation error of a measurement (rad).
    pub rotation_sigma: f64,
    /// Condition number above which a set is poorly conditioned.
    pub condition_limit: f64,
    /// Seed of the default random pose set.
    pub seed: u64,
    /// Also analyse which compliances the poses determine.
    pub identify_stiffness: bool,
    /// Stiffness for `identify_stiffness` [default: the built-in Robonaut's, or the library
    /// defaults for another robot].
    pub stiffness: Option<StiffnessSource>,
    /// Payloads (kg at every tool) every pose is measured at, for `identify_stiffness`.
    pub payloads: Option<Vec<f64>>,
    /// Relative uncertainty of the prior stiffness.
    pub stiffness_prior: f64,
}

impl Default for CheckConfig {
    fn default() -> Self {
        Self {
            robot: RobotSource::BuiltIn,
            tools: None,
            reference_link: None,
            pose_file: None,
            measurements: None,
            length_unit: None,
            joint_length_unit: None,
            angle_unit: None,
            ignore_columns: Vec::new(),
            targets: 3,
            plan: PlanSource::Auto,
            position_sigma: DEFAULT_POSITION_SIGMA,
            rotation_sigma: DEFAULT_ROTATION_SIGMA,
            condition_limit: crate::calibration::DEFAULT_CONDITION_LIMIT,
            seed: 0,
            identify_stiffness: false,
            stiffness: None,
            payloads: None,
            stiffness_prior: 0.5,
        }
    }
}

/// What [`check`] found.
#[derive(Debug, Clone)]
pub struct Check {
    /// What the CLI prints on stderr, in order.
    pub notes: Vec<Note>,
    /// The per-stage analyses.
    pub report: CheckReport,
    /// What the poses determine of the compliances, when asked.
    pub compliance: Option<ComplianceIdentifiability>,
    /// The text report (what `check` prints by default).
    pub text: String,
    /// The JSON report (`check --format json`).
    pub json: serde_json::Value,
}

impl Check {
    /// The JSON / YAML layout: the report, which holds the compliance analysis when there is one.
    fn output(&self) -> &CheckReport {
        &self.report
    }

    /// The report as pretty JSON (keys in report order).
    pub fn to_json(&self) -> Result<String> {
        to_json(&self.output())
    }

    /// The report as YAML.
    pub fn to_yaml(&self) -> Result<String> {
        to_yaml(&self.output())
    }
}

/// The rows analysed, whether they carry stage labels, and where they came from.
struct Rows {
    rows: Vec<PoseRow>,
    has_stage: bool,
    source: String,
    observation: ObservationKind,
}

fn invalid(setting: &str, message: String) -> Error {
    Error::setting(setting, message)
}

/// Analyses the pose set; writes nothing.
pub fn check(config: &CheckConfig) -> Result<Check> {
    validate(config)?;
    let mut notes = Vec::new();
    let robot = config.robot.load()?;
    notes.extend(robot.notes());
    let mut import = robot.import;
    let branches = match &config.measurements {
        Some(source) => {
            // Measured points become marker links, as in `calibrate`.
            let points = add_measured_points(&mut import, config.tools.as_deref(), source)?;
            notes.extend(points.note());
            let tools = points.tools.as_deref().or(config.tools.as_deref());
            measured_branches(&import, tools, config.reference_link.as_deref(), source)?
        }
        None => branches(
            &import,
            config.tools.as_deref(),
            config.reference_link.as_deref(),
        )?,
    };
    let tree = &import.tree;
    let model = McpcModel::from_tree(tree, &branches)?;
    notes.extend(branches.roles_summary(tree).map(Note::info));
    notes.extend(branches.reference_summary(tree).map(Note::info));
    notes.extend(crate::calibration::gauge_summary(&model, tree).map(Note::info));
    let requested = requested_plan(&config.plan)?;
    let rows = rows(
        config,
        tree,
        &branches,
        &model,
        requested.as_ref(),
        &mut notes,
    )?;
    let (plan, plan_name) = match requested {
        Some(plan) => (plan, plan_name(&config.plan)),
        None if rows.has_stage => (Plan::staged(), "staged".to_owned()),
        None => (Plan::simultaneous(), "simultaneous".to_owned()),
    };
    let sigmas = (config.position_sigma, config.rotation_sigma);
    let mut stages = Vec::new();
    if !rows.has_stage && plan.stages.iter().any(|s| s.measurements.is_some()) {
        notes.push(Note::info("the poses have no 'stage' column; every row is analysed in the arms stage, and the torso stage needs rows labelled torso (arms locked)"));
    }
    if rows.has_stage {
        let labels: Vec<Option<&str>> = rows.rows.iter().map(|r| r.stage.as_deref()).collect();
        let ids: Vec<String> = (1..=labels.len()).map(|row| row.to_string()).collect();
        notes.extend(unused_stage_rows(&plan, &labels, &ids).map(Note::warning));
    }
    for stage in &plan.stages {
        let selected = stage_rows(&rows, stage.measurements.as_deref());
        stages.push(if selected.is_empty() {
            let label = stage.measurements.as_deref().unwrap_or(&stage.name);
            StageCheck::skipped(
                &stage.name,
                format!(
                    "no rows labelled {label} (add a 'stage' column, or use `plan` simultaneous)"
                ),
            )
        } else {
            let analysis = stage_analysis(
                tree,
                &branches,
                &model,
                &selected,
                rows.observation,
                stage.parameters,
                sigmas,
                config.condition_limit,
            )?;
            StageCheck::analysed(&stage.name, analysis)
        });
    }
    let report = CheckReport::new(
        tree.name().to_owned(),
        rows.source.clone(),
        rows.observation,
        plan_name,
        stages,
    );
    for stage in &report.stages {
        for warning in stage.analysis.iter().flat_map(|a| a.warnings()) {
            notes.push(Note::warning(format!("stage {}: {warning}", stage.name)));
        }
    }
    let compliance = match config.identify_stiffness {
        true => Some(compliance_check(config, tree, &model, &rows)?),
        false => None,
    };
    finish(notes, report, compliance, config.stiffness_prior)
}

/// The outcome, with its text and JSON.
fn finish(
    notes: Vec<Note>,
    mut report: CheckReport,
    compliance: Option<ComplianceIdentifiability>,
    prior: f64,
) -> Result<Check> {
    report.compliance = compliance.clone();
    let mut text = report.to_text();
    if let Some(c) = &compliance {
        text += &compliance_identifiability_markdown(c, prior);
    }
    let mut check = Check {
        notes,
        report,
        compliance,
        text,
        json: serde_json::Value::Null,
    };
    check.json =
        serde_json::to_value(check.output()).map_err(|e| invalid("output", e.to_string()))?;
    Ok(check)
}

/// The analysis of one stage's rows, as `check` and `plan` both report it: the rows weighted
/// by `sigmas` (position m, rotation rad), the `parameters` the stage identifies.
#[allow(clippy::too_many_arguments)]
pub fn stage_analysis(
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    rows: &[PoseRow],
    observation: ObservationKind,
    parameters: ParameterSet,
    sigmas: (f64, f64),
    condition_limit: f64,
) -> Result<IdentifiabilityReport> {
    let options = IdentifiabilityOptions {
        position_sigma: sigmas.0,
        rotation_sigma: sigmas.1,
        parameters,
        condition_limit,
        ..IdentifiabilityOptions::default()
    };
    analyse(tree, branches, model, rows, observation, &options)
}

fn validate(config: &CheckConfig) -> Result<()> {
    sigmas(config.position_sigma, config.rotation_sigma)?;
    if !(config.condition_limit.is_finite() && config.condition_limit >= 1.0) {
        let message = format!("{} must be a number of at least 1", config.condition_limit);
        return Err(invalid("condition_limit", message));
    }
    if !matches!(config.targets, 1 | 3) {
        return Err(invalid(
            "targets",
            "2 targets give neither a full pose nor a single position; use 3 (a pose) or 1 (a position)".into(),
        ));
    }
    if config.pose_file.is_some() && config.measurements.is_some() {
        let message = "give a pose file or a measurement file, not both".into();
        return Err(invalid("pose_file", message));
    }
    Ok(())
}

/// The plan asked for; `None` for `Auto` (decided by the rows' labels).
fn requested_plan(source: &PlanSource) -> Result<Option<Plan>> {
    Ok(match source {
        PlanSource::Auto => None,
        PlanSource::Staged => Some(Plan::staged()),
        PlanSource::Simultaneous => Some(Plan::simultaneous()),
        PlanSource::File(path) => Some(read_plan(path)?),
    })
}

fn plan_name(source: &PlanSource) -> String {
    match source {
        PlanSource::Auto | PlanSource::Staged => "staged".into(),
        PlanSource::Simultaneous => "simultaneous".into(),
        PlanSource::File(path) => path.display().to_string(),
    }
}

/// The rows of a stage: those labelled `label` (all without a label filter). Unlabelled rows
/// all go to every stage but the torso's, which needs its arms locked.
fn stage_rows(rows: &Rows, label: Option<&str>) -> Vec<PoseRow> {
    match label {
        None => rows.rows.clone(),
        Some("torso") if !rows.has_stage => Vec::new(),
        Some(_) if !rows.has_stage => rows.rows.clone(),
        Some(label) => rows
            .rows
            .iter()
            .filter(|r| r.stage.as_deref() == Some(label))
            .cloned()
            .collect(),
    }
}

/// The rows to analyse: the measurement file's, the pose file's, or the default random set.
fn rows(
    config: &CheckConfig,
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    plan: Option<&Plan>,
    notes: &mut Vec<Note>,
) -> Result<Rows> {
    let observation = match config.targets {
        1 => ObservationKind::Position,
        _ => ObservationKind::Pose,
    };
    if let Some(source) = &config.measurements {
        return measurement_rows(config, tree, model, source, notes);
    }
    if let Some(path) = &config.pose_file {
        let (rows, has_stage, source) = pose_file_rows(config, tree, model, path, notes)?;
        return Ok(Rows {
            rows,
            has_stage,
            source,
            observation,
        });
    }
    // The torso set only when a stage needs it (the default and staged plans).
    let torso = plan.is_none_or(|p| {
        p.stages
            .iter()
            .any(|s| s.parameters == ParameterSet::Coupled)
    });
    let (rows, source) = default_rows(config.seed, tree, branches, model, torso)?;
    notes.push(Note::info(format!(
        "no `pose_file` given; analysing the {source}"
    )));
    Ok(Rows {
        rows,
        has_stage: true,
        source,
        observation,
    })
}

fn measurement_rows(
    config: &CheckConfig,
    tree: &KinematicTree,
    model: &McpcModel,
    source: &MeasurementSource,
    notes: &mut Vec<Note>,
) -> Result<Rows> {
    let options = MeasurementReadOptions {
        length_unit: config.length_unit,
        angle_unit: config.angle_unit,
        joint_length_unit: config.joint_length_unit,
        ignore_columns: config.ignore_columns.clone(),
        strict_limits: false,
        tool: config
            .tools
            .as_ref()
            .filter(|t| t.len() == 1)
            .map(|t| t[0].trim().to_owned()),
    };
    let set = source.read(tree, model, &options)?;
    notes.extend(set.warnings.iter().map(Note::warning));
    notes.extend(set.notes.iter().map(Note::info));
    let rows: Vec<PoseRow> = set
        .measurements
        .iter()
        .map(|m| PoseRow {
            tool: m.tool,
            q: m.q.clone(),
            stage: m.stage.clone(),
        })
        .collect();
    let observation = match set.observation {
        crate::io::ObservationKind::Position => ObservationKind::Position,
        _ => ObservationKind::Pose,
    };
    Ok(Rows {
        has_stage: rows.iter().any(|r| r.stage.is_some()),
        source: format!("{} ({} observations)", source.origin(), rows.len()),
        rows,
        observation,
    })
}

fn pose_file_rows(
    config: &CheckConfig,
    tree: &KinematicTree,
    model: &McpcModel,
    path: &Path,
    notes: &mut Vec<Note>,
) -> Result<(Vec<PoseRow>, bool, String)> {
    let origin = path.display().to_string();
    let text = limits::read_text(path, limits::MAX_CSV_BYTES)?;
    let table = parse_csv(&text, &origin)?;
    let scale = match config.angle_unit {
        Some(AngleUnit::Degree) => std::f64::consts::PI / 180.0,
        _ => 1.0,
    };
    let set = pose_rows(&table, tree, model, scale, &origin)?;
    for column in &set.mapping.unmatched {
        notes.push(Note::info(format!(
            "column '{}' of {origin} matches no joint of '{}' and is not used",
            table.headers[*column],
            tree.name()
        )));
    }
    for (_, reason) in &set.mapping.implied {
        notes.push(Note::info(format!(
            "{origin}: {reason}; the column is not used"
        )));
    }
    let source = format!("{origin} ({} rows)", table.records.len());
    Ok((set.rows, set.has_stage, source))
}

/// The seeded random collision-free set: `DEFAULT_TORSO` torso configurations (if `torso`) and
/// `DEFAULT_ARMS` arm configurations, every tool measured at each.
fn default_rows(
    seed: u64,
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    torso: bool,
) -> Result<(Vec<PoseRow>, String)> {
    let checker = CollisionChecker::new(tree)?;
    let torso_count = if torso { DEFAULT_TORSO } else { 0 };
    let set = staged_pose_set(
        tree,
        branches,
        Some(&checker),
        torso_count,
        DEFAULT_LOCKS,
        DEFAULT_ARMS,
        seed,
    )?;
    let every_tool = |configurations: Vec<Vec<f64>>, stage: &str| -> Vec<PoseRow> {
        configurations
            .into_iter()
            .flat_map(|q| {
                (0..model.tools().len()).map(move |tool| PoseRow {
                    tool,
                    q: q.clone(),
                    stage: Some(stage.into()),
                })
            })
            .collect()
    };
    let mut rows = every_tool(set.torso, "torso");
    rows.extend(every_tool(set.arms, "arms"));
    let source = if torso {
        format!(
            "default random collision-free set (seed {seed}): {DEFAULT_TORSO} torso configurations at {DEFAULT_LOCKS} locked arm configurations, {DEFAULT_ARMS} arm configurations; give your own with `pose_file`"
        )
    } else {
        format!(
            "default random collision-free set (seed {seed}): {DEFAULT_ARMS} configurations; give your own with `pose_file`"
        )
    };
    Ok((rows, source))
}

/// What the rows determine of the compliances: every row at each of the payloads (or at the
/// stiffness file's), the geometry free.
fn compliance_check(
    config: &CheckConfig,
    tree: &KinematicTree,
    model: &McpcModel,
    rows: &Rows,
) -> Result<ComplianceIdentifiability> {
    if !(config.stiffness_prior.is_finite() && config.stiffness_prior > 0.0) {
        let message = format!("{} must be a positive number", config.stiffness_prior);
        return Err(invalid("stiffness_prior", message));
    }
    let stiffness = match (&config.stiffness, &config.robot) {
        (Some(source), _) => source.read(tree, model)?,
        (None, RobotSource::BuiltIn) => StiffnessSource::BuiltIn.read(tree, model)?,
        (None, _) => Stiffness::default(),
    };
    let flexibility = FlexibilityModel::new(tree, model, &stiffness)?;
    let loads: Vec<Option<f64>> = match &config.payloads {
        Some(list) => list.iter().map(|&p| Some(p)).collect(),
        None => vec![None],
    };
    let mut measurements = Vec::new();
    let mut payloads = Vec::new();
    for row in &rows.rows {
        // The observed values do not enter the analysis; the nominal pose stands in.
        let pose = model.tool_poses(&row.q)[row.tool];
        let observation = match rows.observation {
            ObservationKind::Pose => Observation::Pose(pose),
            ObservationKind::Position => Observation::Position(pose.translation.vector),
        };
        for load in &loads {
            measurements.push(Measurement {
                payload: None,
                tool: row.tool,
                q: row.q.clone(),
                observation: observation.clone(),
                stage: row.stage.clone(),
                session: None,
            });
            payloads.push(*load);
        }
    }
    let payloads: Option<Vec<f64>> = payloads.iter().copied().collect();
    let options = IdentificationOptions {
        position_sigma: config.position_sigma,
        rotation_sigma: config.rotation_sigma,
        ..IdentificationOptions::default()
    };
    let free: Vec<usize> = (0..model.parameter_count()).collect();
    analyse_compliance(
        tree,
        model,
        &flexibility,
        &measurements,
        payloads.as_deref(),
        &free,
        &options,
        config.stiffness_prior,
    )
}
