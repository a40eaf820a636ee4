//! A bounding volume hierarchy over triangles: binned surface-area-heuristic
//! build with an explicit work stack, iterative closest-hit and any-hit
//! traversal, all in f64.

use super::ray::{Aabb, Ray, RayShear, TriangleHit, intersect_sheared};
use glam::DVec3;

/// Centroid bins per axis of the binned SAH build.
const BINS: usize = 16;
/// Leaves never hold more triangles than this unless they cannot be split.
const MAX_LEAF: usize = 4;
/// Traversal stack depth; a deeper tree falls back to a forced leaf at build.
const MAX_DEPTH: usize = 64;

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `order`; inner: index of the left child (the
    /// right child follows it).
    first: u32,
    /// Triangles in a leaf; 0 for an inner node.
    count: u32,
}

/// A BVH over a triangle list it owns; query results name triangles by
/// their index in that list.
#[derive(Clone, Debug)]
pub struct Bvh {
    triangles: Vec<[DVec3; 3]>,
    nodes: Vec<Node>,
    order: Vec<u32>,
}

/// The closest triangle a ray meets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhHit {
    /// Index into the triangle list the BVH was built from.
    pub triangle: u32,
    /// Ray parameter and barycentrics.
    pub hit: TriangleHit,
}

impl Bvh {
    /// Build over `triangles`. Triangles with a non-finite vertex or zero
    /// area are kept in the list (indices stay stable) but never inserted,
    /// so they can never be hit.
    pub fn build(triangles: Vec<[DVec3; 3]>) -> Self {
        let usable: Vec<u32> = (0..triangles.len() as u32)
            .filter(|&i| {
                let [a, b, c] = triangles[i as usize];
                a.is_finite()
                    && b.is_finite()
                    && c.is_finite()
                    && (b - a).cross(c - a) != DVec3::ZERO
            })
            .collect();
        let bounds: Vec<Aabb> = triangles
            .iter()
            .map(|t| Aabb::point(t[0]).grow(t[1]).grow(t[2]))
            .collect();
        let scale = usable
            .iter()
            .map(|&i| {
                bounds[i as usize]
                    .min
                    .abs()
                    .max(bounds[i as usize].max.abs())
                    .max_element()
            })
            .fold(0.0_f64, f64::max);
        // A tiny padding keeps flat boxes (axis-aligned walls) from being
        // culled by rounding in the slab test.
        let pad = 1e-12 * scale.max(f64::MIN_POSITIVE);
        let mut bvh = Self {
            triangles,
            nodes: Vec::new(),
            order: usable,
        };
        if bvh.order.is_empty() {
            return bvh;
        }
        let centroids: Vec<DVec3> = bounds.iter().map(Aabb::center).collect();
        bvh.nodes.push(Node {
            bounds: Aabb::EMPTY,
            first: 0,
            count: bvh.order.len() as u32,
        });
        // (node, start, end, depth)
        let mut work = vec![(0usize, 0usize, bvh.order.len(), 0usize)];
        while let Some((node, start, end, depth)) = work.pop() {
            let prims = &mut bvh.order[start..end];
            let node_bounds = prims
                .iter()
                .fold(Aabb::EMPTY, |b, &i| b.union(bounds[i as usize]));
            bvh.nodes[node] = Node {
                bounds: node_bounds.padded(pad),
                first: start as u32,
                count: prims.len() as u32,
            };
            if prims.len() <= MAX_LEAF.min(2) || depth + 1 >= MAX_DEPTH {
                continue;
            }
            let Some(mid) = split(prims, &bounds, &centroids, node_bounds) else {
                continue;
            };
            let left = bvh.nodes.len();
            bvh.nodes.push(bvh.nodes[node]);
            bvh.nodes.push(bvh.nodes[node]);
            bvh.nodes[node].first = left as u32;
            bvh.nodes[node].count = 0;
            work.push((left, start, start + mid, depth + 1));
            work.push((left + 1, start + mid, end, depth + 1));
        }
        bvh
    }

    /// The triangles, as given to [`Bvh::build`].
    pub fn triangles(&self) -> &[[DVec3; 3]] {
        &self.triangles
    }

    /// Number of triangles that can be hit (finite, non-zero area).
    pub fn usable_triangles(&self) -> usize {
        self.order.len()
    }

