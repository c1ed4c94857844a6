//! Iterative identification (paper eq. (26)–(29)), made robust: the Levenberg–Marquardt loop
//! of one stage and what it found.
//!
//! Each iteration linearises the weighted residuals `r = W·(measured ⊖ predicted − D_f)`
//! (`linearise`, through the observation seam) around the current parameters, scales the
//! Jacobian's columns to unit norm (so millimetres and radians are comparable), and takes the
//! minimum-norm Gauss–Newton step through the SVD (`linear_algebra`), keeping only singular
//! values above `rank_tolerance · σ_max`: combinations of parameters the data cannot determine
//! are reported and left where they started (at their nominal values). When the Gauss–Newton
//! step does not reduce the cost, the step is damped (Levenberg–Marquardt) until it does. Not
//! converging is an outcome in the report, not an error. See `docs/identification.md`.
//!
//! The predictors, the options, the linearisation, the linear algebra, the analysis of one
//! iteration and the report live in files of their own (`predictor`, `options`, `linearise`,
//! `linear_algebra`, `solver_analysis`, `solver_report`); they are re-exported here under their
//! former paths.

use super::coarse_to_fine::CoarseToFine;
use super::linearise::{residual_rms, rows_of};
use super::normal_equations::{accumulate_with, NormalEquations, Problem, Products, ProductsMemo};
use super::observation::{kind_of, Nuisance};
use super::solver_analysis::{analyse, unscaled_inverse, Analysis};
pub(crate) use super::solver_report::combination;
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::measurement::Measurement;
use nalgebra::{DMatrix, DVector, Vector6};
use rayon::prelude::*;

pub use super::linearise::{weighted_jacobian, weighted_residual};
pub use super::options::IdentificationOptions;
pub use super::predictor::{
    Deflected, DeflectedWithDerivative, Predictor, Rigid, CORRECTION_RADIUS,
};
pub use super::solver_report::{
    Combination, IdentificationReport, Termination, IDENTIFIABLE_NULL_WEIGHT,
};

