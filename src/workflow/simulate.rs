//! `simulate`: the paper's section 5.2 experiment — a randomly wrong, gravity-loaded robot
//! measured by a noisy tracker, calibrated without and with flexibility compensation, judged on
//! the identification and on separate validation configurations, over seeded trials.

use super::checker::{collision_checker, collision_statement};
use super::checks::{check_outputs as check_paths, count, Output};
use super::source::{NominalRobot, PlanSource, RobotSource, StiffnessSource};
use super::{no_progress, Note, Progress, ProgressFn};
use crate::calibration::{Plan, StiffnessOptions};
use crate::io::{
    measurements_to_csv_with, read_plan, write_atomically, AngleUnit, LengthUnit,
    MeasurementWriteOptions,
};
use crate::kinematics::{FlexibilityModel, Stiffness};
use crate::limits;
use crate::report::arm_error_plots;
use crate::report::simulation_markdown;
use crate::sim::ErrorRanges;
use crate::sim::PlanningOptions;
use crate::sim::{run_trials, summarise};
use crate::sim::{NoiseModel, Targets};
use crate::sim::{SimulationOptions, TrialReport};
use crate::{Error, KinematicTree, McpcModel, Result};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

pub use super::simulate_config::{
    MeasurementFormat, ObservationChoice, PosesFrom, SimulateConfig, Simulation,
};

/// Runs the simulation; writes nothing.
pub fn simulate(config: &SimulateConfig) -> Result<Simulation> {
    simulate_with_progress(config, &no_progress)
}

/// [`simulate`], calling `progress` after every finished trial.
pub fn simulate_with_progress(
    config: &SimulateConfig,
    progress: ProgressFn<'_>,
) -> Result<Simulation> {
    let started = super::provenance::Started::now();
    validate(config)?;
    if !config.contacts.is_empty() {
        crate::limits::check_range(config.encoder_noise, (0.0, 0.1), "encoder_noise", "rad")?;
        if config.observation == ObservationChoice::Tracker {
            return super::simulate_contacts::simulate_contacts(config, progress);
        }
    }
    if config.observation != ObservationChoice::Tracker {
        return super::simulate_camera::simulate_camera(config, progress);
    }
    let noise = NoiseModel::parse(&config.noise)?;
    let mut notes = Vec::new();
    let NominalRobot {
        import,
        branches,
        model: nominal,
    } = config.robot.nominal(
        config.tools.as_deref(),
        config.reference_link.as_deref(),
        &mut notes,
    )?;
    let tree = &import.tree;
    notes.extend(branches.roles_summary(tree).map(Note::info));
    notes.extend(branches.reference_summary(tree).map(Note::info));
    notes.extend(crate::calibration::gauge_summary(&nominal, tree).map(Note::info));
    let stiffness = stiffness(config, tree, &nominal)?;
    let truth_flexibility = FlexibilityModel::new(tree, &nominal, &stiffness)?;
    let model_flexibility = truth_flexibility.scaled(1.0 / config.model_stiffness_scale)?;
    let checker = collision_checker(
        &config.robot,
        tree,
        &config.package_paths,
        config.collision_check,
        &mut notes,
    )?;
    let collisions = collision_statement(config.collision_check, &checker);
    let options = options(config, noise)?;
    let setup = crate::sim::Setup {
        tree,
        branches: &branches,
        nominal: &nominal,
        truth_flexibility: &truth_flexibility,
        model_flexibility: &model_flexibility,
        checker: Some(&checker),
    };
    let done = AtomicUsize::new(0);
    let tick = || {
        progress(Progress {
            stage: None,
            done: done.fetch_add(1, Ordering::SeqCst) + 1,
            total: config.trials,
            unit: "trials",
        })
    };
    let reports = run_trials(&setup, &options, config.trials, &tick)?;
    let summary = summarise(&reports);
    if let Some(first) = reports.first() {
        notes.extend(first.notes.iter().map(Note::info));
    }
    let markdown = simulation_markdown(
        &header(config, tree, &options, &collisions),
        &reports,
        &summary,
    );
    let labelled = crate::report::simulation_results(tree.name(), config.seed, &reports, &summary);
    let mut results = serde_json::to_value(&labelled).map_err(|e| crate::Error::InvalidData {
        origin: "results.json".into(),
        message: e.to_string(),
    })?;
    let mut files = vec![
        ("summary.md".to_owned(), markdown.clone().into_bytes()),
        // From the value the outcome holds, so that the file is `to_json_rows(&outcome.results)`
        // to the byte (keys sorted).
        (
            "results.json".to_owned(),
            crate::io::to_json_rows(&results)?.into_bytes(),
        ),
    ];
    files.extend(plots(reports.first())?);
    let inputs: Vec<PathBuf> = [
        config.robot.path(),
        config.stiffness.as_ref().and_then(StiffnessSource::path),
    ]
    .into_iter()
    .flatten()
    .map(Path::to_owned)
    .collect();
    let record = super::provenance::record(
        "simulate",
        super::provenance::settings_text(config),
        &inputs,
        &[("master", config.seed)],
        started,
    )?;
    super::provenance::attach(
        &record,
        "results.json",
        (&mut results, &Default::default()),
        &mut files,
    )?;
    let measurements_csv = match (config.measurement_format, reports.first()) {
        (Some(format), Some(first)) => Some(measurements_csv(format, tree, &nominal, first)?),
        _ => None,
    };
    Ok(Simulation {
        notes,
        reports,
        summary,
        results,
        markdown,
        files,
        measurements_csv,
        camera_reports: Vec::new(),
    })
}

