//! Whether a segment passes through an object's triangles: a
//! Moller-Trumbore test with a margin on both sides, which answers only
//! where it is sure (away from edges, ends and planes).

use super::Bounds;
use crate::finite::finite_or_zero;
use glam::DVec3;

/// Where a segment stands against an object's triangles, with a margin
/// far above round-off and the ray offsets of
/// [`SceneGeometry::visible`](crate::SceneGeometry::visible).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::radiosity::shooting::moving) enum Crossing {
    /// It certainly passes through a triangle's interior.
    Hit,
    /// It certainly misses every triangle.
    Miss,
    /// Too close to an edge, an end or a plane to tell.
    Unsure,
}

/// Relative margin of [`crossing`] (in barycentric and segment units).
const CROSSING_MARGIN: f64 = 1e-6;

/// A triangle prepared for [`crossing`]: its plane, first corner, the
/// dual basis that gives a point's barycentric coordinates, and its box.
#[derive(Clone, Copy, Debug)]
pub(in crate::radiosity::shooting::moving) struct PreparedTriangle {
    /// Unit normal of the plane (zero when degenerate).
    normal: DVec3,
    v0: DVec3,
    /// `(p - v0) . u_axis` and `(p - v0) . v_axis` are the barycentric
    /// coordinates of a point `p` of the plane along the two edges.
    u_axis: DVec3,
    v_axis: DVec3,
    /// Length of the edges' cross product over the product of their
    /// lengths (the sine of the corner angle).
    sine: f64,
    lo: DVec3,
    hi: DVec3,
}

impl PreparedTriangle {
    /// `[v0, v1, v2]` prepared.
    pub(in crate::radiosity::shooting::moving) fn new([v0, v1, v2]: [DVec3; 3]) -> Self {
        let (e1, e2) = (v1 - v0, v2 - v0);
        let n = e1.cross(e2);
        let n2 = n.length_squared();
        let (u_axis, v_axis) = if n2 > 0.0 && n2.is_finite() {
            (e2.cross(n) / n2, n.cross(e1) / n2)
        } else {
            (DVec3::ZERO, DVec3::ZERO)
        };
        let sine = n.length() / (e1.length() * e2.length());
        Self {
            normal: n.normalize_or_zero(),
            v0,
            u_axis,
            v_axis,
            sine: finite_or_zero(sine),
            lo: v0.min(v1).min(v2),
            hi: v0.max(v1).max(v2),
        }
    }
}

/// How the segment `a`-`b` meets `triangles` (Moller-Trumbore with a
/// margin on both sides).
#[cfg(test)]
fn crossing(triangles: &[PreparedTriangle], a: DVec3, b: DVec3) -> Crossing {
    crossing_from(triangles, a, b, &mut 0)
}

