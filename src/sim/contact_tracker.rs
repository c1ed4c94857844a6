//! Tracker rows beside simulated contacts (`simulate --observation flush,tracker`, issue 29):
//! the true robot's tool origins seen by a tracker in its own frame at random configurations
//! within the joint limits, with Gaussian position noise. The configurations are recorded
//! exactly (the tracker's σ is the rows' whole noise), so a fit's σ̂ of the tracker rows is 1
//! when the declared σ is the one simulated.

use super::contacts::random_configuration;
use super::stance::contact_limits;
use crate::kinematics::McpcModel;
use crate::math::{Pose, Vec3};
use crate::measurement::{Measurement, Observation};
use crate::tree::KinematicTree;
use nalgebra::{Translation3, UnitQuaternion};
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// σ of a simulated tracker position (m, each coordinate).
pub const CONTACT_TRACKER_SIGMA: f64 = 1e-4;

/// The simulated tracker's frame: the reference link's origin 1.5 m in front of it, 0.2 m to
/// the side and 0.8 m below, turned 30° about its vertical (a tracker on a tripod).
pub fn contact_tracker_frame() -> Pose {
    Pose::from_parts(
        Translation3::new(1.5, 0.2, -0.8),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 30f64.to_radians()),
    )
}

/// `count` tracker rows of each tool in `tools` made by `truth`: the tool origin in
/// `tracker_from_reference`'s frame plus noise of σ `sigma` (m), at random configurations.
pub fn contact_tracker_rows(
    tree: &KinematicTree,
    truth: &McpcModel,
    tools: &[usize],
    count: usize,
    (tracker_from_reference, sigma): (&Pose, f64),
    rng: &mut ChaCha8Rng,
) -> Vec<Measurement> {
    let limits = contact_limits(tree, truth);
    let mut rows = Vec::with_capacity(count * tools.len());
    for _ in 0..count {
        let q = random_configuration(&limits, rng);
        for &tool in tools {
            let at = tracker_from_reference * truth.tool_pose(tool, &q);
            let noise = Vec3::from_fn(|_, _| {
                let z: f64 = StandardNormal.sample(rng);
                sigma * z
            });
            rows.push(Measurement {
                tool,
                q: q.clone(),
                observation: Observation::Position(at.translation.vector + noise),
                stage: None,
                payload: None,
                session: None,
            });
        }
    }
    rows
}
