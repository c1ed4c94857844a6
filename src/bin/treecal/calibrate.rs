//! `treecal calibrate`: flags → [`CalibrateConfig`] → [`treecal::workflow::calibrate_for_writing`] →
//! notes on stderr, report.md on stdout, the files in `--out`.

use crate::cli::{
    CalibrateArgs, GravityFrame, JointErrorArg, MeasurementFrame, ModelArg, NoiseArg, PlanArg,
    PlanChoice,
};
use std::path::Path;
use treecal::workflow::{
    calibrate_camera_files, CameraCalibrateConfig, CameraContactsInput, CameraTrackerInput,
    DetectionsSource,
};
use treecal::workflow::{
    calibrate_for_writing, CalibrateConfig, MeasurementFrameChoice, MeasurementSource, NoiseChoice,
    PlanSource, RobotSource, StiffnessSource,
};
use treecal::workflow::{ModelChoice, ModelLevel, ParameterPatterns};
use treecal::{Error, Result};

pub fn run(args: CalibrateArgs) -> Result<()> {
    // With --camera, contacts are fitted with the pixels (`run_camera`).
    if let (Some(camera), Some(detections)) = (&args.camera, &args.detections) {
        one_file_each(&args, "--camera")?;
        return run_camera(&args, camera, detections);
    }
    if let (Some(contacts), Some(setup)) = (&args.contacts, &args.contact_setup) {
        one_file_each(&args, "--contacts")?;
        return run_contacts(&args, contacts, setup);
    }
    let config = config(&args);
    // The output folder is replaced as a whole at the end: refuse one that holds an input or
    // is not a previous output before computing anything.
    config.check_output(&args.out)?;
    // report.json is rendered straight into the folder (at 10⁶ configurations ~900 MB).
    // report.md and report.html say the flags (`--model offsets`), as stdout and stderr do.
    let flag = |setting: &str| crate::settings::flag(setting).map(str::to_owned);
    let calibration = calibrate_for_writing(&config, Some(&flag))?;
    let finished = finish(
        &args,
        &calibration.notes,
        &calibration.report_markdown,
        calibration.write(&args.out),
        calibration.usable(),
        "verdict failed",
    );
    // The process ends next and returns its memory whole: freeing the result piece by piece
    // first took a few tenths of a second at 10⁶ configurations.
    std::mem::forget(calibration);
    finished
}

fn config(args: &CalibrateArgs) -> CalibrateConfig {
    let plan = match (&args.plan, &args.plan_file) {
        (_, Some(path)) | (Some(PlanArg::File(path)), None) => PlanSource::File(path.clone()),
        (Some(PlanArg::Choice(PlanChoice::Staged)), None) => PlanSource::Staged,
        (Some(PlanArg::Choice(PlanChoice::Simultaneous)), None) => PlanSource::Simultaneous,
        (None, None) => PlanSource::Auto,
    };
    CalibrateConfig {
        robot: RobotSource::from_path(args.robot.clone()),
        measurements: MeasurementSource::from_paths(args.measurements.clone()),
        validation: (!args.validation.is_empty())
            .then(|| MeasurementSource::from_paths(args.validation.clone())),
        stiffness: args.stiffness.clone().map(StiffnessSource::File),
        tools: args.tools.clone(),
        reference_link: args.reference_link.clone(),
        plan,
        length_unit: args.length_unit,
        angle_unit: args.angle_unit,
        joint_length_unit: args.joint_length_unit,
        ignore_columns: args.ignore_columns.clone(),
        strict: args.strict,
        measurement_frame: measurement_frame(&args.measurement_frame),
        position_sigma: args.position_sigma,
        rotation_sigma: args.rotation_sigma,
        seed: args.seed,
        robust: args.robust.into(),
        identify_stiffness: args.identify_stiffness,
        stiffness_prior: args.stiffness_prior,
        gravity_frame: match args.gravity_frame {
            GravityFrame::Measurement => treecal::workflow::GravityFrame::Measurement,
            GravityFrame::Base => treecal::workflow::GravityFrame::Base,
        },
        // On by default for calibrate (docs/export.md); the flag is kept for scripts.
        add_tool_links: true,
        model: model_choice(args.model),
        harmonics: args.joint_errors.contains(&JointErrorArg::Harmonics),
        backlash: args.joint_errors.contains(&JointErrorArg::Backlash),
        prior: args.prior,
        prior_scale: args.prior_scale,
        significant: args.significant,
        noise: match args.noise {
            NoiseArg::Adaptive => NoiseChoice::Adaptive,
            NoiseArg::Estimated => NoiseChoice::Estimated,
            NoiseArg::Declared => NoiseChoice::Declared,
        },
        patterns: ParameterPatterns {
            freeze: args.freeze.clone(),
            free: args.free.clone(),
        },
        cv: args.cv,
        cv_repeats: args.cv_repeats,
        cv_joint_steps: args.cv_joint_steps,
    }
}

