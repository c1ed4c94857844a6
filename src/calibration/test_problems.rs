//! Simulated identification problems shared by the unit tests of the solver's parts
//! (`normal_equations`, `coarse_to_fine`).

use crate::kinematics::McpcModel;
use crate::measurement::{Measurement, Observation};
use crate::{detect_branches, load_urdf};
use nalgebra::{UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

/// The built-in Robonaut and its number of joint values.
pub(super) fn robonaut() -> (McpcModel, usize) {
    robonaut_with_branches().0
}

/// The built-in Robonaut, its number of joint values and its branches.
pub(super) fn robonaut_with_branches() -> ((McpcModel, usize), crate::tree::Branches) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/robonaut/robonaut.urdf");
    let tree = load_urdf(&path).expect("robonaut.urdf loads").tree;
    let branches = detect_branches(&tree, None).expect("branches");
    let model = McpcModel::from_tree(&tree, &branches).expect("model");
    ((model, tree.dof_count()), branches)
}

/// Measurements of a model off the nominal one at random configurations: full poses, or
/// positions only (a rank-deficient problem).
pub(super) fn problem(
    (model, dofs): &(McpcModel, usize),
    configurations: usize,
    poses: bool,
) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut truth = model.clone();
    let values: Vec<f64> = model
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-0.02..0.02))
        .collect();
    truth.set_parameters(&values).expect("parameters");
    let mut measurements = Vec::new();
    for _ in 0..configurations {
        let q: Vec<f64> = (0..*dofs).map(|_| rng.random_range(-2.0..2.0)).collect();
        for (tool, pose) in truth.tool_poses(&q).into_iter().enumerate() {
            let observation = if poses {
                Observation::Pose(pose)
            } else {
                Observation::Position(pose.translation.vector)
            };
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation,
                stage: None,
                session: None,
            });
        }
    }
    measurements
}

/// `measurements` with uniform noise of half-width `[position (m), rotation (rad)]` on every
/// coordinate of the poses (seeded).
pub(super) fn with_noise(mut measurements: Vec<Measurement>, noise: [f64; 2]) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(24);
    let mut draw = |half: f64| Vector3::from_fn(|_, _| rng.random_range(-half..half));
    for m in &mut measurements {
        if let Observation::Pose(pose) = &mut m.observation {
            pose.translation.vector += draw(noise[0]);
            pose.rotation = UnitQuaternion::from_scaled_axis(draw(noise[1])) * pose.rotation;
        }
    }
    measurements
}
