//! Hierarchical radiosity with clustering (Hanrahan, Salzman and Aupperle
//! 1991; Smits, Arvo and Greenberg 1994): energy moves along *links*
//! between nodes of a cluster tree over the elements, each link at the
//! coarsest level where it carries less than `epsilon` of the injected
//! power (BF refinement), so the number of links grows about linearly with
//! the elements instead of with their square.
//!
//! - **Tree** (`tree.rs`): a median-split binary tree over the active
//!   elements. Flat nodes (coplanar members) act as one patch; the others
//!   are volume clusters.
//! - **Sources**: a node radiates with the intensity of its members,
//!   `I(w) = sum B_i A_i max(0, n_i . w) / pi`, approximated from three
//!   moments pulled up the tree, `Q = sum B A`, `P = sum B A n` and
//!   `M = sum B A n n^T`: `I(w) = (P.w + sqrt(Q w^T M w)) / (2 pi)`,
//!   exact for a flat node (then it is `Q max(0, n.w) / pi`) and 15 % high
//!   for a sphere's worth of orientations. A flat node (and a leaf) takes
//!   the cheaper `max(0, P.w) / pi`, which is the same there.
//! - **Receivers**: a flat node takes irradiance with the cosine at its
//!   normal; a volume cluster keeps it as spherical harmonics (`sh.rs`),
//!   read by each member at its own normal when pushed down.
//! - **Links**: between leaves that are close, the closed-form
//!   point-to-triangle form factor averaged over four points of the
//!   receiver; otherwise the point-to-disk estimate
//!   `I cos_r / (r^2 + A_s / pi)`. Either times the visible fraction of
//!   `visibility_rays` rays between random points of the two nodes.
//! - **Solve**: Jacobi gathers (pull moments, gather along links, push
//!   irradiance down) until B changes by less than `tolerance`; then the
//!   links are checked against the new B and refined where they now carry
//!   too much, `refine_rounds` times.
//! - Virtual lights are not geometry: their direct irradiance is
//!   evaluated at four points of every leaf (`sources`).
//!
//! The result is B per element of the [`RadiosityMesh`], as the
//! progressive solver's, so B0..B3, the vertex gathers and the irradiance
//! maps take it unchanged.

mod links;
mod moving;
mod sh;
mod tree;

use super::mesh::{RadiosityMesh, barycentric_point, sub_centroids};
use super::sources::direct_irradiance;
use crate::finite::finite_or_zero;
use crate::sampling::hash64;
use crate::{Occluders, SceneGeometry};
use glam::{DVec2, DVec3};
use links::{Link, Moments};
pub use moving::{HierarchyMove, MoveError, ObjectMove};
use rayon::prelude::*;
use sh::Sh;
use showcase_proto::Light;
use std::borrow::Cow;
use std::sync::Arc;
use tree::Tree;

/// Settings of a hierarchical solve.
#[derive(Clone, Debug, PartialEq)]
pub struct HierarchyOptions {
    /// A link is refined while it may carry more than this fraction of the
    /// injected power (BF refinement).
    pub epsilon: f64,
    /// Visibility rays per link.
    pub visibility_rays: u32,
    /// Stop gathering when the power changed by less than this fraction.
    pub tolerance: f64,
    /// Gathers at most, per round.
    pub max_iterations: u32,
    /// Times the links are refined again against the solved B.
    pub refine_rounds: u32,
    /// Samples of an area light per point.
    pub light_samples: u32,
    /// Seed of the visibility rays and light samples.
    pub seed: u64,
    /// Refuse to make more links than this (a memory guard).
    pub max_links: usize,
    /// Told at each stage; returning `false` stops the solve where it is.
    pub progress: HierarchyProgress,
}

impl Default for HierarchyOptions {
    fn default() -> Self {
        Self {
            epsilon: 1e-6,
            visibility_rays: 4,
            tolerance: 1e-3,
            max_iterations: 200,
            refine_rounds: 1,
            light_samples: 4,
            seed: 1,
            max_links: 40_000_000,
            progress: HierarchyProgress::default(),
        }
    }
}

