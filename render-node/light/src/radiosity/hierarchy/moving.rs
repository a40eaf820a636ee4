//! The update after an object moves, on the hierarchy (after Drettakis
//! and Sillion 1997, the paper's reference [8]): only the links the move
//! can change are made again, and the gathers start from the old B.
//!
//! A mover has a subtree of its own, and the few nodes that hold it and
//! something else (`mixed`) carry no link, so every link the move changes
//! is one of:
//! - **the links between the mover and the rest** (one end in its
//!   subtree): removed, and those pairs refined again from the top against
//!   the current B, as a fresh refinement would (their coefficients,
//!   visibility and level all depend on where it is);
//! - **the links within the mover**: a rigid move leaves their
//!   coefficients as they were and turns their directions with it; only
//!   their visibility may change, where something else comes into or
//!   leaves their shaft, so those whose capsule meets a static triangle
//!   or another mover near the old or new place are evaluated again;
//! - **a link whose shaft the mover crossed**, before or after the move:
//!   its visibility rays run between points of its two nodes, so they lie
//!   in the capsule around the segment between the nodes' centres, with
//!   the larger node radius; a link whose capsule misses the bounding
//!   spheres of the mover's old and new place cannot see a difference and
//!   is kept as it is. The others are evaluated again (same seeds, so as
//!   a fresh link). A pair of leaves that something able to move relative
//!   to them hides kept its link at zero ([`Hierarchy::with_movers`]), so
//!   a move that uncovers it finds it.
//!
//! The direct light changes on the mover's elements and on the elements
//! whose capsule towards a light crosses the old or new place; only those
//! are evaluated again, with the seeds of a full evaluation.

use super::tree::NONE;
use super::{Hierarchy, HierarchyError, Link};
use crate::SceneGeometry;
use crate::radiosity::mesh::MeshError;
use glam::{DAffine3, DVec3};
use rayon::prelude::*;
use showcase_proto::Light;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Why a move cannot be applied.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MoveError {
    /// The object was not given to [`Hierarchy::with_movers`].
    #[error(
        "object {0} may not move: make the hierarchy with it among the movers \
         (Hierarchy::with_movers)"
    )]
    NotAMover(u32),
    /// The motion is not rigid, or the object has no element.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The direct light is not one value per element.
    #[error(
        "the direct light has {got} values for {elements} elements: pass Hierarchy::direct's \
         result (or nothing, with no lights)"
    )]
    DirectLength {
        /// Values given.
        got: usize,
        /// Elements of the mesh.
        elements: usize,
    },
    /// Refining the mover's links failed (e.g. the link limit).
    #[error(transparent)]
    Hierarchy(#[from] HierarchyError),
}

/// One rigid move of a mover, as [`Hierarchy::move_object`] takes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectMove {
    /// The object (a mover of the hierarchy).
    pub object: u32,
    /// Its rigid motion from where the hierarchy has it. The hierarchy
    /// moves its mesh ([`crate::radiosity::RadiosityMesh::move_object`])
    /// and the object's BVH ([`SceneGeometry::moved`]) by it alike, so
    /// they stay on each other to the last bit: a BVH built from the
    /// scene's single-precision transform sat 1e-8 m off the elements,
    /// more than the rays' surface offset, and a turned object shadowed
    /// itself.
    pub motion: DAffine3,
}

/// What a move did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct HierarchyMove {
    /// The mover's links removed.
    pub links_removed: usize,
    /// Links within the mover, kept (turned with it).
    pub links_within: usize,
    /// Of those, links whose shaft something else may enter or leave,
    /// evaluated again.
    pub links_within_rechecked: usize,
    /// The mover's links made again.
    pub links_made: usize,
    /// Other links tested against the mover's places.
    pub links_scanned: usize,
    /// Of those, links whose shaft a place crossed, evaluated again.
    pub links_rechecked: usize,
    /// Of those, links that no longer carry anything and are dropped.
    pub links_dropped: usize,
    /// Elements whose direct light was evaluated again.
    pub direct_updated: usize,
}

