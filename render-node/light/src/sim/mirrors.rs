//! Light from a delta source (a projector, point or spot light) that
//! reaches a diffuse surface by way of one mirror facet: the caustic that
//! path tracing with next-event estimation cannot find, since no
//! continuation ray ever hits a point.
//!
//! A planar facet reflects a point source as the source mirrored in the
//! facet's plane, seen through the facet. So a surface point `x` receives
//! `tint * I * cos(theta) / |x - L'|^2` by way of facet `f` exactly when
//! the segment from `x` to the mirrored source `L'` crosses `f` at a point
//! `p`, `x` and the source are on the same side of it, and both legs (`x`
//! to `p`, `p` to the source) are unoccluded; `I` is the source's radiant
//! intensity toward `p` and `tint` the mirror's albedo at `p`. The sum over
//! the facets is exact for any mirror mesh taken as it is (its geometric
//! normals, as the path tracer's mirrors).
//!
//! A facet can only reflect the source to `x` if its normal bisects the
//! directions from its point `p` to `x` and to the source. A tree of
//! bounding spheres and normal cones over the facets skips every group
//! whose normals cannot ([`MirrorFacets::for_each_candidate`]): a
//! conservative test, so the sum is the same as over every facet.

use crate::{Aabb, WorldTriangle};
use glam::DVec3;

/// Facets per leaf of the tree.
const LEAF: usize = 4;
/// Deepest tree [`MirrorFacets::for_each_candidate`] walks without
/// allocating: median splits halve the facets, so 2^40 of them fit.
const MAX_DEPTH: usize = 40;

/// One planar mirror facet.
#[derive(Clone, Debug)]
pub(super) struct Facet {
    vertices: [DVec3; 3],
    /// Unit normal of the front side.
    normal: DVec3,
    /// `normal . vertices[0]`.
    offset: f64,
    /// Its object in the scene.
    pub(super) object: u32,
    /// Its triangle within that object's mesh.
    pub(super) triangle: u32,
}

/// Where a facet reflects a source to a surface point
/// ([`Facet::reflection`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Reflection {
    /// The point of the facet the light bounces at.
    pub(super) point: DVec3,
    /// The facet's unit normal on the side of the source and the surface
    /// point.
    pub(super) facing: DVec3,
    /// The whole path's length squared (surface point to facet to
    /// source): the distance to the mirrored source.
    pub(super) distance2: f64,
}

impl Facet {
    /// The facet of a scene triangle; `None` for a degenerate one.
    pub(super) fn new(t: &WorldTriangle) -> Option<Self> {
        let normal = t.normal;
        if !(t.area > 0.0 && normal.is_finite() && normal != DVec3::ZERO) {
            return None;
        }
        Some(Self {
            vertices: t.vertices,
            normal,
            offset: normal.dot(t.vertices[0]),
            object: t.object,
            triangle: t.triangle,
        })
    }

    /// Where this facet reflects a point source at `source` to `x`, if it
    /// does (visibility not checked).
    pub(super) fn reflection(&self, x: DVec3, source: DVec3) -> Option<Reflection> {
        let sx = self.normal.dot(x) - self.offset;
        let ss = self.normal.dot(source) - self.offset;
        if !(sx * ss > 0.0) {
            return None;
        }
        let image = source - 2.0 * ss * self.normal;
        // The segment x -> image crosses the plane at the fraction of its
        // length where the signed distance (sx to -ss) is zero.
        let point = x + (image - x) * (sx / (sx + ss));
        if !(point.is_finite() && self.contains(point)) {
            return None;
        }
        Some(Reflection {
            point,
            facing: self.normal * sx.signum(),
            distance2: (image - x).length_squared(),
        })
    }

    /// True when `p`, a point of the facet's plane, lies in the triangle
    /// (edges included).
    fn contains(&self, p: DVec3) -> bool {
        let [a, b, c] = self.vertices;
        let n = self.normal;
        (b - a).cross(p - a).dot(n) >= 0.0
            && (c - b).cross(p - b).dot(n) >= 0.0
            && (a - c).cross(p - c).dot(n) >= 0.0
    }
}

/// A node of the tree: a bounding sphere of its facets and a cone holding
/// their normals.
#[derive(Clone, Debug)]
struct Node {
    center: DVec3,
    radius: f64,
    /// Unit axis of the normal cone.
    axis: DVec3,
    /// Half-angle of the normal cone (radians; `PI` when unbounded).
    half_angle: f64,
    /// Its cosine and sine.
    cos_half: f64,
    sin_half: f64,
    /// Leaf: `facets[first..first + count]`; inner: children at `first`
    /// and `first + 1` (`count` 0).
    first: u32,
    count: u32,
}

/// The scene's mirror facets, in a tree that finds those that may reflect
/// a source to a point.
#[derive(Clone, Debug, Default)]
pub(super) struct MirrorFacets {
    facets: Vec<Facet>,
    nodes: Vec<Node>,
}

