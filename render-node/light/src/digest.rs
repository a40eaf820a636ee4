//! Stable digests: FNV-1a over bytes, for output hashes that must agree
//! across nodes, runs and replays (std's hasher is randomly seeded per
//! process), and for the version keys that decide whether a pass must run.

/// FNV-1a, 64 bit: a stable hash for output digests (std's hasher is
/// randomly seeded per process, which would defeat replay comparisons).
#[derive(Clone, Copy, Debug)]
pub struct Fnv64(u64);

impl Default for Fnv64 {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv64 {
    /// Mix in bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= *b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// The digest.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// Hash linear RGBA pixels bit for bit.
pub fn hash_pixels(rgba: &[[f32; 4]]) -> u64 {
    let mut h = Fnv64::default();
    for p in rgba {
        for c in p {
            h.write(&c.to_bits().to_le_bytes());
        }
    }
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_matches_reference_vectors() {
        // FNV-1a 64 test vectors.
        let h = |s: &str| {
            let mut f = Fnv64::default();
            f.write(s.as_bytes());
            f.finish()
        };
        assert_eq!(h(""), 0xcbf29ce484222325);
        assert_eq!(h("a"), 0xaf63dc4c8601ec8c);
        assert_eq!(h("foobar"), 0x85944171f73967e8);
    }
}
