//! The model a contact calibration's data support (`calibrate --contacts` with `model` auto or
//! adaptive, `cv`, `prior`; issues 28 and 29): joint zero offsets, the full geometry, the full
//! geometry with the prior on the nominal values, compared by K-fold cross-validation over the
//! contact postures (grouped: a repeated posture never sits on both sides). A held-out contact
//! is scored by its violation under the fold's fit — the robot and the nuisance (each
//! session's plane as the fold's training rows found it) — each equation divided by its kind's
//! σ, so heights, tilts, gaps and bar lengths weigh as the fit weighs them. The choice follows
//! the tracker's rule (`docs/contacts.md`, "The model the data support").

use super::contact_fit::{contact_violations, fit_contacts, ContactFit, ContactProblem};
use super::contact_model::{offsets_model, robot_free};
use super::cross_validation::{paired, DEFAULT_FOLDS, REPEATS, SIGNIFICANT_T};
use super::model_choice::{
    grouped_folds, posture_groups, ModelChoice, ModelLevel, ParameterPatterns,
};
use super::note::Note;
use crate::calibration::{IdentificationOptions, MeasurementKind, Prior, RowKind};
use crate::error::{Error, Result};
use crate::measurement::{Contact, Measurement, Observation};
use crate::tree::KinematicTree;
use rayon::prelude::*;

/// One model of a contact calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ContactModelSpec {
    /// Joint zero offsets only (else every joint frame's four parameters).
    pub offsets: bool,
    /// The default prior on the nominal values (`docs/identification.md`, prior), its σ's
    /// divided by the residual scale σ̂ of the same fit without it when σ̂ > 1.
    pub prior: bool,
}

impl ContactModelSpec {
    /// `offsets`, `offsets+prior`, `geometry` or `geometry+prior`.
    pub fn name(self) -> &'static str {
        match (self.offsets, self.prior) {
            (true, false) => "offsets",
            (true, true) => "offsets+prior",
            (false, false) => "geometry",
            (false, true) => "geometry+prior",
        }
    }
}

/// The candidates of `model` auto, in the order tried; the last is the reference.
pub const CONTACT_CANDIDATES: [ContactModelSpec; 3] = [
    ContactModelSpec {
        offsets: true,
        prior: false,
    },
    ContactModelSpec {
        offsets: false,
        prior: false,
    },
    ContactModelSpec {
        offsets: false,
        prior: true,
    },
];

/// `model` adaptive with contacts cross-validates when the geometry fit's residual scale σ̂
/// exceeds this: a contact fit costs milliseconds, so the data choose as soon as the residuals
/// are not the declared noise.
pub const CONTACT_ADAPTIVE_SIGMA: f64 = 2.0;

/// How the candidate is chosen (report.md, report.json `model_choice.rule`).
pub const CONTACT_RULE: &str = "the full geometry with the prior on the nominal values is the reference; a candidate replaces it only when significantly lower in held-out RMS (each equation over its kind's σ; paired t ≥ 2 over the postures), and among those the lowest wins";

/// One candidate's cross-validated error.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ContactCvRow {
    /// The candidate.
    pub model: &'static str,
    /// The candidate's settings.
    pub spec: ContactModelSpec,
    /// Free robot parameters.
    pub parameters: usize,
    /// Held-out RMS over every contact equation, each over its kind's σ (`None`: a fold failed).
    pub rms_sigma: Option<f64>,
    /// Held-out RMS of the heights (flush and point contacts), mm.
    pub height_rms_mm: Option<f64>,
    /// Held-out RMS of the tilts (flush contacts), degrees.
    pub tilt_rms_deg: Option<f64>,
    /// Held-out RMS of the gaps and bar lengths (touch and distance contacts), mm.
    pub pair_rms_mm: Option<f64>,
    /// `rms_sigma` minus the reference's.
    pub difference_sigma: Option<f64>,
    /// The standard error of that difference (paired over the postures); `None` for the
    /// reference.
    pub difference_se_sigma: Option<f64>,
    /// Why a fold failed, if one did.
    pub error: Option<String>,
}

/// The cross-validation of a contact calibration and its choice.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ContactCv {
    /// Folds.
    pub folds: usize,
    /// Fold assignments (seeds `seeds`) whose held-out errors are pooled.
    pub seeds: Vec<u64>,
    /// Posture groups of the training contacts.
    pub postures: usize,
    /// Training contacts cross-validated.
    pub contacts: usize,
    /// One row per candidate.
    pub rows: Vec<ContactCvRow>,
    /// The chosen row.
    pub chosen: Option<usize>,
    /// The rule's reference row.
    pub reference: Option<usize>,
    /// The rule.
    pub rule: &'static str,
    /// Why.
    pub reason: String,
}

