//! One still interval of a pairing and whether it became a measurement (data only).

use crate::math::{Rotation, Vec3};

/// Whether a plateau became a measurement.
#[derive(Debug, Clone, PartialEq)]
pub enum PlateauStatus {
    /// Paired: one measurement row.
    Kept,
    /// Not paired, and why.
    Rejected(String),
}

/// One interval where the joints were still, on the joint log's clock.
#[derive(Debug, Clone, PartialEq)]
pub struct Plateau {
    /// Start and end (s) of the samples averaged (for a rejected plateau: of the joints' run).
    pub start: f64,
    /// See `start`.
    pub end: f64,
    /// Mean of every watched joint.
    pub joint_mean: Vec<f64>,
    /// Standard deviation of every watched joint.
    pub joint_std: Vec<f64>,
    /// Joint samples averaged.
    pub joint_samples: usize,
    /// Mean target position (m), if the tracker has samples in the interval.
    pub position: Option<Vec3>,
    /// RMS distance of the target's samples from `position` (m).
    pub position_spread: Option<f64>,
    /// Mean orientation of the rigid body, when the tracker reports poses.
    pub orientation: Option<Rotation>,
    /// RMS angle of the samples from `orientation` (rad).
    pub rotation_spread: Option<f64>,
    /// Tracker samples averaged.
    pub tracker_samples: usize,
    /// Kept or rejected.
    pub status: PlateauStatus,
}
