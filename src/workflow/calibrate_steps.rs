//! The named steps of [`super::calibrate::calibrate`]: checking the configuration, reading,
//! identifying and exporting (rendering is in `calibrate_outputs`).

use super::calibrate::{CalibrateConfig, GravityFrame, MeasurementFrameChoice, NoiseChoice};
use super::checks::unused_stage_rows;
use super::cross_validation::{
    candidates, cross_validate, markdown as cross_validation_markdown, CrossValidation,
    CrossValidationInput, DEFAULT_FOLDS, MAX_STEPS,
};
use super::export::export_notes;
use super::model_choice::{
    frame_joints, prepare, run_model, run_model_with_noise, shows_model_error, ModelChoice,
    ModelLevel, ModelSpec, NoiseEstimate,
};
use super::note::Note;
use super::source::{add_measured_points, measured_branches, LoadedRobot, MeasuredPoints};
use crate::calibration::{
    calibrate_with_stiffness, hold_out_indices, identified_stiffness, CalibrationInput,
    CalibrationRun, Finding, Fitted, IdentificationOptions, MeasurementFrame, Plan,
    StiffnessOptions,
};
use crate::error::{Error, Result};
use crate::io::{read_registration, MeasurementReadOptions};
use crate::kinematics::{FlexibilityModel, McpcModel, Stiffness};
use crate::measurement::Measurement;
use crate::report::StiffnessSummary;
use crate::tree::Branches;
use crate::urdf::{export_urdf_with, ExportOptions, ExportReport};

/// Fraction of the configurations held out for validation without validation data.
const HOLD_OUT: f64 = 0.2;

fn invalid(setting: &str, message: String) -> Error {
    Error::setting(setting, message)
}

/// The σ within their bounds (a tiny σ overflows the weighted cost, a huge one hides every
/// residual) and a positive stiffness prior.
pub(super) fn check_config(config: &CalibrateConfig) -> Result<()> {
    super::checks::sigmas(config.position_sigma, config.rotation_sigma)?;
    let prior = config.stiffness_prior;
    if config.identify_stiffness && !(prior.is_finite() && prior > 0.0) {
        return Err(invalid(
            "stiffness_prior",
            format!("{prior} must be a positive number"),
        ));
    }
    let scale = config.prior_scale;
    if !(scale.is_finite() && scale > 0.0) {
        return Err(invalid(
            "prior_scale",
            format!("{scale} must be a positive number (1: the default σ)"),
        ));
    }
    Ok(())
}

/// The robot with its measured branches and nominal model, and the measurement frame.
pub(super) struct Loaded {
    pub robot: LoadedRobot,
    pub branches: Branches,
    pub nominal: McpcModel,
    pub frame: MeasurementFrame,
    /// The measured points added to the robot as marker links.
    pub points: MeasuredPoints,
}

impl Loaded {
    pub fn new(config: &CalibrateConfig) -> Result<Self> {
        let frame = match &config.measurement_frame {
            MeasurementFrameChoice::Auto => MeasurementFrame::Auto,
            MeasurementFrameChoice::Fit => MeasurementFrame::Fit,
            MeasurementFrameChoice::Base => MeasurementFrame::Base,
            MeasurementFrameChoice::File(path) => MeasurementFrame::Known(read_registration(path)?),
        };
        let mut robot = config.robot.load()?;
        let points = add_measured_points(
            &mut robot.import,
            config.tools.as_deref(),
            &config.measurements,
        )?;
        let tools = points.tools.as_deref().or(config.tools.as_deref());
        let branches = measured_branches(
            &robot.import,
            tools,
            config.reference_link.as_deref(),
            &config.measurements,
        )?;
        let tree = robot.tree();
        if config.identify_stiffness && branches.reference != tree.root() {
            return Err(invalid(
                "identify_stiffness",
                format!(
                    "stiffness identification needs the URDF root '{}' as the reference link: the flexibility model's loads flow to the root, not into the sole '{}' the robot stands on, so compliances fitted from it would be wrong; calibrate from '{}' with a given `stiffness` file (its deflections are then approximate, docs/mcpc.md \"Reference link\"), or identify the stiffness from data measured relative to the root",
                    tree.link(tree.root()).name,
                    tree.link(branches.reference).name,
                    tree.link(branches.reference).name,
                ),
            ));
        }
        let nominal = McpcModel::from_tree(tree, &branches)?;
        Ok(Self {
            robot,
            branches,
            nominal,
            frame,
            points,
        })
    }
}

