//! Which compliances the data determine (greedy elimination on the Schur complement after
//! the geometry), and the compliance part of the identifiability analysis.

use super::names::{describe, name, DETERMINED, GROUPS, GROUP_NAMES};
use super::problem::{Linearisation, Problem};
use crate::calibration::linear_algebra::{
    certainly_conditioned, cholesky, column_scales, scale_columns,
};
use crate::calibration::options::IdentificationOptions;
use crate::error::Result;
use crate::kinematics::ComplianceParameter;
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::measurement::Measurement;
use crate::tree::KinematicTree;
use nalgebra::DMatrix;
use serde::Serialize;

/// Which compliances the data determine, and how well.
pub(super) struct Selection {
    /// Indices of the identified compliance parameters.
    pub(super) chosen: Vec<usize>,
    /// Per parameter: how well the data determine its scale with the geometry free (and the
    /// other chosen compliances free), infinite when not at all.
    pub(super) data_std_dev: Vec<f64>,
    /// Null directions met on the way, as (parameter, weight) lists.
    pub(super) combinations: Vec<Vec<(usize, f64)>>,
}

/// Greedy elimination on the compliance information left after the geometry has taken its
/// share (the Schur complement): drop a parameter of an exact null direction first, else the
/// least determined one, until all left are determined to better than `prior_sigma`. Uses the
/// assumed σ's (the rows are weighted by them), not the residuals: the choice does not depend
/// on the noise realised.
pub(super) fn select(
    lin: &Linearisation,
    geometry: usize,
    parameters: &[ComplianceParameter],
    prior_sigma: f64,
    options: &IdentificationOptions,
) -> Selection {
    let compliance_count = lin.jacobian.ncols() - geometry;
    let individual = compliance_count - GROUPS;
    let geometric = lin.jacobian.columns(0, geometry).into_owned();
    let compliance = lin
        .jacobian
        .columns(geometry, compliance_count)
        .into_owned();
    // An orthonormal basis of what the geometry can explain.
    let basis = if geometry > 0 {
        let scaled = scale_columns(&geometric, &column_scales(&geometric));
        let svd = scaled.svd(true, false);
        let largest = svd.singular_values.max();
        match svd.u {
            Some(u) => {
                let kept: Vec<usize> = (0..svd.singular_values.len())
                    .filter(|&i| svd.singular_values[i] > options.rank_tolerance * largest)
                    .collect();
                DMatrix::from_fn(u.nrows(), kept.len(), |r, c| u[(r, kept[c])])
            }
            None => DMatrix::zeros(lin.jacobian.nrows(), 0),
        }
    } else {
        DMatrix::zeros(lin.jacobian.nrows(), 0)
    };
    let left = &compliance - &basis * basis.tr_mul(&compliance);
    let largest_column = compliance
        .column_iter()
        .map(|c| c.norm())
        .fold(0.0, f64::max);
    let mut data_std_dev = vec![f64::INFINITY; compliance_count];
    let mut chosen: Vec<usize> = (0..compliance_count)
        .filter(|&k| compliance.column(k).norm() > 1e-12 * largest_column && largest_column > 0.0)
        .collect();
    let mut combinations = Vec::new();
    // Every entry of a product `Aᵀ·A` is one column's dot product with another, so the
    // information of any subset is the subset of this (the same bits, computed once).
    let gram = left.tr_mul(&left);
    while !chosen.is_empty() {
        let information = DMatrix::from_fn(chosen.len(), chosen.len(), |a, b| {
            gram[(chosen[a], chosen[b])]
        });
        // Most steps are proved full rank by a Cholesky factor (the one inverted below) and
        // two bounds, without the eigen-decomposition: the same decision.
        let factor = certainly_conditioned(&information, 1e-12);
        if factor.is_none() {
            let eigen = information.clone().symmetric_eigen();
            let (smallest, largest) = (eigen.eigenvalues.min(), eigen.eigenvalues.max());
            if largest <= 0.0 || smallest <= 1e-12 * largest {
                let index = eigen.eigenvalues.imin();
                let direction = eigen.eigenvectors.column(index);
                let peak = direction.amax();
                let mut terms: Vec<(usize, f64)> = direction
                    .iter()
                    .enumerate()
                    .filter(|(_, w)| w.abs() >= 0.1 * peak)
                    .map(|(c, &w)| (chosen[c], w))
                    .collect();
                terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
                // A group only goes when its members cannot.
                let worst = terms
                    .iter()
                    .map(|t| t.0)
                    .find(|&k| k < individual)
                    .unwrap_or(terms[0].0);
                if terms.len() > 1 {
                    combinations.push(terms);
                }
                chosen.retain(|&c| c != worst);
                continue;
            }
        }
        // The proved factor's inverse: the same bits as `Cholesky::inverse`, half the work.
        let inverse = match factor {
            Some(factor) => factor.inverse(),
            // nalgebra's factor, bit for bit (`linear_algebra::cholesky`).
            None => match cholesky(information) {
                Some(cholesky) => cholesky.inverse(),
                None => break,
            },
        };
        let dropped = drop_worst(
            &inverse,
            parameters,
            individual,
            prior_sigma,
            &mut chosen,
            &mut data_std_dev,
        );
        if !dropped {
            break;
        }
    }
    chosen.sort_unstable();
    Selection {
        chosen,
        data_std_dev,
        combinations,
    }
}