impl Simulation {
    /// Writes every file into the folder `out` (created if need be), each atomically.
    pub fn write(&self, out: &Path) -> Result<()> {
        std::fs::create_dir_all(out).map_err(|source| Error::Io {
            path: out.to_path_buf(),
            source,
        })?;
        for (name, bytes) in &self.files {
            write_atomically(&out.join(name), bytes)?;
        }
        Ok(())
    }
}

/// Refuses outputs that cannot be written or would replace an input (`out` the folder,
/// `measurements` the CSV of trial 1): call before [`simulate`], which can take minutes.
pub fn check_outputs(
    config: &SimulateConfig,
    out: &Path,
    measurements: Option<&Path>,
) -> Result<()> {
    let inputs: Vec<&Path> = config
        .robot
        .path()
        .into_iter()
        .chain(config.stiffness.as_ref().and_then(StiffnessSource::path))
        .chain(config.plan.path())
        .collect();
    let mut outputs = vec![Output::Folder(out)];
    outputs.extend(measurements.map(Output::File));
    check_paths(&outputs, &inputs)
}

fn invalid(setting: &str, message: String) -> Error {
    Error::setting(setting, message)
}

/// The settings' ranges and counts ([`crate::limits`]), named by their flags.
fn validate(config: &SimulateConfig) -> Result<()> {
    for (value, flag) in [
        (config.truth_harmonics, "truth_harmonics"),
        (config.truth_backlash, "truth_backlash"),
    ] {
        limits::check_range(value, (0.0, 0.5), flag, "rad")?;
    }
    limits::check_range(
        config.angle_error,
        (0.0, std::f64::consts::PI),
        "angle_error",
        "rad",
    )?;
    limits::check_range(
        config.length_error,
        (0.0, limits::MAX_LENGTH),
        "length_error",
        "m",
    )?;
    let scale = (1.0 / limits::MAX_FACTOR, limits::MAX_FACTOR);
    limits::check_range(
        config.model_stiffness_scale,
        scale,
        "model_stiffness_scale",
        "",
    )?;
    for (flag, value) in [
        ("poses", config.poses),
        ("validation_poses", config.validation_poses),
        ("trials", config.trials),
    ] {
        count(flag, value, limits::MAX_POSES)?;
    }
    if config.torso_poses > limits::MAX_POSES {
        count("torso_poses", config.torso_poses, limits::MAX_POSES)?;
    }
    if !(config.outliers.is_finite() && (0.0..=1.0).contains(&config.outliers)) {
        let message = format!("{} is not a fraction between 0 and 1", config.outliers);
        return Err(invalid("outliers", message));
    }
    if !(config.outlier_size_mm.is_finite() && config.outlier_size_mm > 0.0) {
        let message = format!("{} mm must be positive", config.outlier_size_mm);
        return Err(invalid("outlier_size", message));
    }
    if !matches!(config.targets, 1 | 3) {
        return Err(invalid(
            "targets",
            "use 1 (a position) or 3 (a frame)".into(),
        ));
    }
    if config.measurement_format == Some(MeasurementFormat::Tracker) && config.targets != 3 {
        let message = "tracker writes three targets per tool; use it with `targets` 3".into();
        return Err(invalid("measurement_format", message));
    }
    if config.poses_from == PosesFrom::Planned {
        validate_candidates(config)?;
    }
    if config.observation != ObservationChoice::Tracker {
        limits::check_range(config.pixel_sigma, (0.0, 1e3), "pixel_sigma", "px")?;
        if config.poses + config.torso_poses == 0 {
            return Err(invalid(
                "poses",
                "a camera simulation needs at least one configuration (`poses` + `torso_poses`)"
                    .into(),
            ));
        }
        for (flag, set) in [
            ("measurement_format", config.measurement_format.is_some()),
            ("identify_stiffness", config.identify_stiffness),
            ("poses_from", config.poses_from == PosesFrom::Planned),
            ("outliers", config.outliers > 0.0),
        ] {
            if set {
                return Err(invalid(
                    flag,
                    "is not available with camera observations (rigid robot, random visible \
                     configurations); use `observation` tracker"
                        .into(),
                ));
            }
        }
    } else if config.camera_link.is_some() || !config.world_board || config.estimate_intrinsics {
        return Err(invalid(
            "observation",
            "`camera_link`, `no_world_board` and `estimate_intrinsics` need `observation` camera or mixed".into(),
        ));
    }
    Ok(())
}

