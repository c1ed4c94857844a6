//! `--cv K` and `--model auto`: K-fold cross-validation over the identification postures
//! (grouped, so a repeated posture never sits on both sides), one row per model candidate:
//! its held-out RMS position error over every row, and the same without the rows the training
//! fits flag as outliers, by which the choice is made. See `docs/identification.md`
//! (cross-validation).

mod choice;

use choice::{choose, group_index, reference_of, Evaluated};
pub use choice::{paired, CvRow, Paired, RULE, SIGNIFICANT_T};

use super::model_choice::{
    frame_joints, grouped_folds, position_errors, prepare, run_model, ModelLevel, ModelSpec,
    ParameterPatterns,
};
use crate::calibration::validation_in_training_frames;
use crate::calibration::{
    calibrate_with_stiffness, CalibrationInput, CalibrationRun, Fitted, StiffnessOptions,
};
use crate::error::{Error, Result};
use crate::kinematics::{FlexibilityModel, GravitySigns, McpcModel};

use crate::measurement::Measurement;
use crate::tree::KinematicTree;
use rayon::prelude::*;

/// The default number of folds of `--model auto` without `--cv`.
pub const DEFAULT_FOLDS: usize = 5;

/// Fold assignments per cross-validation without `--cv-repeats` (seeds `seed` … `seed +
/// REPEATS − 1`); every row is held out once per assignment and its squared errors are
/// averaged. One split of TIAGo's 37 postures into 5 folds changed the choice with the seed
/// (docs/identification.md, "The CV is noisy").
pub const REPEATS: usize = 3;

/// What the cross-validation works on.
#[derive(Clone, Copy)]
pub struct CrossValidationInput<'a> {
    /// The robot, its nominal model (no extra parameters), the flexibility model if a
    /// stiffness is in play, the plan, the identification options and the measurement frame:
    /// what every fold's calibration runs on.
    pub calibration: CalibrationInput<'a>,
    /// `--freeze` / `--free`.
    pub patterns: &'a ParameterPatterns,
    /// Forward steps of per-joint harmonics/backlash after the first choice (at most this
    /// many, [`joint_steps`]; `--cv-joint-steps`): 0 for none.
    pub joint_steps: usize,
    /// The prior of the identified-stiffness candidates (the stiffness file, or the library
    /// defaults) and the stiffness fit's settings; `None`: no such candidate can run.
    pub stiffness: Option<(&'a FlexibilityModel, StiffnessOptions)>,
}

/// The cross-validation table and the choice.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CrossValidation {
    /// Folds.
    pub folds: usize,
    /// Fold assignments (each with its own seed) whose held-out errors are pooled.
    pub repeats: usize,
    /// Posture groups (a repeated posture is one group).
    pub postures: usize,
    /// One row per candidate, in the order tried.
    pub rows: Vec<CvRow>,
    /// The seeds of the fold assignments.
    pub seeds: Vec<u64>,
    /// The index of the chosen row ([`RULE`]).
    pub chosen: Option<usize>,
    /// The reference of the rule: the full geometry (the lowest row if it is not in the table
    /// or failed; after a forward step, the model the step extends).
    pub best: Option<usize>,
    /// The rule, in words.
    pub rule: &'static str,
    /// Why.
    pub reason: String,
    /// Indices of the identification rows left out of the choice: those the robust fits of
    /// the folds that trained on them flagged as outliers (in more than half of those fits,
    /// over every candidate). Their held-out errors still count in `rms_mm` and `max_mm`.
    #[serde(skip)]
    pub left_out_of_choice: Vec<usize>,
    /// The ids of those rows (report.json `left_out_of_choice`), set by [`Self::name_rows`].
    #[serde(rename = "left_out_of_choice")]
    pub left_out_ids: Vec<String>,
    /// When an identified-stiffness candidate was lowest but not significantly lower than
    /// the best rigid one ([`SIGNIFICANT_T`]): why the rigid one was chosen instead.
    pub doubt: Option<String>,
}

