//! The covariance of the joint fit and the per-compliance estimates with their standard
//! deviations.

use super::fit::Fit;
use super::problem::{Linearisation, Problem};
use super::selection::Selection;
use super::{name, ComplianceEstimate};
use crate::calibration::solver::{column_scales, scale_columns, singular_decomposition};
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
        Ok(self
            .parameters()
            .iter()
            .enumerate()
            .map(|(k, parameter)| {
                let prior = reference.compliance(parameter).recip();
                let effective = self.effective(&fit.scales);
                let scale = effective[k];
                let position = |index: usize| selection.chosen.iter().position(|&c| c == index);
                let chosen = position(k);
                let group =
                    position(self.parameters().len() + usize::from(!parameter.kind.is_joint()));
                // var(ln s·g) = ‖F_s + F_g‖², the rows of the covariance factor.
                let f = &fit.log_factor;
                let variance = match (chosen, group) {
                    (Some(a), Some(b)) => Some((f.row(a) + f.row(b)).norm_squared()),
                    (Some(a), None) | (None, Some(a)) => Some(f.row(a).norm_squared()),
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
                        .map(|v| scale * v.max(0.0).sqrt())
                        .filter(|s| s.is_finite()),
                    data_std_dev: selection.data_std_dev[k],
                    identified: chosen.is_some(),
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
    let columns = column_scales(&lin.jacobian);
    let (singular, v_t) = singular_decomposition(scale_columns(&lin.jacobian, &columns));
    let largest = singular.max();
    let kept: Vec<usize> = (0..singular.len())
        .filter(|&i| singular[i] > tolerance * largest)
        .collect();
    let rows = lin.jacobian.nrows();
    let residual_scale = if rows > kept.len() {
        (2.0 * cost / (rows - kept.len()) as f64).sqrt()
    } else {
        f64::NAN
    };
    // F = σ̂·S⁻¹·V_k·Σ_k⁻¹.
    let factor = DMatrix::from_fn(columns.len(), kept.len(), |k, j| {
        residual_scale * v_t[(kept[j], k)] / singular[kept[j]] / columns[k]
    });
    (kept.len(), residual_scale, factor)
}
