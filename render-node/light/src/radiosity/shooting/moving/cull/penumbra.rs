//! The shooter's penumbra of a box: planes that bound where a segment
//! from a shooting patch through the box can reach, and the tests that
//! reject the receivers outside them with a few dot products.

use super::Bounds;
use glam::DVec3;

/// The 12 edges of a box, as pairs of [`Bounds::corners`] indices.
const BOX_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Relative round-off within which [`penumbra_planes`] takes touching
/// extents as separate.
const TOUCH: f64 = 1e-12;

/// Planes that bound the region a segment from the triangle `shooter`
/// through the box `b` can reach: `(n, c)` with unit `n` such that every
/// point `x` with a segment from a point of `shooter` to `x` that meets
/// `b` has `n . x >= c`. They are the planes through an edge of one and a
/// corner of the other (and the axis planes and the triangle's plane)
/// that have the triangle on their negative and the box on their
/// positive side: for `y` on the triangle, `b` in the box and
/// `x = y + s (b - y)` with `s >= 1`, `n . x >= n . b >= c`. Empty when
/// no plane separates them (the triangle touches or enters the box).
pub(in crate::radiosity::shooting::moving) fn penumbra_planes(
    shooter: &[DVec3; 3],
    b: &Bounds,
) -> Vec<(DVec3, f64)> {
    let corners = b.corners();
    let (center, half) = b.centre_and_half();
    let mut candidates = [DVec3::ZERO; 64];
    candidates[..4].copy_from_slice(&[
        b.axes[0],
        b.axes[1],
        b.axes[2],
        (shooter[1] - shooter[0]).cross(shooter[2] - shooter[0]),
    ]);
    let mut k = 4;
    for e in 0..3 {
        let (a, c) = (shooter[e], shooter[(e + 1) % 3]);
        for v in corners {
            candidates[k] = (c - a).cross(v - a);
            k += 1;
        }
    }
    for (i, j) in BOX_EDGES {
        let (a, c) = (corners[i], corners[j]);
        for y in shooter {
            candidates[k] = (c - a).cross(*y - a);
            k += 1;
        }
    }
    let mut planes: Vec<(DVec3, f64)> = Vec::new();
    let mut push = |n: DVec3, c: f64| {
        let duplicate = planes
            .iter()
            .any(|(m, d)| m.dot(n) > 1.0 - 1e-12 && (d - c).abs() < 1e-12);
        if !duplicate {
            planes.push((n, c));
        }
    };
    for n in candidates {
        // The shooter's and the box's extent along n (the box's from its
        // support function): a plane with normal n or -n separates them
        // when the extents do not overlap. Both scale with n, so only the
        // separating candidates are normalised. A plane through an edge of
        // one and a corner of the other touches both, so the extents meet
        // to round-off: they count as separate within `touch`, which
        // moves a far receiver's side of the plane by far less than the
        // tolerance of the tests (see `outside_penumbra`).
        let y = shooter.map(|y| n.dot(y));
        let (y_lo, y_hi) = (y[0].min(y[1]).min(y[2]), y[0].max(y[1]).max(y[2]));
        let reach = b.local(n).abs().dot(half);
        let mid = n.dot(center);
        let (b_lo, b_hi) = (mid - reach, mid + reach);
        let touch = TOUCH * (y_lo.abs().max(y_hi.abs()) + mid.abs() + reach);
        let (below, above) = (y_hi <= b_lo + touch, b_hi <= y_lo + touch);
        if !(below || above) {
            continue;
        }
        let length = n.length();
        if !(length > 0.0 && length.is_finite()) {
            continue;
        }
        if below {
            push(n / length, b_lo / length);
        }
        if above {
            push(-n / length, -b_hi / length);
        }
    }
    planes
}

/// True when no segment from the shooter of `planes` (see
/// [`penumbra_planes`]) to a point of the triangle `receiver` can meet the
/// box: the receiver lies below one of the planes by more than `tolerance`.
pub(in crate::radiosity::shooting::moving) fn outside_penumbra(
    planes: &[(DVec3, f64)],
    receiver: &[DVec3; 3],
    tolerance: f64,
) -> bool {
    planes
        .iter()
        .any(|(n, c)| receiver.iter().all(|x| n.dot(*x) < c - tolerance))
}

/// [`outside_penumbra`] for a receiver inside the ball `(center, radius)`:
/// one dot product per plane, a little less strict. The plane that
/// rejects moves to the front of `planes`, where the next receiver (the
/// scan's neighbour, often rejected by the same plane) tries it first.
pub(in crate::radiosity::shooting::moving) fn ball_outside_penumbra(
    planes: &mut [(DVec3, f64)],
    center: DVec3,
    radius: f64,
    tolerance: f64,
) -> bool {
    match planes
        .iter()
        .position(|(n, c)| n.dot(center) + radius < c - tolerance)
    {
        Some(k) => {
            planes.swap(0, k);
            true
        }
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::super::WORLD;
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The penumbra test never rejects a receiver that a segment from the
    /// shooter through the box reaches (random segments through random
    /// boxes), and it does reject receivers beside the shooter and off to
    /// the side of the box.
    #[test]
    fn penumbra_planes_never_reject_a_receiver_a_segment_reaches() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let point = |rng: &mut rand_chacha::ChaCha8Rng, s: f64| {
            DVec3::new(
                rng.random_range(-s..s),
                rng.random_range(-s..s),
                rng.random_range(-s..s),
            )
        };
        let mut rejected = 0;
        for k in 0..2000 {
            let lo = point(&mut rng, 0.3);
            // Every other box turned to a random frame.
            let axes = if k % 2 == 0 {
                WORLD
            } else {
                let q = glam::DQuat::from_euler(
                    glam::EulerRot::XYZ,
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                );
                [q * DVec3::X, q * DVec3::Y, q * DVec3::Z]
            };
            let b = Bounds {
                axes,
                lo,
                hi: lo + point(&mut rng, 0.2).abs() + DVec3::splat(0.01),
            };
            let shooter = [0, 1, 2].map(|_| DVec3::new(0.0, 0.0, -1.5) + point(&mut rng, 0.4));
            let mut planes = penumbra_planes(&shooter, &b);
            // A segment from a shooter point through a box point reaches a
            // receiver around its far end: never rejected.
            let w = [
                rng.random::<f64>(),
                rng.random::<f64>(),
                rng.random::<f64>(),
            ];
            let sum: f64 = w.iter().sum();
            let y = (w[0] * shooter[0] + w[1] * shooter[1] + w[2] * shooter[2]) / sum;
            let inside =
                b.lo + (b.hi - b.lo) * DVec3::new(rng.random(), rng.random(), rng.random());
            let through = axes[0] * inside.x + axes[1] * inside.y + axes[2] * inside.z;
            let x = y + rng.random_range(1.0..4.0) * (through - y);
            let receiver = [x, x + point(&mut rng, 0.05), x + point(&mut rng, 0.05)];
            assert!(
                !outside_penumbra(&planes, &receiver, 1e-9),
                "{shooter:?} through {b:?} reaches {x}"
            );
            assert!(!ball_outside_penumbra(&mut planes, x, 0.0, 1e-9));
            // A receiver on the shooter's side, far to the side.
            let beside = [0, 1, 2].map(|k| shooter[k] + DVec3::new(3.0, 0.0, -0.5));
            if outside_penumbra(&planes, &beside, 1e-9) {
                rejected += 1;
            }
        }
        assert!(rejected > 1000, "only {rejected} of 2000 rejected");
    }
}