impl CrossValidation {
    /// Names the rows left out of the choice by their ids (`ids[i]`: the id of
    /// identification row `i`).
    pub fn name_rows(&mut self, ids: &[String]) {
        self.left_out_ids = self
            .left_out_of_choice
            .iter()
            .map(|&i| ids.get(i).cloned().unwrap_or_else(|| format!("#{}", i + 1)))
            .collect();
        self.reason = reason(self) + self.doubt.as_deref().unwrap_or("");
    }
}

/// The candidates `--model auto` and `--cv` compare: offsets and the full geometry, with and
/// without the prior, harmonics and (when the URDF has inertials) backlash, "only the
/// corrections ≥ 2σ"; with a stiffness each geometry candidate with and without
/// compensation; with `identify` (a stiffness prior that can run) the geometry with its
/// compliances identified.
pub fn candidates(
    tree: &KinematicTree,
    nominal: &McpcModel,
    stiffness: bool,
    identify: bool,
) -> Vec<ModelSpec> {
    let backlash = GravitySigns::new(tree, nominal).is_ok();
    let spec = |level, prior, harmonics, with_backlash| ModelSpec {
        level,
        prior,
        harmonics,
        backlash: with_backlash,
        compensate: stiffness,
        ..ModelSpec::default()
    };
    let mut list = vec![
        spec(ModelLevel::Offsets, false, false, false),
        spec(ModelLevel::Offsets, false, true, false),
        spec(ModelLevel::Geometry, false, false, false),
        spec(ModelLevel::Geometry, true, false, false),
        spec(ModelLevel::Geometry, true, true, false),
        ModelSpec {
            significant: Some(2.0),
            ..spec(ModelLevel::Geometry, false, false, false)
        },
    ];
    if backlash {
        list.push(spec(ModelLevel::Offsets, false, true, true));
        list.push(spec(ModelLevel::Geometry, true, true, true));
    }
    if stiffness {
        let rigid: Vec<ModelSpec> = list
            .iter()
            .filter(|s| s.level == ModelLevel::Geometry && s.significant.is_none())
            .map(|s| ModelSpec {
                compensate: false,
                ..*s
            })
            .collect();
        list.extend(rigid);
    }
    if identify {
        list.push(ModelSpec {
            identify_stiffness: true,
            ..spec(ModelLevel::Geometry, false, false, false)
        });
    }
    list
}

/// Cross-validates every candidate over `k` grouped folds of `measurements`; the choice
/// compares the held-out RMS without the rows the training fits flag as outliers, so that a
/// blunder (its held-out error is its size under every model) does not set every
/// candidate's score.
pub fn cross_validate(
    input: &CrossValidationInput<'_>,
    candidates: &[ModelSpec],
    measurements: &[Measurement],
    k: usize,
    repeats: usize,
    seed: u64,
) -> Result<CrossValidation> {
    // Repeated with `repeats` fold assignments (seeds `seed`, `seed + 1`, …): one split of 37
    // postures into 5 folds is noisy enough to change the choice.
    let repeats = repeats.max(1);
    let seeds: Vec<u64> = (0..repeats as u64).map(|r| seed.wrapping_add(r)).collect();
    let folds: Vec<Vec<usize>> = seeds
        .iter()
        .flat_map(|&s| grouped_folds(measurements, k, s))
        .collect();
    let postures = super::model_choice::posture_groups(measurements).len();
    // Candidates and folds are independent fits: run in parallel, collected in order, so the
    // table is the same on any number of threads.
    let mut evaluated = candidates
        .par_iter()
        .map(|spec| evaluate(input, spec, measurements, &folds))
        .collect::<Result<Vec<_>>>()?;
    // A row is left out of the choice when most fits that trained on it flagged it.
    let (mut trained, mut flagged) = (
        vec![0usize; measurements.len()],
        vec![0usize; measurements.len()],
    );
    for e in evaluated.iter().filter(|e| e.row.rms_mm.is_some()) {
        for (i, [t, f]) in e.flags.iter().enumerate() {
            trained[i] += t;
            flagged[i] += f;
        }
    }
    let left_out: Vec<usize> = (0..measurements.len())
        .filter(|&i| 2 * flagged[i] > trained[i])
        .collect();
    let kept: Vec<usize> = (0..measurements.len())
        .filter(|i| left_out.binary_search(i).is_err())
        .collect();
    for e in evaluated.iter_mut().filter(|e| e.row.rms_mm.is_some()) {
        let errors: Vec<f64> = kept.iter().filter_map(|&i| e.errors[i]).collect();
        e.row.choice_rms_mm = Some(rms(&errors) * 1e3);
    }
    let group_of = group_index(
        &super::model_choice::posture_groups(measurements),
        measurements.len(),
    );
    let choice = choose_with_steps(
        input,
        measurements,
        &folds,
        &mut evaluated,
        &kept,
        &group_of,
    )?;
    let rows: Vec<CvRow> = evaluated.into_iter().map(|e| e.row).collect();
    let left_out_ids: Vec<String> = left_out.iter().map(|i| format!("#{}", i + 1)).collect();
    let mut cv = CrossValidation {
        folds: k.max(1),
        repeats,
        seeds,
        reason: String::new(),
        doubt: choice.doubt,
        postures,
        rows,
        chosen: choice.chosen,
        best: choice.best,
        rule: RULE,
        left_out_of_choice: left_out,
        left_out_ids,
    };
    cv.reason = reason(&cv) + cv.doubt.as_deref().unwrap_or("");
    Ok(cv)
}