/// [`crossing`], trying the triangles from index `first` on (wrapping
/// round) and leaving there the one hit: neighbouring rays tend to hit the
/// same triangle, and any triangle hit decides, so the order changes only
/// the time.
pub(in crate::radiosity::shooting::moving) fn crossing_from(
    triangles: &[PreparedTriangle],
    a: DVec3,
    b: DVec3,
    first: &mut usize,
) -> Crossing {
    let d = b - a;
    let d_length = d.length();
    let m = CROSSING_MARGIN;
    let mut all_miss = true;
    // A segment that stays this far on one side of a triangle's plane
    // certainly misses it (its ends are farther than the margin in
    // segment units, and far beyond the ray offsets).
    let off_plane = m * (1.0 + d_length);
    let start = if *first < triangles.len() { *first } else { 0 };
    let (tail, head) = triangles.split_at(start);
    for (k, t) in head.iter().chain(tail).enumerate() {
        let (da, db) = (t.normal.dot(a - t.v0), t.normal.dot(b - t.v0));
        if t.normal != DVec3::ZERO
            && ((da > off_plane && db > off_plane) || (da < -off_plane && db < -off_plane))
        {
            continue;
        }
        // Where the line crosses the plane, as a fraction of the segment.
        let across = da - db;
        if !(across.abs() > 1e-9 * t.sine * d_length) {
            // Parallel to the plane (or degenerate): only sure when the
            // segment is far from the triangle's box.
            let pad = m * (1.0 + (t.hi - t.lo).max_element());
            let bounds = Bounds::aligned(t.lo, t.hi).grown(pad);
            if bounds.meets_segment(a, b) {
                all_miss = false;
            }
            continue;
        }
        let tt = da / across;
        let q = a + tt * d - t.v0;
        let (u, v) = (q.dot(t.u_axis), q.dot(t.v_axis));
        if u > m && v > m && u + v < 1.0 - m && tt > m && tt < 1.0 - m {
            *first = (start + k) % triangles.len();
            return Crossing::Hit;
        }
        let miss = u < -m || v < -m || u + v > 1.0 + m || tt < -m || tt > 1.0 + m;
        if !miss {
            all_miss = false;
        }
    }
    if all_miss {
        Crossing::Miss
    } else {
        Crossing::Unsure
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn crossing_is_sure_only_away_from_edges_and_ends() {
        let tri = [PreparedTriangle::new([DVec3::ZERO, DVec3::X, DVec3::Y])];
        let down = |x: f64, y: f64| crossing(&tri, DVec3::new(x, y, 1.0), DVec3::new(x, y, -1.0));
        assert_eq!(down(0.2, 0.2), Crossing::Hit);
        assert_eq!(down(0.7, 0.7), Crossing::Miss);
        assert_eq!(down(-0.1, 0.2), Crossing::Miss);
        assert_eq!(down(0.5, 0.5), Crossing::Unsure);
        assert_eq!(down(0.0, 0.3), Crossing::Unsure);
        // Ending on the plane, short of it, and in the plane.
        let at = |z: f64| crossing(&tri, DVec3::new(0.2, 0.2, 1.0), DVec3::new(0.2, 0.2, z));
        assert_eq!(at(0.0), Crossing::Unsure);
        assert_eq!(at(0.5), Crossing::Miss);
        assert_eq!(
            crossing(&tri, DVec3::new(-1.0, 0.2, 0.0), DVec3::new(2.0, 0.2, 0.0)),
            Crossing::Unsure
        );
        assert_eq!(
            crossing(&tri, DVec3::new(-1.0, 0.2, 0.5), DVec3::new(2.0, 0.2, 0.5)),
            Crossing::Miss
        );
    }

    /// A sure answer agrees with a plain Moller-Trumbore test (no
    /// margins) on random segments and triangles, and most answers are
    /// sure.
    #[test]
    fn crossing_agrees_with_plain_moller_trumbore() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        let mut p = || DVec3::new(rng.random(), rng.random(), rng.random());
        let plain = |[v0, v1, v2]: [DVec3; 3], a: DVec3, b: DVec3| -> bool {
            let (e1, e2, d) = (v1 - v0, v2 - v0, b - a);
            let h = d.cross(e2);
            let det = e1.dot(h);
            let s = a - v0;
            let (u, q) = (s.dot(h) / det, s.cross(e1));
            let (v, t) = (d.dot(q) / det, e2.dot(q) / det);
            u > 0.0 && v > 0.0 && u + v < 1.0 && t > 0.0 && t < 1.0
        };
        let (mut hits, mut misses, mut unsure) = (0, 0, 0);
        for _ in 0..20_000 {
            let tri = [p(), p(), p()];
            // Half the segments through a point of the triangle's plane
            // near the triangle, half anywhere.
            let (a, b) = if hits + misses + unsure < 10_000 {
                let w = p();
                let (u, v) = (1.4 * w.x - 0.2, 1.4 * w.y - 0.2);
                let on = tri[0] + u * (tri[1] - tri[0]) + v * (tri[2] - tri[0]);
                let dir = p() - 0.5 * DVec3::ONE;
                (on + dir, on - w.z * dir)
            } else {
                (3.0 * p() - DVec3::ONE, 3.0 * p() - DVec3::ONE)
            };
            match crossing(&[PreparedTriangle::new(tri)], a, b) {
                Crossing::Hit => {
                    hits += 1;
                    assert!(plain(tri, a, b), "{tri:?} {a} {b}");
                }
                Crossing::Miss => {
                    misses += 1;
                    assert!(!plain(tri, a, b), "{tri:?} {a} {b}");
                }
                Crossing::Unsure => unsure += 1,
            }
        }
        assert!(
            hits > 1000 && misses > 10_000 && unsure < 50,
            "{hits} {misses} {unsure}"
        );
    }

    /// The answer does not depend on the triangle tried first.
    #[test]
    fn crossing_does_not_depend_on_the_first_triangle() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut p = || DVec3::new(rng.random(), rng.random(), rng.random());
        let tris: Vec<PreparedTriangle> = (0..6)
            .map(|_| PreparedTriangle::new([p(), p(), p()]))
            .collect();
        for _ in 0..500 {
            let (a, b) = (2.0 * p() - DVec3::ONE, 2.0 * p());
            let expected = crossing(&tris, a, b);
            for start in 0..tris.len() + 1 {
                let mut first = start;
                assert_eq!(crossing_from(&tris, a, b, &mut first), expected);
                assert!(first < tris.len() || expected != Crossing::Hit);
            }
        }
    }
}
