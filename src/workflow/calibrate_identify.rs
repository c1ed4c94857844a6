//! The identify step of [`super::calibrate::calibrate`]: the plan, the model (asked for, or
//! chosen by cross-validation when the data show model error), the fit, and with stiffness
//! identification the "calibrate, identify stiffness, calibrate again" sequence.

use super::calibrate::{CalibrateConfig, GravityFrame, NoiseChoice};
use super::calibrate_steps::{invalid, Data, Identified, IdentifiedStiffness, Loaded};
use super::checks::unused_stage_rows;
use super::cross_validation::{
    candidates, cross_validate, CrossValidation, CrossValidationInput, DEFAULT_FOLDS, MAX_STEPS,
};
use super::model_choice::{
    frame_joints, prepare, run_model, run_model_with_noise, shows_model_error, ModelChoice,
    ModelLevel, ModelSpec, NoiseEstimate,
};
use super::note::Note;
use crate::calibration::{
    calibrate_with_stiffness, identified_stiffness, CalibrationInput, CalibrationRun, Fitted,
    IdentificationOptions, Plan, StiffnessOptions,
};
use crate::error::Result;
use crate::kinematics::{FlexibilityModel, McpcModel, Stiffness};
use crate::report::StiffnessSummary;

/// A fit of one model: the run, its options (the rotation σ estimated when asked), the
/// nominal model with the level's parameters, and the noise estimate.
type Fit = (
    CalibrationRun,
    IdentificationOptions,
    McpcModel,
    Option<NoiseEstimate>,
);

/// Chooses the plan, builds the flexibility model and runs the calibration; with stiffness
/// identification, the joint fit from the calibrated geometry and then the plan again with
/// the identified stiffness, so that every table describes it.
pub(super) fn identify(
    config: &CalibrateConfig,
    loaded: &Loaded,
    data: &Data,
    notes: &mut Vec<Note>,
) -> Result<(Identified, IdentifiedStiffness)> {
    let labelled = data
        .measurements
        .iter()
        .any(|m| m.stage.as_deref() == Some("torso"));
    let (plan, plan_name, plan_note) = config.plan.resolve(labelled)?;
    notes.extend(plan_note);
    check_stage_rows(config, data, &plan, notes)?;
    let stiffness = Stiffnesses::new(config, loaded)?;
    let models = Models {
        config,
        loaded,
        data,
        plan: &plan,
        flexibility: stiffness.in_play.as_ref(),
        candidate_prior: stiffness.candidate_prior(config, loaded),
    };
    let picked = models.pick()?;
    let spec = picked.spec;
    notes.extend(model_note(config, loaded, &picked));
    let (run, options, nominal, noise) = picked.fit;
    let (run, identified, flexibility) =
        models.with_stiffness(&stiffness, &spec, &nominal, &options, run)?;
    let identified_run = Identified {
        run,
        noise,
        plan_name,
        options,
        plan,
        flexibility,
        spec,
        cross_validation: picked.cross_validation,
    };
    Ok((identified_run, identified))
}

/// Rows of stages the plan does not use: a warning, not an error, by default (a plan may use
/// some stages of a file on purpose: the arms only, from a file that also holds torso rows);
/// an error with `strict`.
fn check_stage_rows(
    config: &CalibrateConfig,
    data: &Data,
    plan: &Plan,
    notes: &mut Vec<Note>,
) -> Result<()> {
    let labels: Vec<Option<&str>> = data
        .measurements
        .iter()
        .map(|m| m.stage.as_deref())
        .collect();
    if let Some(message) = unused_stage_rows(plan, &labels, &data.ids[0]) {
        if config.strict {
            return Err(invalid(&config.measurements.origin(), message));
        }
        notes.push(Note::warning(message + " (with `strict` this is an error)"));
    }
    Ok(())
}

/// The model calibrated and its fit.
struct Picked {
    spec: ModelSpec,
    cross_validation: Option<CrossValidation>,
    fit: Fit,
    /// The default (`adaptive`) found model error in the geometry fit and chose by
    /// cross-validation.
    adaptive: bool,
}

/// What the models are fitted to: the data, the plan and the stiffness in play.
struct Models<'a> {
    config: &'a CalibrateConfig,
    loaded: &'a Loaded,
    data: &'a Data,
    plan: &'a Plan,
    /// The flexibility the compensated models use.
    flexibility: Option<&'a FlexibilityModel>,
    /// The prior of the cross-validation's identified-stiffness candidate.
    candidate_prior: Option<&'a FlexibilityModel>,
}

