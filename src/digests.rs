//! Digests of data (rows, ids, configurations) and hash maps keyed by them.

use std::hash::{BuildHasher, Hasher};

/// A hasher for a digest of data: foldhash's quality variant (it passes SMHasher3) with a fixed
/// seed, so a digest is the same in every run; several times faster than std's SipHash on
/// long inputs (a measurement file's rows of 400 bytes). Different `seed`s give independent
/// digests of the same data. Digests only find candidates: equal data are always confirmed
/// (or a collision costs a second look, never a wrong result), except the repeated-row
/// warning's 128-bit fingerprint (two seeds).
pub(crate) fn digest_hasher(seed: u64) -> impl Hasher {
    foldhash::quality::FixedState::with_seed(seed).build_hasher()
}

/// Hashes keys that are digests already (uniform 64-bit words: a measurement file's row
/// fingerprints and id digests, configurations' digests): their words are mixed by one
/// multiplication, not hashed again by SipHash.
pub(crate) type Digests = std::hash::BuildHasherDefault<DigestHasher>;

/// The [`Digests`] hasher.
#[derive(Default)]
pub(crate) struct DigestHasher(u64);

impl std::hash::Hasher for DigestHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.write_u64(u64::from(byte));
        }
    }

    fn write_u64(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(29) ^ word).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;
    use std::hash::{BuildHasher, DefaultHasher, Hash, Hasher};

    /// A digest is the same for the same data and seed, differs with the seed, and changes with one byte of a long row.
    #[test]
    fn digests_are_fixed_per_seed_and_independent_across_seeds() {
        let row: Vec<u8> = (0..400u32).map(|i| (i * 7 % 251) as u8).collect();
        let digest = |seed: u64, data: &[u8]| {
            let mut hasher = digest_hasher(seed);
            hasher.write(data);
            hasher.finish()
        };
        assert_eq!(digest(1, &row), digest(1, &row.clone()));
        assert_ne!(digest(1, &row), digest(2, &row));
        let mut changed = row.clone();
        changed[399] ^= 1;
        assert_ne!(digest(1, &row), digest(1, &changed));
    }

    /// A map keyed by digests finds every key, and pairs of digests in either order are
    /// different keys.
    #[test]
    fn digests_key_a_map() {
        let digest = |k: u64| {
            let mut d = DefaultHasher::new();
            k.hash(&mut d);
            d.finish()
        };
        let mut map: HashMap<(u64, u64), u64, Digests> = HashMap::default();
        for k in 0..10_000 {
            map.insert((digest(k), digest(k + 1)), k);
        }
        assert_eq!(map.len(), 10_000);
        assert!((0..10_000).all(|k| map.get(&(digest(k), digest(k + 1))) == Some(&k)));
        assert_eq!(map.get(&(digest(1), digest(0))), None);
        let hash = |pair: (u64, u64)| Digests::default().hash_one(pair);
        assert_ne!(hash((1, 2)), hash((2, 1)));
    }
}
