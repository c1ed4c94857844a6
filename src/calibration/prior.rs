//! A Gaussian prior on the parameters: rows `(θ₀ − θ)/σ` added to the normal equations, so
//! that parameters the data barely see stay near their nominal values and the covariance
//! includes what the prior says. See `docs/identification.md` (prior).

use crate::kinematics::{McpcModel, ParameterKind, ParameterOwner};

/// The default prior σ of an MCPC frame angle (α, β): 0.2°.
pub const DEFAULT_ANGLE_SIGMA: f64 = 0.2 * std::f64::consts::PI / 180.0;

/// The default prior σ of an MCPC frame length (x, y): 2 mm.
pub const DEFAULT_LENGTH_SIGMA: f64 = 2e-3;

/// The default prior σ of a joint zero offset: 1°.
pub const DEFAULT_OFFSET_SIGMA: f64 = std::f64::consts::PI / 180.0;

/// The default prior σ of a harmonic coefficient or a backlash: 0.2°.
pub const DEFAULT_JOINT_ERROR_SIGMA: f64 = 0.2 * std::f64::consts::PI / 180.0;

/// A Gaussian prior: per parameter of the model (flat vector), its centre and σ (rad or m;
/// infinite: no prior on it).
#[derive(Debug, Clone, PartialEq)]
pub struct Prior {
    /// The centre of each parameter (the nominal value).
    pub center: Vec<f64>,
    /// The σ of each parameter; `f64::INFINITY` leaves it free of the prior.
    pub sigma: Vec<f64>,
    /// Divide every σ by the residual scale σ̂ of the fit without the prior (when above 1), so
    /// that the prior weighs against the data as it would if the declared noise were right.
    pub follow_residual_scale: bool,
}

impl Prior {
    /// The default prior of `model` centred on `nominal`'s values: MCPC frame angles
    /// [`DEFAULT_ANGLE_SIGMA`], lengths [`DEFAULT_LENGTH_SIGMA`], joint offsets
    /// [`DEFAULT_OFFSET_SIGMA`], harmonics and backlash [`DEFAULT_JOINT_ERROR_SIGMA`]; tools and
    /// the measurement frame have none (their nominal is a guess, not a drawing).
    pub fn default_for(model: &McpcModel, nominal: &[f64]) -> Self {
        let sigma = model
            .parameter_layout()
            .iter()
            .map(|(owner, kind)| match (owner, kind) {
                (ParameterOwner::Frame(_), ParameterKind::Offset) => DEFAULT_OFFSET_SIGMA,
                (
                    ParameterOwner::Frame(_),
                    ParameterKind::Sine | ParameterKind::Cosine | ParameterKind::Backlash,
                ) => DEFAULT_JOINT_ERROR_SIGMA,
                (ParameterOwner::Frame(_), kind) if kind.is_angle() => DEFAULT_ANGLE_SIGMA,
                (ParameterOwner::Frame(_), _) => DEFAULT_LENGTH_SIGMA,
                _ => f64::INFINITY,
            })
            .collect();
        Self {
            center: nominal.to_vec(),
            sigma,
            follow_residual_scale: false,
        }
    }

    /// The same prior with every σ multiplied by `factor` (> 0; else unchanged).
    pub fn scaled(mut self, factor: f64) -> Self {
        if factor.is_finite() && factor > 0.0 {
            for sigma in &mut self.sigma {
                *sigma *= factor;
            }
        }
        self
    }

    /// The same prior for a reduced model whose first `shared` parameters are this one's
    /// (a coupled stage: the torso frames), with `count` parameters in all.
    pub fn for_reduced_model(&self, shared: usize, count: usize) -> Self {
        let pick = |values: &[f64], fill: f64| -> Vec<f64> {
            (0..count)
                .map(|p| {
                    if p < shared {
                        values.get(p).copied().unwrap_or(fill)
                    } else {
                        fill
                    }
                })
                .collect()
        };
        Self {
            center: pick(&self.center, 0.0),
            sigma: pick(&self.sigma, f64::INFINITY),
            follow_residual_scale: self.follow_residual_scale,
        }
    }

    /// The prior rows over the `free` parameters, with every weight multiplied by `scale²`.
    pub(crate) fn rows(&self, free: &[usize], scale: f64) -> PriorRows {
        let weight = |p: usize| {
            let sigma = self.sigma.get(p).copied().unwrap_or(f64::INFINITY);
            if sigma.is_finite() && sigma > 0.0 {
                scale * scale / (sigma * sigma)
            } else {
                0.0
            }
        };
        PriorRows {
            weights: free.iter().map(|&p| weight(p)).collect(),
            centers: free
                .iter()
                .map(|&p| self.center.get(p).copied().unwrap_or(0.0))
                .collect(),
        }
    }
}

/// The prior's rows over the free parameters (the columns of the identification).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PriorRows {
    /// `1/σ²` per free column (0: no prior row).
    pub(crate) weights: Vec<f64>,
    /// The centre per free column.
    pub(crate) centers: Vec<f64>,
}

impl PriorRows {
    /// How many rows the prior adds.
    pub(crate) fn count(&self) -> usize {
        self.weights.iter().filter(|w| **w > 0.0).count()
    }

    /// The same rows with every weight times `factor` (a prior against a fraction of the data).
    pub(crate) fn scaled(&self, factor: f64) -> PriorRows {
        PriorRows {
            weights: self.weights.iter().map(|w| w * factor).collect(),
            centers: self.centers.clone(),
        }
    }
}