/// The [`RULE`] over `evaluated` (the full geometry the reference), then forward steps: one
/// joint's harmonics or backlash added to the chosen model, each taken only when significantly
/// lower than the model it extends (that model the reference of the step's choice).
fn choose_with_steps(
    input: &CrossValidationInput<'_>,
    measurements: &[Measurement],
    folds: &[Vec<usize>],
    evaluated: &mut Vec<Evaluated>,
    kept: &[usize],
    group_of: &[usize],
) -> Result<choice::Choice> {
    let mut reference = reference_of(evaluated.iter().map(|e| &e.row.spec));
    let mut pool: Vec<usize> = (0..evaluated.len()).collect();
    let mut choice = choose(evaluated, kept, group_of, reference, &pool, SIGNIFICANT_T);
    for _ in 0..input.joint_steps.min(MAX_STEPS) {
        let Some(base) = choice.chosen else {
            break;
        };
        let steps: Vec<ModelSpec> = joint_steps(input, &evaluated[base].row.spec, measurements)
            .into_iter()
            .filter(|s| !evaluated.iter().any(|e| e.row.spec == *s))
            .collect();
        let before = evaluated.len();
        let mut more = steps
            .par_iter()
            .map(|spec| evaluate(input, spec, measurements, folds))
            .collect::<Result<Vec<_>>>()?;
        for e in more.iter_mut().filter(|e| e.row.rms_mm.is_some()) {
            let errors: Vec<f64> = kept.iter().filter_map(|&i| e.errors[i]).collect();
            e.row.choice_rms_mm = Some(rms(&errors) * 1e3);
        }
        evaluated.extend(more);
        let step_pool: Vec<usize> = (before..evaluated.len()).collect();
        let threshold = choice::step_threshold(step_pool.len());
        let step = choose(evaluated, kept, group_of, Some(base), &step_pool, threshold);
        if step.chosen.is_none_or(|i| i < before) {
            // No step is significant: the table's differences stay against the last reference.
            choose(evaluated, kept, group_of, reference, &pool, SIGNIFICANT_T);
            break;
        }
        (reference, pool, choice) = (Some(base), step_pool, step);
    }
    Ok(choice)
}

/// The most forward steps of joint-angle error terms after the rule's first choice (each step
/// offers one more joint's harmonics or backlash).
pub const MAX_STEPS: usize = 2;

