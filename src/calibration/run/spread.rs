//! The spread of each validation prediction that the identification noise leaves.

use super::assembled_covariance;
use crate::calibration::plan::CalibrationReport;
use crate::kinematics::ChainFrames;
use crate::measurement::Measurement;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Per validation observation, `√trace(J_p·C·J_pᵀ)` with `C` the assembled parameter
/// covariance ([`assembled_covariance`]) (mm): the spread of the predicted position that the
/// identification noise leaves.
pub(super) fn predicted_spread(report: &CalibrationReport, validation: &[Measurement]) -> Vec<f64> {
    // A stage without redundancy has no covariance: nothing can be predicted (not zero).
    let undetermined = report
        .stages
        .iter()
        .any(|s| s.identification.covariance.is_none());
    if validation.is_empty() || undetermined {
        return Vec::new();
    }
    let covariance = assembled_covariance(report);
    let model = &report.model;
    let buffers = || {
        let jacobian = DMatrix::zeros(6, model.parameter_count());
        (ChainFrames::default(), jacobian, Vec::new())
    };
    // In parallel, in validation order; each row's figure from its own Jacobian alone.
    validation
        .par_iter()
        .map_init(buffers, |(chain, jacobian, columns), m| {
            model.tool_jacobian_into(m.tool, &m.q, chain, jacobian);
            position_variance(jacobian, &covariance, columns)
                .max(0.0)
                .sqrt()
                * 1e3
        })
        .collect()
}

/// `trace(J_p·C·J_pᵀ)` for the position rows `J_p` of a 6 × n tool Jacobian, summed over
/// the columns where `J_p` is not zero (a tool's chain: about half of a branched robot's),
/// `columns` a buffer for them.
fn position_variance(
    jacobian: &DMatrix<f64>,
    covariance: &DMatrix<f64>,
    columns: &mut Vec<usize>,
) -> f64 {
    // Column-major: column c of the Jacobian is `j[6c..6c + 6]`, its position part the first 3.
    let j = jacobian.as_slice();
    columns.clear();
    columns.extend((0..jacobian.ncols()).filter(|&c| j[6 * c..6 * c + 3] != [0.0; 3]));
    let mut total = 0.0;
    for &b in columns.iter() {
        let c_b = &covariance.as_slice()[covariance.nrows() * b..][..covariance.nrows()];
        let mut w = [0.0; 3];
        for &a in columns.iter() {
            let c = c_b[a];
            for (r, w) in w.iter_mut().enumerate() {
                *w += c * j[6 * a + r];
            }
        }
        total += (0..3).map(|r| j[6 * b + r] * w[r]).sum::<f64>();
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    /// The sum over the Jacobian's non-zero columns is the dense `trace(J_p·C·J_pᵀ)`.
    #[test]
    fn the_sparse_sum_is_the_dense_trace() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let n = 30;
        let a = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let covariance = &a * a.transpose() * 1e-6;
        let mut columns = Vec::new();
        for trial in 0..20 {
            // Columns off the chain are zero; one column has only a rotation part.
            let jacobian = DMatrix::from_fn(6, n, |r, c| {
                let off_chain = (c + trial) % 3 == 0 || (c == 5 && r < 3);
                if off_chain {
                    0.0
                } else {
                    rng.random_range(-1.0..1.0)
                }
            });
            let p = jacobian.rows(0, 3);
            let dense = (p * &covariance * p.transpose()).trace();
            let sparse = position_variance(&jacobian, &covariance, &mut columns);
            assert!((sparse - dense).abs() <= 1e-12 * dense, "{sparse} {dense}");
            assert!(columns.len() < n);
        }
    }
}