/// `calibrate --contacts C.csv --contact-setup S.yaml` (issue 29).
fn run_contacts(args: &CalibrateArgs, contacts: &Path, setup: &Path) -> Result<()> {
    use treecal::workflow::{calibrate_contacts, ContactCalibrateConfig, CONTACT_OUTPUTS};
    treecal::io::check_output_folder(&args.out, &|name| CONTACT_OUTPUTS.contains(&name))?;
    let mut calibration = calibrate_contacts(&ContactCalibrateConfig {
        robot: RobotSource::from_path(args.robot.clone()),
        contacts: contacts.to_owned(),
        setup: setup.to_owned(),
        validation: args.validation.first().cloned(),
        reference_link: args.reference_link.clone(),
        tools: args.tools.clone(),
        tracker: tracker_input(args),
        model: model_choice(args.model),
        prior: args.prior.then_some(args.prior_scale),
        cv: args.cv,
        cv_repeats: args.cv_repeats,
        seed: args.seed,
        patterns: ParameterPatterns {
            freeze: args.freeze.clone(),
            free: args.free.clone(),
        },
    })?;
    // report.md says the flags (`--prior`), as stdout and stderr do; report.json keeps the
    // library's names.
    calibration.report_markdown = crate::settings::with_flags(&calibration.report_markdown);
    finish(
        args,
        &calibration.notes,
        &calibration.report_markdown,
        calibration.write(&args.out),
        calibration.usable(),
        calibration.refused.as_deref().unwrap_or(
            "the calibrated robot does not predict the held-out contacts better than the \
             registered nominal robot",
        ),
    )
}

/// Camera and contact calibrations read one tracker file and one validation file: more is
/// an error naming the flag (join the files, with a `session` column, instead).
fn one_file_each(args: &CalibrateArgs, mode: &str) -> Result<()> {
    for (setting, files) in [
        ("measurements", &args.measurements),
        ("validation", &args.validation),
    ] {
        if files.len() > 1 {
            return Err(Error::setting(
                setting,
                format!(
                    "given {} times; with {mode} it takes one file: join the rows into one file \
                     (a `session` column keeps one measurement frame per day)",
                    files.len()
                ),
            ));
        }
    }
    Ok(())
}

/// The tracker rows of `--measurements` fitted with pixels or contacts, with their σ's.
fn tracker_input(args: &CalibrateArgs) -> Option<CameraTrackerInput> {
    args.measurements.first().map(|path| CameraTrackerInput {
        measurements: path.clone(),
        position_sigma: args.position_sigma,
        rotation_sigma: args.rotation_sigma,
        frame: measurement_frame(&args.measurement_frame),
        length_unit: args.length_unit,
        ignore_columns: args.ignore_columns.clone(),
    })
}

/// The library's choice of the measurement frame for the flag's.
fn measurement_frame(flag: &MeasurementFrame) -> MeasurementFrameChoice {
    match flag {
        MeasurementFrame::Auto => MeasurementFrameChoice::Auto,
        MeasurementFrame::Fit => MeasurementFrameChoice::Fit,
        MeasurementFrame::Base => MeasurementFrameChoice::Base,
        MeasurementFrame::File(path) => MeasurementFrameChoice::File(path.clone()),
    }
}

/// `calibrate --camera FILE --detections FILE [--measurements FILE]`: the camera calibration
/// from files, with tracker rows when given.
fn run_camera(args: &CalibrateArgs, camera: &Path, detections: &Path) -> Result<()> {
    let config = CameraCalibrateConfig {
        robot: RobotSource::from_path(args.robot.clone()),
        tools: args.tools.clone(),
        camera_file: camera.to_owned(),
        detections: DetectionsSource::File(detections.to_owned()),
        validation: args.validation.first().cloned(),
        pixel_sigma: args.pixel_sigma,
        tracker: tracker_input(args),
        contacts: match (&args.contacts, &args.contact_setup) {
            (Some(contacts), Some(setup)) => Some(CameraContactsInput {
                contacts: contacts.clone(),
                setup: setup.clone(),
            }),
            _ => None,
        },
        angle_unit: args.angle_unit,
        length_unit: args.joint_length_unit.or(args.length_unit),
        add_tool_links: true,
    };
    config.check_output(&args.out)?;
    let mut calibration = calibrate_camera_files(&config)?;
    // report.md says the flags (`--pixel-sigma`), as stdout and stderr do.
    calibration.report_markdown = crate::settings::with_flags(&calibration.report_markdown);
    let flag = |setting: &str| crate::settings::flag(setting).map(str::to_owned);
    treecal::workflow::spell_reports(&mut calibration.files, &flag);
    finish(
        args,
        &calibration.notes,
        &calibration.report_markdown,
        calibration.write(&args.out),
        calibration.usable(),
        "verdict failed",
    )
}

/// The end of a calibration (tracker, contacts or camera): its notes on stderr, the written folder's
/// report on stdout, and an error when the verdict says the result is not usable.
fn finish(
    args: &CalibrateArgs,
    notes: &[treecal::workflow::Note],
    report_markdown: &str,
    written: Result<()>,
    usable: bool,
    failure: &str,
) -> Result<()> {
    for note in notes {
        crate::output::note(note);
    }
    written?;
    crate::output::print(report_markdown)?;
    crate::output::note(format_args!("wrote {}", args.out.display()));
    if !usable {
        return Err(Error::InvalidData {
            origin: "calibration".into(),
            message: format!(
                "{failure} (see the errors above and {}); calibrated.urdf was not written",
                args.out.join("report.md").display()
            ),
        });
    }
    Ok(())
}

/// `--model` as the library's choice.
fn model_choice(model: ModelArg) -> ModelChoice {
    match model {
        ModelArg::Offsets => ModelChoice::Level(ModelLevel::Offsets),
        ModelArg::Geometry => ModelChoice::Level(ModelLevel::Geometry),
        ModelArg::Auto => ModelChoice::Auto,
        ModelArg::Adaptive => ModelChoice::Adaptive,
    }
}
