//! `treecal check`.

use crate::cli::{AngleUnit, CheckArgs, Format, PlanChoice};
use treecal::calibration::{
    analyse, analyse_compliance, ComplianceIdentifiability, IdentifiabilityOptions,
    IdentificationOptions, ObservationKind, ParameterSet, PoseRow,
};
use treecal::io::{
    parse_csv, parse_stiffness, pose_rows, read_measurements, read_stiffness, to_json, to_yaml,
    MeasurementReadOptions,
};
use treecal::kinematics::{FlexibilityModel, Stiffness};
use treecal::limits;
use treecal::measurement::{Measurement, Observation};
use treecal::report::compliance_identifiability_markdown;
use treecal::report::{CheckReport, StageCheck};
use treecal::sim::collision::CollisionChecker;
use treecal::sim::pose_set::staged_pose_set;
use treecal::{Error, McpcModel, Result};

/// Size of the default pose set: arm configurations, torso configurations, locked arm
/// configurations (as `treecal simulate`).
const DEFAULT_ARMS: usize = 20;
const DEFAULT_TORSO: usize = 10;
const DEFAULT_LOCKS: usize = 2;

fn invalid(flag: &str, message: String) -> Error {
    Error::InvalidData {
        origin: flag.into(),
        message,
    }
}

pub fn run(args: CheckArgs) -> Result<()> {
    crate::checks::sigmas(args.position_sigma, args.rotation_sigma)?;
    if !(args.condition_limit.is_finite() && args.condition_limit >= 1.0) {
        return Err(invalid(
            "--condition-limit",
            format!("{} must be a number of at least 1", args.condition_limit),
        ));
    }
    if args.targets == 2 {
        return Err(invalid(
            "--targets",
            "2 targets give neither a full pose nor a single position; use 3 (a pose) or 1 (a position)".into(),
        ));
    }
    let import = crate::robot::load(args.robot.as_deref())?;
    let tree = &import.tree;
    let branches = match &args.measurements {
        Some(path) => crate::robot::measured_branches(&import, args.tools.as_deref(), path)?,
        None => crate::robot::branches(&import, args.tools.as_deref())?,
    };
    let model = McpcModel::from_tree(tree, &branches)?;
    let measured = match &args.measurements {
        Some(path) => {
            let options = MeasurementReadOptions {
                length_unit: args.length_unit,
                angle_unit: args.angle_unit.map(|unit| match unit {
                    AngleUnit::Rad => treecal::io::AngleUnit::Radian,
                    AngleUnit::Deg => treecal::io::AngleUnit::Degree,
                }),
                joint_length_unit: args.joint_length_unit,
                ignore_columns: args.ignore_columns.clone(),
                strict_limits: false,
            };
            let set = read_measurements(path, tree, &model, &options)?;
            for warning in &set.warnings {
                eprintln!("treecal: warning: {warning}");
            }
            Some((path, set))
        }
        None => None,
    };
    let observation = match &measured {
        Some((_, set)) if set.observation == treecal::io::ObservationKind::Position => {
            ObservationKind::Position
        }
        Some(_) => ObservationKind::Pose,
        None if args.targets == 1 => ObservationKind::Position,
        None => ObservationKind::Pose,
    };
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
    let staged = matches!(args.plan, PlanChoice::Staged);
    let (rows, has_stage, source) = match (&args.poses, measured) {
        (_, Some((path, set))) => {
            let rows: Vec<PoseRow> = set
                .measurements
                .iter()
                .map(|m| PoseRow {
                    tool: m.tool,
                    q: m.q.clone(),
                    stage: m.stage.clone(),
                })
                .collect();
            let has_stage = rows.iter().any(|r| r.stage.is_some());
            let source = format!("{} ({} observations)", path.display(), rows.len());
            (rows, has_stage, source)
        }
        (Some(path), None) => {
            let origin = path.display().to_string();
            let text = limits::read_text(path, limits::MAX_CSV_BYTES)?;
            let table = parse_csv(&text, &origin)?;
            let scale = match args.angle_unit {
                Some(AngleUnit::Deg) => std::f64::consts::PI / 180.0,
                Some(AngleUnit::Rad) | None => 1.0,
            };
            let set = pose_rows(&table, tree, &model, scale, &origin)?;
            for column in &set.mapping.unmatched {
                eprintln!(
                    "treecal: note: column '{}' of {origin} matches no joint of '{}' and is not used",
                    table.headers[*column],
                    tree.name()
                );
            }
            for (_, reason) in &set.mapping.implied {
                eprintln!("treecal: note: {origin}: {reason}; the column is not used");
            }
            let source = format!("{origin} ({} rows)", table.records.len());
            (set.rows, set.has_stage, source)
        }
        (None, None) => {
            let checker = CollisionChecker::new(tree)?;
            let torso = if staged { DEFAULT_TORSO } else { 0 };
            let set = staged_pose_set(
                tree,
                &branches,
                Some(&checker),
                torso,
                DEFAULT_LOCKS,
                DEFAULT_ARMS,
                args.seed,
            )?;
            let mut rows = every_tool(set.torso, "torso");
            rows.extend(every_tool(set.arms, "arms"));
            let source = if staged {
                format!(
                    "default random collision-free set (seed {}): {DEFAULT_TORSO} torso configurations at {DEFAULT_LOCKS} locked arm configurations, {DEFAULT_ARMS} arm configurations; give your own with --poses",
                    args.seed
                )
            } else {
                format!(
                    "default random collision-free set (seed {}): {DEFAULT_ARMS} configurations; give your own with --poses",
                    args.seed
                )
            };
            eprintln!("treecal: note: no --poses given; analysing the {source}");
            (rows, true, source)
        }
    };
    let options = |parameters: ParameterSet| IdentifiabilityOptions {
        position_sigma: args.position_sigma,
        rotation_sigma: args.rotation_sigma,
        parameters,
        condition_limit: args.condition_limit,
        ..IdentifiabilityOptions::default()
    };
    let run_stage =
        |name: &str, parameters: ParameterSet, rows: &[PoseRow]| -> Result<StageCheck> {
            let report = analyse(
                tree,
                &branches,
                &model,
                rows,
                observation,
                &options(parameters),
            )?;
            Ok(StageCheck::analysed(name, report))
        };
    let stages = if staged {
        let labelled = |stage: &str| -> Vec<PoseRow> {
            rows.iter()
                .filter(|r| r.stage.as_deref() == Some(stage))
                .cloned()
                .collect()
        };
        let (torso, arms) = if has_stage {
            (labelled("torso"), labelled("arms"))
        } else {
            eprintln!(
                "treecal: note: the poses have no `stage` column; every row is analysed in the arms stage, and the torso stage needs rows labelled torso (arms locked)"
            );
            (Vec::new(), rows.clone())
        };
        let stage = |name: &str, parameters: ParameterSet, rows: &[PoseRow]| {
            if rows.is_empty() {
                Ok(StageCheck::skipped(
                    name,
                    format!("no rows labelled {name} (add a `stage` column, or use --plan simultaneous)"),
                ))
            } else {
                run_stage(name, parameters, rows)
            }
        };
        vec![
            stage("torso", ParameterSet::Coupled, &torso)?,
            stage("arms", ParameterSet::Arms, &arms)?,
        ]
    } else {
        vec![run_stage("all", ParameterSet::All, &rows)?]
    };
    let report = CheckReport::new(
        tree.name().to_owned(),
        source,
        observation,
        if staged { "staged" } else { "simultaneous" }.into(),
        stages,
    );
    for stage in &report.stages {
        for warning in stage.analysis.iter().flat_map(|a| a.warnings()) {
            eprintln!("treecal: warning: stage {}: {warning}", stage.name);
        }
    }
    let compliance = if args.identify_stiffness {
        Some(compliance_check(&args, tree, &model, &rows, observation)?)
    } else {
        None
    };
    let text = match (args.format, &compliance) {
        (Format::Text, None) => report.to_text(),
        (Format::Text, Some(c)) => {
            report.to_text() + &compliance_identifiability_markdown(c, args.stiffness_prior)
        }
        (Format::Yaml, None) => to_yaml(&report)?,
        (Format::Json, None) => to_json(&report)?,
        (format, Some(c)) => {
            let mut value =
                serde_json::to_value(&report).map_err(|e| invalid("output", e.to_string()))?;
            value["compliance"] =
                serde_json::to_value(c).map_err(|e| invalid("output", e.to_string()))?;
            match format {
                Format::Yaml => to_yaml(&value)?,
                _ => to_json(&value)?,
            }
        }
    };
    print!("{text}");
    Ok(())
}

