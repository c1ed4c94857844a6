//! Pairing a joint-state log with a tracker log (`treecal pair`): the clock offset between
//! the two from the motion itself, then the static plateaus where both are still, averaged
//! into one measurement each. SI units, times in seconds; no files here (readers: `crate::io`).
//! See docs/file-formats.md ("Joint-state and tracker logs") and docs/workflows.md.

mod average;
mod clock;
mod plateau;
mod plateaus;
mod speed;

pub use speed::SpeedNorm;

pub use clock::{estimate_clock_offset, ClockEstimate, ClockOptions, ClockVerdict};
pub use plateaus::{find_plateaus, Plateau, PlateauOptions, PlateauSearch, PlateauStatus};
pub use speed::windowed_speeds;

use crate::math::{Rotation, Vec3};

/// Joint values over time, on the joint log's clock.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointSeries {
    /// The watched joints' names (messages name them).
    pub names: Vec<String>,
    /// Whether each watched joint is prismatic (values in m) rather than rotational (rad).
    pub prismatic: Vec<bool>,
    /// Sample times (s), increasing.
    pub times: Vec<f64>,
    /// Per sample, one value per watched joint (rad, or m for prismatic joints).
    pub values: Vec<Vec<f64>>,
}

/// Tracker samples of one target or rigid body over time.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackerSeries {
    /// Sample times (s), increasing; on the tracker's clock until shifted by the offset.
    pub times: Vec<f64>,
    /// The target's position (m) per sample, in the tracker frame.
    pub positions: Vec<Vec3>,
    /// The rigid body's orientation per sample, when the tracker reports poses.
    pub orientations: Option<Vec<Rotation>>,
}

impl TrackerSeries {
    /// The same samples with `offset` added to every time (tracker clock → joint clock).
    pub fn shifted(&self, offset: f64) -> Self {
        Self {
            times: self.times.iter().map(|t| t + offset).collect(),
            ..self.clone()
        }
    }
}

/// The median spacing of increasing times (s); 0 with fewer than two.
pub fn median_period(times: &[f64]) -> f64 {
    let mut steps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.is_empty() {
        return 0.0;
    }
    steps.sort_by(f64::total_cmp);
    steps[steps.len() / 2]
}
