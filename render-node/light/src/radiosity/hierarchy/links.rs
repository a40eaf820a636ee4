//! Links: the refinement that decides at which level two nodes exchange
//! light, the link's coefficient and visibility, and the exitance moments
//! a source radiates with (see the module docs of [`super`]).

use super::{Hierarchy, HierarchyError, LINK_BYTES};
use crate::finite::finite_or_zero;
use crate::radiosity::mesh::barycentric_point;
use crate::sampling::{hash64, triangle_sample, unit};
use crate::{Occluders, SceneGeometry, form_factor_point_polygon};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Pairs of nodes closer than this many times the sum of their radii are
/// not "separated": the point-to-disk estimate does not hold for them.
const SEPARATION: f64 = 1.0;
/// Links that may carry this many refinement limits of power or more get
/// all their visibility rays ([`Hierarchy::rays_for`]).
const FULL_RAYS_POWER: f64 = 64.0;
/// Draws of a member facing the other node before a visibility ray takes
/// any member ([`Hierarchy::random_point`]).
const FACING_TRIES: u64 = 8;
/// Relative error of a volume cluster's intensity or received harmonics.
const CLUSTER_ERROR: f64 = 0.25;
/// Leaves closer than this many times the sum of their radii get the
/// precise form factor.
const PRECISE: f64 = 4.0;

/// One link: `receiver` gathers from `source`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Link {
    pub(super) source: u32,
    pub(super) receiver: u32,
    /// Precise (`dir` zero): the visible form factor, times the source's
    /// B. Otherwise the visible `cos_r / (r^2 + A_s / pi)` (without the
    /// cosine for a volume receiver), times the source's intensity.
    pub(super) coef: f64,
    /// Unit direction from the source's centre to the receiver's; zero for
    /// a precise link.
    pub(super) dir: DVec3,
    /// For a flat receiver: the gradient of the irradiance over the
    /// receiver's plane relative to its value at the centroid (1/m), so
    /// that its members take `E (1 + slope . (x - c))`.
    pub(super) slope: DVec3,
}

/// Exitance moments of a node, per RGB channel (see the module docs).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Moments {
    q: DVec3,
    p: [DVec3; 3],
    /// `M` as `[xx, yy, zz, xy, xz, yz]` per channel.
    m: [[f64; 6]; 3],
    /// Every member faces one way (a leaf, or a flat node): the intensity
    /// is `max(0, P . w) / pi`, which needs no `M`.
    flat: bool,
}

impl Moments {
    pub(super) fn leaf(b: DVec3, area: f64, n: DVec3) -> Self {
        let q = b * area;
        let nn = [
            n.x * n.x,
            n.y * n.y,
            n.z * n.z,
            n.x * n.y,
            n.x * n.z,
            n.y * n.z,
        ];
        Self {
            q,
            p: [n * q.x, n * q.y, n * q.z],
            m: [0, 1, 2].map(|c| nn.map(|v| v * q[c])),
            flat: true,
        }
    }

    /// The sum of two nodes' moments, for their parent; `flat` when the
    /// parent is.
    pub(super) fn parent(a: &Self, b: &Self, flat: bool) -> Self {
        let mut s = *a;
        s.add(b);
        s.flat = flat;
        s
    }

    fn add(&mut self, o: &Self) {
        self.q += o.q;
        for c in 0..3 {
            self.p[c] += o.p[c];
            for k in 0..6 {
                self.m[c][k] += o.m[c][k];
            }
        }
    }

    /// Radiant intensity (W/sr per channel) towards unit direction `w`.
    /// A flat node's members all face `w` or all face away (but within a
    /// hair of grazing), so it is `max(0, P . w) / pi`: the sum of the
    /// members' own cosine lobes, which the general form equals there.
    pub(super) fn intensity(&self, w: DVec3) -> DVec3 {
        if self.flat {
            return DVec3::new(self.p[0].dot(w), self.p[1].dot(w), self.p[2].dot(w))
                .max(DVec3::ZERO)
                / PI;
        }
        let ww = [
            w.x * w.x,
            w.y * w.y,
            w.z * w.z,
            2.0 * w.x * w.y,
            2.0 * w.x * w.z,
            2.0 * w.y * w.z,
        ];
        let mut out = DVec3::ZERO;
        for c in 0..3 {
            let wmw: f64 = self.m[c].iter().zip(&ww).map(|(a, b)| a * b).sum();
            let v = 0.5 * (self.p[c].dot(w) + (self.q[c] * wmw).max(0.0).sqrt()) / PI;
            out[c] = v.max(0.0);
        }
        out
    }
}

