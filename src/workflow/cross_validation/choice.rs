//! The choice of the cross-validation: the one-standard-error rule over the paired
//! per-posture differences of held-out errors (docs/identification.md, "Repeated folds and
//! the one-standard-error rule").

use crate::workflow::ModelSpec;

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
    /// ([`super::CrossValidation::left_out_of_choice`]): what the choice compares (mm).
    pub choice_rms_mm: Option<f64>,
    /// The largest held-out position error (mm).
    pub max_mm: Option<f64>,
    /// `choice_rms_mm` minus the reference's ([`super::CrossValidation::best`]), mm.
    pub difference_mm: Option<f64>,
    /// The standard error of that difference from the paired per-posture differences of
    /// squared held-out errors ([`paired`]), mm; `None` for the reference itself.
    pub difference_se_mm: Option<f64>,
    /// Why a fold failed, if one did.
    pub error: Option<String>,
}

/// The identified-stiffness candidate changes what is shipped (a rigid-only URDF and a
/// compensation file), so it must beat the best other candidate by this many standard errors
/// of the paired difference of squared held-out errors over the postures ([`paired`]; a
/// one-sided test at about 2.5 %).
pub const SIGNIFICANT_T: f64 = 2.0;

/// How a candidate is chosen (report.md, report.json `model_choice.rule`).
pub const RULE: &str = "one-standard-error rule: the simplest candidate whose held-out RMS is within one standard error of the lowest (standard errors of the paired per-posture differences; simpler = fewer free parameters, then a prior or the ≥ kσ selection before an unrestricted fit, then the table's order); the identified stiffness only when significantly lowest (paired t ≥ 2)";

/// The paired comparison of two candidates over the posture groups: the difference of their
/// mean squared held-out errors (m²) and its standard error, from the per-group sums `a`, `b`
/// of squared errors over `rows` rows (groups are the independent units: a posture's rows share
/// their fold).
#[derive(Debug, Clone, Copy)]
pub struct Paired {
    /// `MSE(a) − MSE(b)`.
    pub difference: f64,
    /// Its standard error.
    pub se: f64,
}

impl Paired {
    /// The t statistic `difference / se` (∞ with a positive difference and no spread).
    pub fn t(&self) -> f64 {
        if self.se > 0.0 {
            self.difference / self.se
        } else if self.difference > 0.0 {
            f64::INFINITY
        } else {
            0.0
        }
    }
}

/// [`Paired`] of per-group sums `a`, `b` (groups with no kept row are left out by the caller)
/// over `rows` kept rows: `ΔMSE = Σ_g d_g / n`, `se = √G · sd(d) / n`.
pub fn paired(a: &[f64], b: &[f64], rows: usize) -> Paired {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    let (g, n) = (d.len() as f64, rows.max(1) as f64);
    let mean = d.iter().sum::<f64>() / g.max(1.0);
    let variance = if d.len() < 2 {
        0.0
    } else {
        d.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (g - 1.0)
    };
    Paired {
        difference: g * mean / n,
        se: g.sqrt() * variance.sqrt() / n,
    }
}

/// The posture group of each of `rows` rows.
pub(super) fn group_index(groups: &[Vec<usize>], rows: usize) -> Vec<usize> {
    let mut index = vec![0; rows];
    for (g, group) in groups.iter().enumerate() {
        for &i in group {
            index[i] = g;
        }
    }
    index
}

/// What [`choose`] decided.
pub(super) struct Choice {
    pub(super) chosen: Option<usize>,
    pub(super) best: Option<usize>,
    pub(super) doubt: Option<String>,
}

/// The order of simplicity of a row: free parameters (an estimated noise ratio counts as one
/// more), then a prior or the ≥ kσ selection before an unrestricted fit, then the table's
/// order.
fn simplicity(row: &CvRow, index: usize) -> (usize, bool, usize) {
    let spec = &row.spec;
    (
        row.parameters + usize::from(spec.estimate_noise),
        !(spec.prior || spec.significant.is_some()),
        index,
    )
}

/// The [`RULE`]: sets each row's difference to the reference and its standard error, and
/// returns the chosen row, the reference and, when the identified stiffness was lowest but
/// not significantly, why it was not taken.
pub(super) fn choose(evaluated: &mut [Evaluated], kept: &[usize], group_of: &[usize]) -> Choice {
    // Per candidate, the sums of squared held-out errors per posture group with a kept row.
    let groups = group_of.iter().max().map_or(0, |g| g + 1);
    let mut used = vec![false; groups];
    for &i in kept {
        used[group_of[i]] = true;
    }
    let sums: Vec<Option<Vec<f64>>> = evaluated
        .iter()
        .map(|e| {
            e.row.choice_rms_mm?;
            let mut sum = vec![0.0; groups];
            for &i in kept {
                sum[group_of[i]] += e.errors[i]? * e.errors[i]?;
            }
            Some((0..groups).filter(|&g| used[g]).map(|g| sum[g]).collect())
        })
        .collect();
    let lowest = |rigid: bool| {
        (0..evaluated.len())
            .filter(|&i| sums[i].is_some())
            .filter(|&i| !(rigid && evaluated[i].row.spec.identify_stiffness))
            .min_by(|&a, &b| {
                let rms = |i: usize| evaluated[i].row.choice_rms_mm.unwrap_or(f64::INFINITY);
                rms(a).total_cmp(&rms(b))
            })
    };
    let (Some(overall), Some(rigid)) = (lowest(false), lowest(true)) else {
        return Choice {
            chosen: lowest(false),
            best: lowest(false),
            doubt: None,
        };
    };
    let compare = |a: usize, b: usize| {
        paired(
            sums[a].as_deref().unwrap_or(&[]),
            sums[b].as_deref().unwrap_or(&[]),
            kept.len(),
        )
    };
    let mut doubt = None;
    let best = if overall != rigid {
        let t = compare(rigid, overall).t();
        if t < SIGNIFICANT_T {
            doubt = Some(format!(
                "; '{}' was lower, but not significantly over the postures (paired t = {t:.2} < {SIGNIFICANT_T}), and it would ship the URDF with a compensation file",
                evaluated[overall].row.model
            ));
            rigid
        } else {
            overall
        }
    } else {
        overall
    };
    let reference = evaluated[best].row.choice_rms_mm.unwrap_or(f64::NAN);
    let mut within = Vec::new();
    for i in 0..evaluated.len() {
        let Some(rms) = evaluated[i].row.choice_rms_mm.filter(|_| sums[i].is_some()) else {
            continue;
        };
        let p = compare(i, best);
        let row = &mut evaluated[i].row;
        row.difference_mm = Some(rms - reference);
        if i != best {
            // rms_i − rms_best = ΔMSE / (rms_i + rms_best): the same scale for its SE.
            row.difference_se_mm = Some(p.se * 1e6 / (rms + reference));
        }
        let stiffness = row.spec.identify_stiffness && i != best;
        if i == best || (!stiffness && p.difference <= p.se) {
            within.push(i);
        }
    }
    let chosen = within
        .into_iter()
        .min_by_key(|&i| simplicity(&evaluated[i].row, i));
    Choice {
        chosen,
        best: Some(best),
        doubt,
    }
}

/// One candidate over every fold: its row, each measurement's held-out error, and per
/// measurement how many training fits used it and how many flagged it as an outlier.
pub(super) struct Evaluated {
    pub(super) row: CvRow,
    pub(super) errors: Vec<Option<f64>>,
    pub(super) flags: Vec<[usize; 2]>,
}
