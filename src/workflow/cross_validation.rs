//! `--cv K` and `--model auto`: K-fold cross-validation over the identification postures
//! (grouped, so a repeated posture never sits on both sides), one row per model candidate:
//! its held-out RMS position error. See `docs/identification.md` (cross-validation).

use super::model_choice::{
    grouped_folds, position_errors, prepare, run_model, ModelLevel, ModelSpec, ParameterPatterns,
};
use crate::calibration::CalibrationInput;
use crate::error::Result;
use crate::kinematics::{GravitySigns, McpcModel};
use crate::measurement::Measurement;
use crate::tree::KinematicTree;

/// The default number of folds of `--model auto` without `--cv`.
pub const DEFAULT_FOLDS: usize = 5;

/// What the cross-validation works on.
#[derive(Clone, Copy)]
pub struct CrossValidationInput<'a> {
    /// The robot, its nominal model (no extra parameters), the flexibility model if a
    /// stiffness is in play, the plan, the identification options and the measurement frame:
    /// what every fold's calibration runs on.
    pub calibration: CalibrationInput<'a>,
    /// `--freeze` / `--free`.
    pub patterns: &'a ParameterPatterns,
}

/// One candidate's cross-validated error.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CvRow {
    /// The candidate's name.
    pub model: String,
    /// The candidate.
    pub spec: ModelSpec,
    /// Free parameters (before "≥ kσ" freezing).
    pub parameters: usize,
    /// Held-out RMS position error over every identification row (mm); `None` if a fold
    /// failed.
    pub rms_mm: Option<f64>,
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
    /// Posture groups (a repeated posture is one group).
    pub postures: usize,
    /// One row per candidate, in the order tried.
    pub rows: Vec<CvRow>,
    /// The index of the chosen row (lowest held-out RMS).
    pub chosen: Option<usize>,
    /// Why.
    pub reason: String,
}

/// The candidates `--model auto` and `--cv` compare: offsets and the full geometry, with and
/// without the prior, harmonics and (when the URDF has inertials) backlash, "only the
/// corrections ≥ 2σ", and with a stiffness each with and without compensation.
pub fn candidates(tree: &KinematicTree, nominal: &McpcModel, stiffness: bool) -> Vec<ModelSpec> {
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
    list
}

/// Cross-validates every candidate over `k` grouped folds of `measurements`.
pub fn cross_validate(
    input: &CrossValidationInput<'_>,
    candidates: &[ModelSpec],
    measurements: &[Measurement],
    k: usize,
    seed: u64,
) -> Result<CrossValidation> {
    let folds = grouped_folds(measurements, k, seed);
    let postures = super::model_choice::posture_groups(measurements).len();
    let mut rows = Vec::new();
    for spec in candidates {
        rows.push(evaluate(input, spec, measurements, &folds)?);
    }
    let chosen = rows
        .iter()
        .enumerate()
        .filter_map(|(i, r)| r.rms_mm.map(|rms| (i, rms)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i);
    let reason = match chosen {
        Some(i) => {
            let best = rows[i].rms_mm.unwrap_or(f64::NAN);
            let next = rows
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .filter_map(|(_, r)| r.rms_mm.map(|rms| (r.model.clone(), rms)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match next {
                Some((name, rms)) => format!(
                    "'{}' has the lowest held-out RMS over {k} folds of {postures} postures: {best:.3} mm (next: '{name}' {rms:.3} mm)",
                    rows[i].model
                ),
                None => format!("'{}' is the only candidate that ran", rows[i].model),
            }
        }
        None => "no candidate ran on every fold".into(),
    };
    Ok(CrossValidation {
        folds: folds.len(),
        postures,
        rows,
        chosen,
        reason,
    })
}

/// One candidate over every fold.
fn evaluate(
    input: &CrossValidationInput<'_>,
    spec: &ModelSpec,
    measurements: &[Measurement],
    folds: &[Vec<usize>],
) -> Result<CvRow> {
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
    let mut errors = Vec::new();
    for fold in folds.iter().filter(|f| !f.is_empty()) {
        let (held, train): (Vec<Measurement>, Vec<Measurement>) = {
            let mut held = Vec::new();
            let mut train = Vec::new();
            for (i, m) in measurements.iter().enumerate() {
                if fold.binary_search(&i).is_ok() {
                    held.push(m.clone());
                } else {
                    train.push(m.clone());
                }
            }
            (held, train)
        };
        // A held-out row of a later session is predicted in that session's frame as the
        // fold's fit found it (every session has training rows: folds split postures, not
        // sessions); in the first session's frame the moved frames would swamp the model.
        let outcome = run_model(&calibration, spec.significant, &train, &[]).and_then(|run| {
            let held = crate::calibration::sessions::validation_in_training_frames(
                &held,
                run.sessions.as_ref(),
            );
            position_errors(&calibration, &run, &held)
        });
        match outcome {
            Ok(found) => errors.extend(found),
            Err(error) => {
                return Ok(CvRow {
                    model: spec.name(),
                    spec: *spec,
                    parameters,
                    rms_mm: None,
                    max_mm: None,
                    error: Some(error.to_string()),
                })
            }
        }
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt();
    let max = errors.iter().copied().fold(0.0, f64::max);
    Ok(CvRow {
        model: spec.name(),
        spec: *spec,
        parameters,
        rms_mm: Some(rms * 1e3),
        max_mm: Some(max * 1e3),
        error: None,
    })
}

/// The table in Markdown (report.md).
pub fn markdown(cv: &CrossValidation) -> String {
    let mut text = format!(
        "\n## Model choice (cross-validation)\n\n{} folds over {} postures (a repeated posture stays in one fold); held-out position error of every identification row, each predicted by the model fitted without its fold.\n\n| model | free parameters | compensation | held-out RMS (mm) | max (mm) |\n| --- | --- | --- | --- | --- |\n",
        cv.folds, cv.postures
    );
    for (i, row) in cv.rows.iter().enumerate() {
        let mark = if Some(i) == cv.chosen {
            " **(chosen)**"
        } else {
            ""
        };
        let number = |v: Option<f64>| v.map_or("failed".to_string(), |v| format!("{v:.3}"));
        text.push_str(&format!(
            "| {}{mark} | {} | {} | {} | {} |\n",
            row.model,
            row.parameters,
            if row.spec.compensate { "yes" } else { "no" },
            number(row.rms_mm),
            number(row.max_mm)
        ));
    }
    text.push_str(&format!("\n{}\n", cv.reason));
    text
}