impl Models<'_> {
    /// The calibration input of `nominal` with `options`, compensated when `compensate`.
    fn input<'b>(
        &'b self,
        nominal: &'b McpcModel,
        options: &'b IdentificationOptions,
        compensate: bool,
    ) -> CalibrationInput<'b> {
        CalibrationInput {
            tree: self.loaded.robot.tree(),
            branches: &self.loaded.branches,
            nominal,
            flexibility: self.flexibility.filter(|_| compensate),
            plan: self.plan,
            options,
            measurement_frame: self.loaded.frame,
            diagnose_columns: true,
        }
    }

    /// [`choose_model`] with this data and stiffness.
    fn choose(
        &self,
        model: ModelChoice,
        options: &IdentificationOptions,
    ) -> Result<(ModelSpec, Option<CrossValidation>)> {
        choose_model(
            self.config,
            model,
            self.loaded,
            [self.flexibility, self.candidate_prior],
            self.plan,
            options,
            self.data,
        )
    }

    /// Fits the model `spec` (its noise estimated when it asks).
    fn fit(&self, spec: &ModelSpec, options: &IdentificationOptions) -> Result<Fit> {
        let tree = self.loaded.robot.tree();
        let patterns = &self.config.patterns;
        let prepared = prepare(spec, tree, &self.loaded.nominal, options, patterns)?;
        let input = self.input(&prepared.nominal, &prepared.options, spec.compensate);
        let data = self.data;
        let (run, noise) =
            run_model_with_noise(&input, spec, &data.measurements, &data.validation)?;
        let mut options = prepared.options;
        if let Some(noise) = &noise {
            options.rotation_sigma = noise.rotation_sigma;
        }
        Ok((run, options, prepared.nominal, noise))
    }

    /// The model to calibrate and its fit. The default: the full geometry, unless its fit
    /// shows model error; then as `auto`. A model asked for by flags (prior, joint errors,
    /// significance) is kept.
    fn pick(&self) -> Result<Picked> {
        let config = self.config;
        let declared = IdentificationOptions {
            position_sigma: config.position_sigma,
            rotation_sigma: config.rotation_sigma,
            robust: config.robust,
            ..IdentificationOptions::default()
        };
        let asked_extras =
            config.prior || config.harmonics || config.backlash || config.significant.is_some();
        let data_decide = match config.model {
            ModelChoice::Auto => true,
            ModelChoice::Adaptive => !asked_extras,
            ModelChoice::Level(_) => false,
        };
        let (mut spec, mut cross_validation) = if data_decide {
            let compensate = self.flexibility.is_some();
            (asked_spec(config, ModelLevel::Geometry, compensate), None)
        } else {
            self.choose(config.model, &declared)?
        };
        let (mut run, mut options, mut nominal, mut noise) = self.fit(&spec, &declared)?;
        let mut adaptive = false;
        if data_decide {
            // With `--noise estimated` the geometry fit estimated the σ ratio (variance
            // components) and every candidate keeps it; by default (`adaptive`) the estimate
            // is a candidate of its own, each fold estimating its own ratio.
            let model_error = shows_model_error(&run);
            adaptive = config.model == ModelChoice::Adaptive && model_error;
            if config.model == ModelChoice::Auto || model_error || config.cv.is_some() {
                let (chosen, cv) = self.choose(ModelChoice::Auto, &options)?;
                if (config.model == ModelChoice::Auto || model_error) && chosen != spec {
                    let estimated = noise.take();
                    (run, options, nominal, noise) = self.fit(&chosen, &options)?;
                    noise = noise.or(estimated);
                    spec = chosen;
                }
                cross_validation = cv;
            }
            spec.estimate_noise |= noise.is_some();
        }
        Ok(Picked {
            spec,
            cross_validation,
            fit: (run, options, nominal, noise),
            adaptive,
        })
    }

    /// The final run: `run` itself, or with stiffness identification (asked, or the chosen
    /// model's) the joint fit of the stiffness from it and the plan again with the identified
    /// stiffness. Also the stiffness identified and the flexibility of the final run.
    fn with_stiffness(
        &self,
        stiffness: &Stiffnesses,
        spec: &ModelSpec,
        nominal: &McpcModel,
        options: &IdentificationOptions,
        run: CalibrationRun,
    ) -> Result<(
        CalibrationRun,
        IdentifiedStiffness,
        Option<FlexibilityModel>,
    )> {
        let (config, data) = (self.config, self.data);
        let flexibility = self.flexibility.filter(|_| spec.compensate);
        let identify_now = config.identify_stiffness || spec.identify_stiffness;
        let Some((prior_stiffness, prior)) = stiffness.prior.as_ref().filter(|_| identify_now)
        else {
            // The fit above is the run without a stiffness fit.
            return Ok((run, None, flexibility.cloned()));
        };
        let input = self.input(nominal, options, spec.compensate);
        let run_with = |flexibility: Option<&FlexibilityModel>| {
            let input = CalibrationInput {
                flexibility,
                ..input
            };
            // The rotation σ is the estimated one already (`options`): no second estimate.
            let spec = ModelSpec {
                estimate_noise: false,
                ..*spec
            };
            run_model(&input, &spec, &data.measurements, &data.validation)
        };
        let stiffness_options = StiffnessOptions {
            prior_sigma: config.stiffness_prior,
            ..StiffnessOptions::default()
        };
        let tree = self.loaded.robot.tree();
        let sequence = calibrate_with_stiffness(
            tree,
            prior,
            flexibility,
            options,
            &stiffness_options,
            run_with,
            |run: &CalibrationRun| Fitted {
                model: run.report.model.clone(),
                // Every session's rows in the first session's frame, by the frames the run
                // fitted.
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
        let file = identified_stiffness(
            prior_stiffness,
            tree,
            &self.loaded.nominal,
            &report.estimates,
        );
        let summary = StiffnessSummary::new(&report, config.stiffness_prior);
        Ok((run, Some((summary, file)), Some(report.flexibility)))
    }
}

/// The note naming the model chosen and why, when there was a cross-validation.
fn model_note(config: &CalibrateConfig, loaded: &Loaded, picked: &Picked) -> Option<Note> {
    let cv = picked.cross_validation.as_ref()?;
    let reason = match config.model {
        ModelChoice::Auto => cv.reason.clone(),
        ModelChoice::Adaptive if picked.adaptive => format!(
            "the geometry fit leaves residuals over {}× the declared noise (model error), so the model is chosen by cross-validation: {}; `model` geometry keeps the full geometry",
            crate::calibration::SIGMA_WARNING,
            cv.reason
        ),
        _ => "as asked; `model` auto would choose by the cross-validation in report.md".into(),
    };
    Some(Note::info(format!(
        "model: '{}' ({reason})",
        picked
            .spec
            .named(&frame_joints(loaded.robot.tree(), &loaded.nominal)),
    )))
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
            diagnose_columns: false,
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
