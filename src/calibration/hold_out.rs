//! The validation data a calibration holds out when none is given: a seeded fifth of the
//! configurations.

use crate::error::{Error, Result};
use crate::measurement::Measurement;
use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use rand::SeedableRng;

/// Splits off a seeded fifth of the configurations for validation: whole configurations
/// (every tool observed there), never torso-stage ones (the staged plan needs them), at
/// least one. Returns `(identification, validation)`.
pub fn hold_out(
    measurements: &[Measurement],
    fraction: f64,
    seed: u64,
) -> Result<(Vec<Measurement>, Vec<Measurement>)> {
    let (identification, validation) = hold_out_indices(measurements, fraction, seed)?;
    let pick = |indices: Vec<usize>| indices.iter().map(|&i| measurements[i].clone()).collect();
    Ok((pick(identification), pick(validation)))
}

/// [`hold_out`] as indices into `measurements` (each part in file order), so that callers can
/// carry row ids along.
pub fn hold_out_indices(
    measurements: &[Measurement],
    fraction: f64,
    seed: u64,
) -> Result<(Vec<usize>, Vec<usize>)> {
    // Distinct configurations, in file order, with the stage they belong to (hashed: a linear
    // search made this O(N²)). `+ 0.0` makes −0 and +0 one key, as `==` does.
    let mut groups: Vec<(&[f64], Option<&str>)> = Vec::new();
    let mut index: std::collections::HashMap<(Vec<u64>, Option<&str>), usize> =
        std::collections::HashMap::new();
    let group_of: Vec<usize> = measurements
        .iter()
        .map(|m| {
            let bits = m.q.iter().map(|v| (v + 0.0).to_bits()).collect();
            *index.entry((bits, m.stage.as_deref())).or_insert_with(|| {
                groups.push((m.q.as_slice(), m.stage.as_deref()));
                groups.len() - 1
            })
        })
        .collect();
    let mut eligible: Vec<usize> = (0..groups.len())
        .filter(|&g| groups[g].1 != Some("torso"))
        .collect();
    let count = ((eligible.len() as f64 * fraction).round() as usize).max(1);
    if eligible.len() < count + 2 {
        return Err(Error::InvalidData {
            origin: "measurements".into(),
            message: format!(
                "{} configurations (not counting torso-stage ones) are too few to hold out a validation set; give one with `validation`",
                eligible.len()
            ),
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    eligible.shuffle(&mut rng);
    let mut held = vec![false; groups.len()];
    for &g in &eligible[..count] {
        held[g] = true;
    }
    let (mut identification, mut validation) = (Vec::new(), Vec::new());
    for (index, &g) in group_of.iter().enumerate() {
        if held[g] {
            validation.push(index);
        } else {
            identification.push(index);
        }
    }
    Ok((identification, validation))
}