/// A bounding sphere.
#[derive(Clone, Copy, Debug)]
struct Ball {
    center: DVec3,
    radius: f64,
}

impl Ball {
    fn of(geometry: &SceneGeometry) -> Option<Self> {
        let b = geometry.bounds();
        (b.min.is_finite() && b.max.is_finite()).then(|| Self {
            center: 0.5 * (b.min + b.max),
            radius: 0.5 * (b.max - b.min).length(),
        })
    }

    /// Whether this ball (grown by `margin`) meets a segment between a
    /// point of ball `(a, ra)` and one of ball `(b, rb)`: such a segment's
    /// point at parameter `s` lies within `(1 - s) ra + s rb` of the axis
    /// point `a + s (b - a)`, so it can come no nearer the centre than
    /// `min over s of |c - a(s)| - lerp(ra, rb, s)`, a convex function of
    /// `s` minimised in closed form. Tighter than a capsule of the larger
    /// radius where the two ends differ (a wall's cluster and an element).
    fn meets_shaft(&self, a: DVec3, ra: f64, b: DVec3, rb: f64, margin: f64) -> bool {
        let ab = b - a;
        let len = ab.length();
        let delta = rb - ra;
        if !(len > delta.abs()) {
            // One ball holds the other: the capsule.
            return self.meets_capsule(a, b, ra.max(rb), margin);
        }
        let t0 = (self.center - a).dot(ab) / (len * len);
        let h = (self.center - a - t0 * ab).length();
        // f(s) = sqrt(((s - t0) len)^2 + h^2) - (ra + s delta); f'(s) = 0 at
        // (s - t0) len^2 / sqrt(...) = delta.
        let s = (t0 + delta * h / (len * (len * len - delta * delta).sqrt())).clamp(0.0, 1.0);
        let reach = ((s - t0) * len).hypot(h) - (ra + s * delta);
        reach <= self.radius + margin
    }