/// Each planned set is chosen from `candidates` configurations: no fewer than it has poses
/// (the count used is the count said).
fn validate_candidates(config: &SimulateConfig) -> Result<()> {
    count("candidates", config.candidates, limits::MAX_CANDIDATES)?;
    let largest = config.poses.max(config.torso_poses);
    if config.candidates < largest {
        let flag = if config.poses >= config.torso_poses {
            "`poses`"
        } else {
            "`torso_poses`"
        };
        return Err(invalid(
            "candidates",
            format!(
                "{} candidates cannot give {flag} {largest}; ask for at least as many candidates as poses",
                config.candidates
            ),
        ));
    }
    Ok(())
}

/// The truth's stiffness: the file's (the built-in one for the built-in robot), with the
/// payload and joint stiffness overrides.
fn stiffness(
    config: &SimulateConfig,
    tree: &KinematicTree,
    nominal: &McpcModel,
) -> Result<Stiffness> {
    let mut stiffness = match (&config.stiffness, &config.robot) {
        (Some(source), _) => source.read(tree, nominal)?,
        (None, RobotSource::BuiltIn) => StiffnessSource::BuiltIn.read(tree, nominal)?,
        (None, _) => {
            let message = "a robot given with `robot` needs its stiffness file: the simulated \
                           robot bends under its link weights and payloads (docs/flexibility.md, \
                           section 8); for a rigid robot give a file holding `self_weight: false` \
                           (and no payloads: nothing then loads the structure)";
            return Err(invalid("stiffness", message.into()));
        }
    };
    for &mass in &config.payloads {
        limits::check_range(mass, (0.0, limits::MAX_MASS), "payloads", "kg")?;
    }
    if let Some(mass) = config.payload {
        limits::check_range(mass, (0.0, limits::MAX_MASS), "payload", "kg")?;
        for payload in &mut stiffness.payloads {
            payload.mass = mass;
        }
    }
    if let Some(k) = config.joint_stiffness {
        if !(k.is_finite() && k >= limits::MIN_STIFFNESS) {
            return Err(invalid(
                "joint_stiffness",
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
    Ok(stiffness)
}

/// The calibration plan of the simulated calibrations.
fn plan(source: &PlanSource) -> Result<Plan> {
    match source {
        PlanSource::Auto | PlanSource::Staged => Ok(Plan::staged()),
        PlanSource::Simultaneous => Ok(Plan::simultaneous()),
        PlanSource::File(path) => read_plan(path),
    }
}

/// The library's options of one trial.
fn options(config: &SimulateConfig, noise: NoiseModel) -> Result<SimulationOptions> {
    Ok(SimulationOptions {
        poses: config.poses,
        torso_poses: config.torso_poses,
        locks: 2,
        validation_poses: config.validation_poses,
        errors: ErrorRanges {
            angle: config.angle_error,
            length: config.length_error,
        },
        joint_errors: crate::sim::JointErrorRanges {
            harmonics: config.truth_harmonics,
            backlash: config.truth_backlash,
        },
        noise,
        targets: if config.targets == 1 {
            Targets::One
        } else {
            Targets::Three
        },
        plan: plan(&config.plan)?,
        seed: config.seed,
        planning: (config.poses_from == PosesFrom::Planned).then(|| PlanningOptions {
            candidates: config.candidates,
            ..PlanningOptions::default()
        }),
        identify_stiffness: config.identify_stiffness.then(StiffnessOptions::default),
        robust: config.robust,
        outliers: config.outliers,
        outlier_size: config.outlier_size_mm * 1e-3,
        payloads: config.payloads.clone(),
    })
}

/// The paragraph under summary.md's title: every setting that shaped the numbers.
fn header(
    config: &SimulateConfig,
    tree: &KinematicTree,
    options: &SimulationOptions,
    collisions: &str,
) -> String {
    let poses_from = match config.poses_from {
        PosesFrom::Random => "random".to_owned(),
        PosesFrom::Planned => format!("planned from {} candidates", config.candidates),
    };
    let plan = match &config.plan {
        PlanSource::Auto | PlanSource::Staged => "staged".to_owned(),
        PlanSource::Simultaneous => "simultaneous".to_owned(),
        PlanSource::File(path) => format!("'{}'", path.display()),
    };
    let blunders = if config.outliers > 0.0 {
        format!(
            "; {} % of the measurements made blunders of {} mm",
            config.outliers * 100.0,
            config.outlier_size_mm
        )
    } else {
        String::new()
    };
    let header = format!(
        "Robot '{}', {} trial(s), seed {}; {} arm + {} torso configurations ({poses_from}), {} validation; errors ±{} rad, ±{} m; noise {}; {} target(s) per tool; {plan} plan; model stiffness × {}; robust loss {}{blunders}; self-collision check: {collisions}.",
        tree.name(),
        config.trials,
        config.seed,
        options.poses,
        options.torso_poses,
        options.validation_poses,
        config.angle_error,
        config.length_error,
        config.noise,
        config.targets,
        config.model_stiffness_scale,
        options.robust,
    );
    let header = if options.joint_errors.any() {
        header
            + &format!(
                " The true robot's joints turn with first-harmonic errors up to ±{} rad and backlash up to {} rad (half the dead band), which the calibrations do not model.",
                config.truth_harmonics, config.truth_backlash
            )
    } else {
        header
    };
    if config.identify_stiffness {
        header + " Compliances identified jointly with the geometry (prior: the model's stiffness, ±50 %)."
    } else {
        header
    }
}

/// Trial 1's per-configuration error plots (SVG), per arm.
fn plots(first: Option<&TrialReport>) -> Result<Vec<(String, Vec<u8>)>> {
    let mut files = Vec::new();
    for arm in first.iter().flat_map(|f| &f.identification) {
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
        files.extend(
            plots
                .into_iter()
                .map(|(stem, svg)| (format!("{stem}.svg"), svg.into_bytes())),
        );
    }
    Ok(files)
}

/// Trial 1's measurements as CSV in `format`.
fn measurements_csv(
    format: MeasurementFormat,
    tree: &KinematicTree,
    nominal: &McpcModel,
    first: &TrialReport,
) -> Result<String> {
    let options = match format {
        MeasurementFormat::Si => MeasurementWriteOptions::default(),
        MeasurementFormat::Tracker => MeasurementWriteOptions {
            length_unit: LengthUnit::Millimetre,
            angle_unit: AngleUnit::Degree,
            three_targets: true,
        },
    };
    measurements_to_csv_with(tree, nominal, &first.measurements, &options)
}