/// Identifies the `free` parameters of `model` from `measurements`.
///
/// `offsets`, if given, holds one predicted flexibility error per measurement (eq. (26): the
/// residual is `measured ⊖ predicted − D_f`); `predictor` is how the model predicts the tool
/// poses (rigid FK, or a deflected FK). Errors only for inputs that make no sense (a tool
/// index out of range, a configuration of the wrong size, non-finite values, too few rows).
pub fn identify(
    model: &McpcModel,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<IdentificationReport> {
    identify_with_nuisance(
        model,
        Nuisance::none(),
        measurements,
        offsets,
        predictor,
        free,
        options,
    )
}

/// [`identify`] with nuisance parameters of the measurement kinds (contacts' planes,
/// contact points, bar lengths): the solver's parameter vector is the model's parameters
/// followed by `nuisance`'s values, and `free` indexes it (free or fixed like the model's
/// parameters). The report's `parameters` are the model's, its `nuisance` the fitted values.
pub fn identify_with_nuisance(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<IdentificationReport> {
    identify_coarse_to_fine(
        (model, nuisance),
        (measurements, offsets),
        predictor,
        free,
        options,
        CoarseToFine::DEFAULT,
        None,
    )
}

/// [`identify`] with the last products over `measurements` kept in `memo` (a robust loop's
/// refits): a refit at the same parameters whose weights changed on few measurements updates
/// them instead of a pass over every row.
pub(crate) fn identify_reusing(
    model: &McpcModel,
    (measurements, offsets): (&[Measurement], Option<&[Vector6<f64>]>),
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
    memo: Option<&ProductsMemo<'_>>,
) -> Result<IdentificationReport> {
    identify_coarse_to_fine(
        (model, Nuisance::none()),
        (measurements, offsets),
        predictor,
        free,
        options,
        CoarseToFine::DEFAULT,
        memo,
    )
}

/// [`identify_with_nuisance`] with the thresholds of the coarse-to-fine start given (tests
/// lower them) and the memo of [`identify_reusing`].
pub(crate) fn identify_coarse_to_fine(
    (model, nuisance): (&McpcModel, &Nuisance),
    (measurements, offsets): (&[Measurement], Option<&[Vector6<f64>]>),
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
    thresholds: CoarseToFine,
    memo: Option<&ProductsMemo<'_>>,
) -> Result<IdentificationReport> {
    validate(model, nuisance, measurements, offsets, free, options)?;
    let prior_rows = if nuisance.is_empty() {
        prior_rows(model, measurements, offsets, predictor, free, options)?
    } else {
        // A prior that follows the residual scale refits without it: not with nuisance.
        options
            .prior
            .as_ref()
            .map(|prior| prior.rows(free, 1.0))
            .filter(|rows| rows.count() > 0)
    };
    // JᵀWJ and JᵀWr streamed over the configurations (`normal_equations`), with the triangle
    // R of J too once a problem has proved rank-deficient.
    let problem = Problem {
        measurements,
        offsets,
        predictor,
        free,
        options,
        prior: prior_rows.as_ref(),
        memo,
    };
    let descent = match thresholds.subsample(measurements) {
        // A large problem started at the previous solution: every row from there.
        Some(_) if nuisance.is_empty() && options.warm_start => {
            descend(model, nuisance, &problem, Stop::Predicted)?
        }
        Some(selected) if nuisance.is_empty() => {
            descend_from_subsample(model, nuisance, &problem, &selected)?
        }
        _ => descend(model, nuisance, &problem, Stop::Evaluated)?,
    };
    summarise(descent, &problem)
}

/// The descent over every row of `problem`, started where the descent over the rows
/// `selected` (an evenly spread subsample, [`CoarseToFine`]) converged from `model`: the same
/// full-data solution, reached with most iterations paid on the subsample. The report counts
/// the iterations of both; its costs are the full-data ones.
fn descend_from_subsample(
    model: &McpcModel,
    nuisance: &Nuisance,
    problem: &Problem<'_>,
    selected: &[usize],
) -> Result<Descent> {
    let coarse = {
        let measurements: Vec<Measurement> = selected
            .iter()
            .map(|&i| problem.measurements[i].clone())
            .collect();
        let offsets: Option<Vec<Vector6<f64>>> = problem
            .offsets
            .map(|offsets| selected.iter().map(|&i| offsets[i]).collect());
        let options = problem.options.for_measurements(selected);
        // The prior weighs against a fraction of the data: scaled alike, the subsample's
        // optimum is near the full one.
        let fraction = selected.len() as f64 / problem.measurements.len() as f64;
        let prior = problem.prior.map(|prior| prior.scaled(fraction));
        let subsample = Problem {
            measurements: &measurements,
            offsets: offsets.as_deref(),
            options: &options,
            prior: prior.as_ref(),
            memo: None,
            ..*problem
        };
        descend(model, nuisance, &subsample, Stop::Evaluated)?
    };
    let mut fine = descend(&coarse.model, &coarse.nuisance, problem, Stop::Predicted)?;
    fine.iterations += coarse.iterations;
    Ok(fine)
}

/// Where the Levenberg–Marquardt iteration ended.
struct Descent {
    /// The model at the solution.
    model: McpcModel,
    /// The nuisance parameters at the solution.
    nuisance: Nuisance,
    /// Its parameters.
    parameters: Vec<f64>,
    /// Cost before the first and after each accepted iteration.
    costs: Vec<f64>,
    /// Accepted iterations.
    iterations: usize,
    /// Why it stopped.
    termination: Termination,
    /// The analysis of the linearisation at the solution, when the loop ended with a valid one.
    analysis: Option<Analysis>,
    /// The latest products.
    lin: NormalEquations,
}

/// How [`descend`] may stop besides its step and cost tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stop {
    /// Only on evaluated steps (every problem that is not large).
    Evaluated,
    /// Also before evaluating a step whose predicted effect is negligible
    /// ([`NEGLIGIBLE_STEP`]): a large problem's passes over every row are dear, and near the
    /// solution a step a thousandth of a standard deviation long lowers the cost by less than
    /// its rounding over millions of rows, so evaluating it cannot accept it.
    Predicted,
}

/// A Gauss–Newton step is negligible when its length in the parameters' standard deviations
/// (`δᵀ N δ / σ̂²`, with `σ̂² = 2·cost / (equations − unknowns)`) is below this.
const NEGLIGIBLE_STEP: f64 = 1e-3;

/// Whether the full step `full_step` (scaled units, with the scaled gradient `gradient` of
/// the linearisation) is negligible ([`NEGLIGIBLE_STEP`]) at `cost` over `equations` rows.
fn negligible_step(
    full_step: &DVector<f64>,
    gradient: &DVector<f64>,
    cost: f64,
    equations: usize,
) -> bool {
    let unknowns = full_step.len();
    if equations <= unknowns || cost.is_nan() || cost <= 0.0 {
        return false;
    }
    // δ = N⁻¹g, so δᵀNδ = δᵀg: twice the decrease the linearisation predicts.
    let squared_length = full_step.dot(gradient);
    let variance = 2.0 * cost / (equations - unknowns) as f64;
    squared_length <= NEGLIGIBLE_STEP * NEGLIGIBLE_STEP * variance
}

/// The damped Gauss–Newton iteration from `model` (eq. (27)–(29)): minimum-norm steps over
/// the retained singular directions, damped (Levenberg–Marquardt) until the cost decreases.
fn descend(
    model: &McpcModel,
    nuisance: &Nuisance,
    problem: &Problem<'_>,
    stop: Stop,
) -> Result<Descent> {
    let (free, options) = (problem.free, problem.options);
    let mut current = model.clone();
    let mut current_nuisance = nuisance.clone();
    let mut parameters = current.parameters();
    parameters.extend(nuisance.values());
    let mut lin = accumulate_with(&current, &current_nuisance, problem, Products::Normal)?;
    let mut cost = lin.cost;
    let mut costs = vec![cost];
    let mut damping = 0.0;
    let mut iterations = 0;
    let mut termination = Termination::MaxIterations;
    // The analysis of the linearisation at `current` once the loop ends, if still valid.
    let mut final_analysis: Option<Analysis> = None;
    let equations = match stop {
        Stop::Predicted => rows_of(problem.measurements),
        Stop::Evaluated => 0,
    };

    while iterations < options.max_iterations {
        // An SVD of a non-finite matrix never ends: stop with an error instead. The normal
        // matrix's diagonal holds the squared column norms, so it is finite exactly when the
        // weighted Jacobian is and no square overflows (e.g. a tiny sigma); the cost likewise.
        crate::limits::ensure_finite(
            lin.normal
                .iter()
                .chain(lin.gradient.iter())
                .chain(std::iter::once(&lin.cost)),
            "identification: the weighted Jacobian and residual",
        )?;
        let analysis = analyse(&mut lin, options.rank_tolerance, || {
            accumulate_with(
                &current,
                &current_nuisance,
                problem,
                Products::NormalAndFactor,
            )
        })?;
        // Converged when the full Gauss–Newton step is negligible against the parameters.
        let scaled_parameters = free
            .iter()
            .zip(analysis.scales.iter())
            .map(|(&p, s)| (parameters[p] * s).powi(2))
            .sum::<f64>()
            .sqrt();
        // The undamped step, also the first trial below (one Cholesky factorisation, not two).
        let full_step = damped_step(&analysis, options.rank_tolerance, 0.0);
        if full_step.norm() <= options.step_tolerance * (1.0 + scaled_parameters)
            || (stop == Stop::Predicted
                && negligible_step(&full_step, &analysis.gradient, cost, equations))
        {
            termination = Termination::StepConverged;
            final_analysis = Some(analysis);
            break;
        }
        // A large problem's undamped step is nearly always taken: its trial computes the
        // products the next iteration needs, in place of a cost-only pass and then a pass.
        let trial_products = match (stop, lin.factor.is_some()) {
            (Stop::Predicted, false) => Products::Normal,
            _ => Products::Cost,
        };
        let Some(accepted) = first_decrease(
            (&current, &current_nuisance),
            &parameters,
            problem,
            (&analysis, &full_step, trial_products),
            cost,
            &mut damping,
        )?
        else {
            termination = Termination::NoDecrease;
            final_analysis = Some(analysis);
            break;
        };
        let previous = cost;
        current = accepted.model;
        current_nuisance = accepted.nuisance;
        parameters = accepted.parameters;
        cost = accepted.cost;
        costs.push(cost);
        iterations += 1;
        damping *= 0.1;
        if previous - cost <= options.cost_tolerance * previous {
            // The last step was negligible: the analysis before it describes the solution
            // (rank, singular values) as well as a new one would, at half the cost.
            termination = Termination::CostConverged;
            final_analysis = Some(analysis);
            break;
        }
        let products = if lin.factor.is_some() {
            Products::NormalAndFactor
        } else {
            Products::Normal
        };
        lin = match accepted.products {
            Some(at_trial) => at_trial,
            None => accumulate_with(&current, &current_nuisance, problem, products)?,
        };
    }
    parameters.truncate(current.parameter_count());
    Ok(Descent {
        model: current,
        nuisance: current_nuisance,
        parameters,
        costs,
        iterations,
        termination,
        analysis: final_analysis,
        lin,
    })
}

/// The minimum-norm (damped) Gauss–Newton step in scaled units over the retained singular
/// directions: `Σ vᵢ (vᵢᵀ g) / (σᵢ² + λ)`, with `g = J_sᵀ r`; by Cholesky of `N + λI` when the
/// scaled normal matrix is well conditioned (the same step).
fn damped_step(analysis: &Analysis, rank_tolerance: f64, damping: f64) -> DVector<f64> {
    let columns = analysis.scales.len();
    if let (0.0, Some(factor)) = (damping, &analysis.cholesky) {
        // The factor that proved the matrix well conditioned: `N + 0·I` is `N`.
        return factor.cholesky.solve(&analysis.gradient);
    }
    if let Some(normal) = &analysis.normal {
        let damped = normal + DMatrix::identity(columns, columns) * damping;
        if let Some(cholesky) = damped.cholesky() {
            return cholesky.solve(&analysis.gradient);
        }
    }
    let singular_values = analysis.singular_values();
    let sigma_max = singular_values.iter().copied().fold(0.0, f64::max);
    let threshold = rank_tolerance * sigma_max;
    let mut step = DVector::zeros(columns);
    for (i, &sigma) in singular_values.iter().enumerate() {
        if sigma > threshold {
            let v = analysis.v_t.row(i).transpose();
            let along = v.dot(&analysis.gradient) / (sigma * sigma + damping);
            step += v * along;
        }
    }
    step
}

/// A step [`first_decrease`] took.
struct Accepted {
    model: McpcModel,
    nuisance: Nuisance,
    /// The model's parameters, then the nuisance values.
    parameters: Vec<f64>,
    cost: f64,
    /// The products there, when the trial computed them.
    products: Option<NormalEquations>,
}

/// The first of up to 40 ever more damped steps from `current` that lowers the cost below
/// `cost`; `None` when none does. The undamped step (`full_step`) is tried with
/// `first_products` (the cost only, or the products the next iteration needs), the damped
/// ones with the cost only. `damping` is left where the accepted step was taken (or where
/// the attempts gave up).
fn first_decrease(
    (current, nuisance): (&McpcModel, &Nuisance),
    parameters: &[f64],
    problem: &Problem<'_>,
    (analysis, full_step, first_products): (&Analysis, &DVector<f64>, Products),
    cost: f64,
    damping: &mut f64,
) -> Result<Option<Accepted>> {
    let count = current.parameter_count();
    // Only a rejected step needs σ_max (the first damping): the eigenvalues wait until then.
    let sigma_max = || {
        analysis
            .singular_values()
            .iter()
            .copied()
            .fold(0.0, f64::max)
    };
    for _attempt in 0..40 {
        let step_scaled = if *damping == 0.0 {
            full_step.clone()
        } else {
            damped_step(analysis, problem.options.rank_tolerance, *damping)
        };
        let step: DVector<f64> = step_scaled.component_div(&analysis.scales);
        let mut trial = parameters.to_vec();
        for (k, &p) in problem.free.iter().enumerate() {
            trial[p] += step[k];
        }
        let mut candidate = current.clone();
        candidate.set_parameters(&trial[..count])?;
        let mut candidate_nuisance = nuisance.clone();
        candidate_nuisance.set_values(&trial[count..])?;
        let products = if *damping == 0.0 {
            first_products
        } else {
            Products::Cost
        };
        let at_trial = accumulate_with(&candidate, &candidate_nuisance, problem, products)?;
        if at_trial.cost < cost {
            return Ok(Some(Accepted {
                model: candidate,
                nuisance: candidate_nuisance,
                parameters: trial,
                cost: at_trial.cost,
                products: (products != Products::Cost).then_some(at_trial),
            }));
        }
        *damping = if *damping == 0.0 {
            1e-6 * sigma_max() * sigma_max()
        } else {
            *damping * 10.0
        };
    }
    Ok(None)
}

/// The report at the solution: rank, singular values, unidentifiable combinations, residual
/// RMS, the a-posteriori scale σ̂ and the covariance on the identifiable subspace.
fn summarise(descent: Descent, problem: &Problem<'_>) -> Result<IdentificationReport> {
    let (free, options, measurements) = (problem.free, problem.options, problem.measurements);
    let Descent {
        model: current,
        nuisance,
        parameters,
        costs,
        iterations,
        termination,
        analysis,
        mut lin,
    } = descent;
    let cost = costs.last().copied().unwrap_or(lin.cost);
    // Identifiability at the solution.
    let analysis = match analysis {
        Some(analysis) => analysis,
        None => analyse(&mut lin, options.rank_tolerance, || {
            accumulate_with(&current, &nuisance, problem, Products::NormalAndFactor)
        })?,
    };
    let all = analysis.singular_values();
    let mut order: Vec<usize> = (0..all.len()).collect();
    order.sort_by(|&a, &b| all[b].total_cmp(&all[a]));
    let singular_values: Vec<f64> = order.iter().map(|&i| all[i]).collect();
    let sigma_max = singular_values.first().copied().unwrap_or(0.0);
    let threshold = options.rank_tolerance * sigma_max;
    let rank = singular_values.iter().filter(|&&s| s > threshold).count();
    let condition_number = match singular_values.get(rank.saturating_sub(1)) {
        Some(&smallest) if rank > 0 && smallest > 0.0 => sigma_max / smallest,
        _ => f64::INFINITY,
    };
    // Null-space directions: the rows of Vᵀ for the small singular values.
    let unidentifiable = order[rank..]
        .iter()
        .map(|&i| {
            combination(
                &analysis
                    .v_t
                    .row(i)
                    .transpose()
                    .component_div(&analysis.scales),
                free,
            )
        })
        .collect();
    let (residual_rms_position, residual_rms_rotation) = residual_rms(
        &current,
        &nuisance,
        measurements,
        problem.offsets,
        problem.predictor,
        options,
    )?;
    // A-posteriori scale of the assumed σ's.
    // Rows of measurements left out (weight 0, robust estimation) carry no information.
    let rows = rows_of(measurements)
        - measurements
            .iter()
            .zip(&options.observation_weights)
            .filter(|(_, &w)| w == 0.0)
            .map(|(m, _)| m.observation.rows())
            .sum::<usize>()
        + problem.prior.map_or(0, |p| p.count());
    let residual_scale = if rows > rank {
        (2.0 * cost / (rows - rank) as f64).sqrt()
    } else {
        f64::NAN
    };
    let unscaled_inverse = unscaled_inverse(&analysis, &order[..rank]);
    let covariance = residual_scale
        .is_finite()
        .then(|| &unscaled_inverse * residual_scale.powi(2));
    let standard_deviations = (0..free.len())
        .map(|k| residual_scale * unscaled_inverse[(k, k)].max(0.0).sqrt())
        .collect();
    let identifiable = (0..free.len())
        .map(|k| {
            let null: f64 = order[rank..]
                .iter()
                .map(|&i| analysis.v_t[(i, k)].powi(2))
                .sum();
            null.sqrt() < IDENTIFIABLE_NULL_WEIGHT
        })
        .collect();
    Ok(IdentificationReport {
        covariance,
        residual_scale,
        standard_deviations,
        identifiable,
        parameters,
        nuisance,
        free: free.to_vec(),
        iterations,
        costs,
        termination,
        rows,
        rank,
        singular_values,
        condition_number,
        unidentifiable,
        residual_rms_position,
        residual_rms_rotation,
    })
}

/// The prior's rows over `free`, if the options have a prior; with `follow_residual_scale`,
/// weighted by the residual scale σ̂ (when above 1) of the same fit without the prior, so that
/// the prior weighs against the data as if the declared noise were right.
fn prior_rows(
    model: &McpcModel,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<Option<super::prior::PriorRows>> {
    let Some(prior) = &options.prior else {
        return Ok(None);
    };
    let rows = prior.rows(free, 1.0);
    if rows.count() == 0 {
        return Ok(None);
    }
    let scale = if prior.follow_residual_scale {
        let plain = IdentificationOptions {
            prior: None,
            ..options.clone()
        };
        let report = identify(model, measurements, offsets, predictor, free, &plain)?;
        let scale = report.residual_scale;
        if scale.is_finite() {
            scale.max(1.0)
        } else {
            1.0
        }
    } else {
        1.0
    };
    Ok(Some(prior.rows(free, scale)))
}

fn validate(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<()> {
    let bad = |message: String| Error::InvalidData {
        origin: "identification".into(),
        message,
    };
    if measurements.is_empty() {
        return Err(bad("no measurements".into()));
    }
    if free.is_empty() {
        return Err(bad(
            "nothing to fit: every parameter and nuisance value is held (free some, e.g. a plane or the bar length of the contact setup)".into(),
        ));
    }
    if !options.noise().is_valid() {
        return Err(bad(
            "position_sigma and rotation_sigma must be positive".into()
        ));
    }
    let count = model.parameter_count() + nuisance.len();
    if let Some(&p) = free.iter().find(|&&p| p >= count) {
        return Err(bad(format!(
            "free parameter {p} does not exist (the model and its nuisance have {count})"
        )));
    }
    let observation_weights = &options.observation_weights;
    if !observation_weights.is_empty() && observation_weights.len() != measurements.len() {
        return Err(bad(format!(
            "{} observation weights for {} measurements",
            observation_weights.len(),
            measurements.len()
        )));
    }
    if let Some(w) = observation_weights
        .iter()
        .find(|w| !(w.is_finite() && **w >= 0.0))
    {
        return Err(bad(format!(
            "observation weight {w} is not a non-negative number"
        )));
    }
    if let Some(offsets) = offsets {
        if offsets.len() != measurements.len() {
            return Err(bad(format!(
                "{} flexibility offsets for {} measurements",
                offsets.len(),
                measurements.len()
            )));
        }
    }
    let tools = model.tools().len();
    let problem = |(index, m): (usize, &Measurement)| {
        let second = match &m.observation {
            crate::measurement::Observation::Contact(contact) => contact.second_tool(),
            _ => None,
        };
        if let Some(tool) = second.filter(|&t| t >= tools) {
            return Some(format!(
                "measurement {index} names a second tool {tool} of {tools}"
            ));
        }
        if m.tool >= tools {
            return Some(format!(
                "measurement {index} names tool {} of {tools}",
                m.tool
            ));
        }
        let finite = m.q.iter().all(|v| v.is_finite()) && kind_of(&m.observation).is_finite();
        (!finite).then(|| format!("measurement {index} has a non-finite value"))
    };
    // In parallel (a serial scan at every fit of 10⁶ configurations); the first wrong
    // measurement is named, as a scan in order would.
    if let Some(message) = measurements.par_iter().enumerate().find_map_first(problem) {
        return Err(bad(message));
    }
    Ok(())
}
