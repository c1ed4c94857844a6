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

/// Joint-angle errors of the true robot beyond its geometry (`kinematics::joint_errors`):
/// `θ = q + a·sin q + b·cos q + h·sign(τ)` on every revolute joint.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct JointErrorRanges {
    /// First-harmonic errors: `a` and `b` uniform in ±this (rad); 0: none.
    pub harmonics: f64,
    /// Backlash, half the dead band: `h` uniform in [this/2, this] (rad; a real dead band is
    /// never negative); 0: none. Needs the URDF's inertials (the gravity torque signs).
    pub backlash: f64,
}

impl JointErrorRanges {
    /// Whether the truth has any joint-angle error.
    pub fn any(&self) -> bool {
        self.harmonics > 0.0 || self.backlash > 0.0
    }
}

/// `truth` with random joint-angle errors of `ranges` on every revolute joint (unchanged when
/// `ranges` has none); the backlash signs follow the gravity torques of `tree`'s inertials at
/// `truth`. The ranges must be finite, ≥ 0 and within [`MAX_ANGLE`].
pub fn with_joint_errors(
    truth: &McpcModel,
    tree: &crate::tree::KinematicTree,
    ranges: &JointErrorRanges,
    rng: &mut ChaCha8Rng,
) -> Result<McpcModel> {
    use crate::kinematics::{GravitySigns, JointErrorTerms, ParameterKind};
    for (name, range) in [
        ("harmonic", ranges.harmonics),
        ("backlash", ranges.backlash),
    ] {
        if !(range.is_finite() && (0.0..=MAX_ANGLE).contains(&range)) {
            return Err(Error::InvalidData {
                origin: "simulation".into(),
                message: format!(
                    "the {name} joint error {range} rad must be a number from 0 to {MAX_ANGLE:e}"
                ),
            });
        }
    }
    if !ranges.any() {
        return Ok(truth.clone());
    }
    let terms = JointErrorTerms {
        offsets: false,
        harmonics: ranges.harmonics > 0.0,
        backlash: ranges.backlash > 0.0,
    };
    let gravity = if terms.backlash {
        Some(GravitySigns::new(tree, truth)?)
    } else {
        None
    };
    let mut model = truth.with_joint_errors(terms, gravity)?;
    let mut values = model.parameters();
    for (value, (_, kind)) in values.iter_mut().zip(model.parameter_layout()) {
        match kind {
            ParameterKind::Sine | ParameterKind::Cosine => {
                *value = rng.random_range(-ranges.harmonics..ranges.harmonics);
            }
            ParameterKind::Backlash => {
                *value = rng.random_range(0.5 * ranges.backlash..ranges.backlash);
            }
            _ => {}
        }
    }
    model.set_parameters(&values)?;
    Ok(model)
}
