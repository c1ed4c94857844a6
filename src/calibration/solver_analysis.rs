//! The linear algebra of one Levenberg–Marquardt iteration: column scaling, the singular
//! values (or a Cholesky factor) of the scaled normal matrix, and the covariance on the
//! identifiable subspace (used by the loop in `solver`).

use super::linear_algebra::{
    certainly_conditioned, cholesky, eigen_decomposition, floored_scales, qr_svd, scale_columns,
    well_conditioned, ProvedFactor, WELL_CONDITIONED,
};
use super::normal_equations::NormalEquations;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use std::cell::OnceCell;

/// The column-scaled Jacobian's singular values and right singular vectors, and the scaled
/// gradient `g = J_sᵀ·r`.
pub(super) struct Analysis {
    pub(super) scales: DVector<f64>,
    /// Filled at once when the singular vectors are needed, else on the first call of
    /// [`Analysis::singular_values`] (the eigenvalues of `normal`).
    singular_values: OnceCell<DVector<f64>>,
    pub(super) v_t: DMatrix<f64>,
    pub(super) gradient: DVector<f64>,
    /// The scaled normal matrix `J_sᵀJ_s` when it is well conditioned (then `v_t` is empty and
    /// steps and covariance come from its Cholesky factor).
    pub(super) normal: Option<DMatrix<f64>>,
    /// The Cholesky factor of `normal` (and its `L⁻¹`), when the cheap bounds proved it well
    /// conditioned.
    pub(super) cholesky: Option<ProvedFactor>,
}

impl Analysis {
    /// The singular values (unsorted). On the well-conditioned path they are the square
    /// roots of the eigenvalues of `normal`, computed only when asked for: most iterations
    /// need only the Cholesky step, the damping and the final report need these.
    pub(super) fn singular_values(&self) -> &DVector<f64> {
        self.singular_values.get_or_init(|| match &self.normal {
            Some(normal) => normal.symmetric_eigenvalues().map(f64::sqrt),
            None => DVector::zeros(0),
        })
    }
}

/// Column scaling, then the SVD of the small triangle `R` of `J_s = Q·R` (same singular values
/// and `V` as `J_s`, at a fraction of the cost). With fewer rows than columns, zero rows
/// complete the matrix so that `V` spans the whole null space. All from the streamed normal
/// equations; `with_factor` recomputes them with `R` when `lin` lacks it and it is needed.
pub(super) fn analyse(
    lin: &mut NormalEquations,
    rank_tolerance: f64,
    with_factor: impl FnOnce() -> Result<NormalEquations>,
) -> Result<Analysis> {
    let scales = floored_scales(lin.normal.diagonal().iter().map(|d| d.max(0.0).sqrt()));
    let gradient = lin.gradient.component_div(&scales);
    // Fast path: the singular values from the eigenvalues of the normal matrix alone, and the
    // steps and the covariance by Cholesky, when it is well conditioned (see
    // `singular_decomposition`); no singular vectors are needed then (nothing is
    // unidentifiable).
    let normal = DMatrix::from_fn(scales.len(), scales.len(), |a, b| {
        lin.normal[(a, b)] / (scales[a] * scales[b])
    });
    // Full rank with a margin, also for a caller's coarser rank tolerance.
    let ratio = WELL_CONDITIONED.max(100.0 * rank_tolerance * rank_tolerance);
    // Most iterations are proved well conditioned by a Cholesky factor and two bounds,
    // without the eigenvalues (the same decision, see `certainly_conditioned`).
    if let Some(cholesky) = certainly_conditioned(&normal, ratio) {
        return Ok(Analysis {
            scales,
            singular_values: OnceCell::new(),
            v_t: DMatrix::zeros(0, 0),
            gradient,
            normal: Some(normal),
            cholesky: Some(cholesky),
        });
    }
    let eigenvalues = normal.symmetric_eigenvalues();
    let largest = eigenvalues.max();
    if largest > 0.0 && eigenvalues.min() > ratio * largest {
        return Ok(Analysis {
            scales,
            singular_values: OnceCell::from(eigenvalues.map(f64::sqrt)),
            v_t: DMatrix::zeros(0, 0),
            gradient,
            normal: Some(normal),
            cholesky: None,
        });
    }
    // Singular vectors are needed: from the same normal matrix while squaring still resolves
    // the spectrum (a caller's coarse rank tolerance), else from QR + SVD.
    let (singular_values, v_t) = if well_conditioned(&eigenvalues) {
        eigen_decomposition(normal)
    } else {
        if lin.factor.is_none() {
            *lin = with_factor()?;
        }
        let factor = lin.factor.as_ref().ok_or_else(|| Error::InvalidData {
            origin: "identification".into(),
            message: "no triangular factor".into(),
        })?;
        // R·S⁻¹ is the triangle of the scaled Jacobian J·S⁻¹.
        qr_svd(scale_columns(factor, &scales))
    };
    Ok(Analysis {
        scales,
        singular_values: OnceCell::from(singular_values),
        v_t,
        gradient,
        normal: None,
        cholesky: None,
    })
}

/// `(JᵀWJ)⁺` in parameter units on the identifiable subspace (the retained directions
/// `retained`, indices into the analysis's singular values): the covariance over σ̂².
/// `C = σ̂²·S⁻¹·N⁺·S⁻¹` with `N⁺ = V_r·Σ_r⁻²·V_rᵀ`, or `N⁻¹` by Cholesky when well
/// conditioned: Σ over retained directions of `(v_k / s_k)² / σᵢ²`.
pub(super) fn unscaled_inverse(analysis: &Analysis, retained: &[usize]) -> DMatrix<f64> {
    let columns = analysis.scales.len();
    // The proved factor's inverse is the same bits as `Cholesky::inverse`, half the work.
    let inverse = match &analysis.cholesky {
        Some(factor) => Some(factor.inverse()),
        None => analysis
            .normal
            .as_ref()
            .and_then(|n| cholesky(n.clone()))
            .map(|cholesky| cholesky.inverse()),
    };
    match inverse {
        Some(inverse) => DMatrix::from_fn(columns, columns, |a, b| {
            inverse[(a, b)] / (analysis.scales[a] * analysis.scales[b])
        }),
        None => {
            // W = S⁻¹·V_r·Σ_r⁻¹, N⁺ in parameter units = W·Wᵀ.
            let mut w = DMatrix::zeros(columns, retained.len());
            for (column, &i) in retained.iter().enumerate() {
                for k in 0..columns {
                    w[(k, column)] =
                        analysis.v_t[(i, k)] / analysis.scales[k] / analysis.singular_values()[i];
                }
            }
            &w * w.transpose()
        }
    }
}