/// The identification and validation measurements, with their row ids.
pub(super) struct Data {
    pub measurements: Vec<Measurement>,
    pub validation: Vec<Measurement>,
    /// Where the validation data come from, for the report.
    pub validation_source: String,
    /// The row ids of the identification and validation data, for the outlier report.
    pub ids: [Vec<String>; 2],
}

/// Reads the measurements, and the validation data or a seeded held-out fifth.
pub(super) fn read_data(
    config: &CalibrateConfig,
    loaded: &Loaded,
    notes: &mut Vec<Note>,
) -> Result<Data> {
    let options = MeasurementReadOptions {
        length_unit: config.length_unit,
        angle_unit: config.angle_unit,
        joint_length_unit: config.joint_length_unit,
        ignore_columns: config.ignore_columns.clone(),
        strict_limits: config.strict,
        tool: config
            .tools
            .as_ref()
            .filter(|t| t.len() == 1)
            .map(|t| t[0].trim().to_owned()),
    };
    notes.extend(loaded.points.note());
    let tree = loaded.robot.tree();
    notes.extend(loaded.branches.roles_summary(tree).map(Note::info));
    notes.extend(loaded.branches.reference_summary(tree).map(Note::info));
    let mut read = |source: &super::source::MeasurementSource| {
        let set = source.read(tree, &loaded.nominal, &options)?;
        notes.extend(set.warnings.iter().map(Note::warning));
        notes.extend(set.notes.iter().map(Note::info));
        Ok::<_, Error>((set.measurements, set.ids))
    };
    let (all, all_ids) = read(&config.measurements)?;
    if let Some(source) = &config.validation {
        let (validation, validation_ids) = read(source)?;
        return Ok(Data {
            measurements: all,
            validation,
            validation_source: source.origin(),
            ids: [all_ids, validation_ids],
        });
    }
    let (kept, held) = hold_out_indices(&all, HOLD_OUT, config.seed)?;
    let validation_source = format!(
        "{} of {} observations held out from the measurements (a fifth of the configurations, seed {}; give `validation` to use your own)",
        held.len(),
        all.len(),
        config.seed
    );
    notes.push(Note::info(validation_source.clone()));
    let pick = |rows: &[usize]| rows.iter().map(|&i| all[i].clone()).collect();
    let ids = [&kept, &held].map(|rows| rows.iter().map(|&i| all_ids[i].clone()).collect());
    Ok(Data {
        measurements: pick(&kept),
        validation: pick(&held),
        validation_source,
        ids,
    })
}

/// A finished identification and how it was set up.
pub(super) struct Identified {
    pub run: CalibrationRun,
    pub plan_name: String,
    pub options: IdentificationOptions,
    /// The plan the run used.
    pub plan: Plan,
    /// The flexibility model of the final run (with the identified stiffness, if any).
    pub flexibility: Option<FlexibilityModel>,
    /// The model calibrated.
    pub spec: ModelSpec,
    /// The cross-validation table (`--cv`, `--model auto`).
    pub cross_validation: Option<CrossValidation>,
    /// The noise estimated from the residuals (`estimate_noise`), if any.
    pub noise: Option<NoiseEstimate>,
}

/// A fit of one model: the run, its options (the rotation σ estimated when asked), the
/// nominal model with the level's parameters, and the noise estimate.
type Fit = (
    CalibrationRun,
    IdentificationOptions,
    McpcModel,
    Option<NoiseEstimate>,
);

/// With `--identify-stiffness`: the report's summary and the identified stiffness.
pub(super) type IdentifiedStiffness = Option<(StiffnessSummary, Stiffness)>;

