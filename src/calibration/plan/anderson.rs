//! Anderson acceleration of a repeated plan's cycles (and of the sessions' alternation).

use nalgebra::{DMatrix, DVector};

/// How many earlier cycles the Anderson extrapolation of a repeated plan uses.
pub(super) const ANDERSON_DEPTH: usize = 3;

/// Anderson acceleration (type II) of the fixed-point iteration `x ← G(x)` formed by the
/// cycles of a repeated plan (Walker & Ni, SIAM J. Numer. Anal. 49, 2011): the next start is
/// `G(xₖ) − ΔG·γ` with `γ` the least-squares fit of the latest residual `fₖ = G(xₖ) − xₖ` by
/// the last residual differences `ΔF`. Falls back to the plain step `G(xₖ)` whenever the
/// residual grew, so it is never worse than repeating the plan.
pub(in crate::calibration) struct Anderson {
    depth: usize,
    /// `(G(x), f)` of the latest cycles, oldest first.
    history: Vec<(DVector<f64>, DVector<f64>)>,
}

impl Anderson {
    pub(in crate::calibration) fn new(depth: usize) -> Self {
        Self {
            depth,
            history: Vec::new(),
        }
    }

    /// The start of the next cycle, given this cycle's start `x` and result `g = G(x)`.
    pub(in crate::calibration) fn next(&mut self, x: &[f64], g: &[f64]) -> Vec<f64> {
        let g = DVector::from_column_slice(g);
        let f = &g - DVector::from_column_slice(x);
        if self
            .history
            .last()
            .is_some_and(|(_, previous)| f.norm() >= previous.norm())
        {
            self.history.clear();
        }
        self.history.push((g.clone(), f.clone()));
        if self.history.len() > self.depth + 1 {
            self.history.remove(0);
        }
        let columns = self.history.len() - 1;
        if columns == 0 {
            return g.as_slice().to_vec();
        }
        let n = g.len();
        let mut delta_f = DMatrix::zeros(n, columns);
        let mut delta_g = DMatrix::zeros(n, columns);
        for k in 0..columns {
            delta_f.set_column(k, &(&self.history[k + 1].1 - &self.history[k].1));
            delta_g.set_column(k, &(&self.history[k + 1].0 - &self.history[k].0));
        }
        // Small least-squares problem: SVD with a relative cut keeps it stable when the
        // differences are nearly parallel.
        if !delta_f.iter().chain(f.iter()).all(|v| v.is_finite()) {
            // No SVD of a non-finite matrix (it never ends): take the plain step.
            return g.as_slice().to_vec();
        }
        let svd = delta_f.svd(true, true);
        match svd.solve(&f, 1e-10 * svd.singular_values.max()) {
            Ok(gamma) if gamma.iter().all(|v| v.is_finite()) => {
                (g - delta_g * gamma).as_slice().to_vec()
            }
            _ => g.as_slice().to_vec(),
        }
    }
}