/// The largest ratio of two gathers' changes whose tail an update adds:
/// above it the series is too slow for its tail to be estimated.
const MAX_TAIL_RATIO: f64 = 0.9;

/// The least relative uncertainty an update assumes of its tail.
const MIN_TAIL_DRIFT: f64 = 0.1;

/// Bytes one link takes.
pub const LINK_BYTES: usize = std::mem::size_of::<Link>();

/// Fewest links per element a solve makes in practice (each element
/// gathers from at least a few nodes); the floor of an up-front memory
/// estimate. Measured: 51 per element on the demo cabinet, 196 on the
/// Cornell box, 230 in the furnace.
pub const MIN_LINKS_PER_ELEMENT: usize = 16;

/// Bytes a [`Hierarchy`] over `elements` active elements with `links`
/// links takes while it gathers: the tree, each node's moments and
/// gathered and pushed irradiance, the link offsets, the per-element
/// vectors of a solve, and the links.
pub fn estimate_bytes(elements: usize, links: usize) -> usize {
    use std::mem::size_of;
    let nodes = 2 * elements;
    let per_node = size_of::<tree::Node>()
        + size_of::<Moments>()
        + 2 * size_of::<Gathered>()
        + size_of::<u32>();
    // B, its initial value, the next and the reflected, the direct light
    // and the output; the leaf index and the order.
    let per_element = 6 * size_of::<DVec3>() + 2 * size_of::<u32>();
    nodes
        .saturating_mul(per_node)
        .saturating_add(elements.saturating_mul(per_element))
        .saturating_add(links.saturating_mul(LINK_BYTES))
}

/// Where a hierarchical solve is.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct HierarchyPoint {
    /// Refinement round (0 is the first set of links).
    pub round: u32,
    /// Links in use.
    pub links: usize,
    /// Gathers so far in this round.
    pub iterations: u32,
    /// Relative change of the power in the last gather: how far from
    /// converged (the hierarchical counterpart of the unshot fraction).
    pub residual: f64,
}

/// A callback told the solve's progress; it returns `false` to stop (a
/// time budget is this, in the caller: the solver reads no clock).
#[derive(Clone, Default)]
pub struct HierarchyProgress(Option<Arc<dyn Fn(HierarchyPoint) -> bool + Send + Sync>>);

impl HierarchyProgress {
    /// Call `f` at each stage; it returns whether to go on.
    pub fn new(f: impl Fn(HierarchyPoint) -> bool + Send + Sync + 'static) -> Self {
        Self(Some(Arc::new(f)))
    }

    /// Tell the callback, if there is one; true (go on) when there is
    /// none.
    pub fn report_to(&self, point: HierarchyPoint) -> bool {
        self.0.as_ref().is_none_or(|f| f(point))
    }
}

impl std::fmt::Debug for HierarchyProgress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "HierarchyProgress(set)"
        } else {
            "HierarchyProgress(none)"
        })
    }
}

impl PartialEq for HierarchyProgress {
    fn eq(&self, other: &Self) -> bool {
        match (&self.0, &other.0) {
            (None, None) => true,
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}

/// Why a hierarchical solve cannot run.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum HierarchyError {
    /// A setting is out of range.
    #[error("hierarchical radiosity setting {name} = {value} must be {must}")]
    BadOption {
        /// The setting.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        must: &'static str,
    },
    /// The active mask does not have one entry per element.
    #[error("active mask has {got} entries for {elements} elements")]
    MaskLength {
        /// Entries given.
        got: usize,
        /// Elements in the mesh.
        elements: usize,
    },
    /// Refinement would make more links than allowed.
    #[error(
        "refinement needs more than {limit} links ({bytes} bytes): raise epsilon \
         (now {epsilon}) or mesh with larger patches"
    )]
    TooManyLinks {
        /// The limit.
        limit: usize,
        /// Its memory.
        bytes: usize,
        /// The refinement threshold in use.
        epsilon: f64,
    },
}