/// `base` (the full geometry's problem) as `spec`'s: joint zero offsets appended to the
/// model, the free robot parameters of the level (less `patterns`' freezes), the tracker's
/// registration parameters found again in the new layout.
pub fn candidate_problem(
    tree: &KinematicTree,
    base: &ContactProblem,
    spec: ContactModelSpec,
    patterns: &ParameterPatterns,
) -> Result<ContactProblem> {
    let mut problem = base.clone();
    problem.model = offsets_model(base.model.clone(), spec.offsets)?;
    problem.robot_free = robot_free(tree, &problem.model, spec.offsets, patterns)?;
    let (old, new) = (
        base.model.parameter_layout(),
        problem.model.parameter_layout(),
    );
    problem.registration_free = base
        .registration_free
        .iter()
        .filter_map(|&k| new.iter().position(|entry| *entry == old[k]))
        .collect();
    Ok(problem)
}

/// Fits `problem` as `spec` says: without the prior, or with the default prior (σ's times
/// `prior_scale`) divided by the residual scale of the fit without it when that is above 1,
/// so that the prior weighs against the data as it would if the declared σ's were right.
pub fn fit_candidate(
    problem: &ContactProblem,
    options: &IdentificationOptions,
    spec: ContactModelSpec,
    prior_scale: f64,
) -> Result<ContactFit> {
    let plain = fit_contacts(problem, options)?;
    if !spec.prior {
        return Ok(plain);
    }
    let residual = plain.after.residual_scale;
    let scale = if residual.is_finite() {
        residual.max(1.0)
    } else {
        1.0
    };
    let nominal = problem.model.parameters();
    let prior = Prior::default_for(&problem.model, &nominal).scaled(prior_scale / scale);
    let with_prior = IdentificationOptions {
        prior: Some(prior),
        ..options.clone()
    };
    fit_contacts(problem, &with_prior)
}

/// What the cross-validation works on.
pub struct ContactCvInput<'a> {
    /// The robot.
    pub tree: &'a KinematicTree,
    /// The full geometry's problem (every training row: contacts, then tracker rows).
    pub base: &'a ContactProblem,
    /// `freeze` / `free`.
    pub patterns: &'a ParameterPatterns,
    /// The identification options (the setup's σ's).
    pub options: &'a IdentificationOptions,
    /// The prior's σ factor.
    pub prior_scale: f64,
}

/// Cross-validates [`CONTACT_CANDIDATES`] over `k` folds of the training contacts' postures,
/// repeated with `repeats` fold assignments (seeds `seed` …); tracker rows stay in every
/// training set. Errors when there are fewer posture groups than folds.
pub fn cross_validate_contacts(
    input: &ContactCvInput<'_>,
    k: usize,
    repeats: usize,
    seed: u64,
) -> Result<ContactCv> {
    let contacts: Vec<usize> = (0..input.base.training.len())
        .filter(|&i| matches!(input.base.training[i].observation, Observation::Contact(_)))
        .collect();
    let rows: Vec<Measurement> = contacts
        .iter()
        .map(|&i| input.base.training[i].clone())
        .collect();
    let groups = posture_groups(&rows);
    let k = k.max(2);
    if groups.len() < k {
        return Err(Error::InvalidSetting {
            setting: "cv".into(),
            message: format!(
                "{} contact postures cannot fill {k} folds; give more contacts or fewer folds",
                groups.len()
            ),
        });
    }
    let seeds: Vec<u64> = (0..repeats.max(1) as u64)
        .map(|r| seed.wrapping_add(r))
        .collect();
    let folds: Vec<Vec<usize>> = seeds
        .iter()
        .flat_map(|&s| grouped_folds(&rows, k, s))
        .filter(|fold| !fold.is_empty())
        .collect();
    let evaluated: Vec<Evaluated> = CONTACT_CANDIDATES
        .par_iter()
        .map(|&spec| evaluate(input, spec, &contacts, &folds))
        .collect::<Result<_>>()?;
    let mut cv = ContactCv {
        folds: k,
        seeds,
        postures: groups.len(),
        contacts: rows.len(),
        rows: Vec::new(),
        chosen: None,
        reference: None,
        rule: CONTACT_RULE,
        reason: String::new(),
    };
    choose(&mut cv, evaluated, &groups);
    Ok(cv)
}