/// What the rows determine of the compliances: every row at each of `--payloads` (or at the
/// file's payloads), the geometry free.
fn compliance_check(
    args: &CheckArgs,
    tree: &treecal::KinematicTree,
    model: &McpcModel,
    rows: &[PoseRow],
    observation: ObservationKind,
) -> Result<ComplianceIdentifiability> {
    if !(args.stiffness_prior.is_finite() && args.stiffness_prior > 0.0) {
        return Err(invalid(
            "--stiffness-prior",
            format!("{} must be a positive number", args.stiffness_prior),
        ));
    }
    let stiffness = match (&args.stiffness, &args.robot) {
        (Some(path), _) => read_stiffness(path, tree, model)?,
        (None, None) => parse_stiffness(
            crate::robot::BUILT_IN_STIFFNESS,
            "built-in stiffness.yaml",
            tree,
            model,
        )?,
        (None, Some(_)) => Stiffness::default(),
    };
    let flexibility = FlexibilityModel::new(tree, model, &stiffness)?;
    let mut measurements = Vec::new();
    let mut payloads = Vec::new();
    let loads: Vec<Option<f64>> = match &args.payloads {
        Some(list) => list.iter().map(|&p| Some(p)).collect(),
        None => vec![None],
    };
    for row in rows {
        // The observed values do not enter the analysis; the nominal pose stands in.
        let pose = model.tool_poses(&row.q)[row.tool];
        let observation = match observation {
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
            });
            payloads.push(*load);
        }
    }
    let payloads: Option<Vec<f64>> = payloads.iter().copied().collect();
    let options = IdentificationOptions {
        position_sigma: args.position_sigma,
        rotation_sigma: args.rotation_sigma,
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
        args.stiffness_prior,
    )
}
