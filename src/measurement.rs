//! Measured configurations and what was observed there (data only).

use crate::math::{Pose, Vec3};

/// What a measuring instrument reports for one tool at one configuration, in the
/// measurement frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Observation {
    /// A full tool pose (e.g. the three-target frame of the paper's section 5.3.1).
    Pose(Pose),
    /// The position of one target fixed on the tool (a single laser-tracker reflector).
    Position(Vec3),
}

impl Observation {
    /// Rows this observation contributes to the identification problem (6 or 3).
    pub fn rows(&self) -> usize {
        match self {
            Observation::Pose(_) => 6,
            Observation::Position(_) => 3,
        }
    }
}

/// One measurement: a configuration, the tool observed, and the observation.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Index of the tool in [`crate::McpcModel::tools`].
    pub tool: usize,
    /// The configuration (one value per independent joint of the tree).
    pub q: Vec<f64>,
    /// What was measured.
    pub observation: Observation,
    /// The calibration stage the measurement was taken for (e.g. `torso` for configurations
    /// with the arms locked), if labelled.
    pub stage: Option<String>,
}