/// Each held-out contact with its violation (m and rad).
type Violations = Vec<(Contact, Vec<f64>)>;

/// One candidate over every fold: its row and each contact's held-out squared error (mean
/// over its equations, in σ², averaged over the repetitions).
struct Evaluated {
    row: ContactCvRow,
    errors: Vec<Option<f64>>,
}

/// Squares and counts of held-out values of one kind.
#[derive(Default, Clone, Copy)]
struct Sum {
    squares: f64,
    count: usize,
}

impl Sum {
    fn add(&mut self, value: f64) {
        self.squares += value * value;
        self.count += 1;
    }
    fn rms(self) -> Option<f64> {
        (self.count > 0).then(|| (self.squares / self.count as f64).sqrt())
    }
}

fn evaluate(
    input: &ContactCvInput<'_>,
    spec: ContactModelSpec,
    contacts: &[usize],
    folds: &[Vec<usize>],
) -> Result<Evaluated> {
    let problem = candidate_problem(input.tree, input.base, spec, input.patterns)?;
    let mut row = ContactCvRow {
        model: spec.name(),
        spec,
        parameters: problem.robot_free.len(),
        rms_sigma: None,
        height_rms_mm: None,
        tilt_rms_deg: None,
        pair_rms_mm: None,
        difference_sigma: None,
        difference_se_sigma: None,
        error: None,
    };
    let outcomes: Vec<Result<Violations>> = folds
        .par_iter()
        .map(|fold| held_out_violations(input, &problem, spec, contacts, fold))
        .collect();
    let noise = input.options.noise();
    let mut squares = vec![(0.0, 0usize); contacts.len()];
    let mut sums = [Sum::default(); 4];
    for (fold, outcome) in folds.iter().zip(outcomes) {
        let violations = match outcome {
            Ok(violations) => violations,
            Err(error) => {
                row.error = Some(error.to_string());
                return Ok(Evaluated {
                    row,
                    errors: vec![None; contacts.len()],
                });
            }
        };
        for (&i, (contact, values)) in fold.iter().zip(violations) {
            let mut whitened = 0.0;
            for (value, &kind) in values.iter().zip(contact.row_kinds()) {
                let scaled = value / noise.sigma(kind);
                whitened += scaled * scaled;
                sums[0].add(scaled);
                sums[summary_of(kind)].add(*value);
            }
            squares[i].0 += whitened / values.len() as f64;
            squares[i].1 += 1;
        }
    }
    let errors: Vec<Option<f64>> = squares
        .iter()
        .map(|(s, n)| (*n > 0).then(|| s / *n as f64))
        .collect();
    row.rms_sigma = sums[0].rms();
    row.height_rms_mm = sums[1].rms().map(|v| v * 1e3);
    row.tilt_rms_deg = sums[2].rms().map(f64::to_degrees);
    row.pair_rms_mm = sums[3].rms().map(|v| v * 1e3);
    Ok(Evaluated { row, errors })
}

/// The held-out contacts of `fold` (indices among `contacts`) scored under the fit of the
/// other training rows.
fn held_out_violations(
    input: &ContactCvInput<'_>,
    problem: &ContactProblem,
    spec: ContactModelSpec,
    contacts: &[usize],
    fold: &[usize],
) -> Result<Violations> {
    let held: Vec<usize> = fold.iter().map(|&i| contacts[i]).collect();
    let mut train = problem.clone();
    train.training = (0..problem.training.len())
        .filter(|i| held.binary_search(i).is_err())
        .map(|i| problem.training[i].clone())
        .collect();
    let fit = fit_candidate(&train, input.options, spec, input.prior_scale)?;
    let rows: Vec<Measurement> = held.iter().map(|&i| problem.training[i].clone()).collect();
    contact_violations(
        &problem.model,
        &fit.after.parameters,
        &fit.after.nuisance,
        &rows,
    )
}

/// Where a row of `kind` is summed for the table: 1 heights, 2 tilts, 3 gaps and bar lengths
/// (0 is every row over its σ).
fn summary_of(kind: RowKind) -> usize {
    match kind {
        RowKind::Height => 1,
        RowKind::Tilt => 2,
        _ => 3,
    }
}