/// Records the deviations of the `chosen` scales from the inverse of their information and
/// drops the least determined one (see [`select`]); `false` when all are determined.
fn drop_worst(
    inverse: &DMatrix<f64>,
    parameters: &[ComplianceParameter],
    individual: usize,
    prior_sigma: f64,
    chosen: &mut Vec<usize>,
    data_std_dev: &mut [f64],
) -> bool {
    let deviations: Vec<f64> = (0..chosen.len())
        .map(|c| inverse[(c, c)].max(0.0).sqrt())
        .collect();
    for (c, &k) in chosen.iter().enumerate() {
        data_std_dev[k] = deviations[c];
    }
    // The least determined individual compliance goes first. Then, while a group is not
    // determined, its least determined member goes (the common scale matters more than
    // one member's deviation from it), and the group itself only when it has none left.
    let group_of = |c: usize| usize::from(!parameters[chosen[c]].kind.is_joint());
    let worst = |keep: &dyn Fn(usize) -> bool, limit: f64| {
        deviations
            .iter()
            .enumerate()
            .filter(|(c, _)| keep(*c))
            .max_by(|a, b| a.1.total_cmp(b.1))
            .filter(|(_, &d)| d > limit)
            .map(|(c, _)| c)
    };
    let limit = prior_sigma * DETERMINED;
    let undetermined_group = worst(&|c| chosen[c] >= individual, limit);
    let drop = worst(&|c| chosen[c] < individual, limit).or_else(|| {
        let group = chosen[undetermined_group?] - individual;
        worst(&|c| chosen[c] < individual && group_of(c) == group, 0.0).or(undetermined_group)
    });
    match drop {
        Some(c) => {
            chosen.remove(c);
            true
        }
        None => false,
    }
}

/// What a set of measurements (their configurations, tools and payloads; the observed values
/// do not matter) can determine of the compliances, with the geometric parameters `free`:
/// the identifiability analysis of the compliance parameters, before measuring.
#[derive(Debug, Clone, Serialize)]
pub struct ComplianceIdentifiability {
    /// Per compliance parameter: its name, how well the data determine its scale (relative,
    /// infinite: not at all), and whether it would be identified (JSON: an object per
    /// parameter with `name`, `relative_std_dev` (`null`: infinite) and `identified`).
    #[serde(serialize_with = "compliance_parameters_json")]
    pub parameters: Vec<(String, f64, bool)>,
    /// Combinations the data cannot tell apart from the geometry or each other, in words.
    pub unidentifiable: Vec<String>,
}

fn compliance_parameters_json<S: serde::Serializer>(
    parameters: &[(String, f64, bool)],
    serializer: S,
) -> std::result::Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Parameter<'a> {
        name: &'a str,
        relative_std_dev: Option<f64>,
        identified: bool,
    }
    serializer.collect_seq(parameters.iter().map(|(name, sd, identified)| Parameter {
        name,
        relative_std_dev: sd.is_finite().then_some(*sd),
        identified: *identified,
    }))
}

/// The compliance part of the identifiability analysis at `model` (see
/// [`ComplianceIdentifiability`]).
#[allow(clippy::too_many_arguments)]
pub fn analyse_compliance(
    tree: &KinematicTree,
    model: &McpcModel,
    prior: &FlexibilityModel,
    measurements: &[Measurement],
    payloads: Option<&[f64]>,
    free: &[usize],
    options: &IdentificationOptions,
    prior_sigma: f64,
) -> Result<ComplianceIdentifiability> {
    let problem = Problem::new(tree, prior, measurements, payloads, free, options)?;
    let count = problem.parameters().len() + GROUPS;
    let all: Vec<usize> = (0..count).collect();
    let lin = problem.linearise(model, &vec![1.0; count], &all, &[], true)?;
    let selection = select(&lin, free.len(), problem.parameters(), prior_sigma, options);
    Ok(ComplianceIdentifiability {
        parameters: (0..count)
            .map(|k| {
                let name = match problem.parameters().get(k) {
                    Some(p) => name(tree, model, p),
                    None => GROUP_NAMES[k - problem.parameters().len()].to_owned(),
                };
                (
                    name,
                    selection.data_std_dev[k],
                    selection.chosen.contains(&k),
                )
            })
            .collect(),
        unidentifiable: selection
            .combinations
            .iter()
            .map(|c| describe(tree, model, problem.parameters(), c))
            .collect(),
    })
}
