//! Blunders for studying robust estimation: a target bumped on the tool (or a single target
//! moved) between the robot's move and the tracker's reading.

use crate::math::Vec3;
use crate::measurement::{frame_from_targets, targets_on, Measurement, Observation};
use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// Turns `round(fraction · measurements)` of the measurements into blunders, chosen with a
/// generator of their own seeded from `seed` (so the clean data of a trial stay the same):
/// one of the three targets of a frame observation (A, B or C, at random) or the single
/// target of a position observation moved by `size` (m) in a random direction. Returns the
/// indices of the blunders, ascending.
pub fn inject_blunders(
    measurements: &mut [Measurement],
    fraction: f64,
    size: f64,
    seed: u64,
) -> Vec<usize> {
    let count = ((measurements.len() as f64 * fraction).round() as usize).min(measurements.len());
    if count == 0 {
        return Vec::new();
    }
    // A stream apart from the trial's own.
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x00B1_D0E5_5ED0_u64);
    let mut indices: Vec<usize> = (0..measurements.len()).collect();
    indices.shuffle(&mut rng);
    let mut chosen = indices[..count].to_vec();
    chosen.sort_unstable();
    for &index in &chosen {
        let observation = &mut measurements[index].observation;
        *observation = bumped(observation, size, &mut rng);
    }
    chosen
}

/// `observation` with one target moved by `size` in a random direction.
fn bumped(observation: &Observation, size: f64, rng: &mut ChaCha8Rng) -> Observation {
    let mut direction = Vec3::zeros();
    while direction.norm() < 1e-6 {
        direction = Vec3::from_fn(|_, _| StandardNormal.sample(rng));
    }
    let offset = direction.normalize() * size;
    match observation {
        Observation::Position(p) => Observation::Position(p + offset),
        // A contact has no reading to bump.
        Observation::Contact(contact) => Observation::Contact(contact.clone()),
        Observation::Pose(pose) => {
            let mut targets = targets_on(pose);
            let which = (rand::RngExt::random::<u32>(rng) % 3) as usize;
            targets[which] += offset;
            let [a, b, c] = targets;
            // A bump that makes the targets collinear (`size` near the spacing, in exactly the
            // wrong direction) moves the frame's origin instead.
            Observation::Pose(frame_from_targets(&a, &b, &c).unwrap_or_else(|| {
                let mut moved = *pose;
                moved.translation.vector += offset;
                moved
            }))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Pose;

    #[test]
    fn the_chosen_rows_move_by_the_size_and_the_others_not() {
        let clean: Vec<Measurement> = (0..100)
            .map(|k| Measurement {
                payload: None,
                tool: 0,
                q: vec![k as f64],
                observation: if k % 2 == 0 {
                    Observation::Pose(Pose::identity())
                } else {
                    Observation::Position(Vec3::zeros())
                },
                stage: None,
                session: None,
            })
            .collect();
        let mut data = clean.clone();
        let chosen = inject_blunders(&mut data, 0.03, 0.05, 7);
        assert_eq!(chosen.len(), 3);
        for (k, (a, b)) in clean.iter().zip(&data).enumerate() {
            assert_eq!(a == b, !chosen.contains(&k), "row {k}");
            if let (Observation::Position(p), Observation::Position(q)) =
                (&a.observation, &b.observation)
            {
                let moved = (p - q).norm();
                assert!(moved == 0.0 || (moved - 0.05).abs() < 1e-12, "row {k}");
            }
        }
        assert_eq!(
            inject_blunders(&mut data, 0.0, 0.05, 7),
            Vec::<usize>::new()
        );
    }
}
