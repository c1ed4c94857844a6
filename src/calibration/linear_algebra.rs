//! Dense linear algebra of the identification: column scaling, and singular values and vectors
//! of a column-scaled Jacobian (from the normal matrix when it is well conditioned, else by
//! QR + SVD). Shared by the solver, the identifiability analysis and the stiffness fit.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

/// Smallest eigenvalue ratio of the scaled normal matrix for which squaring the Jacobian
/// loses nothing near the rank tolerance (σ ratio 1e-5): eigenvalues then come out to ~1e-6
/// relative.
pub(super) const WELL_CONDITIONED: f64 = 1e-10;

/// Singular values (unsorted) and `Vᵀ` of a column-scaled Jacobian: from the normal matrix
/// when it is well conditioned, else through the SVD of the small triangle `R` of
/// `J_s = Q·R`. Shared with `calibration::identifiability`.
pub(crate) fn singular_decomposition(scaled: DMatrix<f64>) -> (DVector<f64>, DMatrix<f64>) {
    // Fast path: the eigen-decomposition of the scaled normal matrix gives σ² and V in a third
    // of the time of QR + SVD, and exactly enough when the matrix is well conditioned (σ²
    // ratios above 1e-10 are resolved to ~1e-6 relative, far from the rank tolerance). Near
    // rank deficiency, where squaring would lose the small singular values, QR + SVD decide.
    let normal = normal_matrix(&scaled);
    if certainly_conditioned(&normal, WELL_CONDITIONED).is_some()
        || well_conditioned(&normal.symmetric_eigenvalues())
    {
        eigen_decomposition(normal)
    } else {
        qr_svd(scaled)
    }
}

/// Whether the eigenvalues of a normal matrix are all above [`WELL_CONDITIONED`] of the
/// largest.
pub(super) fn well_conditioned(eigenvalues: &DVector<f64>) -> bool {
    let largest = eigenvalues.max();
    largest > 0.0 && eigenvalues.min() > WELL_CONDITIONED * largest
}