impl HierarchyOptions {
    fn check(&self) -> Result<(), HierarchyError> {
        let bad = |name, value: f64, must| HierarchyError::BadOption { name, value, must };
        if !(self.epsilon > 0.0 && self.epsilon < 1.0) {
            return Err(bad("epsilon", self.epsilon, "in (0, 1)"));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(bad("tolerance", self.tolerance, "in (0, 1)"));
        }
        if self.visibility_rays == 0 {
            return Err(bad("visibility_rays", 0.0, "at least 1"));
        }
        Ok(())
    }
}

/// Irradiance gathered at a node: at its centroid, its gradient over a
/// flat node's plane (per channel), and harmonics for a volume cluster.
#[derive(Clone, Copy, Debug)]
struct Gathered {
    scalar: DVec3,
    gradient: [DVec3; 3],
    harmonics: Sh,
}

impl Default for Gathered {
    fn default() -> Self {
        Self {
            scalar: DVec3::ZERO,
            gradient: [DVec3::ZERO; 3],
            harmonics: sh::ZERO,
        }
    }
}

impl Gathered {
    fn add(&mut self, o: &Self) {
        self.scalar += o.scalar;
        for c in 0..3 {
            self.gradient[c] += o.gradient[c];
        }
        sh::accumulate(&mut self.harmonics, &o.harmonics);
    }
}

/// What a hierarchical solve did.
#[derive(Clone, Debug, PartialEq)]
pub struct HierarchySolution {
    /// B per element of the mesh (zero on inactive elements).
    pub radiosity: Vec<DVec3>,
    /// Links at the end.
    pub links: usize,
    /// Nodes of the cluster tree.
    pub nodes: usize,
    /// Gathers over all rounds.
    pub iterations: u32,
    /// Relative power change of the last gather.
    pub residual: f64,
    /// False when the progress callback stopped the solve early.
    pub complete: bool,
}

/// An object that may move, with its own occluder BVH at its current
/// place.
struct Mover {
    object: u32,
    geometry: SceneGeometry,
}

/// The occluders of a hierarchy: the static scene and every mover.
struct Blockers<'h> {
    fixed: &'h SceneGeometry,
    movers: &'h [Mover],
}

impl Occluders for Blockers<'_> {
    fn visible(&self, a: DVec3, normal_a: DVec3, b: DVec3, b_on_surface: bool) -> bool {
        self.fixed.visible(a, normal_a, b, b_on_surface)
            && self
                .movers
                .iter()
                .all(|m| m.geometry.visible(a, normal_a, b, b_on_surface))
    }
}

/// A cluster tree with its links over one set of elements and occluders.
pub struct Hierarchy<'a> {
    /// The mesh; its own copy once a mover moved ([`Self::move_object`]).
    mesh: Cow<'a, RadiosityMesh>,
    /// The occluders that never move: every object's, or, with movers,
    /// all but theirs.
    geometry: &'a SceneGeometry,
    /// Objects that may move ([`Self::with_movers`]), each in a subtree of
    /// its own and with its own occluders.
    movers: Vec<Mover>,
    options: HierarchyOptions,
    tree: Tree,
    /// Links sorted by receiver; `offsets[n]..offsets[n + 1]` end at node n.
    links: Vec<Link>,
    offsets: Vec<u32>,
    /// Power the refinement is relative to (max channel, W).
    reference_power: f64,
    /// The four points (barycentric) at which a leaf's direct light and
    /// precise form factors are averaged.
    quadrature: Vec<DVec2>,
}

