//! `treecal check`.

use crate::cli::{AngleUnit, CheckArgs, Format, PlanChoice};
use treecal::calibration::{
    analyse, IdentifiabilityOptions, ObservationKind, ParameterSet, PoseRow,
};
use treecal::io::{
    parse_csv, pose_rows, read_measurements, to_json, to_yaml, MeasurementReadOptions,
};
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
    for (flag, value) in [
        ("--position-sigma", args.position_sigma),
        ("--rotation-sigma", args.rotation_sigma),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(invalid(flag, format!("{value} must be a positive number")));
        }
    }
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
            let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
                path: path.clone(),
                source,
            })?;
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
    let text = match args.format {
        Format::Text => report.to_text(),
        Format::Yaml => to_yaml(&report)?,
        Format::Json => to_json(&report)?,
    };
    print!("{text}");
    Ok(())
}
