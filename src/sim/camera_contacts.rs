//! Contacts beside the camera (`simulate --observation camera,touch`, issue 29): the true
//! augmented robot of a camera trial also makes contacts (touch, bar, flush, point:
//! [`super::contacts::contact_scene`] on its robot tools), and the camera fit takes them as
//! rows of their own ([`crate::camera::ContactRows`]) with their nuisance values among its
//! unknowns.
//!
//! The contacts' configurations are recorded with the simulation's encoder noise; their rows
//! are weighed by the σ that noise implies at a 0.5 m lever (heights, gaps, bar lengths; tilts
//! by the encoder σ itself), or by the default contact σ's (1 mm, 0.01 rad) when the encoder
//! noise is zero — what a lab declares without a better figure. The fit starts the freed
//! nuisance values `nuisance_start_error` off the truth.

use super::contact_trial::nuisance_start;
use super::contacts::{contact_scene, ContactScene, ContactSimulation};
use crate::calibration::{Noise, Nuisance};
use crate::camera::Unknown;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::tree::KinematicTree;
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;

/// The lever (m) that turns an encoder σ (rad) into a contact row's σ (m).
const LEVER: f64 = 0.5;

/// The contacts the true augmented robot `truth` makes in a trial of seed `seed` (their own
/// random stream: the camera's data are those without contacts), with the fit's starting
/// nuisance values.
pub fn camera_contact_scene(
    tree: &KinematicTree,
    truth: &McpcModel,
    settings: &ContactSimulation,
    seed: u64,
) -> Result<(ContactScene, Nuisance)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xC0A7_AC75_0000_0003);
    let scene = contact_scene(tree, truth, settings, &mut rng)?;
    let start = nuisance_start(&scene, settings.nuisance_start_error, &mut rng)?;
    Ok((scene, start))
}

/// The contacts' unknowns of the camera fit: the scene's freed nuisance values.
pub fn contact_unknowns(scene: &ContactScene) -> impl Iterator<Item = Unknown> + '_ {
    scene.free_nuisance.iter().map(|&k| Unknown::Nuisance(k))
}

/// The σ's the contact rows are weighed by (module documentation).
pub fn contact_noise(settings: &ContactSimulation) -> Noise {
    let sigma = settings.encoder_sigma;
    if sigma > 0.0 {
        Noise {
            height: sigma * LEVER,
            tilt: sigma,
            gap: sigma * LEVER,
            length: sigma * LEVER,
            ..Noise::default()
        }
    } else {
        Noise::default()
    }
}
