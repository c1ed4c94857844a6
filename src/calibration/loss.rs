//! The robust losses (Huber, Cauchy) that turn a measurement's standardized residual norm
//! into its weight, and the robust scale of the norms; `robust` runs the reweighting with
//! them. See `docs/identification.md`, "Robust estimation".

use crate::measurement::Measurement;
use serde::Serialize;

/// How measurements are weighted by their residuals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RobustLoss {
    /// Huber: weight 1 up to the threshold [`threshold`], `k/u` beyond. Convex, so the
    /// result does not depend on where the iteration starts; clean data keep weight 1 and
    /// give the least-squares result bit for bit.
    #[default]
    Huber,
    /// Cauchy: weight `1/(1 + (u/k)²)`. Redescending (a blunder's pull vanishes), but every
    /// measurement is down-weighted a little, so clean data give a slightly different result.
    Cauchy,
    /// Plain least squares: every weight 1.
    Off,
}

impl RobustLoss {
    /// `huber`, `cauchy` or `off`.
    pub fn as_str(self) -> &'static str {
        match self {
            RobustLoss::Huber => "huber",
            RobustLoss::Cauchy => "cauchy",
            RobustLoss::Off => "off",
        }
    }

    /// The weight of a measurement with `rows` rows (3 or 6) whose residual norm is `u` robust
    /// scales.
    pub fn weight(self, u: f64, rows: usize) -> f64 {
        let k = threshold(rows);
        match self {
            RobustLoss::Off => 1.0,
            RobustLoss::Huber if u <= k => 1.0,
            RobustLoss::Huber => k / u,
            RobustLoss::Cauchy => 1.0 / (1.0 + (u / k).powi(2)),
        }
    }
}

impl RobustLoss {
    /// The standardized norm beyond which a measurement's weight is below
    /// [`OUTLIER_WEIGHT`] (infinite when the loss is off).
    pub fn outlier_norm(self, rows: usize) -> f64 {
        let k = threshold(rows);
        match self {
            RobustLoss::Huber => k / OUTLIER_WEIGHT,
            RobustLoss::Cauchy => k * (1.0 / OUTLIER_WEIGHT - 1.0).sqrt(),
            RobustLoss::Off => f64::INFINITY,
        }
    }
}

impl std::fmt::Display for RobustLoss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The threshold `k` of the losses for a measurement with `rows` rows: the standardized norm
/// of a clean Gaussian measurement exceeds it with probability 10⁻⁸ (`√χ²` quantile with 3 or
/// 6 degrees of freedom), so clean data keep weight 1 even over thousands of measurements and
/// with the scale estimated from few of them.
pub fn threshold(rows: usize) -> f64 {
    if rows <= 3 {
        6.335
    } else {
        6.954
    }
}

/// The median of `√χ²` with 3 or 6 degrees of freedom: the median norm of a clean measurement
/// with unit noise per row.
pub(super) fn chi_median(rows: usize) -> f64 {
    if rows <= 3 {
        1.5382
    } else {
        2.3126
    }
}

/// A measurement whose weight falls below this is an outlier: named, and left out of the
/// final fit. For Huber that is a norm beyond twice the threshold (about 14 robust σ for a
/// pose), for Cauchy beyond the threshold.
pub const OUTLIER_WEIGHT: f64 = 0.5;

/// The robust scale is never taken below this (in units of the assumed σ's): residuals
/// smaller than 1 % of the assumed noise (noise-free data, round-off) say nothing about
/// blunders.
pub const SCALE_FLOOR: f64 = 0.01;

/// One measurement's residual at a model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Residual {
    /// Position error `‖measured − predicted‖` (m).
    pub position: f64,
    /// Rotation error (rad); `None` for a position observation.
    pub rotation: Option<f64>,
    /// `‖W·r‖`: the position error over `position_sigma` and the rotation error over
    /// `rotation_sigma`, combined.
    pub norm: f64,
}

/// The weight of every measurement under `loss` at robust scale `scale`.
pub fn weights_of(
    loss: RobustLoss,
    residuals: &[Residual],
    measurements: &[Measurement],
    scale: f64,
) -> Vec<f64> {
    residuals
        .iter()
        .zip(measurements)
        .map(|(r, m)| loss.weight(r.norm / scale, m.observation.rows()))
        .collect()
}

/// The robust scale of standardized residual norms: the median of `norm / median(√χ²_d)`
/// (a median absolute deviation about zero, the residuals' expected value, consistent for
/// Gaussian rows), floored at [`SCALE_FLOOR`]. 1 when there are no residuals.
pub fn robust_scale(residuals: &[Residual], measurements: &[Measurement]) -> f64 {
    median_scale(
        residuals
            .iter()
            .zip(measurements)
            .map(|(r, m)| r.norm / chi_median(m.observation.rows())),
    )
}

/// The median of the finite `normalised` norms, floored at [`SCALE_FLOOR`]; 1 without any.
pub(super) fn median_scale(normalised: impl Iterator<Item = f64>) -> f64 {
    let mut normalised: Vec<f64> = normalised.filter(|v| v.is_finite()).collect();
    if normalised.is_empty() {
        return 1.0;
    }
    // The middle elements by selection, not a sort (linear time: 1.6·10⁶ norms at 10⁶
    // configurations); the same values a sort puts there.
    let n = normalised.len();
    let (below, &mut upper, _) = normalised.select_nth_unstable_by(n / 2, f64::total_cmp);
    let median = if n % 2 == 1 {
        upper
    } else {
        let lower = below
            .iter()
            .copied()
            .max_by(f64::total_cmp)
            .unwrap_or(upper);
        0.5 * (lower + upper)
    };
    median.max(SCALE_FLOOR)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The selected median is the sorted one, bit for bit, for odd and even counts, repeated
    /// values and non-finite norms (left out).
    #[test]
    fn the_selected_median_is_the_sorted_one() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for count in [1, 2, 3, 4, 101, 1000, 1001] {
            let mut values: Vec<f64> = (0..count).map(|_| 0.02 + 3.0 * next()).collect();
            values.extend([f64::NAN, f64::INFINITY, values[0]]);
            let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
            sorted.sort_by(f64::total_cmp);
            let n = sorted.len();
            let expected = match n % 2 {
                1 => sorted[n / 2],
                _ => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
            };
            assert_eq!(
                median_scale(values.into_iter()).to_bits(),
                expected.max(SCALE_FLOOR).to_bits()
            );
        }
        assert_eq!(median_scale(std::iter::empty()), 1.0);
    }
}
