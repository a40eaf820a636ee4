//! A camera response's quantisation, `(encode(c, s) * max_code).round()`
//! ([`CameraResponse::encode`]), found without a `powf` per value: the code
//! is a monotone step function of the signal, so it is fixed by the least
//! signal of each code. Those thresholds are found once per response
//! (bisection on the bit patterns of `f64`, which order as the values do for
//! non-negative values), so a lookup gives exactly the code the formula
//! gives. A grid over the signal's exponent and leading mantissa bits gives
//! the code at each cell's start; the few thresholds inside a cell are then
//! stepped over. On the demo's photometric calibration, the response's
//! `powf` and rounding were 12 % of the run time (perf).

use showcase_proto::CameraResponse;

/// Octaves of signal below full scale the grid covers; a smaller signal is
/// looked up by bisection over the thresholds.
const OCTAVES: u64 = 40;

/// The quantiser of one response (see the module docs).
#[derive(Clone, Debug)]
pub struct Quantiser {
    /// What the codes depend on: gamma, knee, shoulder (bit patterns) and
    /// bits. The gain and exposure scale the signal before it.
    key: [u32; 6],
    /// Per channel, the least signal of code `k` at index `k - 1`; infinite
    /// for a code no signal in `0..=1` reaches.
    thresholds: [Vec<f64>; 3],
    /// Per channel, the code at the start of each grid cell.
    cells: [Vec<u16>; 3],
    /// Mantissa bits of a cell: a cell spans a `2^-mantissa_bits` part of an
    /// octave.
    mantissa_bits: u32,
    /// The bit pattern of the grid's first cell, shifted.
    first_cell: u64,
}

/// What a response's codes depend on.
fn key(r: &CameraResponse) -> [u32; 6] {
    [
        r.gamma.x.to_bits(),
        r.gamma.y.to_bits(),
        r.gamma.z.to_bits(),
        r.knee.to_bits(),
        r.shoulder.to_bits(),
        r.bits.clamp(1, 16),
    ]
}

impl Quantiser {
    /// The quantiser of `response`.
    pub fn new(response: &CameraResponse) -> Self {
        let bits = response.bits.clamp(1, 16);
        let max_code = (1u32 << bits) - 1;
        let mantissa_bits = bits.clamp(6, 12);
        let shift = 52 - mantissa_bits;
        let first_cell = (1.0f64 / 2f64.powi(OCTAVES as i32)).to_bits() >> shift;
        let last_cell = 1.0f64.to_bits() >> shift;
        let thresholds: [Vec<f64>; 3] = std::array::from_fn(|c| {
            let code = |s: f64| direct_code(response, c, s, max_code);
            (1..=max_code).map(|k| least_signal(code, k)).collect()
        });
        let cells = std::array::from_fn(|c| {
            (first_cell..=last_cell)
                .map(|cell| by_bisection(&thresholds[c], f64::from_bits(cell << shift)))
                .collect()
        });
        Self {
            key: key(response),
            thresholds,
            cells,
            mantissa_bits,
            first_cell,
        }
    }

    /// Whether this quantises `response`'s codes.
    pub fn matches(&self, response: &CameraResponse) -> bool {
        self.key == key(response)
    }

    /// The code of signal `s` (`0..=1`; the caller clamps) in `channel`:
    /// `(response.encode(channel, s) * max_code).round()`.
    pub fn code(&self, channel: usize, s: f64) -> u16 {
        let c = channel.min(2);
        let t = &self.thresholds[c];
        // Below the first threshold (a dark pixel's noise clipped to 0 is
        // common): code 0, without the grid.
        if t.first().is_none_or(|&t1| s < t1) {
            return 0;
        }
        let cell = s.to_bits() >> (52 - self.mantissa_bits);
        let Some(i) = cell.checked_sub(self.first_cell) else {
            return by_bisection(t, s);
        };
        let Some(&start) = self.cells[c].get(i as usize) else {
            return by_bisection(t, s);
        };
        let mut k = start as usize;
        while k < t.len() && t[k] <= s {
            k += 1;
        }
        k as u16
    }
}

