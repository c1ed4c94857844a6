//! The choice of the cross-validation: the full geometry is the reference, replaced only by a
//! candidate significantly lower over the paired per-posture differences of held-out errors
//! (docs/identification.md, "Repeated folds and the choice").

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

/// A candidate replaces the reference when its paired t statistic over the posture groups
/// ([`paired`]: the reference's mean squared held-out error minus the candidate's, over its
/// standard error) reaches this (a one-sided test at about 2.5 %). The identified stiffness
/// changes what is shipped (a rigid-only URDF and a compensation file), so it must also beat
/// the lowest significant rigid candidate by as much.
pub const SIGNIFICANT_T: f64 = 2.0;

/// How a candidate is chosen (report.md, report.json `model_choice.rule`).
pub const RULE: &str = "the full geometry with the prior on the nominal values (the paper's model; without the prior when it is not a candidate) is the reference; a candidate replaces it only when significantly lower in held-out RMS (paired t ≥ 2 over the postures), and among those the lowest wins; the identified stiffness only when also significantly lower than the lowest significant rigid candidate; a forward step only when significantly lower than the model it extends, its t corrected for the number of joint terms offered (Bonferroni)";

/// The t a forward step must reach when `offered` one-joint extensions compete for it: the
/// one-sided 2.5 % test corrected for the multiple comparison (Bonferroni, `1 − 0.025/offered`
/// quantile of the normal distribution), never below [`SIGNIFICANT_T`]. With 11 offers (a
/// 7-joint arm's harmonics and 4 backlash joints) 2.84: a rigid robot's noise passes 2.0 in
/// about one of four runs somewhere among 11 offers.
pub fn step_threshold(offered: usize) -> f64 {
    normal_quantile_upper(0.025 / offered.max(1) as f64).max(SIGNIFICANT_T)
}

/// The `z` with `P(Z > z) = p` for a standard normal `Z`, `0 < p ≤ 0.5` (Abramowitz & Stegun
/// 26.2.23, error below 4.5e-4).
fn normal_quantile_upper(p: f64) -> f64 {
    let t = (-2.0 * p.clamp(1e-300, 0.5).ln()).sqrt();
    t - (2.515517 + 0.802853 * t + 0.010328 * t * t)
        / (1.0 + 1.432788 * t + 0.189269 * t * t + 0.001308 * t * t * t)
}

/// The reference of the [`RULE`] in `specs`: the full geometry with the prior on the nominal
/// values (the paper's model, its weakly determined parameters held near the URDF), else the
/// plain full geometry; neither selection, joint terms, estimated noise nor identified
/// stiffness.
pub fn reference_of<'a>(specs: impl IntoIterator<Item = &'a ModelSpec> + Clone) -> Option<usize> {
    let full = |s: &ModelSpec, prior: bool| {
        s.level == crate::workflow::ModelLevel::Geometry
            && s.prior == prior
            && !(s.harmonics || s.backlash || s.identify_stiffness || s.estimate_noise)
            && s.significant.is_none()
    };
    specs
        .clone()
        .into_iter()
        .position(|s| full(s, true))
        .or_else(|| specs.into_iter().position(|s| full(s, false)))
}

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

/// The [`RULE`] over the rows `pool`: sets each row's difference to `reference` (the lowest
/// row when `reference` is `None` or did not run) and its standard error, and returns the
/// lowest row of `pool` significantly lower than the reference (else the reference) and, when
/// the identified stiffness was that row but not significantly lower than the lowest
/// significant rigid one, why it was not taken.
pub(super) fn choose(
    evaluated: &mut [Evaluated],
    kept: &[usize],
    group_of: &[usize],
    reference: Option<usize>,
    pool: &[usize],
    threshold: f64,
) -> Choice {
    let sums = group_sums(evaluated, kept, group_of);
    let values: Vec<f64> = evaluated
        .iter()
        .map(|e| e.row.choice_rms_mm.unwrap_or(f64::INFINITY))
        .collect();
    let rms = |i: usize| values[i];
    let ran: Vec<usize> = (0..evaluated.len())
        .filter(|&i| sums[i].is_some())
        .collect();
    let lowest =
        |rows: &mut dyn Iterator<Item = usize>| rows.min_by(|&a, &b| rms(a).total_cmp(&rms(b)));
    let Some(best) = reference
        .filter(|&r| sums[r].is_some())
        .or_else(|| lowest(&mut ran.iter().copied()))
    else {
        return Choice {
            chosen: None,
            best: None,
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
    for &i in &ran {
        let row = &mut evaluated[i].row;
        let (value, reference_rms) = (values[i], values[best]);
        row.difference_mm = Some(value - reference_rms);
        // rms_i − rms_ref = ΔMSE / (rms_i + rms_ref): the same scale for its SE.
        row.difference_se_mm =
            (i != best).then(|| compare(i, best).se * 1e6 / (value + reference_rms));
    }
    let significant: Vec<usize> = pool
        .iter()
        .copied()
        .filter(|&i| i != best && sums[i].is_some())
        .filter(|&i| compare(best, i).t() >= threshold)
        .collect();
    let stiffness = |i: usize| evaluated[i].row.spec.identify_stiffness;
    let Some(winner) = lowest(&mut significant.iter().copied()) else {
        return Choice {
            chosen: Some(best),
            best: Some(best),
            doubt: None,
        };
    };
    let rigid = lowest(&mut significant.iter().copied().filter(|&i| !stiffness(i)));
    let mut doubt = None;
    let chosen = match rigid.filter(|_| stiffness(winner)) {
        Some(rigid) if compare(rigid, winner).t() < SIGNIFICANT_T => {
            doubt = Some(format!(
                "; '{}' was lower, but not significantly lower than '{}' over the postures (paired t = {:.2} < {SIGNIFICANT_T}), and it would ship the URDF with a compensation file",
                evaluated[winner].row.model,
                evaluated[rigid].row.model,
                compare(rigid, winner).t()
            ));
            rigid
        }
        _ => winner,
    };
    Choice {
        chosen: Some(chosen),
        best: Some(best),
        doubt,
    }
}

/// Per candidate, the sums of squared held-out errors per posture group with a kept row
/// (`None` for a candidate that did not run on every fold).
fn group_sums(
    evaluated: &[Evaluated],
    kept: &[usize],
    group_of: &[usize],
) -> Vec<Option<Vec<f64>>> {
    let groups = group_of.iter().max().map_or(0, |g| g + 1);
    let mut used = vec![false; groups];
    for &i in kept {
        used[group_of[i]] = true;
    }
    evaluated
        .iter()
        .map(|e| {
            e.row.choice_rms_mm?;
            let mut sum = vec![0.0; groups];
            for &i in kept {
                sum[group_of[i]] += e.errors[i]? * e.errors[i]?;
            }
            Some((0..groups).filter(|&g| used[g]).map(|g| sum[g]).collect())
        })
        .collect()
}

/// One candidate over every fold: its row, each measurement's held-out error, and per
/// measurement how many training fits used it and how many flagged it as an outlier.
pub(super) struct Evaluated {
    pub(super) row: CvRow,
    pub(super) errors: Vec<Option<f64>>,
    pub(super) flags: Vec<[usize; 2]>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_step_threshold_is_the_corrected_normal_quantile() {
        assert!((normal_quantile_upper(0.025) - 1.960).abs() < 1e-3);
        assert!((normal_quantile_upper(0.025 / 11.0) - 2.836).abs() < 2e-3);
        assert_eq!(step_threshold(1), SIGNIFICANT_T);
        assert!(step_threshold(20) > step_threshold(11));
    }
}
