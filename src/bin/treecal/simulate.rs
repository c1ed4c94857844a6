//! `treecal simulate`.

use crate::cli::{MeasurementFormat, PlanChoice, PosesFrom, SimulateArgs};
use std::io::IsTerminal;
use treecal::calibration::Plan;
use treecal::io::{
    measurements_to_csv, measurements_to_csv_with, parse_stiffness, read_stiffness, to_json,
    write_atomically, LengthUnit, MeasurementWriteOptions,
};
use treecal::kinematics::FlexibilityModel;
use treecal::report::plot::arm_error_plots;
use treecal::report::simulate::simulation_markdown;
use treecal::sim::experiment::{Setup, SimulationOptions};
use treecal::sim::monte_carlo::{run_trials, summarise};
use treecal::sim::noise::{NoiseModel, Targets};
use treecal::sim::planning::PlanningOptions;
use treecal::sim::truth::ErrorRanges;
use treecal::{Error, McpcModel, Result};

fn invalid(flag: &str, message: String) -> Error {
    Error::InvalidData {
        origin: flag.into(),
        message,
    }
}

pub fn run(args: SimulateArgs) -> Result<()> {
    for (flag, value) in [
        ("--angle-error", args.angle_error),
        ("--length-error", args.length_error),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(invalid(
                flag,
                format!("{value} is not a non-negative number"),
            ));
        }
    }
    if !(args.model_stiffness_scale.is_finite() && args.model_stiffness_scale > 0.0) {
        return Err(invalid(
            "--model-stiffness-scale",
            format!("{} must be positive", args.model_stiffness_scale),
        ));
    }
    if args.poses == 0 || args.validation_poses == 0 || args.trials == 0 {
        return Err(invalid(
            "--poses/--validation-poses/--trials",
            "must be at least 1".into(),
        ));
    }
    let noise = NoiseModel::parse(&args.noise)?;
    let import = crate::robot::load(args.robot.as_deref())?;
    let tree = &import.tree;
    let branches = crate::robot::branches(&import, args.tools.as_deref())?;
    let nominal = McpcModel::from_tree(tree, &branches)?;
    let mut stiffness = match (&args.stiffness, &args.robot) {
        (Some(path), _) => read_stiffness(path, tree, &nominal)?,
        (None, None) => parse_stiffness(
            crate::robot::BUILT_IN_STIFFNESS,
            "built-in stiffness.yaml",
            tree,
            &nominal,
        )?,
        (None, Some(_)) => {
            return Err(invalid(
                "--stiffness",
                "a robot given with --robot needs its stiffness file (see docs/flexibility.md)"
                    .into(),
            ))
        }
    };
    if let Some(mass) = args.payload {
        if !(mass.is_finite() && mass >= 0.0) {
            return Err(invalid(
                "--payload",
                format!("{mass} kg is not a non-negative mass"),
            ));
        }
        for payload in &mut stiffness.payloads {
            payload.mass = mass;
        }
    }
    if let Some(k) = args.joint_stiffness {
        if !(k.is_finite() && k > 0.0) {
            return Err(invalid(
                "--joint-stiffness",
                format!("{k} N·m/rad must be positive"),
            ));
        }
        stiffness.joint_default.bending = k;
        stiffness.joint_default.torsion = k;
        stiffness.joint_overrides.clear();
    }
    let truth_flexibility = FlexibilityModel::new(tree, &nominal, &stiffness)?;
    let model_flexibility = truth_flexibility.scaled(1.0 / args.model_stiffness_scale)?;
    let checker = crate::robot::checker(args.robot.as_deref(), tree)?;
    if args.poses_from == PosesFrom::Planned && args.candidates == 0 {
        return Err(invalid("--candidates", "must be at least 1".into()));
    }
    let options = SimulationOptions {
        poses: args.poses as usize,
        torso_poses: args.torso_poses as usize,
        locks: 2,
        validation_poses: args.validation_poses as usize,
        errors: ErrorRanges {
            angle: args.angle_error,
            length: args.length_error,
        },
        noise,
        targets: if args.targets == 1 {
            Targets::One
        } else {
            Targets::Three
        },
        plan: match args.plan {
            PlanChoice::Staged => Plan::staged(),
            PlanChoice::Simultaneous => Plan::simultaneous(),
        },
        seed: args.seed,
        planning: (args.poses_from == PosesFrom::Planned).then(|| PlanningOptions {
            candidates: args.candidates as usize,
            ..PlanningOptions::default()
        }),
        identify_stiffness: args
            .identify_stiffness
            .then(treecal::calibration::StiffnessOptions::default),
    };
    if args.targets == 2 {
        return Err(invalid(
            "--targets",
            "use 1 (a position) or 3 (a frame)".into(),
        ));
    }
    let setup = Setup {
        tree,
        branches: &branches,
        nominal: &nominal,
        truth_flexibility: &truth_flexibility,
        model_flexibility: &model_flexibility,
        checker: Some(&checker),
    };
    let trials = args.trials as usize;
    let bar = (trials > 1 && std::io::stderr().is_terminal())
        .then(|| indicatif::ProgressBar::new(trials as u64));
    let progress = || {
        if let Some(bar) = &bar {
            bar.inc(1);
        }
    };
    let reports = run_trials(&setup, &options, trials, &progress)?;
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let summary = summarise(&reports);

    let header = format!(
        "Robot '{}', {} trial(s), seed {}; {} arm + {} torso configurations ({}), {} validation; errors ±{} rad, ±{} m; noise {}; {} target(s) per tool; {} plan; model stiffness × {}.",
        tree.name(),
        trials,
        args.seed,
        options.poses,
        options.torso_poses,
        match args.poses_from {
            PosesFrom::Random => "random".to_owned(),
            PosesFrom::Planned => format!("planned from {} candidates", args.candidates),
        },
        options.validation_poses,
        args.angle_error,
        args.length_error,
        args.noise,
        args.targets,
        match args.plan {
            PlanChoice::Staged => "staged",
            PlanChoice::Simultaneous => "simultaneous",
        },
        args.model_stiffness_scale
    );
    let header = if args.identify_stiffness {
        header + " Compliances identified jointly with the geometry (prior: the model's stiffness, ±50 %)."
    } else {
        header
    };
    let markdown = simulation_markdown(&header, &reports, &summary);
    let results = serde_json::json!({
        "robot": tree.name(),
        "seed": args.seed,
        "trials": reports,
        "summary": summary,
    });
    std::fs::create_dir_all(&args.out).map_err(|source| Error::Io {
        path: args.out.clone(),
        source,
    })?;
    write_atomically(&args.out.join("summary.md"), markdown.as_bytes())?;
    write_atomically(
        &args.out.join("results.json"),
        to_json(&results)?.as_bytes(),
    )?;
    if let Some(first) = reports.first() {
        for arm in &first.identification {
            let plots = arm_error_plots(
                &arm.arm,
                &arm.arm,
                "before and after calibration",
                &[
                    "before calibration",
                    "after, without flexibility compensation",
                    "after, with flexibility compensation",
                ],
                &arm.position_mm,
                &arm.orientation_deg,
            )?;
            for (stem, svg) in plots {
                write_atomically(&args.out.join(format!("{stem}.svg")), svg.as_bytes())?;
            }
        }
        if let Some(path) = &args.write_measurements {
            let text = match args.measurement_format {
                MeasurementFormat::Si => measurements_to_csv(tree, &nominal, &first.measurements)?,
                MeasurementFormat::Tracker => {
                    if args.targets != 3 {
                        return Err(invalid(
                            "--measurement-format",
                            "tracker writes three targets per tool; use it with --targets 3".into(),
                        ));
                    }
                    measurements_to_csv_with(
                        tree,
                        &nominal,
                        &first.measurements,
                        &MeasurementWriteOptions {
                            length_unit: LengthUnit::Millimetre,
                            angle_unit: treecal::io::AngleUnit::Degree,
                            three_targets: true,
                        },
                    )?
                }
            };
            write_atomically(path, text.as_bytes())?;
        }
    }
    print!("{markdown}");
    eprintln!("treecal: wrote {}", args.out.display());
    Ok(())
}