impl MirrorFacets {
    /// The tree over `facets`.
    pub(super) fn new(mut facets: Vec<Facet>) -> Self {
        let mut nodes = Vec::new();
        if !facets.is_empty() {
            nodes.push(bound(&facets));
            let mut stack = vec![(0usize, 0usize, facets.len())];
            while let Some((node, start, end)) = stack.pop() {
                if end - start <= LEAF {
                    nodes[node].first = start as u32;
                    nodes[node].count = (end - start) as u32;
                    continue;
                }
                split_at_median(&mut facets[start..end]);
                let mid = start + (end - start) / 2;
                let left = nodes.len();
                nodes.push(bound(&facets[start..mid]));
                nodes.push(bound(&facets[mid..end]));
                nodes[node].first = left as u32;
                nodes[node].count = 0;
                stack.push((left, start, mid));
                stack.push((left + 1, mid, end));
            }
        }
        Self { facets, nodes }
    }

    /// True when there is no mirror.
    pub(super) fn is_empty(&self) -> bool {
        self.facets.is_empty()
    }

    /// Calls `f` with every facet that may reflect a point source at
    /// `source` to `x`: each facet that does is among them.
    pub(super) fn for_each_candidate(&self, x: DVec3, source: DVec3, mut f: impl FnMut(&Facet)) {
        if self.nodes.is_empty() {
            return;
        }
        // Depth-first, on the stack: this runs at every next-event estimate.
        let mut stack = [0u32; MAX_DEPTH + 1];
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let node = &self.nodes[stack[len] as usize];
            if !may_reflect(node, x, source) {
                continue;
            }
            let first = node.first as usize;
            if node.count > 0 {
                for facet in &self.facets[first..first + node.count as usize] {
                    f(facet);
                }
            } else {
                stack[len] = node.first;
                stack[len + 1] = node.first + 1;
                len += 2;
            }
        }
    }

    /// Every facet (for tests against the tree).
    #[cfg(test)]
    pub(super) fn facets(&self) -> &[Facet] {
        &self.facets
    }
}

/// Whether some facet of `node` may have a normal that bisects the
/// directions from its reflection point to `x` and to `source`.
///
/// For a point `p` within the node's sphere `(c, R)`, the unit direction
/// to `x` turns by at most `asin(R / |x - c|)` from the direction from `c`
/// (and so moves by at most that much), and likewise to the source. So
/// their sum `w` moves by at most the sum `delta` of the two angles, and
/// its direction turns by at most `asin(delta / |w_c|)`. A normal (either
/// way round: mirrors reflect on both sides) within the node's cone must
/// then lie within that turn of `w_c`'s direction. Without trigonometry:
/// `asin(a) <= a / sqrt(1 - a^2)` bounds `delta` from above, and the angle
/// test compares cosines.
fn may_reflect(node: &Node, x: DVec3, source: DVec3) -> bool {
    if node.half_angle >= std::f64::consts::FRAC_PI_2 {
        return true;
    }
    let (to_x, to_s) = (x - node.center, source - node.center);
    let (dx, ds) = (to_x.length(), to_s.length());
    if !(dx > node.radius && ds > node.radius) {
        return true;
    }
    let bound = |a: f64| a / (1.0 - a * a).sqrt();
    let delta = bound(node.radius / dx) + bound(node.radius / ds);
    let w = to_x / dx + to_s / ds;
    let m = w.length();
    if !(delta < m) {
        return true;
    }
    // cos(half_angle + turn), both in [0, pi / 2].
    let (sin_t, cos_t) = (delta / m, (1.0 - (delta / m).powi(2)).sqrt());
    let cos_limit = node.cos_half * cos_t - node.sin_half * sin_t;
    // A little slack for rounding: a skipped facet must be far outside.
    w.dot(node.axis).abs() >= m * (cos_limit - 1e-9)
}

/// The bounding sphere and normal cone of `facets` (not empty).
fn bound(facets: &[Facet]) -> Node {
    let center = facets
        .iter()
        .flat_map(|f| f.vertices)
        .fold(Aabb::EMPTY, Aabb::grow)
        .center();
    let radius = facets
        .iter()
        .flat_map(|f| f.vertices)
        .map(|v| (v - center).length())
        .fold(0.0, f64::max);
    let sum: DVec3 = facets.iter().map(|f| f.normal).sum();
    let axis = sum.normalize_or_zero();
    let half_angle = if axis == DVec3::ZERO {
        std::f64::consts::PI
    } else {
        facets
            .iter()
            .map(|f| f.normal.dot(axis).clamp(-1.0, 1.0).acos())
            .fold(0.0, f64::max)
    };
    Node {
        center,
        radius,
        axis,
        half_angle,
        cos_half: half_angle.cos(),
        sin_half: half_angle.sin(),
        first: 0,
        count: 0,
    }
}