/// Chooses the plan, builds the flexibility model and runs the calibration; with stiffness
/// identification, the joint fit from the calibrated geometry and then the plan again with
/// the identified stiffness, so that every table describes it.
pub(super) fn identify(
    config: &CalibrateConfig,
    loaded: &Loaded,
    data: &Data,
    notes: &mut Vec<Note>,
) -> Result<(Identified, IdentifiedStiffness)> {
    let tree = loaded.robot.tree();
    let labelled = data
        .measurements
        .iter()
        .any(|m| m.stage.as_deref() == Some("torso"));
    let (plan, plan_name, plan_note) = config.plan.resolve(labelled)?;
    notes.extend(plan_note);
    // A warning, not an error, by default: a plan may use some stages of a file on purpose
    // (the arms only, from a file that also holds torso rows).
    let labels: Vec<Option<&str>> = data
        .measurements
        .iter()
        .map(|m| m.stage.as_deref())
        .collect();
    if let Some(message) = unused_stage_rows(&plan, &labels, &data.ids[0]) {
        if config.strict {
            return Err(invalid(&config.measurements.origin(), message));
        }
        notes.push(Note::warning(message + " (with `strict` this is an error)"));
    }
    let stiffness = Stiffnesses::new(config, loaded)?;
    let flexibility = stiffness.in_play.clone();
    let declared = IdentificationOptions {
        position_sigma: config.position_sigma,
        rotation_sigma: config.rotation_sigma,
        robust: config.robust,
        ..IdentificationOptions::default()
    };
    let candidate_prior = stiffness.candidate_prior(config, loaded);
    let choose = |model, options: &IdentificationOptions| {
        choose_model(
            config,
            model,
            loaded,
            [flexibility.as_ref(), candidate_prior],
            &plan,
            options,
            data,
        )
    };
    let fit = |spec: &ModelSpec, options: &IdentificationOptions| -> Result<Fit> {
        let prepared = prepare(spec, tree, &loaded.nominal, options, &config.patterns)?;
        let input = CalibrationInput {
            tree,
            branches: &loaded.branches,
            nominal: &prepared.nominal,
            flexibility: flexibility.as_ref().filter(|_| spec.compensate),
            plan: &plan,
            options: &prepared.options,
            measurement_frame: loaded.frame,
        };
        let (run, noise) =
            run_model_with_noise(&input, spec, &data.measurements, &data.validation)?;
        let mut options = prepared.options;
        if let Some(noise) = &noise {
            options.rotation_sigma = noise.rotation_sigma;
        }
        Ok((run, options, prepared.nominal, noise))
    };
    // The default: the full geometry, unless its fit shows model error; then as `auto`. A
    // model asked for by flags (prior, joint errors, significance) is kept.
    let asked_extras =
        config.prior || config.harmonics || config.backlash || config.significant.is_some();
    let data_decide = match config.model {
        ModelChoice::Auto => true,
        ModelChoice::Adaptive => !asked_extras,
        ModelChoice::Level(_) => false,
    };
    let (mut spec, mut cross_validation) = if data_decide {
        (
            asked_spec(config, ModelLevel::Geometry, flexibility.is_some()),
            None,
        )
    } else {
        choose(config.model, &declared)?
    };
    let (mut run, mut options, mut nominal, mut noise) = fit(&spec, &declared)?;
    let mut adaptive = false;
    if data_decide {
        // With `--noise estimated` the geometry fit estimated the σ ratio (variance
        // components) and every candidate keeps it; by default (`adaptive`) the estimate is a
        // candidate of its own, each fold estimating its own ratio.
        let model_error = shows_model_error(&run);
        adaptive = config.model == ModelChoice::Adaptive && model_error;
        if config.model == ModelChoice::Auto || model_error || config.cv.is_some() {
            let (chosen, cv) = choose(ModelChoice::Auto, &options)?;
            if (config.model == ModelChoice::Auto || model_error) && chosen != spec {
                let estimated = noise.take();
                (run, options, nominal, noise) = fit(&chosen, &options)?;
                noise = noise.or(estimated);
                spec = chosen;
            }
            cross_validation = cv;
        }
        spec.estimate_noise |= noise.is_some();
    }
    notes.extend(cross_validation.as_ref().map(|cv| {
        Note::info(format!(
            "model: '{}' ({})",
            spec.named(&frame_joints(loaded.robot.tree(), &loaded.nominal)),
            match config.model {
                ModelChoice::Auto => cv.reason.clone(),
                ModelChoice::Adaptive if adaptive => format!(
                    "the geometry fit leaves residuals over {}× the declared noise (model error), so the model is chosen by cross-validation: {}; `model` geometry keeps the full geometry",
                    crate::calibration::SIGMA_WARNING,
                    cv.reason
                ),
                _ => "as asked; `model` auto would choose by the cross-validation in report.md".into(),
            }
        ))
    }));
    let input = CalibrationInput {
        tree,
        branches: &loaded.branches,
        nominal: &nominal,
        flexibility: flexibility.as_ref().filter(|_| spec.compensate),
        plan: &plan,
        options: &options,
        measurement_frame: loaded.frame,
    };
    let run_with = |flexibility: Option<&FlexibilityModel>| {
        let input = CalibrationInput {
            flexibility,
            ..input
        };
        // The rotation σ is the estimated one already (`options`): no second estimate.
        let spec = ModelSpec {
            estimate_noise: false,
            ..spec
        };
        run_model(&input, &spec, &data.measurements, &data.validation)
    };
    let mut identified = None;
    let mut final_flexibility = flexibility.clone().filter(|_| spec.compensate);
    let identify_now = config.identify_stiffness || spec.identify_stiffness;
    let run = match (&stiffness.prior, identify_now) {
        (Some((stiffness, prior)), true) => {
            let stiffness_options = StiffnessOptions {
                prior_sigma: config.stiffness_prior,
                ..StiffnessOptions::default()
            };
            let sequence = calibrate_with_stiffness(
                tree,
                prior,
                input.flexibility,
                &options,
                &stiffness_options,
                run_with,
                |run: &CalibrationRun| Fitted {
                    model: run.report.model.clone(),
                    // Every session's rows in the first session's frame, by the frames the
                    // run fitted.
                    measurements: crate::calibration::validation_in_training_frames(
                        &data.measurements,
                        run.sessions.as_ref(),
                    ),
                    outliers: run.robust.outliers(),
                },
            )?;
            let report = sequence.stiffness;
            let mut run = sequence.again;
            run.findings
                .extend(crate::calibration::stiffness_below_zero(&report));
            let file = identified_stiffness(stiffness, tree, &loaded.nominal, &report.estimates);
            identified = Some((StiffnessSummary::new(&report, config.stiffness_prior), file));
            final_flexibility = Some(report.flexibility);
            run
        }
        // The fit above is the run without a stiffness fit.
        _ => run,
    };
    let identified_run = Identified {
        run,
        noise,
        plan_name,
        options,
        plan,
        flexibility: final_flexibility,
        spec,
        cross_validation,
    };
    Ok((identified_run, identified))
}

