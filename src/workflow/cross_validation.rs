//! `--cv K` and `--model auto`: K-fold cross-validation over the identification postures
//! (grouped, so a repeated posture never sits on both sides), one row per model candidate:
//! its held-out RMS position error over every row, and the same without the rows the training
//! fits flag as outliers, by which the choice is made. See `docs/identification.md`
//! (cross-validation).

use super::model_choice::{
    grouped_folds, position_errors, prepare, run_model, ModelLevel, ModelSpec, ParameterPatterns,
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

/// Fold assignments per cross-validation (seeds `seed` … `seed + REPEATS − 1`); every row is
/// held out once per assignment and its errors are pooled (RMS). One for now: on TIAGo the
/// choice changes with the fold seed (docs/identification.md), but three assignments triple
/// the run time and have not yet been measured on every data set.
pub const REPEATS: usize = 1;

/// What the cross-validation works on.
#[derive(Clone, Copy)]
pub struct CrossValidationInput<'a> {
    /// The robot, its nominal model (no extra parameters), the flexibility model if a
    /// stiffness is in play, the plan, the identification options and the measurement frame:
    /// what every fold's calibration runs on.
    pub calibration: CalibrationInput<'a>,
    /// `--freeze` / `--free`.
    pub patterns: &'a ParameterPatterns,
    /// The prior of the identified-stiffness candidates (the stiffness file, or the library
    /// defaults) and the stiffness fit's settings; `None`: no such candidate can run.
    pub stiffness: Option<(&'a FlexibilityModel, StiffnessOptions)>,
}

/// One candidate's cross-validated error.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CvRow {
    /// The candidate's name.
    pub model: String,
    /// The candidate.
    pub spec: ModelSpec,
    /// Free parameters (before "≥ kσ" freezing; without the identified compliances).
    pub parameters: usize,
    /// Held-out RMS position error over every identification row (mm); `None` if a fold
    /// failed.
    pub rms_mm: Option<f64>,
    /// Held-out RMS position error without the rows the training fits flagged as outliers
    /// ([`CrossValidation::left_out_of_choice`]): what the choice compares (mm).
    pub choice_rms_mm: Option<f64>,
    /// The largest held-out position error (mm).
    pub max_mm: Option<f64>,
    /// Why a fold failed, if one did.
    pub error: Option<String>,
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
    /// The index of the chosen row (lowest held-out RMS without the flagged rows).
    pub chosen: Option<usize>,
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

/// The identified-stiffness candidate changes what is shipped (a rigid-only URDF and a
/// compensation file), so it must beat the best other candidate by this many standard errors
/// of the paired difference of squared held-out errors over the rows (a one-sided test at
/// about 2.5 %).
pub const SIGNIFICANT_T: f64 = 2.0;

/// The paired t statistic of `a² − b²` over the rows `kept` (positive: `b` is lower).
fn paired_t(a: &[Option<f64>], b: &[Option<f64>], kept: &[usize]) -> f64 {
    let d: Vec<f64> = kept
        .iter()
        .filter_map(|&i| Some(a[i]? * a[i]? - b[i]? * b[i]?))
        .collect();
    if d.len() < 2 {
        return 0.0;
    }
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let variance = d.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    if variance == 0.0 {
        return if mean > 0.0 { f64::INFINITY } else { 0.0 };
    }
    mean / (variance / n).sqrt()
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
        self.reason = reason(
            &self.rows,
            self.chosen,
            self.folds,
            self.postures,
            &self.left_out_ids,
        ) + self.doubt.as_deref().unwrap_or("");
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
    seed: u64,
) -> Result<CrossValidation> {
    // Repeated with REPEATS fold assignments (seeds `seed`, `seed + 1`, …): one split of 37
    // postures into 5 folds is noisy enough to change the choice.
    let folds: Vec<Vec<usize>> = (0..REPEATS as u64)
        .flat_map(|r| grouped_folds(measurements, k, seed.wrapping_add(r)))
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
    let lowest = |rigid: bool| {
        evaluated
            .iter()
            .enumerate()
            .filter(|(_, e)| !(rigid && e.row.spec.identify_stiffness))
            .filter_map(|(i, e)| e.row.choice_rms_mm.map(|rms| (i, rms)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    };
    let mut chosen = lowest(false);
    let mut doubt = None;
    if let (Some(i), Some(j)) = (chosen, lowest(true)) {
        if evaluated[i].row.spec.identify_stiffness {
            let t = paired_t(&evaluated[j].errors, &evaluated[i].errors, &kept);
            if t < SIGNIFICANT_T {
                chosen = Some(j);
                doubt = Some(format!(
                    "; '{}' was lower, but not significantly over the rows (paired t = {t:.2} < {SIGNIFICANT_T}), and it would ship the URDF with a compensation file",
                    evaluated[i].row.model
                ));
            }
        }
    }
    let rows: Vec<CvRow> = evaluated.into_iter().map(|e| e.row).collect();
    let left_out_ids: Vec<String> = left_out.iter().map(|i| format!("#{}", i + 1)).collect();
    Ok(CrossValidation {
        folds: k.max(1),
        repeats: REPEATS,
        reason: reason(&rows, chosen, k.max(1), postures, &left_out_ids)
            + doubt.as_deref().unwrap_or(""),
        doubt,
        postures,
        rows,
        chosen,
        left_out_of_choice: left_out,
        left_out_ids,
    })
}

/// Why the chosen row was chosen.
fn reason(
    rows: &[CvRow],
    chosen: Option<usize>,
    k: usize,
    postures: usize,
    left_out: &[String],
) -> String {
    let Some(i) = chosen else {
        return "no candidate ran on every fold".into();
    };
    let best = rows[i].choice_rms_mm.unwrap_or(f64::NAN);
    let next = rows
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != i)
        .filter_map(|(_, r)| r.choice_rms_mm.map(|rms| (r.model.clone(), rms)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let without = match left_out.len() {
        0 => String::new(),
        n => format!(
            " without the {n} row(s) the training fits flagged as outliers ({}; every row counts in the table's RMS column)",
            left_out.join(", ")
        ),
    };
    match next {
        // The chosen one is not the lowest (a significance rule): say which is, not "next".
        Some((name, rms)) if rms < best => format!(
            "'{}' is chosen by the held-out RMS over {k} folds ×{REPEATS} of {postures} postures{without}: {best:.3} mm (lowest: '{name}' {rms:.3} mm)",
            rows[i].model
        ),
        Some((name, rms)) => format!(
            "'{}' has the lowest held-out RMS over {k} folds ×{REPEATS} of {postures} postures{without}: {best:.3} mm (next: '{name}' {rms:.3} mm)",
            rows[i].model
        ),
        None => format!("'{}' is the only candidate that ran", rows[i].model),
    }
}

/// Root mean square (0 for none).
fn rms(values: &[f64]) -> f64 {
    (values.iter().map(|e| e * e).sum::<f64>() / values.len().max(1) as f64).sqrt()
}

/// One candidate over every fold: its row, each measurement's held-out error, and per
/// measurement how many training fits used it and how many flagged it as an outlier.
struct Evaluated {
    row: CvRow,
    errors: Vec<Option<f64>>,
    flags: Vec<[usize; 2]>,
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
        model: spec.name(),
        spec: *spec,
        parameters,
        rms_mm: None,
        choice_rms_mm: None,
        max_mm: None,
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

/// The table in Markdown (report.md).
pub fn markdown(cv: &CrossValidation) -> String {
    let mut text = format!(
        "\n## Model choice (cross-validation)\n\n{} folds over {} postures (a repeated posture stays in one fold), repeated with {} fold assignments; held-out position error of every identification row (the RMS of its repetitions), each predicted by the model fitted without its fold. The choice compares the RMS without the rows the training fits flagged as outliers ({}); the RMS and max count every row.\n\n| model | free parameters | compensation | held-out RMS (mm) | without flagged rows (mm) | max (mm) |\n| --- | --- | --- | --- | --- | --- |\n",
        cv.folds,
        cv.postures,
        cv.repeats,
        if cv.left_out_ids.is_empty() {
            "none".to_string()
        } else {
            cv.left_out_ids.join(", ")
        }
    );
    for (i, row) in cv.rows.iter().enumerate() {
        let mark = if Some(i) == cv.chosen {
            " **(chosen)**"
        } else {
            ""
        };
        let number = |v: Option<f64>| v.map_or("failed".to_string(), |v| format!("{v:.3}"));
        text.push_str(&format!(
            "| {}{mark} | {} | {} | {} | {} | {} |\n",
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
