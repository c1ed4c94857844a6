//! The validation data a calibration holds out when none is given: a seeded fifth of the
//! configurations.

use crate::error::{Error, Result};
use crate::measurement::Measurement;
use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rayon::prelude::*;
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
    let (firsts, group_of) = configurations(measurements);
    let mut eligible: Vec<usize> = (0..firsts.len())
        .filter(|&g| measurements[firsts[g]].stage.as_deref() != Some("torso"))
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
    let mut held = vec![false; firsts.len()];
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

/// The distinct configurations (with their stage) of `measurements`, each as its first row,
/// in file order, and each row's configuration (an index into the first list).
///
/// Rows are sorted by a digest of their key in parallel and compared exactly within a run of
/// equal digests (a linear search made this O(N²); a map keyed by the values themselves cost
/// an allocation and a long hash per row; a serial hash map of digests, 0.2 s at 10⁶
/// configurations, while the other core waited).
fn configurations(measurements: &[Measurement]) -> (Vec<usize>, Vec<usize>) {
    let mut by_digest: Vec<(u64, usize)> = measurements
        .par_iter()
        .enumerate()
        .map(|(row, m)| (key_digest(m), row))
        .collect();
    // Every pair is distinct (the rows are): one order on any number of threads.
    by_digest.par_sort_unstable();
    // Per row, the first row with its key: within a run of equal digests (rows ascending),
    // the earliest row found equal, or itself.
    let firsts: Vec<(usize, usize)> = by_digest
        .par_chunk_by(|a, b| a.0 == b.0)
        .flat_map_iter(|run| {
            let mut keys: Vec<usize> = Vec::new();
            run.iter().map(move |&(_, row)| {
                let m = &measurements[row];
                match keys.iter().find(|&&k| same_key(&measurements[k], m)) {
                    Some(&first) => (row, first),
                    None => {
                        keys.push(row);
                        (row, row)
                    }
                }
            })
        })
        .collect();
    drop(by_digest);
    let mut first_of = vec![0; measurements.len()];
    for (row, first) in firsts {
        first_of[row] = first;
    }
    // Numbered in file order: a first row takes the next number, any other row its first's.
    let mut groups = Vec::new();
    let mut group_of = Vec::with_capacity(measurements.len());
    for (row, &first) in first_of.iter().enumerate() {
        if first == row {
            group_of.push(groups.len());
            groups.push(row);
        } else {
            group_of.push(group_of[first]);
        }
    }
    (groups, group_of)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Observation;
    use rand::RngExt;

    /// The configurations found by sorting digests are those a scan finds: the same groups,
    /// numbered by first row in file order, with repeats far apart, −0 and +0 one value, and
    /// the same joint values in another stage another configuration.
    #[test]
    fn configurations_are_what_a_scan_finds() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let values = [0.0, -0.0, 0.25, 1.5];
        let measurements: Vec<Measurement> = (0..600)
            .map(|_| Measurement {
                payload: None,
                tool: rng.random_range(0..2),
                q: (0..3).map(|_| values[rng.random_range(0..4)]).collect(),
                observation: Observation::Position(nalgebra::Vector3::zeros()),
                stage: (rng.random_range(0..4) == 0).then(|| "torso".to_owned()),
                session: None,
            })
            .collect();
        let (groups, group_of) = configurations(&measurements);
        let mut scanned: Vec<usize> = Vec::new();
        for (row, m) in measurements.iter().enumerate() {
            let group = match scanned.iter().position(|&g| same_key(&measurements[g], m)) {
                Some(g) => g,
                None => {
                    scanned.push(row);
                    scanned.len() - 1
                }
            };
            assert_eq!(group_of[row], group, "row {row}");
        }
        assert_eq!(groups, scanned);
        // Repeats are common: 4³ values × 2 stages.
        assert!(groups.len() <= 128 && groups.len() > 40, "{}", groups.len());
    }
}