/// The one-joint extensions of `base`: harmonics on one more revolute joint, backlash on one
/// more joint whose gravity torque changes sign across the identification postures (with a
/// constant sign a backlash is a joint offset). None for the identified-stiffness candidate,
/// or beyond 64 frames.
pub fn joint_steps(
    input: &CrossValidationInput<'_>,
    base: &ModelSpec,
    measurements: &[Measurement],
) -> Vec<ModelSpec> {
    let (tree, nominal) = (input.calibration.tree, input.calibration.nominal);
    let frames = nominal.frames();
    if base.identify_stiffness || frames.len() > 64 {
        return Vec::new();
    }
    let revolute = |f: usize| frames[f].kind == crate::kinematics::FrameKind::Revolute;
    let mut steps = Vec::new();
    if !(base.harmonics && base.harmonic_frames == 0) {
        for f in (0..frames.len()).filter(|&f| revolute(f)) {
            if base.harmonic_frames & (1u64 << f) == 0 {
                steps.push(ModelSpec {
                    harmonics: true,
                    harmonic_frames: base.harmonic_frames | (1u64 << f),
                    ..*base
                });
            }
        }
    }
    let gravity = GravitySigns::new(tree, nominal).ok();
    if let Some(gravity) = gravity.filter(|_| !(base.backlash && base.backlash_frames == 0)) {
        let signs: Vec<_> = measurements.iter().map(|m| gravity.signs(&m.q)).collect();
        for f in (0..frames.len()).filter(|&f| revolute(f)) {
            let seen = |sign: f64| signs.iter().any(|s| s.get(f).copied() == Some(sign));
            if base.backlash_frames & (1u64 << f) == 0 && seen(1.0) && seen(-1.0) {
                steps.push(ModelSpec {
                    backlash: true,
                    backlash_frames: base.backlash_frames | (1u64 << f),
                    ..*base
                });
            }
        }
    }
    steps
}

/// Why the chosen row was chosen.
fn reason(cv: &CrossValidation) -> String {
    let (Some(i), Some(best)) = (cv.chosen, cv.best) else {
        return "no candidate ran on every fold".into();
    };
    let (k, repeats, postures) = (cv.folds, cv.repeats, cv.postures);
    let without = match cv.left_out_ids.len() {
        0 => String::new(),
        n => format!(
            " without the {n} row(s) the training fits flagged as outliers ({}; every row counts in the table's RMS column)",
            cv.left_out_ids.join(", ")
        ),
    };
    let row = &cv.rows[i];
    let rms = |r: &CvRow| r.choice_rms_mm.unwrap_or(f64::NAN);
    let over = format!(
        "held-out RMS over {k} folds × {repeats} assignments of {postures} postures{without}"
    );
    if cv.rows.iter().filter(|r| r.choice_rms_mm.is_some()).count() == 1 {
        return format!("'{}' is the only candidate that ran", row.model);
    }
    let versus = |r: &CvRow| {
        let (d, se) = (
            r.difference_mm.unwrap_or(f64::NAN),
            r.difference_se_mm.unwrap_or(f64::NAN),
        );
        format!("{d:+.3} ± {se:.3} mm, paired t = {:.2}", -d / se)
    };
    let reference = &cv.rows[best];
    let paper = match reference_of([&reference.spec]) {
        Some(_) if reference.spec.prior => {
            " (the full geometry with the prior on the nominal values: the paper's model)"
        }
        Some(_) => " (the full geometry, the paper's model)",
        None => " (the model the forward step extends)",
    };
    if i == best {
        let next = cv
            .rows
            .iter()
            .enumerate()
            .filter(|(j, r)| *j != i && r.choice_rms_mm.is_some())
            .min_by(|a, b| rms(a.1).total_cmp(&rms(b.1)));
        let next = next.map_or(String::new(), |(_, r)| {
            format!(
                "; lowest other '{}' {:.3} mm, {}",
                r.model,
                rms(r),
                versus(r)
            )
        });
        return format!(
            "'{}' is the reference{paper}, {:.3} mm {over}, and no candidate is significantly lower (paired t ≥ {SIGNIFICANT_T} over the postures){next}",
            row.model,
            rms(row)
        );
    }
    format!(
        "'{}' is the lowest candidate significantly lower than the reference '{}'{paper} {over}: {:.3} mm against {:.3} mm, {}",
        row.model,
        reference.model,
        rms(row),
        rms(reference),
        versus(row)
    )
}

