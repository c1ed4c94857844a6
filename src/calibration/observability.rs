//! Observability indices O1–O5 and the planning criteria of a column-scaled identification
//! Jacobian's singular values. See `docs/identifiability.md`.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// The observability indices of a column-scaled identification Jacobian with singular values
/// `σ₁ ≥ … ≥ σ_L` from `m` observations. See `docs/identifiability.md`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ObservabilityIndices {
    /// O1 (Borm & Menq 1991): `(σ₁·…·σ_L)^(1/L) / √m`; larger is better.
    pub o1: f64,
    /// O2 (Driels & Pathre 1990): the condition number `σ₁ / σ_L`; smaller is better, ∞ when
    /// `σ_L = 0` (written `null` in JSON).
    pub o2: f64,
    /// O3 (Nahvi, Hollerbach & Hayward 1994): the minimum singular value `σ_L`; larger is better.
    pub o3: f64,
    /// O4 (Nahvi & Hollerbach 1996), noise amplification index: `σ_L² / σ₁`; larger is better.
    pub o4: f64,
    /// O5 (Nahvi & Hollerbach 1996): `1 / mean(1/σᵢ)`, the harmonic mean; larger is better.
    pub o5: f64,
}

/// The observability indices of `singular_values` (any order; every one counts, so a zero
/// makes O1 = O3 = O4 = O5 = 0 and O2 = ∞) from `measurements` observations (O1's `m`).
///
/// No values, or no measurements for O1, give zeros (and O2 = ∞): nothing is observed.
pub fn observability_indices(singular_values: &[f64], measurements: usize) -> ObservabilityIndices {
    let count = singular_values.len();
    let largest = singular_values.iter().copied().fold(0.0, f64::max);
    let smallest = singular_values
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    if count == 0 || smallest.is_nan() || smallest <= 0.0 {
        return ObservabilityIndices {
            o1: 0.0,
            o2: f64::INFINITY,
            o3: 0.0,
            o4: 0.0,
            o5: 0.0,
        };
    }
    // The geometric mean through logarithms: a product of 64 singular values over- or
    // underflows easily.
    let mean_log = singular_values.iter().map(|s| s.ln()).sum::<f64>() / count as f64;
    let o1 = if measurements == 0 {
        0.0
    } else {
        mean_log.exp() / (measurements as f64).sqrt()
    };
    let mean_inverse = singular_values.iter().map(|s| 1.0 / s).sum::<f64>() / count as f64;
    ObservabilityIndices {
        o1,
        o2: largest / smallest,
        o3: smallest,
        o4: smallest * smallest / largest,
        o5: 1.0 / mean_inverse,
    }
}

/// A scalar criterion a pose planner maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    /// Borm & Menq's O1: the geometric mean of the singular values over √m.
    O1,
    /// D-optimality: `log det(J_sᵀ·J_s) = 2·Σ log σᵢ` of the scaled Jacobian.
    D,
    /// The minimum singular value (O3).
    O3,
}

impl std::str::FromStr for Criterion {
    type Err = Error;

    /// `o1`, `d` or `o3`, in any case.
    fn from_str(text: &str) -> Result<Self> {
        match text.trim().to_ascii_lowercase().as_str() {
            "o1" => Ok(Criterion::O1),
            "d" => Ok(Criterion::D),
            "o3" => Ok(Criterion::O3),
            _ => Err(Error::InvalidData {
                origin: "criterion".into(),
                message: format!("'{text}' is not a criterion; use o1, d or o3"),
            }),
        }
    }
}

impl std::fmt::Display for Criterion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Criterion::O1 => "o1",
            Criterion::D => "d",
            Criterion::O3 => "o3",
        })
    }
}

/// The value of `criterion` for `singular_values` from `measurements` observations; larger is
/// better for all three. D is −∞ when a singular value is zero.
pub fn criterion_value(criterion: Criterion, singular_values: &[f64], measurements: usize) -> f64 {
    match criterion {
        Criterion::O1 => observability_indices(singular_values, measurements).o1,
        Criterion::O3 => observability_indices(singular_values, measurements).o3,
        Criterion::D => {
            if singular_values.is_empty() || singular_values.iter().any(|s| s.is_nan() || *s <= 0.0)
            {
                f64::NEG_INFINITY
            } else {
                2.0 * singular_values.iter().map(|s| s.ln()).sum::<f64>()
            }
        }
    }
}
