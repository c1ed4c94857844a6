//! The covariance of the joint fit and the per-compliance estimates with their standard
//! deviations.

use super::problem::{Fit, Linearisation, Problem};
use super::selection::Selection;
use super::{name, ComplianceEstimate, GROUPS};
use crate::calibration::linear_algebra::{column_scales, scale_columns, singular_decomposition};
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::tree::KinematicTree;
use nalgebra::DMatrix;

impl Problem<'_> {
    pub(super) fn estimates(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        fit: &Fit,
        selection: &Selection,
    ) -> Result<Vec<ComplianceEstimate>> {
        let reference = self.bases[0].1.reference();
        let effective = self.effective(&fit.scales);
        Ok(self
            .parameters()
            .iter()
            .enumerate()
            .map(|(k, parameter)| {
                let prior = reference.compliance(parameter).recip();
                let scale = effective[k];
                let position = |index: usize| selection.chosen.iter().position(|&c| c == index);
                let chosen = position(k);
                let group_index = self.parameters().len() + usize::from(!parameter.kind.is_joint());
                let group = position(group_index);
                // A fitted scale's row is of its effective scale; a held one follows its group's.
                let f = &fit.factor;
                let variance = match (chosen, group) {
                    (Some(a), _) => Some(f.row(a).norm_squared()),
                    (None, Some(b)) => Some((f.row(b) * fit.scales[k]).norm_squared()),
                    (None, None) => None,
                };
                ComplianceEstimate {
                    name: name(tree, model, parameter),
                    owner: tree
                        .joint(model.frames()[parameter.frame].joint)
                        .name
                        .clone(),
                    kind: parameter.kind,
                    unit: parameter.kind.stiffness_unit().into(),
                    prior_stiffness: prior,
                    stiffness: prior / scale,
                    scale,
                    scale_std_dev: variance
                        .map(|v| v.max(0.0).sqrt())
                        .filter(|s| s.is_finite()),
                    data_std_dev: selection.data_std_dev[k],
                    identified: chosen.is_some(),
                    fitted_below_zero: None,
                }
            })
            .collect())
    }
}

/// Rank, `σ̂` and a factor `F` of the covariance `σ̂²·(JᵀJ)⁺` of the columns (`F·Fᵀ`, one row
/// per column), so that every variance is a sum of squares: the variance of a product of
/// scales (an individual scale times its group's) taken as a sum of covariances would lose its
/// digits to rounding.
pub(super) fn covariance(
    lin: &Linearisation,
    cost: f64,
    tolerance: f64,
) -> (usize, f64, DMatrix<f64>) {
    let rows = lin.jacobian.nrows();
    let (rank, unit) = unit_factor(&lin.jacobian, tolerance);
    let residual_scale = if rows > rank {
        (2.0 * cost / (rows - rank) as f64).sqrt()
    } else {
        f64::NAN
    };
    (rank, residual_scale, unit * residual_scale)
}

/// Rank and a factor `G = S⁻¹·V_k·Σ_k⁻¹` of `(JᵀJ)⁺` (SVD-truncated at `tolerance`, on the
/// columns scaled to unit length by `S`).
fn unit_factor(jacobian: &DMatrix<f64>, tolerance: f64) -> (usize, DMatrix<f64>) {
    let columns = column_scales(jacobian);
    let (singular, v_t) = singular_decomposition(scale_columns(jacobian, &columns));
    let largest = singular.max();
    let kept: Vec<usize> = (0..singular.len())
        .filter(|&i| singular[i] > tolerance * largest)
        .collect();
    let factor = DMatrix::from_fn(columns.len(), kept.len(), |k, j| {
        v_t[(kept[j], k)] / singular[kept[j]] / columns[k]
    });
    (kept.len(), factor)
}

impl Problem<'_> {
    /// Adds to the covariance factor of `fit` what the compliances held at the prior leave
    /// uncertain (a "consider" covariance): a held compliance whose scale is off by `δ` moves
    /// the fitted parameters by `K·δ`, `K = (JᵀJ)⁺·Jᵀ·J_c` with `J_c` the held compliances'
    /// columns, so the covariance grows by `K·P_c·Kᵀ`. The prior is log-normal (`ln s` has σ
    /// `prior_sigma`), so a held scale has variance `P_c = e^{σ²}·(e^{σ²} − 1)` (σ 0.5: 0.60²).
    /// The factor gets the columns `√P_c·K`.
    pub(super) fn consider(&self, fit: &mut Fit, chosen: &[usize], prior_sigma: f64) -> Result<()> {
        let held: Vec<usize> = (0..self.parameters().len() + GROUPS)
            .filter(|k| !chosen.contains(k))
            .collect();
        if held.is_empty() {
            return Ok(());
        }
        let all: Vec<usize> = chosen.iter().chain(&held).copied().collect();
        let lin = self.linearise(&fit.model, &fit.scales, &all, chosen, true)?;
        let fitted = self.free.len() + chosen.len();
        let jacobian = lin.jacobian.columns(0, fitted).into_owned();
        let held_columns = lin.jacobian.columns(fitted, held.len());
        let (_, unit) = unit_factor(&jacobian, self.options.rank_tolerance);
        // K = G·Gᵀ·Jᵀ·J_c, of which only the chosen scales' rows are kept.
        let k = &unit * (unit.tr_mul(&jacobian.tr_mul(&held_columns)));
        let extra = k.rows(self.free.len(), chosen.len()) * prior_scale_std_dev(prior_sigma);
        let data = &fit.factor;
        fit.factor = DMatrix::from_fn(data.nrows(), data.ncols() + extra.ncols(), |r, c| {
            if c < data.ncols() {
                data[(r, c)]
            } else {
                extra[(r, c - data.ncols())]
            }
        });
        Ok(())
    }
}

/// Standard deviation of a scale under the log-normal prior, `ln s ~ N(0, σ²)`:
/// `√(e^{σ²}·(e^{σ²} − 1))`.
pub(super) fn prior_scale_std_dev(prior_sigma: f64) -> f64 {
    let v = (prior_sigma * prior_sigma).exp();
    (v * (v - 1.0)).sqrt()
}
