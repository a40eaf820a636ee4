//! Irradiance received by a cluster whose members face many ways, kept as
//! order-2 spherical harmonics (Ramamoorthi and Hanrahan 2001): nine RGB
//! coefficients, already convolved with the clamped cosine, so a member
//! with normal `n` reads its irradiance as `eval(n)`. Within about 6 % of
//! the cosine lobe's peak for a single direction; only links that carry
//! little power end on such clusters (the refinement sees to that).

use glam::DVec3;
use std::f64::consts::PI;

/// Nine coefficients per RGB channel.
pub(super) type Sh = [DVec3; 9];

/// The zero irradiance.
pub(super) const ZERO: Sh = [DVec3::ZERO; 9];

/// The real SH basis up to order 2 at unit direction `d`.
fn basis(d: DVec3) -> [f64; 9] {
    let (x, y, z) = (d.x, d.y, d.z);
    [
        0.282_095,
        0.488_603 * y,
        0.488_603 * z,
        0.488_603 * x,
        1.092_548 * x * y,
        1.092_548 * y * z,
        0.315_392 * (3.0 * z * z - 1.0),
        1.092_548 * x * z,
        0.546_274 * (x * x - y * y),
    ]
}

/// The clamped cosine's SH weights per order.
const A: [f64; 9] = [
    PI,
    2.0 * PI / 3.0,
    2.0 * PI / 3.0,
    2.0 * PI / 3.0,
    PI / 4.0,
    PI / 4.0,
    PI / 4.0,
    PI / 4.0,
    PI / 4.0,
];

/// Add light arriving from unit direction `from` that would give
/// irradiance `e` on a surface facing it.
pub(super) fn add(sh: &mut Sh, from: DVec3, e: DVec3) {
    for (k, y) in basis(from).iter().enumerate() {
        sh[k] += e * (A[k] * y);
    }
}

/// Add `b` to `a`.
pub(super) fn accumulate(a: &mut Sh, b: &Sh) {
    for (x, y) in a.iter_mut().zip(b) {
        *x += *y;
    }
}

/// Irradiance on a surface with unit normal `n` (never negative).
pub(super) fn eval(sh: &Sh, n: DVec3) -> DVec3 {
    let mut e = DVec3::ZERO;
    for (k, y) in basis(n).iter().enumerate() {
        e += sh[k] * *y;
    }
    e.max(DVec3::ZERO)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_direction_reads_back_as_a_clamped_cosine_within_seven_percent() {
        let from = DVec3::new(0.3, -0.5, 0.8).normalize();
        let mut sh = ZERO;
        add(&mut sh, from, DVec3::ONE);
        for n in [
            from,
            -from,
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            DVec3::new(1.0, 1.0, 0.0).normalize(),
        ] {
            let got = eval(&sh, n).x;
            let exact = n.dot(from).max(0.0);
            assert!((got - exact).abs() < 0.07, "{n}: {got} against {exact}");
        }
    }

    #[test]
    fn light_from_all_round_is_exact() {
        // Uniform light from every direction (irradiance pi * L for any
        // normal): the order-0 term alone, which SH holds exactly.
        let mut sh = ZERO;
        let dirs = crate::sampling::stratified(4096, 3);
        for s in &dirs {
            let z = 1.0 - 2.0 * s.x;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * s.y;
            let d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
            // Each direction's share of the integral of L cos over the sphere.
            add(&mut sh, d, DVec3::splat(4.0 * PI / dirs.len() as f64 / PI));
        }
        for n in [DVec3::X, -DVec3::Y, DVec3::new(0.0, 0.6, 0.8)] {
            let got = eval(&sh, n).x;
            assert!((got - 1.0).abs() < 0.02, "{n}: {got}");
        }
    }
}
