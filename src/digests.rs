//! Hash maps keyed by digests.

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
