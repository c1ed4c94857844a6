//! The last streamed products over one measurement slice, kept so that a refit whose robust
//! weights changed on a few measurements updates them instead of a pass over every row.
//!
//! Robust estimation (`calibration::robust`) refits a large problem from the previous fit's
//! solution with new weights. The products at that model differ from the ones the previous
//! fit ended with only in the measurements whose weight changed (at 10⁶ configurations a few
//! hundred of 1.6·10⁶, and the final fit without the outliers changes only theirs): with
//! `Δwᵢ = wᵢ' − wᵢ` and the σ-weighted `Jᵢ`, `rᵢ` of measurement `i`,
//!
//! `JᵀW'J = JᵀWJ + Σ Δwᵢ JᵢᵀJᵢ`, `JᵀW'r = JᵀWr + Σ Δwᵢ Jᵢᵀrᵢ`, `½rᵀW'r = ½rᵀWr + Σ Δwᵢ ½‖rᵢ‖²`,
//!
//! the same sums as a pass in another order (equal to round-off). The memo serves only the
//! slice it was made for (borrowed for its whole life, so no other allocation can be mistaken
//! for it), only problems without flexibility offsets, and only the same free parameters,
//! noise model and parameter values, bit for bit.

use super::super::linearise::linearise;
use super::{NormalEquations, Problem, Products};
use crate::calibration::observation::{Noise, Nuisance};
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::measurement::Measurement;
use rayon::prelude::*;
use std::sync::Mutex;

/// Above this fraction of changed measurements a pass is taken instead of an update.
const MAX_CHANGED_FRACTION: f64 = 0.05;

/// The products of the last pass (or update) over [`Self`]'s measurement slice.
pub(crate) struct ProductsMemo<'m> {
    measurements: &'m [Measurement],
    last: Mutex<Option<Entry>>,
}

/// What one pass computed, and at what.
struct Entry {
    /// The model's parameters, then the nuisance values.
    values: Vec<f64>,
    free: Vec<usize>,
    noise: Noise,
    /// The observation weights used (empty: every weight 1).
    weights: Vec<f64>,
    /// `JᵀWJ`, `JᵀWr`, `½rᵀWr` (no prior, no factor).
    products: NormalEquations,
}

impl<'m> ProductsMemo<'m> {
    /// An empty memo for the problems over `measurements`.
    pub(crate) fn new(measurements: &'m [Measurement]) -> Self {
        Self {
            measurements,
            last: Mutex::new(None),
        }
    }

    /// Whether `problem` is over this memo's slice (the same rows, not equal ones) and has no
    /// offsets.
    fn serves(&self, problem: &Problem<'_>) -> bool {
        std::ptr::eq(self.measurements, problem.measurements) && problem.offsets.is_none()
    }

    /// The products of `problem` at `model` and `nuisance` (without the prior) by updating
    /// the last ones, when they were taken at the same values with weights that differ on few
    /// measurements; `None` when a pass is needed.
    pub(super) fn updated(
        &self,
        model: &McpcModel,
        nuisance: &Nuisance,
        problem: &Problem<'_>,
        products: Products,
    ) -> Option<Result<NormalEquations>> {
        if products != Products::Normal || !self.serves(problem) {
            return None;
        }
        let last = self.last.lock().ok()?;
        let entry = last.as_ref()?;
        let options = problem.options;
        if entry.free != problem.free
            || entry.noise != options.noise()
            || entry.values != values_of(model, nuisance)
        {
            return None;
        }
        let weight = |weights: &[f64], i: usize| weights.get(i).copied().unwrap_or(1.0);
        let changed: Vec<(usize, f64)> = (0..problem.measurements.len())
            .filter_map(|i| {
                let change = weight(&options.observation_weights, i) - weight(&entry.weights, i);
                (change != 0.0).then_some((i, change))
            })
            .collect();
        if changed.len() as f64 > MAX_CHANGED_FRACTION * problem.measurements.len() as f64 {
            return None;
        }
        Some(updated_products(
            &entry.products,
            model,
            nuisance,
            problem,
            &changed,
        ))
    }

    /// Keeps `products` (without the prior) of `problem` at `model` and `nuisance`.
    pub(super) fn record(
        &self,
        model: &McpcModel,
        nuisance: &Nuisance,
        problem: &Problem<'_>,
        products: &NormalEquations,
    ) {
        if !self.serves(problem) || products.normal.is_empty() {
            return;
        }
        if let Ok(mut last) = self.last.lock() {
            *last = Some(Entry {
                values: values_of(model, nuisance),
                free: problem.free.to_vec(),
                noise: problem.options.noise(),
                weights: problem.options.observation_weights.clone(),
                products: NormalEquations {
                    factor: None,
                    ..products.clone()
                },
            });
        }
    }
}