/// Orders `facets` so that each half holds the facets on one side of the
/// median centroid along the centroids' longest extent.
fn split_at_median(facets: &mut [Facet]) {
    let centroid = |f: &Facet| (f.vertices[0] + f.vertices[1] + f.vertices[2]) / 3.0;
    let bounds = facets.iter().map(centroid).fold(Aabb::EMPTY, Aabb::grow);
    let extent = bounds.max - bounds.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = facets.len() / 2;
    facets.select_nth_unstable_by(mid, |a, b| centroid(a)[axis].total_cmp(&centroid(b)[axis]));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::SplitMix64;
    use rand::Rng;

    /// The facets of a UV sphere (`segments` around, half as many rings),
    /// facing out.
    fn sphere(center: DVec3, radius: f64, segments: u32) -> Vec<Facet> {
        let rings = segments / 2;
        let at = |i: u32, j: u32| {
            let (theta, phi) = (
                std::f64::consts::PI * f64::from(j) / f64::from(rings),
                std::f64::consts::TAU * f64::from(i) / f64::from(segments),
            );
            center
                + radius
                    * DVec3::new(
                        theta.sin() * phi.cos(),
                        theta.cos(),
                        theta.sin() * phi.sin(),
                    )
        };
        let mut out = Vec::new();
        for j in 0..rings {
            for i in 0..segments {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                for vertices in [[a, b, c], [a, c, d]] {
                    let n = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]);
                    // Outward: flip a triangle wound inward.
                    let vertices = if n.dot(vertices[0] - center) < 0.0 {
                        [vertices[0], vertices[2], vertices[1]]
                    } else {
                        vertices
                    };
                    let n = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]);
                    let t = WorldTriangle {
                        vertices,
                        object: 0,
                        triangle: out.len() as u32,
                        normal: n.normalize_or_zero(),
                        area: 0.5 * n.length(),
                    };
                    out.extend(Facet::new(&t));
                }
            }
        }
        out
    }

    #[test]
    fn a_facet_reflects_a_source_from_the_point_where_the_image_line_crosses_it() {
        let t = WorldTriangle {
            vertices: [
                DVec3::ZERO,
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 0.0),
            ],
            object: 0,
            triangle: 0,
            normal: DVec3::Y,
            area: 0.5,
        };
        let f = Facet::new(&t).unwrap();
        let r = f
            .reflection(DVec3::new(0.1, 1.0, 0.1), DVec3::new(0.5, 1.0, 0.1))
            .unwrap();
        assert!(
            (r.point - DVec3::new(0.3, 0.0, 0.1)).length() < 1e-12,
            "{r:?}"
        );
        assert_eq!(r.facing, DVec3::Y);
        assert!((r.distance2 - (0.16 + 4.0)).abs() < 1e-12, "{r:?}");
        // Seen from below, the facet reflects on its back.
        let r = f
            .reflection(DVec3::new(0.1, -1.0, 0.1), DVec3::new(0.5, -1.0, 0.1))
            .unwrap();
        assert_eq!(r.facing, -DVec3::Y);
        // Source and point on opposite sides, or the crossing outside the
        // triangle: no reflection.
        assert!(
            f.reflection(DVec3::new(0.1, 1.0, 0.1), DVec3::new(0.5, -1.0, 0.1))
                .is_none()
        );
        assert!(
            f.reflection(DVec3::new(0.9, 1.0, 0.9), DVec3::new(0.9, 1.0, 0.7))
                .is_none()
        );
    }

    #[test]
    fn the_tree_offers_every_facet_that_reflects_and_skips_most_others() {
        let center = DVec3::new(0.1, 0.05, -0.1);
        let facets = sphere(center, 0.045, 48);
        let tree = MirrorFacets::new(facets.clone());
        assert_eq!(tree.facets().len(), facets.len());
        let mut rng = SplitMix64::new(11);
        let mut point = || {
            loop {
                let p = DVec3::new(
                    rng.random_range(-0.3..0.3),
                    rng.random_range(0.0..0.5),
                    rng.random_range(-0.3..0.3),
                );
                if (p - center).length() > 0.05 {
                    return p;
                }
            }
        };
        let (mut reflecting, mut offered) = (0usize, 0usize);
        let queries = 2000u32;
        for _ in 0..queries {
            let (x, source) = (point(), point());
            let mut seen = Vec::new();
            tree.for_each_candidate(x, source, |f| seen.push(f.triangle));
            offered += seen.len();
            for f in tree.facets() {
                if f.reflection(x, source).is_some() {
                    reflecting += 1;
                    assert!(
                        seen.contains(&f.triangle),
                        "facet {} reflects {source} to {x} but the tree skipped it",
                        f.triangle
                    );
                }
            }
        }
        // Flat facets reflect a source as narrow beams with gaps between
        // them (about 5 % of these pairs fall in a beam), enough to check.
        assert!(reflecting >= 50, "{reflecting} reflections");
        let mean = offered as f64 / f64::from(queries);
        assert!(
            mean < 0.05 * facets.len() as f64,
            "{mean:.0} of {} facets offered per query",
            facets.len()
        );
    }
}
