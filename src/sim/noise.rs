//! Laser-tracker measurement noise; the three-target tool frame it measures is built by
//! [`crate::measurement::frame_from_targets`] (paper section 5.3.1).

use crate::error::{Error, Result};
use crate::math::{Pose, Vec3};
use crate::measurement::{frame_from_targets, targets_on, Observation};
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Per-coordinate Gaussian noise whose standard deviation grows with the distance from the
/// tracker: `σ = constant + per_metre · distance`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct NoiseModel {
    /// σ at the tracker (m).
    pub constant: f64,
    /// Growth of σ per metre of distance (m/m).
    pub per_metre: f64,
    /// Where the tracker stands, in the robot base frame (m).
    pub tracker: [f64; 3],
}

impl NoiseModel {
    /// The Leica AT901 class (the paper's instrument): about 15 µm + 6 µm/m per coordinate,
    /// the tracker 3 m in front of the robot.
    pub fn at901() -> Self {
        Self {
            constant: 15e-6,
            per_metre: 6e-6,
            tracker: [3.0, 0.0, 0.0],
        }
    }

    /// No noise.
    pub fn none() -> Self {
        Self {
            constant: 0.0,
            per_metre: 0.0,
            tracker: [3.0, 0.0, 0.0],
        }
    }

    /// Parses `0`/`none`, `at901`, or `CONSTANT_UM+PER_METRE_UM` (e.g. `15+6`, micrometres).
    pub fn parse(text: &str) -> Result<Self> {
        let bad = || {
            Error::setting(
                "noise",
                format!("'{text}' is not a noise model; use 0 (none), at901, or CONSTANT+PER_METRE in µm (e.g. 15+6)"),
            )
        };
        match text.trim() {
            "0" | "none" => Ok(Self::none()),
            "at901" | "AT901" => Ok(Self::at901()),
            other => {
                let (constant, per_metre) = other.split_once('+').ok_or_else(bad)?;
                let constant: f64 = constant.trim().parse().map_err(|_| bad())?;
                let per_metre: f64 = per_metre.trim().parse().map_err(|_| bad())?;
                // Up to 1 m (and 1 m per metre) of noise: more overflows nothing, but means nothing.
                let range = 0.0..=1e6;
                if !(range.contains(&constant) && range.contains(&per_metre)) {
                    return Err(bad());
                }
                Ok(Self {
                    constant: constant * 1e-6,
                    per_metre: per_metre * 1e-6,
                    ..Self::at901()
                })
            }
        }
    }

    /// Whether the model adds no noise.
    pub fn is_none(&self) -> bool {
        self.constant == 0.0 && self.per_metre == 0.0
    }

    /// σ per coordinate at `point` (m).
    pub fn sigma(&self, point: &Vec3) -> f64 {
        self.constant + self.per_metre * (point - Vec3::from(self.tracker)).norm()
    }

    /// `point` as the tracker reports it.
    pub fn measure_point(&self, point: &Vec3, rng: &mut ChaCha8Rng) -> Vec3 {
        let sigma = self.sigma(point);
        if sigma == 0.0 {
            return *point;
        }
        match Normal::new(0.0, sigma) {
            Ok(normal) => {
                point + Vec3::new(normal.sample(rng), normal.sample(rng), normal.sample(rng))
            }
            Err(_) => *point,
        }
    }
}

/// How many targets are fixed on each tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Targets {
    /// One reflector at the tool origin: a position.
    One,
    /// Three reflectors A, B, C: a frame (origin A, X along AB, Z along AB × AC).
    Three,
}

/// What the tracker reports for a tool whose true frame is `tool`.
pub fn observe(
    tool: &Pose,
    targets: Targets,
    noise: &NoiseModel,
    rng: &mut ChaCha8Rng,
) -> Observation {
    match targets {
        Targets::One => Observation::Position(noise.measure_point(&tool.translation.vector, rng)),
        Targets::Three => {
            let [a, b, c] = targets_on(tool).map(|p| noise.measure_point(&p, rng));
            // Targets 10 cm apart with micrometre noise cannot become collinear.
            Observation::Pose(frame_from_targets(&a, &b, &c).unwrap_or(*tool))
        }
    }
}