    /// Number of BVH nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Bounds of everything that can be hit (`Aabb::EMPTY` when nothing can).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| n.bounds)
    }

    /// The closest hit with `t` in `(t_min, t_max)`.
    pub fn closest_hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<BvhHit> {
        let mut best: Option<BvhHit> = None;
        self.traverse(ray, t_min, t_max, |tri, hit, t_max| {
            if hit.t < *t_max {
                *t_max = hit.t;
                best = Some(BvhHit { triangle: tri, hit });
            }
            false
        });
        best
    }

    /// True when the ray meets any triangle with `t` in `(t_min, t_max)`.
    pub fn any_hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        self.traverse(ray, t_min, t_max, |_, _, _| true)
    }

    /// Visits candidate hits; `on_hit` may shrink `t_max` and returns true
    /// to stop. Returns whether it was stopped.
    fn traverse(
        &self,
        ray: &Ray,
        t_min: f64,
        mut t_max: f64,
        mut on_hit: impl FnMut(u32, TriangleHit, &mut f64) -> bool,
    ) -> bool {
        if self.nodes.is_empty() || !ray.is_valid() || t_min.is_nan() || t_max.is_nan() {
            return false;
        }
        let shear = RayShear::new(ray);
        let inv_dir = DVec3::ONE / ray.direction;
        let mut stack = [0u32; MAX_DEPTH + 1];
        let mut top = 0usize;
        if self.nodes[0]
            .bounds
            .hit(ray.origin, inv_dir, t_min, t_max)
            .is_none()
        {
            return false;
        }
        let mut current = 0u32;
        loop {
            let node = self.nodes[current as usize];
            if node.count > 0 {
                let first = node.first as usize;
                for &tri in &self.order[first..first + node.count as usize] {
                    let verts = self.triangles[tri as usize];
                    if let Some(h) = intersect_sheared(&shear, verts, t_min, t_max)
                        && on_hit(tri, h, &mut t_max)
                    {
                        return true;
                    }
                }
            } else {
                let (l, r) = (node.first, node.first + 1);
                let tl = self.nodes[l as usize]
                    .bounds
                    .hit(ray.origin, inv_dir, t_min, t_max);
                let tr = self.nodes[r as usize]
                    .bounds
                    .hit(ray.origin, inv_dir, t_min, t_max);
                match (tl, tr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (l, r) } else { (r, l) };
                        stack[top] = far;
                        top += 1;
                        current = near;
                        continue;
                    }
                    (Some(_), None) => {
                        current = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        current = r;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop, skipping nodes the shrunken t_max now excludes.
            loop {
                if top == 0 {
                    return false;
                }
                top -= 1;
                let n = stack[top];
                if self.nodes[n as usize]
                    .bounds
                    .hit(ray.origin, inv_dir, t_min, t_max)
                    .is_some()
                {
                    current = n;
                    break;
                }
            }
        }
    }
}

/// Partition `prims` by the cheapest binned SAH plane; returns the size of
/// the left part, or `None` when a leaf is cheaper (and small enough) or the
/// centroids cannot be separated.
fn split(
    prims: &mut [u32],
    bounds: &[Aabb],
    centroids: &[DVec3],
    node_bounds: Aabb,
) -> Option<usize> {
    let cb = prims
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.grow(centroids[i as usize]));
    let extent = cb.max - cb.min;
    let n = prims.len();
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, bins left)
    for axis in 0..3 {
        if !(extent[axis] > 0.0) {
            continue;
        }
        let bin_of = |i: u32| {
            let f = (centroids[i as usize][axis] - cb.min[axis]) / extent[axis];
            ((f * BINS as f64) as usize).min(BINS - 1)
        };
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_count = [0usize; BINS];
        for &i in prims.iter() {
            let b = bin_of(i);
            bin_bounds[b] = bin_bounds[b].union(bounds[i as usize]);
            bin_count[b] += 1;
        }
        let mut right_area = [0.0; BINS];
        let mut acc = Aabb::EMPTY;
        for b in (1..BINS).rev() {
            acc = acc.union(bin_bounds[b]);
            right_area[b] = acc.surface_area();
        }
        let (mut left_box, mut left_n) = (Aabb::EMPTY, 0usize);
        for b in 1..BINS {
            left_box = left_box.union(bin_bounds[b - 1]);
            left_n += bin_count[b - 1];
            let right_n = n - left_n;
            if left_n == 0 || right_n == 0 {
                continue;
            }
            let cost = left_box.surface_area() * left_n as f64 + right_area[b] * right_n as f64;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    let (cost, axis, bins_left) = best?;
    let area = node_bounds.surface_area();
    let sah = if area > 0.0 {
        1.0 + cost / area
    } else {
        f64::INFINITY
    };
    if sah >= n as f64 && n <= MAX_LEAF {
        return None;
    }
    let threshold = |i: u32| {
        let f = (centroids[i as usize][axis] - cb.min[axis]) / extent[axis];
        ((f * BINS as f64) as usize).min(BINS - 1) < bins_left
    };
    let mut left = 0;
    for k in 0..n {
        if threshold(prims[k]) {
            prims.swap(k, left);
            left += 1;
        }
    }
    (left > 0 && left < n).then_some(left)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(tris: &[[DVec3; 3]], ray: &Ray) -> Option<(u32, f64)> {
        let mut best: Option<(u32, f64)> = None;
        for (i, t) in tris.iter().enumerate() {
            let tmax = best.map_or(f64::INFINITY, |b| b.1);
            if let Some(h) = super::super::ray::intersect_triangle(ray, *t, 0.0, tmax) {
                best = Some((i as u32, h.t));
            }
        }
        best
    }

    #[test]
    fn empty_and_degenerate_only_bvh_never_hits() {
        let p = DVec3::ONE;
        let bvh = Bvh::build(vec![[p, p, p], [DVec3::NAN, p, DVec3::ZERO]]);
        assert_eq!(bvh.usable_triangles(), 0);
        let ray = Ray::new(DVec3::ZERO, DVec3::ONE);
        assert!(bvh.closest_hit(&ray, 0.0, f64::INFINITY).is_none());
        assert!(!bvh.any_hit(&ray, 0.0, f64::INFINITY));
        assert!(Bvh::build(Vec::new()).closest_hit(&ray, 0.0, 1.0).is_none());
    }

    #[test]
    fn matches_brute_force_on_a_stack_of_coplanar_duplicates() {
        // Many triangles with identical centroids cannot be split: one leaf.
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let tris: Vec<_> = (0..50)
            .map(|k| t.map(|v| v + DVec3::Z * (k as f64 * 0.0)))
            .collect();
        let bvh = Bvh::build(tris.clone());
        let ray = Ray::new(DVec3::new(0.2, 0.2, 1.0), -DVec3::Z);
        let h = bvh.closest_hit(&ray, 0.0, f64::INFINITY).unwrap();
        assert_eq!(h.hit.t, brute(&tris, &ray).unwrap().1);
    }
}
