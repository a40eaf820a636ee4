//! Sampling: the one home of the deterministic hashes (SplitMix64) and
//! the sample patterns that the simulated showcase, reflectance and
//! radiosity draw their points and directions from. Everything is a pure
//! function of its seed, so results do not depend on thread count.

use glam::{DVec2, DVec3};

/// SplitMix64's increment (the golden ratio in 64 bits), also used to
/// spread small indices over the seed space.
pub const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's finaliser: a bijective mix of all 64 bits of `z`.
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// One SplitMix64 output for state `x`: a cheap deterministic hash, e.g.
/// for per-receiver sample jitter.
pub fn hash64(x: u64) -> u64 {
    mix64(x.wrapping_add(GOLDEN_GAMMA))
}

/// A SplitMix64 stream: the random numbers of one path (or one item) of
/// a render. Seeding is one store and each number one [`hash64`], so a
/// path that draws a handful of numbers pays for those only (a ChaCha
/// stream computes a 256-byte block before its first number).
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// The stream whose first output is `hash64(seed)`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }
}

impl rand::RngCore for SplitMix64 {
    fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    fn next_u64(&mut self) -> u64 {
        let out = hash64(self.state);
        self.state = self.state.wrapping_add(GOLDEN_GAMMA);
        out
    }

    fn fill_bytes(&mut self, dst: &mut [u8]) {
        rand::rand_core::impls::fill_bytes_via_next(self, dst)
    }
}

/// A uniform number in `[0, 1)` from a hash.
pub fn unit(x: u64) -> f64 {
    (hash64(x) >> 11) as f64 / (1u64 << 53) as f64
}

/// `count` jittered stratified points in the unit square, seeded.
pub fn stratified(count: u32, seed: u64) -> Vec<DVec2> {
    let count = count.max(1);
    let side = (count as f64).sqrt().ceil() as u32;
    (0..count)
        .map(|k| {
            let (i, j) = (k % side, k / side);
            let rows = count.div_ceil(side);
            let jx = unit(seed ^ (2 * k as u64 + 1).wrapping_mul(0x2545_f491_4f6c_dd1d));
            let jy = unit(seed ^ (2 * k as u64 + 2).wrapping_mul(0x2545_f491_4f6c_dd1d));
            DVec2::new((i as f64 + jx) / side as f64, (j as f64 + jy) / rows as f64)
        })
        .collect()
}

/// A point of triangle `v` from a unit-square sample (area-uniform).
pub fn triangle_sample(v: &[DVec3; 3], s: DVec2) -> DVec3 {
    let r = s.x.sqrt();
    (1.0 - r) * v[0] + r * (1.0 - s.y) * v[1] + r * s.y * v[2]
}

/// Point `s` of `count` of a jittered stratified pattern over the unit
/// square: with `m = floor(sqrt(count))`, points `0..m^2` each fall in
/// their own cell of an `m x m` grid, offset within it by `jitter` (two
/// uniform numbers in `[0, 1)`); points past `m^2` are `jitter` itself.
pub fn stratified_point(s: u32, count: u32, (j1, j2): (f64, f64)) -> (f64, f64) {
    let m = f64::from(count.max(1)).sqrt().floor().max(1.0) as u32;
    if s < m * m {
        (
            (f64::from(s % m) + j1) / f64::from(m),
            (f64::from(s / m) + j2) / f64::from(m),
        )
    } else {
        (j1, j2)
    }
}

/// The cosine-weighted direction around unit `n` that the point
/// `(u1, u2)` of the unit square maps to.
pub fn cosine_direction(n: DVec3, (u1, u2): (f64, f64)) -> DVec3 {
    let r = u1.sqrt();
    let phi = std::f64::consts::TAU * u2;
    let (t, b) = n.any_orthonormal_pair();
    (r * phi.cos() * t + r * phi.sin() * b + (1.0 - u1).max(0.0).sqrt() * n).normalize_or_zero()
}

/// The seed of pixel (or item) `index` of a render seeded with `seed`
/// (SplitMix64 finaliser over both).
pub fn pixel_seed(seed: u64, index: u64) -> u64 {
    mix64(seed ^ index.wrapping_mul(GOLDEN_GAMMA))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, RngCore, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn splitmix64_matches_the_reference_sequence() {
        // SplitMix64 from state 0 (Vigna's reference implementation).
        let mut stream = SplitMix64::new(0);
        assert_eq!(stream.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(stream.next_u64(), 0x6E78_9E6A_A1B9_65F4);
        assert_eq!(stream.next_u32(), 0x06C4_5D18);
        let mut bytes = [0u8; 12];
        SplitMix64::new(0).fill_bytes(&mut bytes);
        assert_eq!(bytes[..8], 0xE220_A839_7B1D_CDAFu64.to_le_bytes());
        assert_eq!(bytes[8..], 0x6E78_9E6Au32.to_le_bytes());
    }

    #[test]
    fn stratified_points_fill_one_cell_each_then_fall_back_to_the_jitter() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for count in [1u32, 2, 9, 10, 128] {
            let m = (count as f64).sqrt().floor() as u32;
            let mut cells = vec![0u32; (m * m) as usize];
            for s in 0..count {
                let j = (rng.random(), rng.random());
                let (u, v) = stratified_point(s, count, j);
                assert!(
                    (0.0..1.0).contains(&u) && (0.0..1.0).contains(&v),
                    "{u} {v}"
                );
                if s < m * m {
                    let (cx, cy) = ((u * m as f64) as u32, (v * m as f64) as u32);
                    assert_eq!((cx, cy), (s % m, s / m), "point {s} of {count}");
                    cells[(cy * m + cx) as usize] += 1;
                } else {
                    assert_eq!((u, v), j, "point {s} of {count} past the grid");
                }
            }
            assert!(cells.iter().all(|&c| c == 1), "{count}: {cells:?}");
        }
    }
}