/// The code the response's formula gives `s` in `channel`.
fn direct_code(response: &CameraResponse, channel: usize, s: f64, max_code: u32) -> u32 {
    (response.encode(channel, s) * f64::from(max_code)).round() as u32
}

/// The number of thresholds at or below `s`: its code.
fn by_bisection(thresholds: &[f64], s: f64) -> u16 {
    thresholds.partition_point(|&t| t <= s) as u16
}

/// The least `s` in `0..=1` whose `code` is at least `k` (infinite when
/// none is): bisection over the bit patterns from 0 to 1.
fn least_signal(code: impl Fn(f64) -> u32, k: u32) -> f64 {
    let (mut lo, mut hi) = (0u64, 1.0f64.to_bits());
    if code(0.0) >= k {
        return 0.0;
    }
    if code(1.0) < k {
        return f64::INFINITY;
    }
    // code(lo) < k <= code(hi)
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if code(f64::from_bits(mid)) >= k {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    f64::from_bits(hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn response(gamma: Vec3, knee: f32, shoulder: f32, bits: u32) -> CameraResponse {
        CameraResponse {
            gamma,
            knee,
            shoulder,
            gain: 1.0,
            exposure_s: 1.0,
            read_noise: 0.0,
            shot_noise: 0.0,
            bits,
        }
    }

    /// Signals spread over the whole range, many octaves down, and each
    /// threshold with its neighbours a few bit patterns either side.
    fn signals(q: &Quantiser) -> Vec<f64> {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut v: Vec<f64> = (0..200_000)
            .map(|i| {
                x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
                let mut z = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
                z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
                let u = (z ^ (z >> 31)) as f64 / u64::MAX as f64;
                if i % 2 == 0 { u } else { u.powi(12) }
            })
            .collect();
        v.extend([
            0.0,
            1.0,
            f64::MIN_POSITIVE,
            1e-300,
            2f64.powi(-40),
            2f64.powi(-41),
        ]);
        for t in q.thresholds.iter().flatten().filter(|t| t.is_finite()) {
            for d in -3i64..=3 {
                v.push(f64::from_bits(t.to_bits().saturating_add_signed(d)).clamp(0.0, 1.0));
            }
        }
        v
    }

    #[test]
    fn codes_are_the_formulas_exactly() {
        for r in [
            response(Vec3::new(2.2, 2.0, 1.8), 0.8, 0.4, 8),
            response(Vec3::splat(1.0), 1.0, 1.0, 8),
            response(Vec3::new(2.4, 0.5, 3.0), 0.6, 0.2, 10),
            response(Vec3::splat(2.2), 0.9, 0.5, 12),
            response(Vec3::splat(1.7), 1.0, 0.0, 3),
        ] {
            let q = Quantiser::new(&r);
            assert!(q.matches(&r));
            let max_code = (1u32 << r.bits) - 1;
            for s in signals(&q) {
                for c in 0..3 {
                    assert_eq!(
                        u32::from(q.code(c, s)),
                        direct_code(&r, c, s, max_code),
                        "channel {c}, signal {s:e} ({r:?})"
                    );
                }
            }
        }
    }

    #[test]
    fn a_changed_curve_does_not_match_but_a_changed_gain_does() {
        let r = response(Vec3::splat(2.2), 0.8, 0.4, 8);
        let q = Quantiser::new(&r);
        let mut gain = r.clone();
        gain.gain = 3.0;
        gain.exposure_s = 0.01;
        assert!(q.matches(&gain));
        let mut gamma = r.clone();
        gamma.gamma.y = 2.0;
        assert!(!q.matches(&gamma));
        let mut bits = r;
        bits.bits = 10;
        assert!(!q.matches(&bits));
    }
}