/// The Cholesky factor of the symmetric matrix `normal` when it proves, without the
/// eigenvalues, that every eigenvalue is above twice `ratio` times the largest: the smallest is
/// at least `1 / tr(N⁻¹) = 1 / ‖L⁻¹‖²_F`, the largest at most the largest absolute row sum
/// (Gershgorin). The bounds lose at most a factor `n·√n`, so a matrix near the threshold gets
/// `None` and the exact eigenvalues decide as before: the decision is the one they would take.
/// Two passes of n³/6 multiply-adds, against 2n³/3 for the eigenvalues' tridiagonalisation
/// alone (see `docs/performance.md`, issue 24).
pub(crate) fn certainly_conditioned(normal: &DMatrix<f64>, ratio: f64) -> Option<ProvedFactor> {
    let cholesky = normal.clone().cholesky()?;
    let l = cholesky.l_dirty();
    let n = l.nrows();
    // tr(N⁻¹) = Σ_j ‖L⁻¹ e_j‖²; column j of L⁻¹ is zero above the diagonal.
    let mut inverse_trace = 0.0;
    let mut l_inverse = DMatrix::zeros(n, n);
    let columns = l.as_slice();
    for j in 0..n {
        let x = &mut l_inverse.as_mut_slice()[j * n..(j + 1) * n];
        x[j] = 1.0;
        for k in j..n {
            let column = &columns[k * n..(k + 1) * n];
            let value = x[k] / column[k];
            x[k] = value;
            inverse_trace += value * value;
            for (x, l) in x[k + 1..].iter_mut().zip(&column[k + 1..]) {
                *x -= l * value;
            }
        }
    }
    let largest_bound = normal
        .row_iter()
        .map(|row| row.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let smallest_bound = 1.0 / inverse_trace;
    (smallest_bound.is_finite() && smallest_bound > 2.0 * ratio * largest_bound).then_some(
        ProvedFactor {
            cholesky,
            l_inverse,
        },
    )
}

/// A Cholesky factor `N = L·Lᵀ` that [`certainly_conditioned`] proved well conditioned, with
/// the `L⁻¹` the proof computed.
#[derive(Clone)]
pub(crate) struct ProvedFactor {
    pub(crate) cholesky: Cholesky<f64, Dyn>,
    /// `L⁻¹` (zero above the diagonal): column j is nalgebra's forward substitution of `e_j`,
    /// the same operations in the same order with the leading zeros skipped (they stay exact
    /// zeros there), so the same bits.
    l_inverse: DMatrix<f64>,
}

impl ProvedFactor {
    /// `N⁻¹`, bit for bit [`Cholesky::inverse`]: its forward substitution of the identity is
    /// `L⁻¹`, already at hand; only the back substitution `L⁻ᵀ·L⁻¹` remains.
    pub(crate) fn inverse(&self) -> DMatrix<f64> {
        let mut inverse = self.l_inverse.clone();
        self.cholesky
            .l_dirty()
            .ad_solve_lower_triangular_unchecked_mut(&mut inverse);
        inverse
    }
}

/// `σ = √λ` and `Vᵀ` from the eigen-decomposition of the normal matrix `JᵀJ`.
pub(super) fn eigen_decomposition(normal: DMatrix<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let eigen = normal.symmetric_eigen();
    (
        eigen.eigenvalues.map(|l| l.max(0.0).sqrt()),
        eigen.eigenvectors.transpose(),
    )
}

/// Singular values and `Vᵀ` through the SVD of the triangle `R` of `J = Q·R` (same σ and `V`);
/// with fewer rows than columns, zero rows complete the matrix so that there is one singular
/// value per column and `V` spans the whole null space.
pub(super) fn qr_svd(scaled: DMatrix<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let columns = scaled.ncols();
    let square = if scaled.nrows() >= columns {
        scaled.qr().r()
    } else {
        scaled.resize_vertically(columns, 0.0)
    };
    let svd = square.svd(false, true);
    let v_t = svd
        .v_t
        .unwrap_or_else(|| DMatrix::identity(columns, columns));
    (svd.singular_values, v_t)
}

/// `AᵀA`. A dense product beat both a row-sparse and a block-sparse accumulation that skip the
/// zeros outside each tool's chain (measured: 100 configurations 12.1 → 7.1 ms per
/// calibration); the blocked kernel ([`super::normal_equations::add_gram`]) beats `tr_mul`.
fn normal_matrix(a: &DMatrix<f64>) -> DMatrix<f64> {
    let mut normal = DMatrix::zeros(a.ncols(), a.ncols());
    super::normal_equations::add_gram(&mut normal, a);
    normal
}

/// Column norms, floored at 1e-6 of the largest: a column that is zero but for rounding (a
/// rotation about an axis through the tool point, say) must stay negligible after scaling,
/// not be blown up into a unit column of noise.
pub(crate) fn column_scales(jacobian: &DMatrix<f64>) -> DVector<f64> {
    floored_scales(jacobian.column_iter().map(|c| c.norm()))
}

/// [`column_scales`] from the column norms.
pub(super) fn floored_scales(norms: impl Iterator<Item = f64>) -> DVector<f64> {
    let norms: Vec<f64> = norms.collect();
    let floor = norms.iter().copied().fold(0.0, f64::max) * 1e-6;
    DVector::from_iterator(
        norms.len(),
        norms.into_iter().map(|n| {
            if n > floor {
                n
            } else if floor > 0.0 {
                floor
            } else {
                1.0
            }
        }),
    )
}

pub(crate) fn scale_columns(jacobian: &DMatrix<f64>, scales: &DVector<f64>) -> DMatrix<f64> {
    let mut scaled = jacobian.clone();
    for (mut column, s) in scaled.column_iter_mut().zip(scales.iter()) {
        column /= *s;
    }
    scaled
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    /// The proved factor's inverse (from the proof's `L⁻¹`) is `Cholesky::inverse` bit for
    /// bit, on seeded random well-conditioned normal matrices of several sizes.
    #[test]
    fn proved_factor_inverse_is_cholesky_inverse_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(24);
        for n in [1, 2, 5, 17, 64] {
            let a = DMatrix::from_fn(2 * n + 3, n, |_, _| rng.random_range(-1.0..1.0));
            let normal = normal_matrix(&a);
            let factor = certainly_conditioned(&normal, 1e-12).expect("well conditioned");
            let expected = normal
                .clone()
                .cholesky()
                .expect("positive definite")
                .inverse();
            assert_eq!(factor.inverse(), expected, "n = {n}");
        }
    }
}