/// The rule over `evaluated`: differences to the reference (geometry+prior, else the lowest
/// that ran), the lowest significantly lower candidate chosen, else the reference.
fn choose(cv: &mut ContactCv, evaluated: Vec<Evaluated>, groups: &[Vec<usize>]) {
    let group_sums = |e: &Evaluated| -> Option<Vec<f64>> {
        e.row.rms_sigma?;
        groups
            .iter()
            .map(|g| g.iter().map(|&i| e.errors[i]).sum::<Option<f64>>())
            .collect()
    };
    let sums: Vec<Option<Vec<f64>>> = evaluated.iter().map(group_sums).collect();
    let rms = |i: usize| evaluated[i].row.rms_sigma.unwrap_or(f64::INFINITY);
    let ran: Vec<usize> = (0..evaluated.len())
        .filter(|&i| sums[i].is_some())
        .collect();
    let lowest =
        |it: &mut dyn Iterator<Item = usize>| it.min_by(|&a, &b| rms(a).total_cmp(&rms(b)));
    let reference = Some(CONTACT_CANDIDATES.len() - 1)
        .filter(|&r| sums[r].is_some())
        .or_else(|| lowest(&mut ran.iter().copied()));
    let n = cv.contacts;
    let compare = |a: usize, b: usize| {
        paired(
            sums[a].as_deref().unwrap_or(&[]),
            sums[b].as_deref().unwrap_or(&[]),
            n,
        )
    };
    let mut rows: Vec<ContactCvRow> = evaluated.iter().map(|e| e.row.clone()).collect();
    let Some(best) = reference else {
        cv.reason = "no candidate ran on every fold".into();
        cv.rows = rows;
        return;
    };
    for &i in &ran {
        rows[i].difference_sigma = Some(rms(i) - rms(best));
        // rms_i − rms_ref = ΔMSE / (rms_i + rms_ref): the same scale for its SE.
        rows[i].difference_se_sigma =
            (i != best).then(|| compare(i, best).se / (rms(i) + rms(best)).max(1e-300));
    }
    let significant: Vec<usize> = ran
        .iter()
        .copied()
        .filter(|&i| i != best && compare(best, i).t() >= SIGNIFICANT_T)
        .collect();
    let chosen = lowest(&mut significant.iter().copied()).unwrap_or(best);
    cv.reason = if chosen == best {
        format!(
            "'{}' is the reference ({:.3} σ held-out RMS) and no candidate is significantly lower (paired t ≥ {SIGNIFICANT_T} over {} postures)",
            rows[best].model,
            rms(best),
            groups.len()
        )
    } else {
        format!(
            "'{}' is significantly lower than the reference '{}' ({:.3} σ against {:.3} σ held-out RMS, paired t = {:.2} over {} postures)",
            rows[chosen].model,
            rows[best].model,
            rms(chosen),
            rms(best),
            compare(best, chosen).t(),
            groups.len()
        )
    };
    cv.rows = rows;
    cv.chosen = Some(chosen);
    cv.reference = Some(best);
}

/// The table in Markdown (report.md).
pub fn contact_cv_markdown(cv: &ContactCv) -> String {
    let cell =
        |v: Option<f64>, digits: usize| v.map_or("—".to_owned(), |v| format!("{v:.digits$}"));
    let mut text = format!(
        "\n## Model choice (cross-validation)\n\n{} folds over {} contact postures ({} contacts; a repeated posture stays in one fold), {} fold assignment(s) (seeds {}); each held-out contact scored under the fit of the other folds (the robot and each session's plane), each equation over its kind's σ. Rule: {}.\n\n| model | free robot parameters | held-out RMS (σ) | height RMS (mm) | tilt RMS (°) | gap / bar RMS (mm) | − reference ± SE (σ) |\n| --- | --- | --- | --- | --- | --- | --- |\n",
        cv.folds,
        cv.postures,
        cv.contacts,
        cv.seeds.len(),
        cv.seeds
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(", "),
        cv.rule
    );
    for (i, row) in cv.rows.iter().enumerate() {
        let mut name = row.model.to_owned();
        if cv.chosen == Some(i) {
            name.push_str(" **(chosen)**");
        }
        if cv.reference == Some(i) {
            name.push_str(" (reference)");
        }
        let difference = match (row.difference_sigma, row.difference_se_sigma) {
            (Some(d), Some(se)) => format!("{d:+.3} ± {se:.3}"),
            (Some(_), None) => "0".to_owned(),
            _ => row.error.clone().unwrap_or_else(|| "—".to_owned()),
        };
        text.push_str(&format!(
            "| {name} | {} | {} | {} | {} | {} | {difference} |\n",
            row.parameters,
            cell(row.rms_sigma, 3),
            cell(row.height_rms_mm, 2),
            cell(row.tilt_rms_deg, 3),
            cell(row.pair_rms_mm, 2),
        ));
    }
    text.push_str(&format!("\n{}.\n", cv.reason));
    text
}