/// The stiffness in play and the prior a stiffness fit starts from.
struct Stiffnesses {
    /// The flexibility the compensated models use: the stiffness file's, or with
    /// `--identify-stiffness` and no file the library defaults'.
    in_play: Option<FlexibilityModel>,
    /// The stiffness a stiffness fit starts from (the file's, else the library defaults) and
    /// its flexibility; `None` when the robot cannot carry it (no inertials, and none asked).
    prior: Option<(Stiffness, FlexibilityModel)>,
}

impl Stiffnesses {
    fn new(config: &CalibrateConfig, loaded: &Loaded) -> Result<Self> {
        let tree = loaded.robot.tree();
        let file = match &config.stiffness {
            Some(source) => Some(source.read(tree, &loaded.nominal)?),
            None => None,
        };
        let build = |stiffness: &Stiffness| -> Result<FlexibilityModel> {
            let model = FlexibilityModel::new(tree, &loaded.nominal, stiffness)?;
            Ok(match config.gravity_frame {
                GravityFrame::Measurement => model.with_gravity_in_measurement_frame(),
                GravityFrame::Base => model,
            })
        };
        // With stiffness identification and no file, the library defaults are the prior.
        let in_play = match (&file, config.identify_stiffness) {
            (Some(stiffness), _) => Some(build(stiffness)?),
            (None, true) => Some(build(&Stiffness::default())?),
            (None, false) => None,
        };
        let stiffness = file.unwrap_or_default();
        let prior = match &in_play {
            Some(flexibility) => Some((stiffness, flexibility.clone())),
            None => build(&stiffness).ok().map(|f| (stiffness, f)),
        };
        Ok(Self { in_play, prior })
    }

    /// The prior of the cross-validation's identified-stiffness candidate: offered unless
    /// `--identify-stiffness` is given anyway, when the robot carries masses and the data are
    /// measured from the URDF root (the loads flow to it).
    fn candidate_prior(
        &self,
        config: &CalibrateConfig,
        loaded: &Loaded,
    ) -> Option<&FlexibilityModel> {
        let tree = loaded.robot.tree();
        if config.identify_stiffness || loaded.branches.reference != tree.root() {
            return None;
        }
        self.prior.as_ref().map(|(_, flexibility)| flexibility)
    }
}