impl<'a> Hierarchy<'a> {
    /// The tree over the elements of `mesh` (those of `active`, or all),
    /// with `geometry` as the occluders. No links yet.
    pub fn new(
        mesh: &'a RadiosityMesh,
        geometry: &'a SceneGeometry,
        active: Option<&[bool]>,
        options: &HierarchyOptions,
    ) -> Result<Self, HierarchyError> {
        Self::with_movers(mesh, geometry, Vec::new(), active, options)
    }

    /// As [`Self::new`], with objects that may move
    /// ([`Self::move_object`]): `movers` holds each one's object index and
    /// its geometry alone (`ObjectFilter::Indices`), and `fixed` every
    /// other object's. Each mover gets a subtree of its own, and a pair of
    /// elements only a mover hides keeps its link (at zero), so that a
    /// move finds it.
    pub fn with_movers(
        mesh: &'a RadiosityMesh,
        fixed: &'a SceneGeometry,
        movers: Vec<(u32, SceneGeometry)>,
        active: Option<&[bool]>,
        options: &HierarchyOptions,
    ) -> Result<Self, HierarchyError> {
        options.check()?;
        let geometry = fixed;
        let movers: Vec<Mover> = movers
            .into_iter()
            .map(|(object, geometry)| Mover { object, geometry })
            .collect();
        let objects: Vec<u32> = movers.iter().map(|m| m.object).collect();
        let all;
        let active = match active {
            Some(a) if a.len() != mesh.elements.len() => {
                return Err(HierarchyError::MaskLength {
                    got: a.len(),
                    elements: mesh.elements.len(),
                });
            }
            Some(a) => a,
            None => {
                all = vec![true; mesh.elements.len()];
                &all
            }
        };
        Ok(Self {
            mesh: Cow::Borrowed(mesh),
            geometry,
            movers,
            options: options.clone(),
            tree: Tree::build(mesh, active, &objects),
            links: Vec::new(),
            offsets: Vec::new(),
            reference_power: 0.0,
            quadrature: sub_centroids(2),
        })
    }

    /// The mesh, with the movers where they are now.
    pub fn mesh(&self) -> &RadiosityMesh {
        &self.mesh
    }

    /// Links in use.
    pub fn links(&self) -> usize {
        self.links.len()
    }

    /// Nodes of the cluster tree.
    pub fn nodes(&self) -> usize {
        self.tree.nodes.len()
    }

