//! The simulated "true" robot: the nominal model with every parameter off by a random error
//! (paper section 5.2: ±0.05 rad on angles, ±5 cm on lengths).

use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::limits::{MAX_ANGLE, MAX_LENGTH};
use rand::rngs::ChaCha8Rng;
use rand::RngExt;

/// Half-widths of the uniform parameter errors of the true robot.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ErrorRanges {
    /// Angle parameters (α, β, γ): uniform in ±this (rad).
    pub angle: f64,
    /// Length parameters (x, y, z): uniform in ±this (m).
    pub length: f64,
}

impl Default for ErrorRanges {
    /// The paper's section 5.2 values.
    fn default() -> Self {
        Self {
            angle: 0.05,
            length: 0.05,
        }
    }
}

/// A copy of `nominal` with every MCPC parameter off by a uniform random error; the ranges
/// must be finite, ≥ 0 and within [`MAX_ANGLE`] and [`MAX_LENGTH`].
pub fn true_model(
    nominal: &McpcModel,
    ranges: &ErrorRanges,
    rng: &mut ChaCha8Rng,
) -> Result<McpcModel> {
    for (name, range, bound) in [
        ("angle", ranges.angle, MAX_ANGLE),
        ("length", ranges.length, MAX_LENGTH),
    ] {
        if !(range.is_finite() && (0.0..=bound).contains(&range)) {
            return Err(Error::InvalidData {
                origin: "simulation".into(),
                message: format!(
                    "the {name} error range {range} must be a number from 0 to {bound:e} \
                     (docs/file-formats.md, \"Limits\")"
                ),
            });
        }
    }
    let values: Vec<f64> = nominal
        .parameters()
        .iter()
        .zip(nominal.parameter_layout())
        .map(|(value, (_, kind))| {
            let range = if kind.is_angle() {
                ranges.angle
            } else {
                ranges.length
            };
            if range > 0.0 {
                value + rng.random_range(-range..range)
            } else {
                *value
            }
        })
        .collect();
    let mut truth = nominal.clone();
    truth.set_parameters(&values)?;
    Ok(truth)
}