/// The model the flags ask for at `level` (`compensate`: a stiffness is in play).
fn asked_spec(config: &CalibrateConfig, level: ModelLevel, compensate: bool) -> ModelSpec {
    ModelSpec {
        level,
        harmonics: config.harmonics,
        backlash: config.backlash,
        prior: config.prior,
        prior_scale: config.prior_scale,
        significant: config.significant,
        compensate,
        identify_stiffness: false,
        estimate_noise: config.noise == NoiseChoice::Estimated,
        ..ModelSpec::default()
    }
}

/// The model to calibrate: the asked level, or the cross-validation's choice; and the
/// cross-validation table when asked (`--cv`) or needed (`--model auto`). `flexibility`: the
/// stiffness in play, and the prior of the identified-stiffness candidate.
fn choose_model(
    config: &CalibrateConfig,
    model: ModelChoice,
    loaded: &Loaded,
    flexibility: [Option<&FlexibilityModel>; 2],
    plan: &crate::calibration::Plan,
    options: &IdentificationOptions,
    data: &Data,
) -> Result<(ModelSpec, Option<CrossValidation>)> {
    let [flexibility, candidate_prior] = flexibility;
    let asked = |level| asked_spec(config, level, flexibility.is_some());
    let level = match model {
        ModelChoice::Level(level) => Some(level),
        ModelChoice::Adaptive => Some(ModelLevel::Geometry),
        ModelChoice::Auto => None,
    };
    let folds = match (level, config.cv) {
        (_, Some(k)) => k,
        (None, None) => DEFAULT_FOLDS,
        (Some(level), None) => return Ok((asked(level), None)),
    };
    if folds < 2 {
        return Err(invalid("cv", format!("{folds} folds: give at least 2")));
    }
    let tree = loaded.robot.tree();
    let input = CrossValidationInput {
        calibration: CalibrationInput {
            tree,
            branches: &loaded.branches,
            nominal: &loaded.nominal,
            flexibility,
            plan,
            options,
            measurement_frame: loaded.frame,
        },
        patterns: &config.patterns,
        joint_steps: if config.cv_joint_steps { MAX_STEPS } else { 0 },
        stiffness: candidate_prior.map(|prior| {
            let options = StiffnessOptions {
                prior_sigma: config.stiffness_prior,
                ..StiffnessOptions::default()
            };
            (prior, options)
        }),
    };
    let mut list = candidates(
        tree,
        &loaded.nominal,
        flexibility.is_some(),
        candidate_prior.is_some(),
    );
    // The σ ratio from the data as a candidate, where there is a ratio (poses: two row kinds).
    let poses = data
        .measurements
        .iter()
        .any(|m| matches!(m.observation, crate::measurement::Observation::Pose(_)));
    if config.noise == NoiseChoice::Adaptive && poses {
        list.push(ModelSpec {
            estimate_noise: true,
            significant: Some(2.0),
            compensate: flexibility.is_some(),
            ..ModelSpec::default()
        });
    }
    if let Some(level) = level {
        let mine = asked(level);
        if !list.contains(&mine) {
            list.insert(0, mine);
        }
    }
    let mut cv = cross_validate(
        &input,
        &list,
        &data.measurements,
        folds,
        config.cv_repeats,
        config.seed,
    )?;
    cv.name_rows(&data.ids[0]);
    let spec = match (level, cv.chosen) {
        (Some(level), _) => asked(level),
        (None, Some(i)) => cv.rows[i].spec,
        (None, None) => asked(ModelLevel::Geometry),
    };
    Ok((spec, Some(cv)))
}