/// Root mean square (0 for none).
fn rms(values: &[f64]) -> f64 {
    crate::math::root_mean_square(values).unwrap_or(0.0)
}

/// One candidate over every fold.
fn evaluate(
    input: &CrossValidationInput<'_>,
    spec: &ModelSpec,
    measurements: &[Measurement],
    folds: &[Vec<usize>],
) -> Result<Evaluated> {
    let prepared = prepare(
        spec,
        input.calibration.tree,
        input.calibration.nominal,
        input.calibration.options,
        input.patterns,
    )?;
    let parameters = prepared.nominal.parameter_count() - prepared.options.frozen.len();
    let calibration = CalibrationInput {
        nominal: &prepared.nominal,
        flexibility: input.calibration.flexibility.filter(|_| spec.compensate),
        options: &prepared.options,
        ..input.calibration
    };
    let mut row = CvRow {
        model: spec.named(&frame_joints(
            input.calibration.tree,
            input.calibration.nominal,
        )),
        spec: *spec,
        parameters,
        rms_mm: None,
        choice_rms_mm: None,
        max_mm: None,
        difference_mm: None,
        difference_se_mm: None,
        error: None,
    };
    let mut errors = vec![None; measurements.len()];
    let mut flags = vec![[0, 0]; measurements.len()];
    let split = |fold: &Vec<usize>| -> (Vec<usize>, Vec<usize>) {
        (0..measurements.len()).partition(|i| fold.binary_search(i).is_ok())
    };
    let pick = |rows: &[usize]| -> Vec<Measurement> {
        rows.iter().map(|&i| measurements[i].clone()).collect()
    };
    let used: Vec<&Vec<usize>> = folds.iter().filter(|f| !f.is_empty()).collect();
    // A held-out row of a later session is predicted in that session's frame as the fold's
    // fit found it (every session has training rows: folds split postures, not sessions); in
    // the first session's frame the moved frames would swamp the model.
    let outcomes: Vec<Result<(Vec<f64>, Vec<usize>)>> = used
        .par_iter()
        .map(|fold| {
            let (held, train) = split(fold);
            let (run, identified) = fit_fold(input, &calibration, spec, &pick(&train))?;
            let predict = CalibrationInput {
                flexibility: identified.as_ref().or(calibration.flexibility),
                ..calibration
            };
            let rows = validation_in_training_frames(&pick(&held), run.sessions.as_ref());
            Ok((
                position_errors(&predict, &run, &rows)?,
                run.robust.outliers(),
            ))
        })
        .collect();
    // Each repetition holds every row out once: a row's error is the RMS of its repetitions.
    let mut squares = vec![(0.0, 0usize); measurements.len()];
    let mut max = 0.0f64;
    for (fold, outcome) in used.into_iter().zip(outcomes) {
        let (held, train) = split(fold);
        match outcome {
            Ok((found, outliers)) => {
                for (&i, e) in held.iter().zip(found) {
                    squares[i].0 += e * e;
                    squares[i].1 += 1;
                    errors[i] = Some((squares[i].0 / squares[i].1 as f64).sqrt());
                    max = max.max(e);
                }
                for &i in &train {
                    flags[i][0] += 1;
                }
                for o in outliers {
                    flags[train[o]][1] += 1;
                }
            }
            Err(error) => {
                row.error = Some(error.to_string());
                return Ok(Evaluated { row, errors, flags });
            }
        }
    }
    let all: Vec<f64> = errors.iter().flatten().copied().collect();
    row.rms_mm = Some(rms(&all) * 1e3);
    row.max_mm = Some(max * 1e3);
    Ok(Evaluated { row, errors, flags })
}

