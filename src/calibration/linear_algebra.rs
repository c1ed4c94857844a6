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
    let cholesky = cholesky(normal.clone())?;
    let l_inverse = lower_inverse(cholesky.l_dirty());
    let n = l_inverse.nrows();
    // tr(N⁻¹) = Σ_j ‖L⁻¹ e_j‖²; column j of L⁻¹ is zero above the diagonal. Summed column by
    // column, top down, as the substitution produced the values.
    let mut inverse_trace = 0.0;
    for (j, column) in l_inverse.as_slice().chunks_exact(n.max(1)).enumerate() {
        for value in &column[j..] {
            inverse_trace += value * value;
        }
    }
    let largest_bound = absolute_row_sums(normal).into_iter().fold(0.0, f64::max);
    let smallest_bound = 1.0 / inverse_trace;
    (smallest_bound.is_finite() && smallest_bound > 2.0 * ratio * largest_bound).then_some(
        ProvedFactor {
            cholesky,
            l_inverse,
        },
    )
}

/// Each row's sum of absolute values, added left to right as a row iterator's `sum` would
/// (from −0, which the first term replaces), column by column over the contiguous storage.
fn absolute_row_sums(matrix: &DMatrix<f64>) -> Vec<f64> {
    let mut sums = vec![-0.0; matrix.nrows()];
    for column in matrix.as_slice().chunks_exact(matrix.nrows().max(1)) {
        for (sum, v) in sums.iter_mut().zip(column) {
            *sum += v.abs();
        }
    }
    sums
}

/// nalgebra's `Cholesky::new`, bit for bit, on contiguous columns. nalgebra's left-looking
/// factorisation updates column j by `y ← (a·x)·1 + 1·y` for k = 0, 1, …, j − 1 through strided
/// views (`axpy`), takes the square root of a positive diagonal and divides the column below
/// it; this does the same operations on each entry in the same order (`(a·x)·1` and `1·y` are
/// exact), four values of k per pass over the column. The upper triangle keeps the input, as
/// nalgebra's does.
pub(crate) fn cholesky(mut matrix: DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    let n = matrix.nrows();
    if matrix.ncols() != n {
        return None;
    }
    let data = matrix.as_mut_slice();
    for j in 0..n {
        let (before, rest) = data.split_at_mut(j * n);
        let target = &mut rest[j..n];
        // Column k's rows j.., and its factor −L[j, k].
        let column = |k: usize| {
            let x = &before[k * n + j..k * n + n];
            (-x[0], x)
        };
        let mut k = 0;
        while k + 4 <= j {
            let [(a0, x0), (a1, x1), (a2, x2), (a3, x3)] = [k, k + 1, k + 2, k + 3].map(column);
            let xs = x0.iter().zip(x1).zip(x2.iter().zip(x3));
            for (y, ((x0, x1), (x2, x3))) in target.iter_mut().zip(xs) {
                *y = a3 * x3 + (a2 * x2 + (a1 * x1 + (a0 * x0 + *y)));
            }
            k += 4;
        }
        for k in k..j {
            let (a, x) = column(k);
            for (y, x) in target.iter_mut().zip(x) {
                *y += a * x;
            }
        }
        let diagonal = target[0];
        // nalgebra: a zero diagonal, or one `try_sqrt` refuses (negative or NaN), fails.
        if diagonal.is_nan() || diagonal <= 0.0 {
            return None;
        }
        let denominator = diagonal.sqrt();
        target[0] = denominator;
        for y in &mut target[1..] {
            *y /= denominator;
        }
    }
    Some(Cholesky::pack_dirty(matrix))
}