fn values_of(model: &McpcModel, nuisance: &Nuisance) -> Vec<f64> {
    let mut values = model.parameters();
    values.extend(nuisance.values());
    values
}

/// `previous` plus `Δwᵢ·(JᵢᵀJᵢ, Jᵢᵀrᵢ, ½‖rᵢ‖²)` of each changed measurement `(i, Δwᵢ)`, with
/// `Jᵢ`, `rᵢ` weighted by the noise only; added in measurement order.
fn updated_products(
    previous: &NormalEquations,
    model: &McpcModel,
    nuisance: &Nuisance,
    problem: &Problem<'_>,
    changed: &[(usize, f64)],
) -> Result<NormalEquations> {
    // The options without observation weights: every weight 1.
    let unit = problem.options.for_range(0..0);
    let parts: Vec<Result<NormalEquations>> = changed
        .par_iter()
        .map(|&(i, change)| {
            let lin = linearise(
                model,
                nuisance,
                &problem.measurements[i..i + 1],
                None,
                problem.predictor,
                problem.free,
                &unit,
                true,
            )?;
            Ok(NormalEquations {
                normal: lin.jacobian.tr_mul(&lin.jacobian) * change,
                gradient: lin.jacobian.tr_mul(&lin.residual) * change,
                cost: 0.5 * lin.residual.norm_squared() * change,
                factor: None,
            })
        })
        .collect();
    let mut total = previous.clone();
    for part in parts {
        total.add(part?);
    }
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::super::accumulate;
    use super::*;
    use crate::calibration::options::IdentificationOptions;
    use crate::calibration::predictor::Rigid;
    use crate::calibration::test_problems::{problem, robonaut, with_noise};
    use nalgebra::{DMatrix, Vector6};

    fn relative(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (a - b).amax() / b.amax()
    }

    fn weighted(count: usize, changed: &[(usize, f64)]) -> IdentificationOptions {
        let mut weights = vec![1.0; count];
        for &(i, w) in changed {
            weights[i] = w;
        }
        IdentificationOptions {
            observation_weights: weights,
            ..Default::default()
        }
    }

    /// Products recorded at one set of weights and updated to another equal a pass at the
    /// new weights (to round-off), down-weighted and left-out rows included.
    #[test]
    fn an_update_equals_a_pass() {
        let robot = robonaut();
        let model = &robot.0;
        let measurements = with_noise(problem(&robot, 300, true), [2e-4, 2e-3]);
        let free: Vec<usize> = (0..model.parameter_count()).collect();
        let memo = ProductsMemo::new(&measurements);
        let problem_with = |options: &'_ IdentificationOptions| -> NormalEquations {
            let problem = Problem {
                measurements: &measurements,
                offsets: None,
                predictor: &Rigid,
                free: &free,
                options,
                prior: None,
                memo: Some(&memo),
            };
            accumulate(model, &problem, Products::Normal).expect("products")
        };
        let before = weighted(measurements.len(), &[(3, 0.5), (40, 0.25)]);
        problem_with(&before);
        let after = weighted(
            measurements.len(),
            &[(3, 0.7), (40, 0.25), (77, 0.0), (101, 0.4)],
        );
        let serving = Problem {
            measurements: &measurements,
            offsets: None,
            predictor: &Rigid,
            free: &free,
            options: &after,
            prior: None,
            memo: Some(&memo),
        };
        assert!(memo
            .updated(model, Nuisance::none(), &serving, Products::Normal)
            .is_some());
        let updated = problem_with(&after);
        let pass = accumulate(
            model,
            &Problem {
                memo: None,
                ..serving
            },
            Products::Normal,
        )
        .expect("pass");
        assert!(relative(&updated.normal, &pass.normal) < 1e-12);
        assert!((&updated.gradient - &pass.gradient).amax() < 1e-12 * pass.gradient.amax());
        assert!((updated.cost - pass.cost).abs() < 1e-12 * pass.cost);
    }

    /// A pass, not an update, whenever the memo cannot vouch for the products: other values
    /// (by one ulp), other rows equal to its own, offsets, another free set or noise model,
    /// too many changed weights, or products it does not keep.
    #[test]
    fn a_pass_when_the_products_may_differ() {
        let robot = robonaut();
        let model = &robot.0;
        let measurements = problem(&robot, 120, true);
        let count = measurements.len();
        let free: Vec<usize> = (0..model.parameter_count()).collect();
        let memo = ProductsMemo::new(&measurements);
        let options = weighted(count, &[]);
        let base = Problem {
            measurements: &measurements,
            offsets: None,
            predictor: &Rigid,
            free: &free,
            options: &options,
            prior: None,
            memo: Some(&memo),
        };
        accumulate(model, &base, Products::Normal).expect("products");
        let serves = |model: &McpcModel, problem: &Problem<'_>, products: Products| {
            memo.updated(model, Nuisance::none(), problem, products)
                .is_some()
        };
        assert!(serves(model, &base, Products::Normal));
        assert!(!serves(model, &base, Products::Cost));
        assert!(!serves(model, &base, Products::NormalAndFactor));
        let mut moved = model.clone();
        let mut values = moved.parameters();
        values[5] = f64::from_bits(values[5].to_bits() + 1);
        moved.set_parameters(&values).expect("parameters");
        assert!(!serves(&moved, &base, Products::Normal));
        let copy = measurements.clone();
        assert!(!serves(
            model,
            &Problem {
                measurements: &copy,
                ..base
            },
            Products::Normal
        ));
        let offsets = vec![Vector6::zeros(); count];
        assert!(!serves(
            model,
            &Problem {
                offsets: Some(&offsets),
                ..base
            },
            Products::Normal
        ));
        let fewer: Vec<usize> = free[1..].to_vec();
        assert!(!serves(
            model,
            &Problem {
                free: &fewer,
                ..base
            },
            Products::Normal
        ));
        let noisier = IdentificationOptions {
            position_sigma: 2e-4,
            ..options.clone()
        };
        assert!(!serves(
            model,
            &Problem {
                options: &noisier,
                ..base
            },
            Products::Normal
        ));
        let many: Vec<(usize, f64)> = (0..count / 10).map(|i| (i, 0.5)).collect();
        let reweighted = weighted(count, &many);
        assert!(!serves(
            model,
            &Problem {
                options: &reweighted,
                ..base
            },
            Products::Normal
        ));
    }

    /// A large problem's refit from the previous solution with a few weights changed (a
    /// robust round) takes its first products from the memo and ends where a refit with a
    /// pass ends: the same parameters, standard deviations and cost to round-off.
    #[test]
    fn a_refit_from_the_memo_ends_where_a_refit_with_a_pass_ends() {
        use crate::calibration::coarse_to_fine::CoarseToFine;
        use crate::calibration::solver::identify_coarse_to_fine;

        let robot = robonaut();
        let model = &robot.0;
        let measurements = with_noise(problem(&robot, 1500, true), [2e-4, 2e-3]);
        let count = measurements.len();
        let free: Vec<usize> = (0..model.parameter_count()).collect();
        let thresholds = CoarseToFine {
            above_rows: 1000,
            coarse_rows: 400,
        };
        let fit = |start: &McpcModel, options: &IdentificationOptions, memo| {
            identify_coarse_to_fine(
                (start, Nuisance::none()),
                (&measurements, None),
                &Rigid,
                &free,
                options,
                thresholds,
                memo,
            )
            .expect("identification")
        };
        let first_options = IdentificationOptions {
            position_sigma: 2e-4,
            rotation_sigma: 2e-3,
            ..weighted(count, &[])
        };
        let plain = fit(model, &first_options, None);
        let mut solved = model.clone();
        solved
            .set_parameters(&plain.parameters)
            .expect("parameters");
        // At the solution, with its weights: a pass, recorded.
        let memo = ProductsMemo::new(&measurements);
        let warm = IdentificationOptions {
            warm_start: true,
            ..first_options.clone()
        };
        let settled = fit(&solved, &warm, Some(&memo));
        assert_eq!(settled.iterations, 0);
        let reweighted = IdentificationOptions {
            warm_start: true,
            observation_weights: weighted(count, &[(9, 0.0), (500, 0.3), (2222, 0.8)])
                .observation_weights,
            ..first_options.clone()
        };
        let serving = Problem {
            measurements: &measurements,
            offsets: None,
            predictor: &Rigid,
            free: &free,
            options: &reweighted,
            prior: None,
            memo: None,
        };
        assert!(memo
            .updated(&solved, Nuisance::none(), &serving, Products::Normal)
            .is_some());
        let from_memo = fit(&solved, &reweighted, Some(&memo));
        let from_pass = fit(&solved, &reweighted, None);
        assert_eq!(from_memo.iterations, from_pass.iterations);
        let (a, b) = (from_memo.costs.last(), from_pass.costs.last());
        let (a, b) = (a.copied().unwrap_or(0.0), b.copied().unwrap_or(0.0));
        assert!((a - b).abs() <= 1e-12 * b, "cost {a} vs {b}");
        for (k, &p) in free.iter().enumerate() {
            let sd = from_pass.standard_deviations[k];
            let difference = (from_memo.parameters[p] - from_pass.parameters[p]).abs();
            assert!(
                difference <= 1e-6 * sd,
                "parameter {p}: {difference} vs σ {sd}"
            );
            let sd_difference = (from_memo.standard_deviations[k] - sd).abs();
            assert!(
                sd_difference <= 1e-9 * sd,
                "σ of {p}: {sd_difference} vs {sd}"
            );
        }
    }
}
