//! Rays, axis-aligned boxes and the watertight ray/triangle test (Woop,
//! Benthin and Wald 2013), all in f64.

use glam::DVec3;

/// A ray `origin + t * direction`. The direction need not be unit length;
/// `t` is measured in multiples of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: DVec3,
    /// Direction (non-zero, finite).
    pub direction: DVec3,
}

impl Ray {
    /// A ray from `origin` along `direction`.
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        Self { origin, direction }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.direction
    }

    /// True when origin and direction are finite and the direction is not zero.
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite() && self.direction.is_finite() && self.direction != DVec3::ZERO
    }
}

/// An axis-aligned bounding box; `EMPTY` has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
}

impl Aabb {
    /// The empty box (the identity of [`Aabb::union`]).
    pub const EMPTY: Self = Self {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// The smallest box holding `p`.
    pub fn point(p: DVec3) -> Self {
        Self { min: p, max: p }
    }

    /// The smallest box holding both.
    pub fn union(self, other: Self) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Grown to hold `p`.
    pub fn grow(self, p: DVec3) -> Self {
        self.union(Self::point(p))
    }

    /// True for the empty box.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// Centre point.
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// Surface area (0 for the empty box).
    pub fn surface_area(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let d = self.max - self.min;
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    /// The box padded by `pad` on every side.
    pub fn padded(&self, pad: f64) -> Self {
        Self {
            min: self.min - DVec3::splat(pad),
            max: self.max + DVec3::splat(pad),
        }
    }

    /// Entry parameter of the slab test against `[t_min, t_max]`, or `None`.
    /// `inv_dir` is `1 / direction` per component (infinite for zero
    /// components). NaN from `0 * inf` (origin on a slab of a ray parallel to
    /// it) is ignored by `f64::max`/`min`, treating the slab as passed.
    pub(crate) fn hit(&self, origin: DVec3, inv_dir: DVec3, t_min: f64, t_max: f64) -> Option<f64> {
        let t0 = (self.min - origin) * inv_dir;
        let t1 = (self.max - origin) * inv_dir;
        let near = t0.min(t1);
        let far = t0.max(t1);
        let enter = t_min.max(near.x).max(near.y).max(near.z);
        // Widen the exit slightly so rounding in the slab test never culls a
        // box a triangle inside it would be hit in (pbrt's 1 + 2 gamma(3)).
        let exit = t_max
            .min(far.x * (1.0 + 4.0 * f64::EPSILON))
            .min(far.y * (1.0 + 4.0 * f64::EPSILON))
            .min(far.z * (1.0 + 4.0 * f64::EPSILON));
        (enter <= exit).then_some(enter)
    }
}

/// Per-ray constants of the watertight test: the axis permutation and shear
/// that map the ray onto +z.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayShear {
    origin: DVec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f64,
    sy: f64,
    sz: f64,
}

impl RayShear {
    /// Constants for `ray` (its direction must be non-zero).
    pub(crate) fn new(ray: &Ray) -> Self {
        let d = ray.direction;
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self {
            origin: ray.origin,
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }
}

/// Where a ray meets a triangle: `t` and the barycentric weights `(u, v)` of
/// the second and third vertex (the first has `1 - u - v`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter.
    pub t: f64,
    /// Weight of vertex 1.
    pub u: f64,
    /// Weight of vertex 2.
    pub v: f64,
}

/// Watertight ray/triangle intersection in `(t_min, t_max)`, both faces.
///
/// Edge functions are evaluated on the sheared vertices; an edge shared by
/// two triangles gives bit-for-bit opposite values in both, and a zero edge
/// function counts as inside, so a ray through a shared edge or vertex hits
/// at least one of the triangles. Degenerate (zero-area or edge-on)
/// triangles give `None`, never NaN.
pub fn intersect_triangle(
    ray: &Ray,
    [a, b, c]: [DVec3; 3],
    t_min: f64,
    t_max: f64,
) -> Option<TriangleHit> {
    if !ray.is_valid() {
        return None;
    }
    intersect_sheared(&RayShear::new(ray), [a, b, c], t_min, t_max)
}

pub(crate) fn intersect_sheared(
    s: &RayShear,
    [a, b, c]: [DVec3; 3],
    t_min: f64,
    t_max: f64,
) -> Option<TriangleHit> {
    let (a, b, c) = (a - s.origin, b - s.origin, c - s.origin);
    let ax = a[s.kx] - s.sx * a[s.kz];
    let ay = a[s.ky] - s.sy * a[s.kz];
    let bx = b[s.kx] - s.sx * b[s.kz];
    let by = b[s.ky] - s.sy * b[s.kz];
    let cx = c[s.kx] - s.sx * c[s.kz];
    let cy = c[s.ky] - s.sy * c[s.kz];
    let e0 = cx * by - cy * bx; // weight of a
    let e1 = ax * cy - ay * cx; // weight of b
    let e2 = bx * ay - by * ax; // weight of c
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let az = s.sz * a[s.kz];
    let bz = s.sz * b[s.kz];
    let cz = s.sz * c[s.kz];
    let t_scaled = e0 * az + e1 * bz + e2 * cz;
    let inv = 1.0 / det;
    let t = t_scaled * inv;
    if !(t > t_min && t < t_max) {
        return None;
    }
    let (u, v) = (e1 * inv, e2 * inv);
    (u.is_finite() && v.is_finite()).then_some(TriangleHit { t, u, v })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI: [DVec3; 3] = [
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(1.0, 0.0, 1.0),
        DVec3::new(0.0, 1.0, 1.0),
    ];

    fn hit(o: DVec3, d: DVec3) -> Option<TriangleHit> {
        intersect_triangle(&Ray::new(o, d), TRI, 0.0, f64::INFINITY)
    }

    #[test]
    fn hits_interior_with_correct_barycentrics() {
        let h = hit(DVec3::new(0.25, 0.5, 0.0), DVec3::Z).unwrap();
        assert!((h.t - 1.0).abs() < 1e-15);
        assert!((h.u - 0.25).abs() < 1e-15 && (h.v - 0.5).abs() < 1e-15);
        // Back face too.
        let h = hit(DVec3::new(0.25, 0.5, 2.0), -DVec3::Z).unwrap();
        assert!((h.t - 1.0).abs() < 1e-15);
    }

    #[test]
    fn parallel_and_in_plane_rays_miss() {
        assert!(hit(DVec3::new(0.2, 0.2, 0.0), DVec3::X).is_none());
        // In the triangle's plane, through its interior: edge-on, no area.
        assert!(hit(DVec3::new(-1.0, 0.2, 1.0), DVec3::X).is_none());
    }

    #[test]
    fn respects_t_range_and_misses_outside() {
        let r = Ray::new(DVec3::new(0.2, 0.2, 0.0), DVec3::Z);
        assert!(intersect_triangle(&r, TRI, 0.0, 1.0).is_none());
        assert!(intersect_triangle(&r, TRI, 1.0, 2.0).is_none());
        assert!(hit(DVec3::new(0.6, 0.6, 0.0), DVec3::Z).is_none());
        assert!(hit(DVec3::new(0.2, 0.2, 2.0), DVec3::Z).is_none());
    }

    #[test]
    fn vertices_and_edges_count_as_inside() {
        for p in [TRI[0], TRI[1], TRI[2], 0.5 * (TRI[1] + TRI[2])] {
            let o = DVec3::new(p.x, p.y, 0.0);
            assert!(hit(o, DVec3::Z).is_some(), "missed {p}");
        }
    }

    #[test]
    fn degenerate_triangles_never_hit() {
        let p = DVec3::new(0.3, 0.3, 1.0);
        let ray = Ray::new(DVec3::new(0.3, 0.3, 0.0), DVec3::Z);
        let line = [DVec3::new(0.0, 0.0, 1.0), p, DVec3::new(1.0, 1.0, 1.0)];
        assert!(intersect_triangle(&ray, [p, p, p], 0.0, f64::INFINITY).is_none());
        assert!(intersect_triangle(&ray, line, 0.0, f64::INFINITY).is_none());
        let nan = [DVec3::NAN, TRI[1], TRI[2]];
        assert!(intersect_triangle(&ray, nan, 0.0, f64::INFINITY).is_none());
        let zero_dir = Ray::new(DVec3::ZERO, DVec3::ZERO);
        assert!(intersect_triangle(&zero_dir, TRI, 0.0, f64::INFINITY).is_none());
    }

    #[test]
    fn slab_test_handles_axis_parallel_rays() {
        let b = Aabb {
            min: DVec3::ZERO,
            max: DVec3::ONE,
        };
        let inv = |d: DVec3| DVec3::ONE / d;
        let d = DVec3::X;
        assert_eq!(
            b.hit(DVec3::new(-1.0, 0.5, 0.5), inv(d), 0.0, 10.0),
            Some(1.0)
        );
        assert_eq!(b.hit(DVec3::new(-1.0, 2.0, 0.5), inv(d), 0.0, 10.0), None);
        assert_eq!(b.hit(DVec3::new(-1.0, 0.5, 0.5), inv(d), 0.0, 0.5), None);
        assert!(Aabb::EMPTY.is_empty() && Aabb::EMPTY.surface_area() == 0.0);
    }
}