/// `L⁻¹` of the lower triangle of `l` (zero above the diagonal), column j by forward
/// substitution of `e_j` as nalgebra's `solve_lower_triangular` does it (`x_k ← x_k / L_kk`,
/// then `x_i ← x_i − L_ik·x_k` below, for k = j, j + 1, …), the leading zeros skipped (they stay
/// exact zeros there). Four columns share each pass over a column of `L`; every entry sees the
/// same operations in the same order.
fn lower_inverse(l: &DMatrix<f64>) -> DMatrix<f64> {
    let n = l.nrows();
    let mut inverse = DMatrix::zeros(n, n);
    let columns = l.as_slice();
    for (block, xs) in inverse.as_mut_slice().chunks_mut(4 * n.max(1)).enumerate() {
        let first = 4 * block;
        let mut xs: Vec<&mut [f64]> = xs.chunks_exact_mut(n).collect();
        for (c, x) in xs.iter_mut().enumerate() {
            x[first + c] = 1.0;
        }
        for k in first..n {
            let column = &columns[k * n..(k + 1) * n];
            // The columns whose substitution has reached row k (column first + c starts there).
            let active = (k + 1 - first).min(xs.len());
            let mut values = [0.0; 4];
            for (c, x) in xs[..active].iter_mut().enumerate() {
                values[c] = x[k] / column[k];
                x[k] = values[c];
            }
            if active == 4 {
                let [x0, x1, x2, x3] = &mut xs[..] else {
                    unreachable!("four columns")
                };
                let (x0, x1) = (&mut x0[k + 1..], &mut x1[k + 1..]);
                let (x2, x3) = (&mut x2[k + 1..], &mut x3[k + 1..]);
                let xs = x0.iter_mut().zip(x1).zip(x2.iter_mut().zip(x3));
                for (l, ((x0, x1), (x2, x3))) in column[k + 1..].iter().zip(xs) {
                    *x0 -= l * values[0];
                    *x1 -= l * values[1];
                    *x2 -= l * values[2];
                    *x3 -= l * values[3];
                }
            } else {
                for (c, x) in xs[..active].iter_mut().enumerate() {
                    for (x, l) in x[k + 1..].iter_mut().zip(&column[k + 1..]) {
                        *x -= l * values[c];
                    }
                }
            }
        }
    }
    inverse
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
    /// `L⁻¹`, already at hand; only the back substitution `L⁻ᵀ·L⁻¹` remains, done as
    /// nalgebra's `ad_solve_lower_triangular_unchecked_mut` does it (see [`back_substitute`]).
    pub(crate) fn inverse(&self) -> DMatrix<f64> {
        let mut inverse = self.l_inverse.clone();
        back_substitute(self.cholesky.l_dirty(), &mut inverse);
        inverse
    }
}

/// `B ← L⁻ᵀ·B` for the lower triangle of `l`, bit for bit nalgebra's
/// `ad_solve_lower_triangular_unchecked_mut`: for i = n − 1 down to 0,
/// `b_i ← (b_i − L[i+1.., i]·b[i+1..]) / L_ii`, the dot product as nalgebra's (eight partial
/// sums over whole groups of eight, combined as (0,4), (1,5), (2,6), (3,7), then the rest in
/// order). Four columns of `B` share each row's pass over `L`'s column.
fn back_substitute(l: &DMatrix<f64>, b: &mut DMatrix<f64>) {
    let n = l.nrows();
    let columns = l.as_slice();
    for xs in b.as_mut_slice().chunks_mut(4 * n.max(1)) {
        let mut xs: Vec<&mut [f64]> = xs.chunks_exact_mut(n).collect();
        for i in (0..n).rev() {
            let below = &columns[i * n + i + 1..(i + 1) * n];
            let diagonal = columns[i * n + i];
            if let [x0, x1, x2, x3] = &mut xs[..] {
                let dots = dots(
                    below,
                    [&x0[i + 1..], &x1[i + 1..], &x2[i + 1..], &x3[i + 1..]],
                );
                for (x, dot) in [x0, x1, x2, x3].into_iter().zip(dots) {
                    x[i] = (x[i] - dot) / diagonal;
                }
            } else {
                for x in xs.iter_mut() {
                    let [dot] = dots(below, [&x[i + 1..]]);
                    x[i] = (x[i] - dot) / diagonal;
                }
            }
        }
    }
}

