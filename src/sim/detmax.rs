//! Choosing K of N candidate measurements to maximise `log det(MᵀM)` of the stacked, weighted
//! and scaled identification Jacobian: a greedy pick followed by DETMAX excursions (Mitchell,
//! Technometrics 16, 1974): add the best candidate, remove the chosen one whose removal costs
//! least, until the one removed is the one just added.
//!
//! Each candidate is a block `A_c` of `r` rows over `L` columns. The information matrix
//! `M = εI + Σ A_cᵀA_c` starts at a tiny ridge `εI` so the greedy start is defined before the
//! chosen rows reach rank `L`. Adding or removing a block changes `log det M` by
//! `log det(I ± G_c)` with `G_c = A_c M⁻¹ A_cᵀ`; every `G_c` is kept up to date with one
//! Sherman–Morrison–Woodbury rank-`r` update per move, done as a single `(N·r) × L` by
//! `L × r` product in fixed-size chunks (in parallel, with results that do not depend on the
//! thread count). See `docs/planning.md`.

use nalgebra::DMatrix;
use rayon::prelude::*;

/// Candidates per parallel chunk: fixed, so results never depend on the thread count.
const CHUNK: usize = 256;

/// The candidate blocks and the state of one design.
pub(crate) struct Design {
    /// Rows per candidate.
    rows: usize,
    /// Every candidate's block, stacked: candidate `c` is rows `c·r .. (c+1)·r`.
    blocks: DMatrix<f64>,
    /// `M⁻¹` of the chosen set (with the ridge).
    inverse: DMatrix<f64>,
    /// `G_c = A_c M⁻¹ A_cᵀ` of every candidate, row-major `r × r` each.
    leverage: Vec<f64>,
    /// Whether each candidate is chosen.
    chosen: Vec<bool>,
}

impl Design {
    /// A design with nothing chosen and information `ridge·I`.
    pub(crate) fn new(blocks: DMatrix<f64>, rows: usize, ridge: f64) -> Self {
        let count = blocks.nrows() / rows;
        let columns = blocks.ncols();
        let mut leverage = vec![0.0; count * rows * rows];
        leverage
            .par_chunks_mut(CHUNK * rows * rows)
            .enumerate()
            .for_each(|(chunk, out)| {
                let first = chunk * CHUNK;
                let n = out.len() / (rows * rows);
                let a = blocks.rows(first * rows, n * rows);
                for c in 0..n {
                    let block = a.rows(c * rows, rows);
                    let g = block * block.transpose() / ridge;
                    for i in 0..rows {
                        for j in 0..rows {
                            out[c * rows * rows + i * rows + j] = g[(i, j)];
                        }
                    }
                }
            });
        Self {
            rows,
            inverse: DMatrix::identity(columns, columns) / ridge,
            blocks,
            leverage,
            chosen: vec![false; count],
        }
    }

    /// Number of candidates.
    pub(crate) fn count(&self) -> usize {
        self.chosen.len()
    }

    /// The chosen candidates, in index order.
    pub(crate) fn chosen(&self) -> Vec<usize> {
        (0..self.count()).filter(|&c| self.chosen[c]).collect()
    }

    /// `log det(I + sign·G_c)`: the change of `log det M` if `c` is added (+1) or removed (−1);
    /// −∞ if that would leave `M` singular.
    fn change(&self, c: usize, sign: f64) -> f64 {
        let r = self.rows;
        let g = &self.leverage[c * r * r..(c + 1) * r * r];
        let mut s = [0.0; MAX_ROWS * MAX_ROWS];
        for i in 0..r {
            for j in 0..r {
                s[i * r + j] = sign * g[i * r + j] + if i == j { 1.0 } else { 0.0 };
            }
        }
        log_det_spd(&mut s[..r * r], r).unwrap_or(f64::NEG_INFINITY)
    }

    /// The change of `log det M` if unchosen candidate `c` were added.
    pub(crate) fn gain(&self, c: usize) -> f64 {
        self.change(c, 1.0)
    }

    /// The unchosen candidate whose addition raises `log det M` most (lowest index on ties).
    pub(crate) fn best_addition(&self) -> Option<usize> {
        best((0..self.count()).filter(|&c| !self.chosen[c]), |c| {
            self.change(c, 1.0)
        })
    }

    /// The chosen candidate whose removal lowers `log det M` least, with that change.
    fn best_removal(&self) -> Option<(usize, f64)> {
        let c = best((0..self.count()).filter(|&c| self.chosen[c]), |c| {
            self.change(c, -1.0)
        })?;
        Some((c, self.change(c, -1.0)))
    }