/// The folds of a contact cross-validation: `k` (`cv`; `None`: 5 when the data choose, no
/// table otherwise), fold assignments (0: 3) and the seed.
#[derive(Debug, Clone, Copy)]
pub struct ContactFolds {
    /// Folds.
    pub k: Option<usize>,
    /// Fold assignments.
    pub repeats: usize,
    /// The first assignment's seed.
    pub seed: u64,
}

/// The model of a contact calibration ([`choose_contact_model`]).
pub struct ContactModelChoice {
    /// The model.
    pub spec: ContactModelSpec,
    /// The cross-validation, when one ran.
    pub cv: Option<ContactCv>,
    /// The fit of `spec` on the base problem when the choice needed it already (`Adaptive`
    /// keeping the full geometry): the same fit the caller would make.
    pub fit: Option<ContactFit>,
}

/// The model of a contact calibration and, when one ran, its cross-validation: `model` as
/// asked (offsets or geometry, with the prior when `prior`), `auto` by the rule, `Adaptive`
/// the full geometry unless its fit's σ̂ exceeds [`CONTACT_ADAPTIVE_SIGMA`]. A
/// cross-validation that cannot run (too few postures) keeps the full geometry, with a note.
pub fn choose_contact_model(
    input: &ContactCvInput<'_>,
    model: ModelChoice,
    prior: bool,
    folds: ContactFolds,
    notes: &mut Vec<Note>,
) -> Result<ContactModelChoice> {
    let asked = |offsets: bool| ContactModelSpec { offsets, prior };
    let repeats = if folds.repeats == 0 {
        REPEATS
    } else {
        folds.repeats
    };
    let run = |k: usize| cross_validate_contacts(input, k, repeats, folds.seed);
    let kept = |spec, fit| -> Result<ContactModelChoice> {
        let cv = folds.k.map(run).transpose()?;
        Ok(ContactModelChoice { spec, cv, fit })
    };
    match model {
        ModelChoice::Level(level) => return kept(asked(level == ModelLevel::Offsets), None),
        ModelChoice::Auto => {}
        ModelChoice::Adaptive => {
            let fit = fit_candidate(input.base, input.options, asked(false), input.prior_scale)?;
            let scale = fit.after.residual_scale;
            if !(scale.is_finite() && scale > CONTACT_ADAPTIVE_SIGMA) {
                return kept(asked(false), Some(fit));
            }
            notes.push(Note::info(format!(
                "model choice: the geometry fit leaves residuals {scale:.1}× the setup's σ's (over {CONTACT_ADAPTIVE_SIGMA}): the model is chosen by cross-validation (`model` geometry keeps the full geometry)"
            )));
        }
    }
    let (spec, cv) = match run(folds.k.unwrap_or(DEFAULT_FOLDS)) {
        Ok(cv) => {
            let spec = cv.chosen.map_or(asked(false), |i| cv.rows[i].spec);
            notes.push(Note::info(format!(
                "model choice (contacts): '{}' ({})",
                spec.name(),
                cv.reason
            )));
            (spec, Some(cv))
        }
        Err(error) => {
            notes.push(Note::warning(format!(
                "model choice (contacts): no cross-validation ({error}); the full geometry is fitted"
            )));
            (asked(false), None)
        }
    };
    Ok(ContactModelChoice {
        spec,
        cv,
        fit: None,
    })
}

/// report.md's lines on the model: which, and the cross-validation table when one ran.
pub fn model_markdown(spec: ContactModelSpec, cv: Option<&ContactCv>) -> String {
    let what = if spec.offsets {
        "joint zero offsets"
    } else {
        "every joint frame's four parameters"
    };
    let prior = if spec.prior {
        ", with the default prior on the nominal values (its σ's divided by the residual scale of the fit without it)"
    } else {
        ""
    };
    let mut text = format!("\nModel: '{}' ({what}{prior}).\n", spec.name());
    if let Some(cv) = cv {
        text.push_str(&contact_cv_markdown(cv));
    }
    text
}