    /// Whether the capsule of radius `r` about the segment `a`-`b` meets
    /// this ball (grown by `margin`).
    fn meets_capsule(&self, a: DVec3, b: DVec3, r: f64, margin: f64) -> bool {
        let ab = b - a;
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 {
            ((self.center - a).dot(ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let reach = self.radius + r + margin;
        (a + t * ab - self.center).length_squared() <= reach * reach
    }
}

/// Something that may come into a shaft: a ball about it, and for a
/// triangle its plane (`n . x = d`), which a capsule wholly on one side
/// cannot meet.
#[derive(Clone, Copy, Debug)]
struct Obstacle {
    ball: Ball,
    plane: Option<(DVec3, f64)>,
}

impl Obstacle {
    fn meets_capsule(&self, a: DVec3, b: DVec3, r: f64, margin: f64) -> bool {
        let off_plane = self.plane.is_some_and(|(n, d)| {
            let (da, db) = (n.dot(a) - d, n.dot(b) - d);
            let reach = r + margin;
            (da > reach && db > reach) || (da < -reach && db < -reach)
        });
        !off_plane && self.ball.meets_capsule(a, b, r, margin)
    }
}

/// The bounding sphere of a light's emitting points.
fn light_ball(light: &Light) -> Ball {
    match light {
        Light::Point { position, .. } | Light::Spot { position, .. } => Ball {
            center: position.as_dvec3(),
            radius: 0.0,
        },
        Light::Area {
            corner,
            edge_u,
            edge_v,
            ..
        } => {
            let (u, v) = (edge_u.as_dvec3(), edge_v.as_dvec3());
            Ball {
                center: corner.as_dvec3() + 0.5 * (u + v),
                radius: 0.5 * (u + v).length().max((u - v).length()),
            }
        }
    }
}

impl<'a> Hierarchy<'a> {
    /// Apply `step` (a rigid move of one mover, of its elements in the
    /// mesh and of its occluders): the links and the direct
    /// light `direct` (per element, from [`Self::direct`] with `lights`)
    /// that the move changes are made again (see the module docs); `b` is
    /// the current solution, whose power the mover's links are refined
    /// against. Then [`Self::update`] from the old B settles the new one.
    /// On an error the hierarchy is gone (one found before anything moved
    /// too, for one rule): solve afresh.
    pub fn move_object(
        self,
        step: ObjectMove,
        b: &[DVec3],
        lights: &[Light],
        direct: &mut [DVec3],
    ) -> Result<(Self, HierarchyMove), MoveError> {
        let ObjectMove { object, motion } = step;
        let mut h = self;
        let k = h
            .movers
            .iter()
            .position(|m| m.object == object)
            .ok_or(MoveError::NotAMover(object))?;
        let no_direct = lights.is_empty() && direct.is_empty();
        if !no_direct && direct.len() != h.mesh.elements.len() {
            return Err(MoveError::DirectLength {
                got: direct.len(),
                elements: h.mesh.elements.len(),
            });
        }
        h.mesh.to_mut().move_object(object, &motion)?;
        let margin = 1e-6 * (1.0 + h.geometry.bounds().max.abs().max_element());
        let geometry = h.movers[k].geometry.moved(&motion);
        let places: Vec<Ball> = [Ball::of(&h.movers[k].geometry), Ball::of(&geometry)]
            .into_iter()
            .flatten()
            .collect();
        // What may come into a shaft within the mover, or leave it: the
        // static triangles and the other movers near its two places.
        let obstacles: Vec<Obstacle> = h
            .geometry
            .triangles()
            .map(|t| {
                let center = (t.vertices[0] + t.vertices[1] + t.vertices[2]) / 3.0;
                let radius = t
                    .vertices
                    .iter()
                    .map(|v| (*v - center).length())
                    .fold(0.0, f64::max);
                let plane = (t.normal != DVec3::ZERO).then(|| (t.normal, t.normal.dot(center)));
                Obstacle {
                    ball: Ball { center, radius },
                    plane,
                }
            })
            .chain(
                h.movers
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != k)
                    .filter_map(|(_, m)| Ball::of(&m.geometry))
                    .map(|ball| Obstacle { ball, plane: None }),
            )
            .filter(|o| {
                places.iter().any(|p| {
                    (o.ball.center - p.center).length() <= o.ball.radius + p.radius + margin
                })
            })
            .collect();
        let back = motion.inverse();
        let turn = motion.matrix3;
        h.movers[k].geometry = geometry;
        h.tree.fill_geometry(&h.mesh);
        let mut stats = HierarchyMove::default();

        let root = h.tree.mover_roots[k];
        let mut in_mover = vec![false; h.tree.nodes.len()];
        if root != NONE {
            for n in h.tree.subtree(root) {
                in_mover[n as usize] = true;
            }
        }
        if !no_direct {
            // The direct light where the move changed it.
            let lights_balls: Vec<Ball> = lights.iter().map(light_ball).collect();
            let elements: Vec<u32> = h
                .tree
                .order
                .par_iter()
                .copied()
                .filter(|&e| {
                    let el = &h.mesh.elements[e as usize];
                    if el.object == object {
                        return true;
                    }
                    let leaf = &h.tree.nodes[h.tree.leaf_of[e as usize] as usize];
                    lights_balls.iter().any(|l| {
                        places.iter().any(|p| {
                            p.meets_shaft(leaf.center, leaf.radius, l.center, l.radius, margin)
                        })
                    })
                })
                .collect();
            stats.direct_updated = elements.len();
            h.direct_at(lights, &elements, direct);
        }
        // The mover's links are refined against its power after the move:
        // a face turned towards a light is brighter than the old B says.
        let mut estimate = b.to_vec();
        if !no_direct {
            for &e in &h.tree.order {
                let el = &h.mesh.elements[e as usize];
                if el.object == object {
                    let lit = el.reflectance * direct[e as usize];
                    estimate[e as usize] = estimate[e as usize].max(lit);
                }
            }
        }
        let moments = h.pull(&estimate);
        // The links that stay, the crossed ones evaluated again.
        let old = std::mem::take(&mut h.links);
        let removed = AtomicUsize::new(0);
        let within = AtomicUsize::new(0);
        let within_rechecked = AtomicUsize::new(0);
        let rechecked = AtomicUsize::new(0);
        let dropped = AtomicUsize::new(0);
        let kept: Vec<Link> = old
            .par_iter()
            .filter_map(|l| {
                let ends = (in_mover[l.receiver as usize], in_mover[l.source as usize]);
                let (rn, sn) = (
                    &h.tree.nodes[l.receiver as usize],
                    &h.tree.nodes[l.source as usize],
                );
                let r = rn.radius.max(sn.radius);
                if ends.0 && ends.1 {
                    within.fetch_add(1, Ordering::Relaxed);
                    let (a, c) = (rn.center, sn.center);
                    let (a0, c0) = (back.transform_point3(a), back.transform_point3(c));
                    let crossed = obstacles.iter().any(|o| {
                        o.meets_capsule(a, c, r, margin) || o.meets_capsule(a0, c0, r, margin)
                    });
                    if !crossed {
                        let mut turned = *l;
                        turned.dir = turn * l.dir;
                        turned.slope = turn * l.slope;
                        return Some(turned);
                    }
                    within_rechecked.fetch_add(1, Ordering::Relaxed);
                    let rays = h.rays_for_pair(l.receiver, l.source, &moments);
                    return h.make_link(l.receiver, l.source, rays);
                }
                if ends.0 || ends.1 {
                    removed.fetch_add(1, Ordering::Relaxed);
                    return None;
                }
                if !places
                    .iter()
                    .any(|p| p.meets_shaft(rn.center, rn.radius, sn.center, sn.radius, margin))
                {
                    return Some(*l);
                }
                rechecked.fetch_add(1, Ordering::Relaxed);
                let rays = h.rays_for_pair(l.receiver, l.source, &moments);
                let fresh = h.make_link(l.receiver, l.source, rays);
                if fresh.is_none() {
                    dropped.fetch_add(1, Ordering::Relaxed);
                }
                fresh
            })
            .collect();
        stats.links_removed = removed.into_inner();
        stats.links_within = within.into_inner();
        stats.links_within_rechecked = within_rechecked.into_inner();
        stats.links_scanned = old.len() - stats.links_removed - stats.links_within;
        stats.links_rechecked = rechecked.into_inner();
        stats.links_dropped = dropped.into_inner();
        drop(old);

        // The mover's pairs, refined from the top.
        let mut made = Vec::new();
        if root != NONE {
            let pairs = h.mover_pairs(root, &in_mover, &moments);
            made = h.refine_pairs(&pairs, &moments, kept.len())?;
        }
        stats.links_made = made.len();
        let mut links = kept;
        links.extend(made);
        h.set_links(links)?;

        Ok((h, stats))
    }

    /// The rays a fresh link of this pair gets ([`Self::rays_for`]): all
    /// of them where the pair would now be refined.
    fn rays_for_pair(&self, r: u32, s: u32, moments: &[super::Moments]) -> u32 {
        self.judge(r, s, moments)
            .map_or(self.options.visibility_rays, |p| self.rays_for(p))
    }

    /// The pairs under which every link between the mover's subtree
    /// (`in_mover`) and the rest lies, and no other link: from the root
    /// pair down, the mixed nodes split as a refinement splits them, and
    /// split further while they must be refined, so that there are enough
    /// to share among the threads.
    fn mover_pairs(
        &self,
        root: u32,
        in_mover: &[bool],
        moments: &[super::Moments],
    ) -> Vec<(u32, u32)> {
        // The mixed nodes above the mover.
        let mut above = vec![false; self.tree.nodes.len()];
        let mut parent = vec![NONE; self.tree.nodes.len()];
        for (n, node) in self.tree.nodes.iter().enumerate() {
            if !node.is_leaf() {
                for c in node.children {
                    parent[c as usize] = n as u32;
                }
            }
        }
        let mut n = parent[root as usize];
        while n != NONE {
            above[n as usize] = true;
            n = parent[n as usize];
        }
        let mut stack = vec![(0u32, 0u32)];
        let mut pairs = Vec::new();
        while let Some((r, s)) = stack.pop() {
            let (ir, is) = (in_mover[r as usize], in_mover[s as usize]);
            if !(ir || is || above[r as usize] || above[s as usize]) {
                continue;
            }
            if ir && is {
                // Within the mover: kept, turned with it.
                continue;
            }
            let mixed = self.tree.nodes[r as usize].mixed || self.tree.nodes[s as usize].mixed;
            if (ir || is) && !mixed {
                pairs.push((r, s));
                continue;
            }
            if r == s {
                stack.extend(self.self_pairs(r).into_iter().flatten());
            } else if !self.culled(r, s) {
                stack.extend(self.split(r, s));
            }
        }
        // Enough independent pairs for the threads: split those that a
        // refinement would split anyway (refine_pair does the same).
        while pairs.len() < 64 {
            let mut next = Vec::with_capacity(2 * pairs.len());
            let mut split_any = false;
            for (r, s) in pairs {
                if r == s {
                    if let Some(p) = self.self_pairs(r) {
                        next.extend(p);
                        split_any = true;
                    }
                } else if self.culled(r, s) {
                    split_any = true;
                } else if self.must_refine(r, s, moments) && !self.is_leaf_pair(r, s) {
                    next.extend(self.split(r, s));
                    split_any = true;
                } else {
                    next.push((r, s));
                }
            }
            pairs = next;
            if !split_any {
                break;
            }
        }
        pairs
    }

    fn is_leaf_pair(&self, r: u32, s: u32) -> bool {
        self.tree.nodes[r as usize].is_leaf() && self.tree.nodes[s as usize].is_leaf()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{hash64, unit};

    fn point_on(key: u64, c: DVec3, r: f64) -> DVec3 {
        loop_point(key, 0, c, r)
    }

    fn loop_point(key: u64, t: u64, c: DVec3, r: f64) -> DVec3 {
        let k = hash64(key ^ t);
        let p = DVec3::new(unit(k ^ 1), unit(k ^ 2), unit(k ^ 3)) * 2.0 - DVec3::ONE;
        // On the sphere: the segments that graze the shaft's boundary.
        if p.length_squared() <= 1.0 && p.length_squared() > 1e-6 {
            c + r * p.normalize()
        } else {
            loop_point(key, t + 1, c, r)
        }
    }

    #[test]
    fn a_shaft_that_misses_a_ball_has_no_segment_through_it() {
        // Random balls and shafts: whenever a segment between points of the
        // two end balls passes through the ball, the test must say so; and
        // it must reject some shafts that the capsule of the larger radius
        // accepts (else it is no tighter).
        let (mut tighter, mut hits) = (0, 0);
        for case in 0..1000u64 {
            let key = hash64(case);
            let v = |i: u64| DVec3::new(unit(key ^ i), unit(key ^ (i + 7)), unit(key ^ (i + 13)));
            let (a, b, c) = (v(1) * 2.0, v(2) * 2.0, v(3) * 2.0);
            let (ra, rb, rc) = (
                0.6 * unit(key ^ 4),
                0.05 * unit(key ^ 5),
                0.2 * unit(key ^ 6),
            );
            let ball = Ball {
                center: c,
                radius: rc,
            };
            let says = ball.meets_shaft(a, ra, b, rb, 0.0);
            for k in 0..200u64 {
                let p = point_on(hash64(key ^ (k << 8) ^ 11), a, ra);
                let q = point_on(hash64(key ^ (k << 8) ^ 12), b, rb);
                let pq = q - p;
                let t = ((c - p).dot(pq) / pq.length_squared()).clamp(0.0, 1.0);
                if (p + t * pq - c).length() <= rc {
                    hits += 1;
                    assert!(
                        says,
                        "case {case}: a segment meets the ball, the test says no"
                    );
                    break;
                }
            }
            if !says && ball.meets_capsule(a, b, ra.max(rb), 0.0) {
                tighter += 1;
            }
        }
        assert!(hits > 20 && tighter > 20, "{hits} hit, {tighter} tighter");
    }
}