    /// The occluders: the static scene and the movers.
    fn blockers(&self) -> Blockers<'_> {
        Blockers {
            fixed: self.geometry,
            movers: &self.movers,
        }
    }

    /// Direct irradiance from `lights` per element (zero on inactive ones):
    /// the mean over four points of each element.
    pub fn direct(&self, lights: &[Light]) -> Vec<DVec3> {
        let mut out = vec![DVec3::ZERO; self.mesh.elements.len()];
        self.direct_at(lights, &self.tree.order, &mut out);
        out
    }

    /// [`Self::direct`] at `elements` only, into `out` (per element of the
    /// mesh); the same values a full evaluation gives them.
    fn direct_at(&self, lights: &[Light], elements: &[u32], out: &mut [DVec3]) {
        if lights.is_empty() {
            for &e in elements {
                out[e as usize] = DVec3::ZERO;
            }
            return;
        }
        let points = &self.quadrature;
        let seed = self.options.seed;
        let samples = self.options.light_samples;
        let blockers = self.blockers();
        let values: Vec<(u32, DVec3)> = elements
            .par_iter()
            .map(|&e| {
                let el = &self.mesh.elements[e as usize];
                let mut sum = DVec3::ZERO;
                for (k, b) in points.iter().enumerate() {
                    let x = barycentric_point(&el.vertices, *b);
                    for (l, light) in lights.iter().enumerate() {
                        let s = hash64(seed ^ (u64::from(e) << 20) ^ ((k as u64) << 8) ^ l as u64);
                        sum += direct_irradiance(light, &blockers, x, el.normal, samples, s);
                    }
                }
                (e, sum / points.len() as f64)
            })
            .collect();
        for (e, v) in values {
            out[e as usize] = v;
        }
    }

    /// Solve for B with the elements' own exitance `emission` (per
    /// element, e.g. `pi Ke`, or B0 for the real passes) and `direct`
    /// irradiance (from [`Self::direct`]; empty for none): refine the
    /// links for the initial B, gather to `tolerance`, and refine again
    /// against the solved B `refine_rounds` times.
    pub fn solve(
        &mut self,
        emission: &[DVec3],
        direct: &[DVec3],
    ) -> Result<HierarchySolution, HierarchyError> {
        let init = self.initial(emission, direct);
        let mut b = init.clone();
        let mut iterations = 0;
        let mut residual = 1.0;
        let mut complete = true;
        for round in 0..=self.options.refine_rounds {
            if self.links.is_empty() {
                self.link(&b)?;
            } else if self.refine_again(&b)? == 0 && round > 0 {
                break;
            }
            let (it, r, go_on) = self.iterate(&init, &mut b, Some(round));
            (iterations, residual, complete) = (iterations + it, r, go_on);
            if !complete {
                break;
            }
        }
        Ok(HierarchySolution {
            radiosity: b,
            links: self.links.len(),
            nodes: self.tree.nodes.len(),
            iterations,
            residual,
            complete,
        })
    }

    /// Update `b`, solved before, for new `emission` and `direct` light (a
    /// virtual light moved, dimmed or was switched): the same links, the
    /// gathers started from `b`, so they stop as soon as the change has
    /// settled. Returns the gathers taken. Where the old links do not suit
    /// the new light (a light moved far), solve afresh.
    ///
    /// After a few gathers the change shrinks by a steady ratio `r` a
    /// gather (the slowest mode of the bounce is left), so the rest of the
    /// series is about `r / (1 - r)` times the last change, element by
    /// element: that tail is added when the gathers stop (the ambient term
    /// of progressive radiosity, from the solution's own ratio). They stop
    /// when the change is under `tolerance`, or earlier once the tail times
    /// the ratio's drift between the last two gathers (at least a tenth) is.
    /// The demo cabinet's lamp moved 5 cm: 4 gathers instead of 6, 0.20 %
    /// off a fresh solve instead of 0.19 % (whose own seed noise is 1.9 %);
    /// a closed box of rho 0.8: 3 gathers and 0.17 % off the converged B,
    /// against 5 and 0.12 % gathering on to the tolerance.
    pub fn update(&self, b: &mut Vec<DVec3>, emission: &[DVec3], direct: &[DVec3]) -> u32 {
        let init = self.initial(emission, direct);
        let tolerance = self.options.tolerance;
        // B is positively homogeneous in its sources (the gather's clips
        // and moments scale with B), so the old B scaled by the new
        // sources' power over the old ones' (`b - rho K b`) starts next to
        // the answer: a light dimmed or switched off would otherwise decay
        // by the reflectance one gather at a time, its change relative to
        // B never falling (a light that left figure 3's box took the 200
        // gathers, 3 s).
        let mut reflected = self.reflect(b);
        let was: Vec<DVec3> = b.iter().zip(&reflected).map(|(b, r)| *b - *r).collect();
        // No old power (0 / 0, x / 0): keep b.
        let scale = self.power(&init) / self.power(&was);
        if scale.is_finite() && scale != 1.0 {
            for v in b.iter_mut().chain(reflected.iter_mut()) {
                *v *= scale;
            }
        }
        // The first gather's bounce is that one, scaled.
        let mut first = Some(reflected);
        let (mut it, mut last, mut last_ratio) = (0, None::<f64>, None::<f64>);
        while it < self.options.max_iterations {
            let bounce = first.take().unwrap_or_else(|| self.reflect(b));
            let next = sum(&init, &bounce);
            let residual = relative_change(&self.mesh, &self.tree.order, b, &next);
            let previous = std::mem::replace(b, next);
            it += 1;
            let ratio = last
                .map(|l| residual / l)
                .filter(|r| r.is_finite() && *r > 0.0 && *r < MAX_TAIL_RATIO);
            let tail = ratio.map(|r| r / (1.0 - r));
            let drift = match (ratio, last_ratio) {
                (Some(r), Some(l)) => ((r - l).abs() / r).max(MIN_TAIL_DRIFT),
                _ => f64::INFINITY,
            };
            let settled = tail.is_some_and(|t| residual * t * drift < tolerance);
            if residual < tolerance || settled {
                if let Some(t) = tail {
                    // Radiosity is never negative, whatever the estimate.
                    for (v, p) in b.iter_mut().zip(&previous) {
                        *v = (*v + (*v - *p) * t).max(DVec3::ZERO);
                    }
                }
                break;
            }
            (last, last_ratio) = (Some(residual), ratio);
        }
        it
    }

    /// Gather `b = init + rho K b` until it changes by less than
    /// `tolerance` or `max_iterations`, telling the progress callback
    /// (refinement round `round`, when given) after each gather. Returns
    /// the gathers, the last relative change, and false when the callback
    /// stopped it.
    fn iterate(&self, init: &[DVec3], b: &mut Vec<DVec3>, round: Option<u32>) -> (u32, f64, bool) {
        let (mut it, mut residual) = (0, 1.0);
        while it < self.options.max_iterations {
            let next = self.gather_step(init, b);
            residual = relative_change(&self.mesh, &self.tree.order, b, &next);
            *b = next;
            it += 1;
            if let Some(round) = round {
                let point = HierarchyPoint {
                    round,
                    links: self.links.len(),
                    iterations: it,
                    residual,
                };
                if !self.options.progress.report_to(point) {
                    return (it, residual, false);
                }
            }
            if residual < self.options.tolerance {
                break;
            }
        }
        (it, residual, true)
    }

    /// Direct irradiance of one light per element, as [`Self::direct`]:
    /// what a light move recomputes.
    pub fn direct_of(&self, light: &Light) -> Vec<DVec3> {
        self.direct(std::slice::from_ref(light))
    }

    /// `init + rho K b`: one gather of exitance `b` over the links.
    pub fn gather_step(&self, init: &[DVec3], b: &[DVec3]) -> Vec<DVec3> {
        sum(init, &self.reflect(b))
    }

    /// `rho K b` per element: the exitance that one bounce of `b` along
    /// the links adds (zero on inactive elements).
    pub fn reflect(&self, b: &[DVec3]) -> Vec<DVec3> {
        let mut out = vec![DVec3::ZERO; self.mesh.elements.len()];
        if self.tree.nodes.is_empty() {
            return out;
        }
        let moments = self.pull(b);
        let gathered: Vec<Gathered> = (0..self.tree.nodes.len())
            .into_par_iter()
            .map(|n| self.gather_node(n, b, &moments))
            .collect();
        // Push down, parents first: a flat node reads the volume clusters'
        // harmonics above it at its own normal, and hands its children its
        // irradiance moved along its gradient to their centroids.
        let mut pushed = vec![Gathered::default(); self.tree.nodes.len()];
        for n in 0..self.tree.nodes.len() {
            let node = &self.tree.nodes[n];
            let mut g = pushed[n];
            g.add(&gathered[n]);
            if node.flat {
                g.scalar += sh::eval(&g.harmonics, node.normal);
                g.harmonics = sh::ZERO;
            }
            if node.is_leaf() {
                let e = node.element as usize;
                let value = g.scalar.max(DVec3::ZERO);
                out[e] = finite_or_zero(self.mesh.elements[e].reflectance * value);
            } else {
                for c in node.children {
                    let offset = self.tree.nodes[c as usize].center - node.center;
                    let mut child = g;
                    child.scalar += DVec3::new(
                        g.gradient[0].dot(offset),
                        g.gradient[1].dot(offset),
                        g.gradient[2].dot(offset),
                    );
                    pushed[c as usize] = child;
                }
            }
        }
        out
    }

    fn initial(&self, emission: &[DVec3], direct: &[DVec3]) -> Vec<DVec3> {
        let mut init = vec![DVec3::ZERO; self.mesh.elements.len()];
        for &e in &self.tree.order {
            let el = &self.mesh.elements[e as usize];
            let d = direct.get(e as usize).copied().unwrap_or(DVec3::ZERO);
            init[e as usize] = finite_or_zero(
                emission.get(e as usize).copied().unwrap_or(DVec3::ZERO) + el.reflectance * d,
            )
            .max(DVec3::ZERO);
        }
        init
    }

    /// `sum max(0, v) A` over the active elements, all channels: the power
    /// of exitance `v`, up to pi.
    fn power(&self, v: &[DVec3]) -> f64 {
        self.tree
            .order
            .iter()
            .map(|&e| {
                v[e as usize].max(DVec3::ZERO).element_sum() * self.mesh.elements[e as usize].area
            })
            .sum()
    }

    /// Moments of every node from B per element, bottom-up.
    fn pull(&self, b: &[DVec3]) -> Vec<Moments> {
        let mut m = vec![Moments::default(); self.tree.nodes.len()];
        for n in (0..self.tree.nodes.len()).rev() {
            let node = &self.tree.nodes[n];
            m[n] = if node.is_leaf() {
                let e = &self.mesh.elements[node.element as usize];
                Moments::leaf(b[node.element as usize], e.area, e.normal)
            } else {
                let [a, b] = node.children.map(|c| &m[c as usize]);
                Moments::parent(a, b, node.flat)
            };
        }
        m
    }

    fn gather_node(&self, n: usize, b: &[DVec3], moments: &[Moments]) -> Gathered {
        let mut g = Gathered::default();
        if self.offsets.len() <= n + 1 {
            return g;
        }
        let flat = self.tree.nodes[n].flat;
        for l in &self.links[self.offsets[n] as usize..self.offsets[n + 1] as usize] {
            if l.dir == DVec3::ZERO {
                let src = self.tree.nodes[l.source as usize].element as usize;
                g.scalar += l.coef * b[src];
            } else {
                let e = l.coef * moments[l.source as usize].intensity(l.dir);
                if flat {
                    g.scalar += e;
                    for c in 0..3 {
                        g.gradient[c] += l.slope * e[c];
                    }
                } else {
                    sh::add(&mut g.harmonics, -l.dir, e);
                }
            }
        }
        g
    }
}

