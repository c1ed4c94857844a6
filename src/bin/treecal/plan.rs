//! `treecal plan`.

use crate::cli::{CriterionChoice, PlanArgs, StageChoice};
use std::io::IsTerminal;
use treecal::calibration::{
    analyse, IdentifiabilityOptions, ObservationKind, ParameterSet, PoseRow,
};
use treecal::io::{planned_poses_to_csv, write_atomically};
use treecal::limits;
use treecal::math::Vec3;
use treecal::measurement::TARGET_SPACING;
use treecal::sim::noise::{NoiseModel, Targets};
use treecal::sim::planning::{plan_poses, Criterion, PlanReport, PlanningOptions, PlanningStage};
use treecal::{Error, McpcModel, Result};

/// What `treecal check` would warn about the planned set of one stage: fewer equations than
/// identifiable parameters, or a rank deficiency the observation type does not explain.
fn pose_set_warnings(
    tree: &treecal::KinematicTree,
    branches: &treecal::Branches,
    model: &McpcModel,
    options: &PlanningOptions,
    label: Option<&str>,
    report: &PlanReport,
) -> Result<Vec<String>> {
    let rows: Vec<PoseRow> = report
        .poses
        .iter()
        .flat_map(|pose| {
            pose.tools.iter().map(|&tool| PoseRow {
                tool,
                q: pose.q.clone(),
                stage: label.map(str::to_owned),
            })
        })
        .collect();
    if rows.is_empty() {
        return Ok(vec!["no poses were planned".into()]);
    }
    // The stage labels of `run`: torso, arms, or none for the simultaneous set.
    let parameters = match label {
        Some("torso") => ParameterSet::Coupled,
        Some("arms") => ParameterSet::Arms,
        _ => ParameterSet::All,
    };
    let observation = match options.targets {
        Targets::One => ObservationKind::Position,
        Targets::Three => ObservationKind::Pose,
    };
    let analysis = analyse(
        tree,
        branches,
        model,
        &rows,
        observation,
        &IdentifiabilityOptions {
            position_sigma: options.position_sigma,
            rotation_sigma: options.rotation_sigma,
            parameters,
            ..IdentifiabilityOptions::default()
        },
    )?;
    Ok(analysis.warnings())
}

fn invalid(flag: &str, message: String) -> Error {
    Error::InvalidData {
        origin: flag.into(),
        message,
    }
}

pub fn run(args: PlanArgs) -> Result<()> {
    crate::checks::count("--poses", args.poses, limits::MAX_POSES)?;
    crate::checks::count("--candidates", args.candidates, limits::MAX_CANDIDATES)?;
    if args.torso_poses as usize > limits::MAX_POSES {
        crate::checks::count("--torso-poses", args.torso_poses, limits::MAX_POSES)?;
    }
    for value in args.workspace.iter().flatten() {
        limits::check(*value, limits::Quantity::Length, || "--workspace".into())?;
    }
    if let Some(robot) = &args.robot {
        crate::checks::refuse_overwrite(&args.output, &[robot])?;
    }
    if args.targets == 2 {
        return Err(invalid(
            "--targets",
            "use 1 (a position) or 3 (a frame)".into(),
        ));
    }
    let workspace = match args.workspace.as_deref() {
        None => None,
        Some([x0, y0, z0, x1, y1, z1]) => {
            Some((Vec3::new(*x0, *y0, *z0), Vec3::new(*x1, *y1, *z1)))
        }
        Some(values) => {
            return Err(invalid(
                "--workspace",
                format!(
                    "give six numbers xmin,ymin,zmin,xmax,ymax,zmax (metres, base frame), not {}",
                    values.len()
                ),
            ))
        }
    };
    let noise = NoiseModel::parse(&args.noise)?;
    let import = crate::robot::load(args.robot.as_deref())?;
    let tree = &import.tree;
    let branches = crate::robot::branches(&import, args.tools.as_deref())?;
    let model = McpcModel::from_tree(tree, &branches)?;
    let checker = crate::robot::checker(args.robot.as_deref(), tree, &args.package_path)?;
    let targets = if args.targets == 1 {
        Targets::One
    } else {
        Targets::Three
    };
    let mut base = PlanningOptions {
        poses: args.poses as usize,
        candidates: args.candidates as usize,
        criterion: match args.criterion {
            CriterionChoice::O1 => Criterion::O1,
            CriterionChoice::D => Criterion::D,
            CriterionChoice::O3 => Criterion::O3,
        },
        targets,
        workspace,
        seed: args.seed,
        ..PlanningOptions::default()
    };
    if !noise.is_none() {
        let sigma = noise.sigma(&Vec3::zeros());
        base.position_sigma = sigma;
        base.rotation_sigma = std::f64::consts::SQRT_2 * sigma / TARGET_SPACING;
    }
    let stages: Vec<(Option<&str>, PlanningStage, usize)> = match args.stage {
        StageChoice::All => vec![(None, PlanningStage::All, args.poses as usize)],
        StageChoice::Arms => vec![(Some("arms"), PlanningStage::Arms, args.poses as usize)],
        StageChoice::Torso => vec![(Some("torso"), PlanningStage::Torso, args.poses as usize)],
        StageChoice::Staged => vec![
            (
                Some("torso"),
                PlanningStage::Torso,
                args.torso_poses as usize,
            ),
            (Some("arms"), PlanningStage::Arms, args.poses as usize),
        ],
    };
    let mut reports: Vec<(Option<&str>, PlanReport)> = Vec::new();
    for (index, (label, stage, poses)) in stages.into_iter().enumerate() {
        let options = PlanningOptions {
            stage,
            poses,
            // Each stage its own candidates.
            seed: base.seed.wrapping_add(index as u64),
            ..base.clone()
        };
        let bar = std::io::stderr().is_terminal().then(|| {
            let bar = indicatif::ProgressBar::new(options.candidates as u64);
            bar.set_message(format!("{} candidates", label.unwrap_or("all")));
            bar
        });
        let progress = |done: usize| {
            if let Some(bar) = &bar {
                bar.set_position(done as u64);
            }
        };
        let report = plan_poses(tree, &branches, &model, Some(&checker), &options, &progress)?;
        if let Some(bar) = &bar {
            bar.finish_and_clear();
        }
        reports.push((label, report));
    }
    let sets: Vec<(Option<&str>, &[_])> = reports
        .iter()
        .map(|(label, report)| (*label, report.poses.as_slice()))
        .collect();
    write_atomically(
        &args.output,
        planned_poses_to_csv(tree, &model, &sets)?.as_bytes(),
    )?;
    for (label, report) in &reports {
        let warnings = pose_set_warnings(tree, &branches, &model, &base, *label, report)?;
        println!(
            "{}: {} poses from {} candidates ({} rejected for self-collision, {} outside the \
             workspace); {:?} over {} parameters: planned {:.6e}, random {:.6e}; {} exchanges",
            label.unwrap_or("all"),
            report.poses.len(),
            report.candidates,
            report.rejected_collision,
            report.rejected_workspace,
            report.criterion,
            report.parameters,
            report.planned_value,
            report.random_value,
            report.exchanges
        );
        for warning in &warnings {
            println!("  warning: {warning}");
            eprintln!("treecal: warning: {}: {warning}", label.unwrap_or("all"));
        }
    }
    eprintln!("treecal: wrote {}", args.output.display());
    Ok(())
}
