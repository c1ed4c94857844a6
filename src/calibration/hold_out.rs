//! The validation data a calibration holds out when none is given: a seeded fifth of the
//! configurations.

use crate::error::{Error, Result};
use crate::measurement::Measurement;
use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rayon::prelude::*;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};

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
    // Distinct configurations, in file order, with the stage they belong to: found by a
    // digest of each row's key (computed in parallel), then compared exactly (a linear search
    // made this O(N²); a map keyed by the values themselves cost an allocation and a long hash
    // per row, a second at 10⁶ configurations).
    let digests: Vec<u64> = measurements.par_iter().map(key_digest).collect();
    // The first group of each digest; further groups of the same digest (rare) chained.
    let mut groups: Vec<&Measurement> = Vec::new();
    let mut next_of_digest: Vec<Option<usize>> = Vec::new();
    let mut index: HashMap<u64, usize, crate::digests::Digests> = HashMap::default();
    // A configuration's rows (one per tool) follow each other: a row at the previous row's
    // configuration joins its group without a look-up.
    let mut group_of: Vec<usize> = Vec::with_capacity(measurements.len());
    for (row, (m, &digest)) in measurements.iter().zip(&digests).enumerate() {
        if let Some(&g) = group_of.last() {
            if digests[row - 1] == digest && same_key(groups[g], m) {
                group_of.push(g);
                continue;
            }
        }
        let mut last = None;
        let mut candidate = index.get(&digest).copied();
        while let Some(g) = candidate {
            if same_key(groups[g], m) {
                break;
            }
            last = Some(g);
            candidate = next_of_digest[g];
        }
        let g = match candidate {
            Some(g) => g,
            None => {
                let g = groups.len();
                groups.push(m);
                next_of_digest.push(None);
                match last {
                    Some(previous) => next_of_digest[previous] = Some(g),
                    None => {
                        index.insert(digest, g);
                    }
                }
                g
            }
        };
        group_of.push(g);
    }
    drop((digests, index, next_of_digest));
    let groups: Vec<(&[f64], Option<&str>)> = groups
        .iter()
        .map(|m| (m.q.as_slice(), m.stage.as_deref()))
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

/// The configuration's joint values (`+ 0.0` makes −0 and +0 one key, as `==` does).
fn key_bits(m: &Measurement) -> impl Iterator<Item = u64> + '_ {
    m.q.iter().map(|v| (v + 0.0).to_bits())
}

/// A digest of the row's configuration and stage.
fn key_digest(m: &Measurement) -> u64 {
    let mut digest = crate::digests::digest_hasher(0);
    key_bits(m).for_each(|bits| bits.hash(&mut digest));
    m.q.len().hash(&mut digest);
    m.stage.as_deref().hash(&mut digest);
    digest.finish()
}

/// Whether two rows are at the same configuration in the same stage.
fn same_key(a: &Measurement, b: &Measurement) -> bool {
    a.q.len() == b.q.len() && key_bits(a).eq(key_bits(b)) && a.stage == b.stage
}