/// `a + b` per element.
fn sum(a: &[DVec3], b: &[DVec3]) -> Vec<DVec3> {
    a.iter().zip(b).map(|(a, b)| *a + *b).collect()
}

/// `sum |next - b| A / sum next A` over the active elements (max channel).
fn relative_change(mesh: &RadiosityMesh, active: &[u32], b: &[DVec3], next: &[DVec3]) -> f64 {
    let (mut change, mut total) = (0.0, 0.0);
    for &e in active {
        let a = mesh.elements[e as usize].area;
        change += (next[e as usize] - b[e as usize]).abs().max_element() * a;
        total += next[e as usize].max_element() * a;
    }
    if total > 0.0 { change / total } else { 0.0 }
}

/// Solve all elements lit by their own emission and `lights`
/// hierarchically: the counterpart of [`super::solve`].
pub fn solve_hierarchical(
    mesh: &RadiosityMesh,
    geometry: &SceneGeometry,
    lights: &[Light],
    options: &HierarchyOptions,
) -> Result<HierarchySolution, HierarchyError> {
    let mut h = Hierarchy::new(mesh, geometry, None, options)?;
    let emission: Vec<DVec3> = mesh.elements.iter().map(|e| e.emission).collect();
    let direct = h.direct(lights);
    h.solve(&emission, &direct)
}

#[cfg(test)]
mod tests;