impl Hierarchy<'_> {
    /// Power node `r` may receive from node `s` when `s` has moments `m`
    /// (max channel, W), for the refinement test.
    pub(super) fn transfer_estimate(&self, r: u32, s: u32, m: &Moments) -> f64 {
        let (rn, sn) = (&self.tree.nodes[r as usize], &self.tree.nodes[s as usize]);
        let d = rn.center - sn.center;
        let dist2 = d.length_squared();
        let w = d / dist2.sqrt();
        let spread = ((rn.radius + sn.radius) / dist2.sqrt()).min(1.0);
        let cos_r = if rn.flat {
            (rn.normal.dot(-w) + spread).clamp(0.0, 1.0)
        } else {
            1.0
        };
        // The source's intensity within the spread of directions: its
        // peak over w and the node's normal cone is bounded by Q / pi.
        let i = m.intensity(w).max_element() + spread * m.q.max_element() / PI;
        rn.rho_max * rn.area * cos_r * i / (dist2 + sn.area / PI)
    }

    /// Whether the pair must be split further: not separated, or its
    /// estimated error above epsilon of the reference power. The error is
    /// the power the link may carry times its relative error: second order
    /// in each node's size over the distance, `(r_r / d)^2 + (r_s / d)^2`
    /// (the source by the centroid rule, the receiver by the linear
    /// irradiance it pushes down), plus [`CLUSTER_ERROR`] for each volume
    /// cluster.
    pub(super) fn must_refine(&self, r: u32, s: u32, moments: &[Moments]) -> bool {
        self.judge(r, s, moments).is_none()
    }

    /// `None` when the pair must be refined ([`Self::must_refine`]), else
    /// the power it may carry in units of the refinement limit.
    pub(super) fn judge(&self, r: u32, s: u32, moments: &[Moments]) -> Option<f64> {
        let (rn, sn) = (&self.tree.nodes[r as usize], &self.tree.nodes[s as usize]);
        let limit = self.options.epsilon * self.reference_power;
        let power = || self.transfer_estimate(r, s, &moments[s as usize]) / limit;
        if rn.is_leaf() && sn.is_leaf() {
            return Some(power());
        }
        if rn.mixed || sn.mixed {
            return None;
        }
        let dist = (rn.center - sn.center).length();
        if dist <= SEPARATION * (rn.radius + sn.radius) {
            return None;
        }
        let mut relative = (rn.radius / dist).powi(2) + (sn.radius / dist).powi(2);
        for node in [rn, sn] {
            if !node.flat {
                relative += CLUSTER_ERROR;
            }
        }
        let power = power();
        (!(power * relative > 1.0)).then_some(power)
    }

    /// Visibility rays for a link that may carry `power` refinement limits:
    /// all of `visibility_rays` from [`FULL_RAYS_POWER`] limits up, fewer
    /// (at least one) below, in proportion. A link's visibility estimate
    /// is unbiased at any count; only its noise grows, and on links that
    /// carry little.
    pub(super) fn rays_for(&self, power: f64) -> u32 {
        let full = self.options.visibility_rays;
        let share = (power / FULL_RAYS_POWER).clamp(0.0, 1.0);
        ((f64::from(full) * share).ceil() as u32).clamp(1, full)
    }

    /// True when the two nodes cannot exchange light: one lies wholly
    /// behind the other's plane (flat nodes only).
    pub(super) fn culled(&self, r: u32, s: u32) -> bool {
        let (rn, sn) = (&self.tree.nodes[r as usize], &self.tree.nodes[s as usize]);
        (rn.flat && rn.normal.dot(sn.center - rn.center) <= -sn.radius)
            || (sn.flat && sn.normal.dot(rn.center - sn.center) <= -rn.radius)
    }

    /// The links of pair `(r, s)` and below, depth first, into `out`.
    pub(super) fn refine_pair(
        &self,
        r: u32,
        s: u32,
        moments: &[Moments],
        out: &mut Vec<Link>,
        made: &AtomicUsize,
    ) {
        let mut stack = vec![(r, s)];
        while let Some((r, s)) = stack.pop() {
            // Over the link limit: stop; set_links reports it.
            if made.load(Ordering::Relaxed) > self.options.max_links {
                return;
            }
            if r == s {
                stack.extend(self.self_pairs(r).into_iter().flatten());
                continue;
            }
            if self.culled(r, s) {
                continue;
            }
            if let Some(power) = self.judge(r, s, moments) {
                if let Some(l) = self.make_link(r, s, self.rays_for(power)) {
                    out.push(l);
                    made.fetch_add(1, Ordering::Relaxed);
                }
                continue;
            }
            stack.extend(self.split(r, s));
        }
    }

    /// The four pairs a node splits into when it gathers from itself
    /// (`None` for a leaf or a flat node, which does not see itself).
    pub(super) fn self_pairs(&self, n: u32) -> Option<[(u32, u32); 4]> {
        let node = &self.tree.nodes[n as usize];
        let [a, b] = node.children;
        (!node.is_leaf() && !node.flat).then_some([(a, a), (a, b), (b, a), (b, b)])
    }

    /// The two pairs `(r, s)` refines into: the larger node's children
    /// (by `radius^2 sqrt(area)`), a leaf never.
    pub(super) fn split(&self, r: u32, s: u32) -> [(u32, u32); 2] {
        let (rn, sn) = (&self.tree.nodes[r as usize], &self.tree.nodes[s as usize]);
        let size = |n: &super::tree::Node| n.radius * n.radius * n.area.sqrt();
        // A mixed node carries no link: it splits first.
        let receiver_first = if rn.mixed || sn.mixed {
            rn.mixed
        } else {
            !rn.is_leaf() && (sn.is_leaf() || size(rn) >= size(sn))
        };
        if receiver_first {
            rn.children.map(|c| (c, s))
        } else {
            sn.children.map(|c| (r, c))
        }
    }

    /// Make the links from scratch for exitance `b` (per element): each
    /// pair of nodes at the coarsest level where its estimated error is
    /// below epsilon of the power of `b`. [`Self::solve`] does this when
    /// there are no links yet and refines the links it has otherwise.
    pub fn link(&mut self, b: &[DVec3]) -> Result<(), HierarchyError> {
        self.reference_power = self
            .tree
            .order
            .iter()
            .map(|&e| b[e as usize].max_element() * self.mesh.elements[e as usize].area)
            .sum();
        let moments = self.pull(b);
        // Split the root pair breadth-first into enough independent pairs
        // to share among the threads.
        let mut frontier = vec![(0u32, 0u32)];
        while frontier.len() < 256 {
            let mut next = Vec::new();
            let mut split_any = false;
            for (r, s) in frontier {
                if r == s {
                    if let Some(pairs) = self.self_pairs(r) {
                        next.extend(pairs);
                        split_any = true;
                    }
                } else {
                    next.push((r, s));
                }
            }
            frontier = next;
            if !split_any {
                break;
            }
        }
        let links = self.refine_pairs(&frontier, &moments, 0)?;
        self.set_links(links)
    }

    /// The links of each pair of `pairs` and below ([`Self::refine_pair`]),
    /// the pairs shared among the threads; an error when they and
    /// `already` links would pass the link limit.
    pub(super) fn refine_pairs(
        &self,
        pairs: &[(u32, u32)],
        moments: &[Moments],
        already: usize,
    ) -> Result<Vec<Link>, HierarchyError> {
        let made = AtomicUsize::new(already);
        let parts: Vec<Vec<Link>> = pairs
            .par_iter()
            .map(|&(r, s)| {
                let mut out = Vec::new();
                self.refine_pair(r, s, moments, &mut out, &made);
                out
            })
            .collect();
        if made.into_inner() > self.options.max_links {
            return Err(self.too_many_links());
        }
        Ok(parts.concat())
    }

    pub(super) fn too_many_links(&self) -> HierarchyError {
        HierarchyError::TooManyLinks {
            limit: self.options.max_links,
            bytes: self.options.max_links * LINK_BYTES,
            epsilon: self.options.epsilon,
        }
    }

    /// Check every link against exitance `b` and refine those that now
    /// carry too much; returns how many were refined.
    pub(super) fn refine_again(&mut self, b: &[DVec3]) -> Result<usize, HierarchyError> {
        let moments = self.pull(b);
        let old = std::mem::take(&mut self.links);
        let made = AtomicUsize::new(old.len());
        let parts: Vec<(Vec<Link>, usize)> = old
            .par_chunks(4096)
            .map(|chunk| {
                let mut out = Vec::with_capacity(chunk.len());
                let mut refined = 0;
                for l in chunk {
                    if self.must_refine(l.receiver, l.source, &moments) {
                        refined += 1;
                        for (r, s) in self.split(l.receiver, l.source) {
                            self.refine_pair(r, s, &moments, &mut out, &made);
                        }
                    } else {
                        out.push(*l);
                    }
                }
                (out, refined)
            })
            .collect();
        // Refinement that stopped at the limit dropped links: an error,
        // never a silently thinner solution.
        if made.into_inner() > self.options.max_links {
            return Err(self.too_many_links());
        }
        let mut links = Vec::new();
        let mut refined = 0;
        for (p, n) in parts {
            links.extend(p);
            refined += n;
        }
        self.set_links(links)?;
        Ok(refined)
    }

    pub(super) fn set_links(&mut self, mut links: Vec<Link>) -> Result<(), HierarchyError> {
        if links.len() > self.options.max_links {
            return Err(self.too_many_links());
        }
        links.par_sort_unstable_by_key(|l| (l.receiver, l.source));
        let mut offsets = vec![0u32; self.tree.nodes.len() + 1];
        for l in &links {
            offsets[l.receiver as usize + 1] += 1;
        }
        for n in 0..self.tree.nodes.len() {
            offsets[n + 1] += offsets[n];
        }
        self.links = links;
        self.offsets = offsets;
        Ok(())
    }

    /// The link from `s` to `r`, with its visibility; `None` when no ray
    /// gets through or nothing can arrive.
    pub(super) fn make_link(&self, r: u32, s: u32, rays: u32) -> Option<Link> {
        let (rn, sn) = (&self.tree.nodes[r as usize], &self.tree.nodes[s as usize]);
        let (visible, may_uncover) = self.visibility(r, s, rays);
        // A link no ray got through is kept (at zero) while its nodes can
        // still be split: dropped, it could never be refined, and a few
        // rays would then take the light of every partly hidden pair that
        // drew a blocked ray away for good, while the pairs that drew a
        // clear one are refined back to their true share (the Cornell box
        // came out 12 % dark with one ray a link, 3 % with four). A pair of
        // leaves only a mover hides is kept too: the mover may move away.
        let leaves = rn.is_leaf() && sn.is_leaf();
        if !(visible > 0.0) && leaves && !may_uncover {
            return None;
        }
        let d = rn.center - sn.center;
        let dist2 = d.length_squared();
        if !(dist2 > 0.0) {
            return None;
        }
        if rn.is_leaf() && sn.is_leaf() && dist2 < (PRECISE * (rn.radius + sn.radius)).powi(2) {
            let re = &self.mesh.elements[rn.element as usize];
            let se = &self.mesh.elements[sn.element as usize];
            let points = &self.quadrature;
            let f: f64 = points
                .iter()
                .map(|b| {
                    let x = barycentric_point(&re.vertices, *b);
                    form_factor_point_polygon(x, re.normal, &se.vertices).unwrap_or(0.0)
                })
                .sum::<f64>()
                / points.len() as f64;
            let coef = f * visible;
            return (coef > 0.0 || (may_uncover && f > 0.0)).then_some(Link {
                source: s,
                receiver: r,
                coef,
                dir: DVec3::ZERO,
                slope: DVec3::ZERO,
            });
        }
        let w = d / dist2.sqrt();
        let cos_r = if rn.flat {
            rn.normal.dot(-w).max(0.0)
        } else {
            1.0
        };
        let geometric = cos_r / (dist2 + sn.area / PI);
        if !(geometric > 0.0) {
            return None;
        }
        let coef = visible * geometric;
        let slope = if rn.flat && !rn.is_leaf() {
            // The kernel's linear variation over the receiver, bounded so
            // it never takes a member below zero or above twice the
            // centroid's value: a source nearly in the receiver's plane
            // makes the relative gradient unbounded (1 / cos_r), and
            // extrapolated over the node it gave one red-wall element of
            // the demo scene at 0.0004 m^2 patches 3,192 W/m^2.
            let g = relative_gradient(
                rn.center,
                rn.normal,
                sn.center,
                sn.flat.then_some(sn.normal),
            );
            let reach = g.length() * rn.radius;
            if reach > 1.0 { g / reach } else { g }
        } else {
            DVec3::ZERO
        };
        (coef > 0.0 || !leaves || may_uncover).then_some(Link {
            source: s,
            receiver: r,
            coef,
            dir: w,
            slope,
        })
    }

    /// The visible fraction of rays between random points of two nodes,
    /// and whether, with none visible, a ray would have got through
    /// without what can move relative to the pair (only then: it costs
    /// those rays again): the movers, for a static pair; everything but
    /// itself, for a pair within one mover.
    pub(super) fn visibility(&self, r: u32, s: u32, rays: u32) -> (f64, bool) {
        let key = hash64(self.options.seed ^ (u64::from(r) << 32 | u64::from(s)));
        let (rc, sc) = (
            self.tree.nodes[r as usize].center,
            self.tree.nodes[s as usize].center,
        );
        let ray = |k: u64| {
            let (a, na) = self.random_point(r, hash64(key ^ (2 * k + 1)), sc);
            let (b, _) = self.random_point(s, hash64(key ^ (2 * k + 2)), rc);
            (a, na, b)
        };
        let blockers = self.blockers();
        let seen = (0..u64::from(rays))
            .filter(|&k| {
                let (a, na, b) = ray(k);
                blockers.visible(a, na, b, true)
            })
            .count() as u32;
        // Links between a mover and the rest are made again at each of
        // its moves.
        let (gr, gs) = (
            self.tree.nodes[r as usize].group,
            self.tree.nodes[s as usize].group,
        );
        let own: Option<&SceneGeometry> = match gr {
            _ if gr != gs || self.movers.is_empty() => None,
            0 => Some(self.geometry),
            super::tree::NONE => None,
            k => self.movers.get(k as usize - 1).map(|m| &m.geometry),
        };
        let may_uncover = seen == 0
            && own.is_some_and(|g| {
                (0..u64::from(rays)).any(|k| {
                    let (a, na, b) = ray(k);
                    g.visible(a, na, b, true)
                })
            });
        (f64::from(seen) / f64::from(rays), may_uncover)
    }

    /// A point of a random member of node `n`, and its normal.
    /// A point of a random member of node `n` that faces `toward` (the
    /// other node's centroid), and its normal. Members facing away carry
    /// nothing along the link (the moments and harmonics see to that);
    /// their rays would be blocked by their own object and count a volume
    /// cluster as hidden (the Cornell box's blocks made it 13 % dark at
    /// epsilon 1e-5). After [`FACING_TRIES`] draws it takes what it has.
    pub(super) fn random_point(&self, n: u32, key: u64, toward: DVec3) -> (DVec3, DVec3) {
        let members = self.tree.members(n);
        let mut point = (DVec3::ZERO, DVec3::ZERO);
        for t in 0..FACING_TRIES {
            let key = hash64(key ^ t);
            let e = members[(key % members.len() as u64) as usize];
            let el = &self.mesh.elements[e as usize];
            let s = DVec2::new(unit(key ^ 0x9e37), unit(key ^ 0x7f4a));
            point = (triangle_sample(&el.vertices, s), el.normal);
            if el.normal.dot(toward - point.0) > 0.0 {
                break;
            }
        }
        point
    }
}

/// The gradient over the receiver's plane of the kernel
/// `K(x) = cos_r cos_s / d^2` (the source's cosine 1 for a volume
/// cluster) at receiver point `x` with normal `nr`, from source point `y`,
/// relative to `K(x)`; zero where `K(x)` is zero.
fn relative_gradient(x: DVec3, nr: DVec3, y: DVec3, ns: Option<DVec3>) -> DVec3 {
    let v = y - x;
    let d2 = v.length_squared();
    let a = nr.dot(v);
    let (b, grad_b) = match ns {
        Some(n) => (-n.dot(v), n),
        None => (d2.sqrt(), -v / d2.sqrt()),
    };
    if !(a > 0.0 && b > 0.0 && d2 > 0.0) {
        return DVec3::ZERO;
    }
    // K = a b / d^4 (with b = d for a cluster, giving cos_r / d^2).
    // grad a = -nr, grad d^2 = -2 v.
    let g = -nr / a + grad_b / b + 4.0 * v / d2;
    // In the plane only: the members all lie in it.
    let g = g - nr * nr.dot(g);
    finite_or_zero(g)
}
