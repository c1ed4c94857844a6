//! `treecal simulate`.

use crate::cli::{MeasurementFormat, PlanChoice, PosesFrom, SimulateArgs};
use std::io::IsTerminal;
use std::path::Path;
use treecal::calibration::Plan;
use treecal::io::{
    measurements_to_csv, measurements_to_csv_with, parse_stiffness, read_stiffness, to_json,
    write_atomically, LengthUnit, MeasurementWriteOptions,
};
use treecal::kinematics::FlexibilityModel;
use treecal::limits;
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

/// The flags' ranges and counts (`treecal::limits`), and no output over an input.
fn check_flags(args: &SimulateArgs) -> Result<()> {
    for (flag, value, bound, unit) in [
        (
            "--angle-error",
            args.angle_error,
            std::f64::consts::PI,
            "rad",
        ),
        ("--length-error", args.length_error, limits::MAX_LENGTH, "m"),
    ] {
        limits::check_range(value, (0.0, bound), flag, unit)?;
    }
    let scale = (1.0 / limits::MAX_FACTOR, limits::MAX_FACTOR);
    limits::check_range(
        args.model_stiffness_scale,
        scale,
        "--model-stiffness-scale",
        "",
    )?;
    for (flag, value) in [
        ("--poses", args.poses),
        ("--validation-poses", args.validation_poses),
        ("--trials", args.trials),
    ] {
        crate::checks::count(flag, value, limits::MAX_POSES)?;
    }
    if args.torso_poses as usize > limits::MAX_POSES {
        crate::checks::count("--torso-poses", args.torso_poses, limits::MAX_POSES)?;
    }
    if !(args.outliers.is_finite() && (0.0..=1.0).contains(&args.outliers)) {
        return Err(invalid(
            "--outliers",
            format!("{} is not a fraction between 0 and 1", args.outliers),
        ));
    }
    if !(args.outlier_size.is_finite() && args.outlier_size > 0.0) {
        return Err(invalid(
            "--outlier-size",
            format!("{} mm must be positive", args.outlier_size),
        ));
    }
    let inputs: Vec<&Path> = args
        .robot
        .iter()
        .chain(&args.stiffness)
        .map(|p| p.as_path())
        .collect();
    if let Some(path) = &args.write_measurements {
        crate::checks::refuse_overwrite(path, &inputs)?;
    }
    let written = ["summary.md", "results.json"];
    crate::checks::refuse_overwrite_in(&args.out, &written, "svg", &inputs)
}

pub fn run(args: SimulateArgs) -> Result<()> {
    check_flags(&args)?;
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
    for &mass in args.payloads.iter().flatten() {
        limits::check_range(mass, (0.0, limits::MAX_MASS), "--payloads", "kg")?;
    }
    if let Some(mass) = args.payload {
        limits::check_range(mass, (0.0, limits::MAX_MASS), "--payload", "kg")?;
        for payload in &mut stiffness.payloads {
            payload.mass = mass;
        }
    }
    if let Some(k) = args.joint_stiffness {
        if !(k.is_finite() && k >= limits::MIN_STIFFNESS) {
            return Err(invalid(
                "--joint-stiffness",
                format!(
                    "{k} N·m/rad must be a number of at least {:e} (docs/file-formats.md, \"Limits\")",
                    limits::MIN_STIFFNESS
                ),
            ));
        }
        stiffness.joint_default.bending = k;
        stiffness.joint_default.torsion = k;
        stiffness.joint_overrides.clear();
    }
    let truth_flexibility = FlexibilityModel::new(tree, &nominal, &stiffness)?;
    let model_flexibility = truth_flexibility.scaled(1.0 / args.model_stiffness_scale)?;
    let checker = crate::robot::checker(args.robot.as_deref(), tree, &args.package_path)?;
    if args.poses_from == PosesFrom::Planned {
        crate::checks::count("--candidates", args.candidates, limits::MAX_CANDIDATES)?;
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
        robust: args.robust.into(),
        outliers: args.outliers,
        outlier_size: args.outlier_size * 1e-3,
        payloads: args.payloads.clone().unwrap_or_default(),
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
    if let Some(first) = reports.first() {
        for note in &first.notes {
            eprintln!("treecal: note: {note}");
        }
    }

    let header = format!(
        "Robot '{}', {} trial(s), seed {}; {} arm + {} torso configurations ({}), {} validation; errors ±{} rad, ±{} m; noise {}; {} target(s) per tool; {} plan; model stiffness × {}; robust loss {}{}.",
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
        args.model_stiffness_scale,
        options.robust,
        if args.outliers > 0.0 {
            format!(
                "; {} % of the measurements made blunders of {} mm",
                args.outliers * 100.0,
                args.outlier_size
            )
        } else {
            String::new()
        }
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
