//! The joint fit: Levenberg–Marquardt over the free geometry and the chosen compliance scales.
//!
//! The scales move additively: the deflections are linear in the compliances, so the fit is
//! nearly linear in them. (Over their logarithms, a step that overshot towards a small scale
//! could end on the plateau at `ln s → −∞`, where the cost no longer changes: at the default
//! prior σ 0.5 that held some 4 % of the scales near 0.) A scale may pass below zero while the
//! fit iterates; one that ends there is not physical and is rejected by the caller.

use super::covariance::covariance;
use super::problem::{Fit, Problem};
use super::GROUPS;
use crate::calibration::linear_algebra::{column_scales, scale_columns, singular_decomposition};
use crate::calibration::Termination;
use crate::error::Result;
use crate::kinematics::McpcModel;
use nalgebra::DVector;

impl Problem<'_> {
    /// The joint fit in two steps: the common scales (all joints, all links) with the geometry
    /// first, then every chosen scale from that geometry. Started from a geometry calibrated with a
    /// stiffness that is off everywhere, the individual scales alone can run into a wrong
    /// minimum (some to 0, some ×10) while the geometry still carries the common error.
    pub(super) fn fit(
        &self,
        start: &McpcModel,
        chosen: &[usize],
        max_iterations: usize,
    ) -> Result<Fit> {
        let count = self.parameters().len() + GROUPS;
        let ones = vec![1.0; count];
        let groups: Vec<usize> = chosen
            .iter()
            .copied()
            .filter(|&c| c >= self.parameters().len())
            .collect();
        if groups.is_empty() || groups.len() == chosen.len() {
            return self.fit_from(start, ones, chosen, max_iterations);
        }
        // The second step keeps only the geometry: the scales restart at the prior, so that
        // what the data leave undetermined stays there.
        let common = self.fit_from(start, ones.clone(), &groups, max_iterations)?;
        let mut fit = self.fit_from(&common.model, ones, chosen, max_iterations)?;
        fit.cost[0] = common.cost[0];
        fit.iterations += common.iterations;
        Ok(fit)
    }

    /// Levenberg–Marquardt over the free geometry and the compliance scales `chosen`, from `start` and `scales`, with SVD-truncated steps (directions the data
    /// cannot determine stay where they start).
    fn fit_from(
        &self,
        start: &McpcModel,
        scales: Vec<f64>,
        chosen: &[usize],
        max_iterations: usize,
    ) -> Result<Fit> {
        let mut model = start.clone();
        let mut scales = scales;
        let mut lin = self.linearise(&model, &scales, chosen, chosen, true)?;
        let mut cost = 0.5 * lin.residual.norm_squared();
        let initial_cost = cost;
        let mut damping = 0.0;
        let mut iterations = 0;
        let mut termination = Termination::MaxIterations;
        let tolerance = self.options.rank_tolerance;
        while iterations < max_iterations {
            let columns = column_scales(&lin.jacobian);
            let scaled = scale_columns(&lin.jacobian, &columns);
            let gradient = scaled.tr_mul(&lin.residual);
            let (singular, v_t) = singular_decomposition(scaled);
            let largest = singular.max();
            let step_for = |damping: f64| -> DVector<f64> {
                let mut step = DVector::zeros(columns.len());
                for (i, &sigma) in singular.iter().enumerate() {
                    if sigma > tolerance * largest {
                        let v = v_t.row(i).transpose();
                        step += &v * (v.dot(&gradient) / (sigma * sigma + damping));
                    }
                }
                step.component_div(&columns)
            };
            if step_for(0.0).component_mul(&columns).norm() <= 1e-12 * (1.0 + largest) {
                termination = Termination::StepConverged;
                break;
            }
            let mut accepted = None;
            for _ in 0..30 {
                let step = step_for(damping);
                let (trial_model, trial_scales) = self.moved(&model, &scales, chosen, &step)?;
                let trial_cost = match &trial_scales {
                    Some(s) => {
                        0.5 * self
                            .linearise(&trial_model, s, chosen, chosen, false)?
                            .residual
                            .norm_squared()
                    }
                    None => f64::INFINITY,
                };
                if trial_cost < cost {
                    accepted = Some((trial_model, trial_scales, trial_cost));
                    damping *= 0.1;
                    break;
                }
                damping = if damping == 0.0 {
                    1e-6 * largest * largest
                } else {
                    damping * 10.0
                };
            }
            let Some((trial_model, Some(trial_scales), trial_cost)) = accepted else {
                termination = Termination::NoDecrease;
                break;
            };
            let decrease = cost - trial_cost;
            model = trial_model;
            scales = trial_scales;
            cost = trial_cost;
            iterations += 1;
            lin = self.linearise(&model, &scales, chosen, chosen, true)?;
            if decrease <= 1e-12 * cost.max(f64::MIN_POSITIVE) || cost < 1e-24 {
                termination = Termination::CostConverged;
                break;
            }
        }
        let (rank, residual_scale, factor) = covariance(&lin, cost, tolerance);
        let factor = factor.rows(self.free.len(), chosen.len()).into_owned();
        Ok(Fit {
            model,
            scales,
            cost: [initial_cost, cost],
            iterations,
            termination,
            rank,
            residual_scale,
            factor,
        })
    }

    /// The model and scales after `step`, both additive: the geometry, the groups' scales, and
    /// the chosen individual scales' effective scales (their own times their group's, which the
    /// group's step does not move); `None` scales if one is not finite.
    fn moved(
        &self,
        model: &McpcModel,
        scales: &[f64],
        chosen: &[usize],
        step: &DVector<f64>,
    ) -> Result<(McpcModel, Option<Vec<f64>>)> {
        let mut values = model.parameters();
        for (k, &p) in self.free.iter().enumerate() {
            values[p] += step[k];
        }
        let mut moved = model.clone();
        moved.set_parameters(&values)?;
        let count = self.parameters().len();
        let mut next = scales.to_vec();
        for (k, &c) in chosen.iter().enumerate() {
            if c >= count {
                next[c] += step[self.free.len() + k];
            }
        }
        for (k, &c) in chosen.iter().enumerate() {
            if let Some(parameter) = self.parameters().get(c) {
                let group = count + usize::from(!parameter.kind.is_joint());
                let effective = scales[c] * scales[group] + step[self.free.len() + k];
                next[c] = effective / next[group];
            }
        }
        let valid = next.iter().all(|s| s.is_finite());
        Ok((moved, valid.then_some(next)))
    }
}