/// Adds the cross-validation table to report.md and report.json (`"model_choice"`), and the
/// model calibrated (`"model"`).
pub(super) fn add_model_choice(
    tree: &crate::tree::KinematicTree,
    result: &Identified,
    outputs: &mut super::calibrate_outputs::Outputs,
    notes: &mut Vec<Note>,
) -> Result<()> {
    if let Some(text) = joint_errors_yaml(tree, &result.run.report.model) {
        let message = "calibrated.urdf cannot carry the identified joint-angle errors (harmonics, backlash): they are in joint_errors.yaml (docs/file-formats.md), to be added to the commanded joint angles; the validation figures include them";
        notes.push(Note::warning(message));
        outputs
            .markdown
            .push_str(&format!("\n## Joint-angle errors\n\n{message}.\n"));
        outputs
            .files
            .push(("joint_errors.yaml".into(), text.into_bytes()));
    }
    let mut extra = vec![(
        "model".to_string(),
        serde_json::json!({
            "name": result.spec.named(&frame_joints(tree, &result.run.report.model)),
            "spec": result.spec
        }),
    )];
    if let Some(noise) = &result.noise {
        notes.push(Note::info(format!("model: {}", noise.describe())));
        outputs.markdown.push_str(&format!(
            "\n## Noise model\n\nThe {} (docs/identification.md, \"Noise model from the data\").\n",
            noise.describe()
        ));
        extra.push((
            "noise".into(),
            serde_json::to_value(noise).map_err(|e| invalid("report.json", e.to_string()))?,
        ));
    }
    if let Some(cv) = &result.cross_validation {
        extra.push((
            "model_choice".into(),
            serde_json::to_value(cv).map_err(|e| invalid("report.json", e.to_string()))?,
        ));
    }
    add_before_stiffness(&mut outputs.report, &extra);
    if let Some(cv) = &result.cross_validation {
        outputs.markdown.push_str(&cross_validation_markdown(cv));
        notes.extend(
            super::cross_validation::lines(cv)
                .into_iter()
                .map(Note::info),
        );
    }
    if let Some((_, bytes)) = outputs.files.iter_mut().find(|(n, _)| n == "report.md") {
        *bytes = outputs.markdown.clone().into_bytes();
    }
    Ok(())
}

/// Adds `extra` to a report.json object, before the `stiffness` block (which stays last).
fn add_before_stiffness(report: &mut serde_json::Value, extra: &[(String, serde_json::Value)]) {
    if let serde_json::Value::Object(map) = report {
        let stiffness = map.shift_remove("stiffness");
        for (key, value) in extra {
            map.insert(key.clone(), value.clone());
        }
        if let Some(stiffness) = stiffness {
            map.insert("stiffness".into(), stiffness);
        }
    }
}

/// joint_errors.yaml: the harmonic and backlash terms of `model` (none: `None`).
pub(super) fn joint_errors_yaml(
    tree: &crate::tree::KinematicTree,
    model: &McpcModel,
) -> Option<String> {
    let terms = model.joint_error_terms();
    if !(terms.harmonics || terms.backlash) {
        return None;
    }
    let mut text = String::from(
        "# Joint-angle errors identified by treecal calibrate (docs/file-formats.md); a URDF cannot carry them.\n# The joint turns by theta = q + sine*sin(q) + cosine*cos(q) + backlash*sign(tau), q the commanded angle,\n# tau the gravity torque about the joint axis (URDF inertials, gravity along -z of the root link).\n# Joint zero offsets are in calibrated.urdf already.\nunits: {angle: rad}\njoints:\n",
    );
    for (frame, f) in model.frames().iter().enumerate() {
        let [_, sine, cosine, backlash] = model.joint_error_values(frame);
        let mut parts = Vec::new();
        for (name, value) in [("sine", sine), ("cosine", cosine), ("backlash", backlash)] {
            if let Some(value) = value {
                parts.push(format!("{name}: {value:.9}"));
            }
        }
        if !parts.is_empty() {
            text.push_str(&format!(
                "  {}: {{{}}}\n",
                tree.joint(f.joint).name,
                parts.join(", ")
            ));
        }
    }
    Some(text)
}

/// The calibrated URDF; what the export dropped or added, or why it failed, goes among the
/// verdict's reasons (so report.md and report.json name them too).
pub(super) fn export_calibrated(
    config: &CalibrateConfig,
    loaded: &Loaded,
    run: &mut CalibrationRun,
) -> Option<ExportReport> {
    let tree = loaded.robot.tree();
    let std_devs: Vec<Option<f64>> = run.parameters.iter().map(|p| p.std_dev).collect();
    let options =
        ExportOptions::with_uncertainty(tree, &run.report.model, &std_devs, config.add_tool_links);
    let robot = &loaded.robot;
    match export_urdf_with(
        &robot.text,
        &robot.origin,
        tree,
        // Joint offsets are carried by the URDF's joint origins.
        &run.report.model.with_offsets_absorbed(),
        &options,
    ) {
        Ok(export) => {
            run.findings.extend(export_notes(&export));
            Some(export)
        }
        Err(error) => {
            run.findings.push(Finding::failed(
                "urdf-export",
                format!("the calibrated model cannot be written as a URDF: {error}"),
            ));
            None
        }
    }
}