/// nalgebra's `dot` of `a` with each of `b`, the same sums in the same order: eight partial
/// sums over whole groups of eight, then `+= acc0 + acc4`, …, `+= acc3 + acc7` and the rest.
#[inline(always)]
fn dots<const C: usize>(a: &[f64], b: [&[f64]; C]) -> [f64; C] {
    let whole = a.len() / 8 * 8;
    let mut acc = [[0.0; 8]; C];
    for (g, a) in a[..whole].chunks_exact(8).enumerate() {
        for (acc, b) in acc.iter_mut().zip(&b) {
            let b = &b[8 * g..8 * g + 8];
            for r in 0..8 {
                acc[r] += a[r] * b[r];
            }
        }
    }
    let mut result = [0.0; C];
    for ((result, acc), b) in result.iter_mut().zip(&acc).zip(&b) {
        let mut sum = 0.0;
        sum += acc[0] + acc[4];
        sum += acc[1] + acc[5];
        sum += acc[2] + acc[6];
        sum += acc[3] + acc[7];
        for (a, b) in a[whole..].iter().zip(&b[whole..]) {
            sum += a * b;
        }
        *result = sum;
    }
    result
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

    fn bits(matrix: &DMatrix<f64>) -> Vec<u64> {
        matrix.iter().map(|v| v.to_bits()).collect()
    }

    /// The proved factor's inverse (from the proof's `L⁻¹`) is `Cholesky::inverse` bit for
    /// bit, on seeded random well-conditioned normal matrices of several sizes.
    #[test]
    fn proved_factor_inverse_is_cholesky_inverse_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(24);
        for n in [1, 2, 3, 4, 5, 8, 9, 17, 56, 64] {
            let a = DMatrix::from_fn(2 * n + 3, n, |_, _| rng.random_range(-1.0..1.0));
            let normal = normal_matrix(&a);
            let factor = certainly_conditioned(&normal, 1e-12).expect("well conditioned");
            let expected = normal
                .clone()
                .cholesky()
                .expect("positive definite")
                .inverse();
            assert_eq!(bits(&factor.inverse()), bits(&expected), "n = {n}");
        }
    }

    /// The row sums of absolute values are the row iterator's sums bit for bit.
    #[test]
    fn absolute_row_sums_are_the_rows_sums() {
        let mut rng = ChaCha8Rng::seed_from_u64(16);
        for (rows, columns) in [(0, 0), (1, 1), (3, 5), (17, 17), (56, 56)] {
            let m: DMatrix<f64> =
                DMatrix::from_fn(rows, columns, |_, _| rng.random_range(-1.0..1.0) * 1e3);
            let expected: Vec<u64> = m
                .row_iter()
                .map(|row| row.iter().map(|v| v.abs()).sum::<f64>().to_bits())
                .collect();
            let ours: Vec<u64> = absolute_row_sums(&m).iter().map(|v| v.to_bits()).collect();
            assert_eq!(ours, expected, "{rows} × {columns}");
        }
    }

    /// `cholesky` is nalgebra's `Cholesky::new` bit for bit (factor and dirty upper
    /// triangle), on seeded random normal matrices of sizes around the blocks of four, and
    /// fails where it fails (not positive definite, NaN); `lower_inverse` is nalgebra's
    /// forward substitution of the identity, bit for bit.
    #[test]
    fn cholesky_and_lower_inverse_are_nalgebras_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(15);
        for n in [0, 1, 2, 3, 4, 5, 7, 8, 9, 16, 17, 32, 56, 64] {
            let a = DMatrix::from_fn(n + 4, n, |_, _| rng.random_range(-1.0..1.0));
            let normal = normal_matrix(&a);
            let ours = cholesky(normal.clone()).expect("positive definite");
            let theirs = normal.clone().cholesky().expect("positive definite");
            assert_eq!(bits(ours.l_dirty()), bits(theirs.l_dirty()), "n = {n}");
            let identity = DMatrix::<f64>::identity(n, n);
            let expected = theirs
                .l_dirty()
                .solve_lower_triangular(&identity)
                .expect("invertible");
            assert_eq!(
                bits(&lower_inverse(ours.l_dirty())),
                bits(&expected),
                "n = {n}"
            );
            if n > 1 {
                let mut indefinite = normal.clone();
                indefinite[(n - 1, n - 1)] = -1.0;
                assert!(cholesky(indefinite.clone()).is_none());
                assert!(indefinite.cholesky().is_none());
                let mut nan = normal.clone();
                nan[(1, 1)] = f64::NAN;
                assert!(cholesky(nan.clone()).is_none());
                assert!(nan.cholesky().is_none());
            }
        }
    }
}