    /// Adds (`sign` = +1) or removes (−1) candidate `c`, updating `M⁻¹` and every `G`.
    pub(crate) fn apply(&mut self, c: usize, sign: f64) {
        let r = self.rows;
        let a = self.blocks.rows(c * r, r).into_owned();
        let u = &self.inverse * a.transpose(); // L × r
        let mut s = &a * &u * sign; // r × r: ±G_c
        for i in 0..r {
            s[(i, i)] += 1.0;
        }
        // S = I ± G_c is positive definite whenever the move leaves M positive definite, which
        // the ridge guarantees; should rounding break that, the move is skipped.
        let Some(cholesky) = s.cholesky() else {
            return;
        };
        // W = U·L⁻ᵀ, so that U·S⁻¹·Uᵀ = W·Wᵀ.
        let Some(w_t) = cholesky.l().solve_lower_triangular(&u.transpose()) else {
            return;
        };
        let w = w_t.transpose();
        self.inverse -= &w * &w_t * sign;
        let blocks = &self.blocks;
        self.leverage
            .par_chunks_mut(CHUNK * r * r)
            .enumerate()
            .for_each(|(chunk, out)| {
                let first = chunk * CHUNK;
                let n = out.len() / (r * r);
                let v = blocks.rows(first * r, n * r) * &w; // (n·r) × r
                for k in 0..n {
                    let vk = v.rows(k * r, r);
                    let g = &mut out[k * r * r..(k + 1) * r * r];
                    for i in 0..r {
                        for j in 0..r {
                            g[i * r + j] -= sign * vk.row(i).dot(&vk.row(j));
                        }
                    }
                }
            });
        self.chosen[c] = sign > 0.0;
    }

    /// Greedy: adds `k` candidates, each the best addition at the time.
    pub(crate) fn greedy(&mut self, k: usize) {
        for _ in 0..k {
            match self.best_addition() {
                Some(c) => self.apply(c, 1.0),
                None => break,
            }
        }
    }

    /// DETMAX excursions of length one, at most `max_exchanges`; returns how many improved.
    pub(crate) fn detmax(&mut self, max_exchanges: usize) -> usize {
        let mut exchanges = 0;
        while exchanges < max_exchanges {
            let Some(added) = self.best_addition() else {
                break;
            };
            let gain = self.change(added, 1.0);
            self.apply(added, 1.0);
            let Some((removed, loss)) = self.best_removal() else {
                break;
            };
            self.apply(removed, -1.0);
            // Removing the point just added would undo the move exactly; anything else gains
            // gain + loss ≥ 0. Stop when nothing measurable is gained.
            if removed == added || gain + loss <= 1e-10 {
                break;
            }
            exchanges += 1;
        }
        exchanges
    }

    /// The information matrix `Σ A_cᵀA_c` of a set of candidates (no ridge).
    pub(crate) fn information(&self, set: &[usize]) -> DMatrix<f64> {
        let r = self.rows;
        let l = self.blocks.ncols();
        let mut m = DMatrix::zeros(l, l);
        for &c in set {
            let a = self.blocks.rows(c * r, r);
            m += a.transpose() * a;
        }
        m
    }

    /// The block of candidate `c`.
    #[cfg(test)]
    fn block(&self, c: usize) -> nalgebra::DMatrixView<'_, f64> {
        self.blocks.rows(c * self.rows, self.rows)
    }
}

/// The largest number of rows a candidate may have (two tools × 6 rows with room to spare).
pub(crate) const MAX_ROWS: usize = 24;

/// The index with the largest score; the lowest index on ties; NaN scores never win.
fn best(indices: impl Iterator<Item = usize>, score: impl Fn(usize) -> f64) -> Option<usize> {
    let mut found: Option<(usize, f64)> = None;
    for c in indices {
        let value = score(c);
        if found.is_none_or(|(_, v)| value > v) {
            found = Some((c, value));
        }
    }
    found.map(|(c, _)| c)
}

/// `log det` of a small symmetric positive definite matrix (row-major `n × n`, overwritten by
/// its Cholesky factor); `None` if it is not positive definite.
fn log_det_spd(a: &mut [f64], n: usize) -> Option<f64> {
    let mut log_det = 0.0;
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        log_det += 2.0 * d.ln();
        for i in j + 1..n {
            let mut v = a[i * n + j];
            for k in 0..j {
                v -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = v / d;
        }
    }
    Some(log_det)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tracked `log det` change of every move equals a fresh computation.
    #[test]
    fn updates_match_direct_determinants() {
        let (rows, columns, count) = (2, 4, 300);
        // A fixed pseudo-random pool of full rank (a multiplicative hash, no RNG needed).
        let blocks = DMatrix::from_fn(count * rows, columns, |i, j| {
            let h = ((i * 7919 + j * 104_729 + 1) as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            (h >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        });
        let ridge = 1e-6;
        let mut design = Design::new(blocks, rows, ridge);
        design.greedy(5);
        design.detmax(20);
        let set = design.chosen();
        assert_eq!(set.len(), 5);
        let mut m = design.information(&set);
        for i in 0..columns {
            m[(i, i)] += ridge;
        }
        let direct = m.clone().try_inverse().unwrap();
        assert!((direct - &design.inverse).norm() < 1e-6 * design.inverse.norm());
        for c in 0..count {
            let a = design.block(c);
            let g = a * m.clone().try_inverse().unwrap() * a.transpose();
            for i in 0..rows {
                for j in 0..rows {
                    let tracked = design.leverage[c * rows * rows + i * rows + j];
                    assert!((tracked - g[(i, j)]).abs() < 1e-6 * (1.0 + g[(i, j)].abs()));
                }
            }
        }
    }

    #[test]
    fn small_log_determinants() {
        let mut a = [4.0, 2.0, 2.0, 3.0];
        assert!((log_det_spd(&mut a, 2).unwrap() - 8f64.ln()).abs() < 1e-14);
        let mut b = [1.0, 2.0, 2.0, 1.0];
        assert!(log_det_spd(&mut b, 2).is_none());
    }
}
