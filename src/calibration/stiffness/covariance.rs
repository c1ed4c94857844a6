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
                // var(ln s·g) = var(ln s) + var(ln g) + 2·cov.
                let c = &fit.log_covariance;
                let variance = match (chosen, group) {
                    (Some(a), Some(b)) => Some(c[(a, a)] + c[(b, b)] + 2.0 * c[(a, b)]),
                    (Some(a), None) | (None, Some(a)) => Some(c[(a, a)]),
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

/// Rank, `σ̂` and the covariance `σ̂²·(JᵀJ)⁺` of the columns.
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
    // W = S⁻¹·V_k·Σ_k⁻¹; covariance σ̂²·W·Wᵀ.
    let n = columns.len();
    let w = DMatrix::from_fn(n, kept.len(), |k, j| {
        v_t[(kept[j], k)] / singular[kept[j]] / columns[k]
    });
    let covariance = (&w * w.transpose()) * residual_scale.powi(2);
    (kept.len(), residual_scale, covariance)
}