/// One fold's fit of `spec` on `train`: the calibration, and with stiffness identification
/// the sequence `calibrate --identify-stiffness` runs (calibrate, fit the compliances with the
/// geometry, calibrate again) with the identified flexibility to predict by.
fn fit_fold(
    input: &CrossValidationInput<'_>,
    calibration: &CalibrationInput<'_>,
    spec: &ModelSpec,
    train: &[Measurement],
) -> Result<(CalibrationRun, Option<FlexibilityModel>)> {
    if !spec.identify_stiffness {
        return Ok((run_model(calibration, spec, train, &[])?, None));
    }
    let Some((prior, options)) = input.stiffness else {
        return Err(Error::InvalidData {
            origin: "cross-validation".into(),
            message: format!("'{}' needs a stiffness prior", spec.name()),
        });
    };
    let sequence = calibrate_with_stiffness(
        calibration.tree,
        prior,
        calibration.flexibility,
        calibration.options,
        &options,
        |flexibility| {
            let input = CalibrationInput {
                flexibility,
                ..*calibration
            };
            run_model(&input, spec, train, &[])
        },
        |run: &CalibrationRun| Fitted {
            model: run.report.model.clone(),
            measurements: validation_in_training_frames(train, run.sessions.as_ref()),
            outliers: run.robust.outliers(),
        },
    )?;
    Ok((sequence.again, Some(sequence.stiffness.flexibility)))
}

/// One line per candidate (the `cv:` notes on stderr): held-out RMS, and its difference to
/// the reference with the standard error.
pub fn lines(cv: &CrossValidation) -> Vec<String> {
    let mm = |v: Option<f64>| v.map_or("failed".to_string(), |v| format!("{v:.3} mm"));
    cv.rows
        .iter()
        .map(|row| {
            let without = if cv.left_out_ids.is_empty() {
                String::new()
            } else {
                format!(" ({} without flagged rows)", mm(row.choice_rms_mm))
            };
            let difference = match (row.difference_mm, row.difference_se_mm) {
                (Some(d), Some(se)) => format!("  {d:+.3} ± {se:.3} mm"),
                (Some(_), None) => "  (reference)".to_string(),
                _ => String::new(),
            };
            format!(
                "cv: {:<45} {:>3} parameters  held-out RMS {}{without}{difference}",
                row.model,
                row.parameters,
                mm(row.rms_mm)
            )
        })
        .collect()
}

/// The table in Markdown (report.md).
pub fn markdown(cv: &CrossValidation) -> String {
    let seeds: Vec<String> = cv.seeds.iter().map(u64::to_string).collect();
    let mut text = format!(
        "\n## Model choice (cross-validation)\n\n{} folds over {} postures (a repeated posture stays in one fold), repeated with {} fold assignments (seeds {}); held-out position error of every identification row (the RMS of its repetitions), each predicted by the model fitted without its fold. The choice compares the RMS without the rows the training fits flagged as outliers ({}); the RMS and max count every row. Rule: {}.\n\n| model | free parameters | compensation | held-out RMS (mm) | without flagged rows (mm) | − reference ± SE (mm) | max (mm) |\n| --- | --- | --- | --- | --- | --- | --- |\n",
        cv.folds,
        cv.postures,
        cv.repeats,
        seeds.join(", "),
        if cv.left_out_ids.is_empty() {
            "none".to_string()
        } else {
            cv.left_out_ids.join(", ")
        },
        cv.rule
    );
    for (i, row) in cv.rows.iter().enumerate() {
        let mark = match (Some(i) == cv.chosen, Some(i) == cv.best) {
            (true, true) => " **(chosen; reference)**",
            (true, false) => " **(chosen)**",
            (false, true) => " (reference)",
            _ => "",
        };
        let number = |v: Option<f64>| v.map_or("failed".to_string(), |v| format!("{v:.3}"));
        let difference = match (row.difference_mm, row.difference_se_mm) {
            (Some(d), Some(se)) => format!("{d:+.3} ± {se:.3}"),
            (Some(_), None) => "0".to_string(),
            _ => "—".to_string(),
        };
        text.push_str(&format!(
            "| {}{mark} | {} | {} | {} | {} | {difference} | {} |\n",
            row.model,
            row.parameters,
            if row.spec.identify_stiffness {
                "identified"
            } else if row.spec.compensate {
                "given"
            } else {
                "no"
            },
            number(row.rms_mm),
            number(row.choice_rms_mm),
            number(row.max_mm)
        ));
    }
    text.push_str(&format!("\n{}\n", cv.reason));
    text
}
