//! Final gather at the mesh vertices: the radiosity of every vertex from
//! a converged solution, `B(x) = emission(x) + rho(x) * E(x)` with
//! `E(x) = sum_p B_p * F(x -> p) * V(x, p)` over the solution's patches
//! (closed-form point-to-polygon form factor `F`, visible fraction `V` of
//! stratified rays) plus the virtual lights' direct irradiance.
//!
//! Why: element radiosity is an area average, and the per-vertex value
//! obtained by averaging the elements around a vertex lies half an element
//! inside at every edge and corner, so Gouraud-interpolated output is
//! biased there by a first-order amount. The gather evaluates B *at* the
//! vertices, so the interpolated output converges with the square of the
//! element size where B is smooth, and soft shadows come from many
//! visibility rays to the emitters instead of the one value per element
//! of the solve. The gather is an integral of the solution, so errors of
//! the patch values enter smoothed and multiplied by `rho * F`.
//!
//! Vertices inside a solid (the floor under a block: the ray along their
//! normal meets a back face first) are never seen, but Gouraud
//! interpolation would carry their darkness into the visible part of every
//! element that straddles the solid's outline. They take the mean of their
//! visible neighbours instead (repeated outwards, a few rings deep).
//!
//! The gather mesh may be finer than the solved one (same scene).
//! Vertices on an edge of their plane are evaluated a hundredth of the way
//! towards the centroid of their elements, so no gather point lies in the
//! plane of a neighbouring wall (where visibility rays would graze it).

use super::RefineOptions;
use super::mesh::RadiosityMesh;
use super::sources::direct_irradiance;
use crate::finite::finite_or_zero;
use crate::sampling::{hash64, stratified, triangle_sample};
use crate::{Ray, SceneGeometry, form_factor_point_polygon};
use glam::DVec3;
use rayon::prelude::*;
use showcase_proto::Light;
use std::collections::HashMap;

/// Settings of a final gather.
#[derive(Clone, Debug, PartialEq)]
pub struct GatherOptions {
    /// Visibility rays per (vertex, patch) pair for reflecting patches.
    pub samples: u32,
    /// Visibility rays per (vertex, patch) pair for emitting patches and
    /// per virtual light (soft shadows need more).
    pub emitter_samples: u32,
    /// Seed of the ray jitter.
    pub seed: u64,
}

impl Default for GatherOptions {
    fn default() -> Self {
        Self {
            samples: 4,
            emitter_samples: 64,
            seed: 7,
        }
    }
}

/// The gather as a cached sparse matrix: for every vertex of a target
/// mesh, the visible form factor `F(x -> p) * V(x, p)` to every patch of
/// the solved mesh it sees. Applying it to new patch values costs one
/// sparse product, so a scene whose geometry is unchanged (a virtual light
/// moved) gathers again almost for free.
#[derive(Clone, Debug)]
pub struct VertexGather {
    /// Per target vertex: `(patch, F * V)`.
    rows: Vec<GatherRow>,
    /// Gather point of each vertex (pulled off edges).
    points: Vec<DVec3>,
    /// Vertex normals.
    normals: Vec<DVec3>,
    /// Vertices inside a solid.
    hidden: Vec<bool>,
    /// Reflectance and emitted exitance per vertex.
    rho: Vec<DVec3>,
    emission: Vec<DVec3>,
    /// Position keys, to reuse rows after the target is refined.
    keys: Vec<[i64; 6]>,
    options: GatherOptions,
}

/// One vertex's gather row: `(patch, F * V)`.
type GatherRow = Vec<(u32, f32)>;

fn key(position: DVec3, normal: DVec3) -> [i64; 6] {
    let p = (position * 1e7).round().as_i64vec3().to_array();
    let n = (normal * 1e4).round().as_i64vec3().to_array();
    [p[0], p[1], p[2], n[0], n[1], n[2]]
}

impl VertexGather {
    /// The gather matrix from the patches of `source` to the vertices of
    /// `target`, reusing the rows of `previous` (an earlier gather from the
    /// same source) for vertices at the same place.
    pub fn build(
        source: &RadiosityMesh,
        target: &RadiosityMesh,
        geometry: &SceneGeometry,
        options: &GatherOptions,
        previous: Option<&VertexGather>,
    ) -> Self {
        let per_element = |f: &dyn Fn(&super::Element) -> DVec3| -> Vec<DVec3> {
            target.vertex_values(&target.elements.iter().map(f).collect::<Vec<_>>())
        };
        let rho = per_element(&|e| e.reflectance);
        let emission = per_element(&|e| e.emission);
        let centroid = per_element(&|e| e.center);
        let keys: Vec<[i64; 6]> = target
            .vertices
            .iter()
            .map(|v| key(v.position, v.normal))
            .collect();
        let old: HashMap<[i64; 6], usize> = previous
            .map(|g| g.keys.iter().enumerate().map(|(i, k)| (*k, i)).collect())
            .unwrap_or_default();
        let emits: Vec<bool> = source
            .patches
            .iter()
            .map(|p| {
                p.elements
                    .iter()
                    .any(|&e| source.elements[e as usize].emission != DVec3::ZERO)
            })
            .collect();
        let samples = options.samples.max(1);
        let emitter_samples = options.emitter_samples.max(1);
        let computed: Vec<(DVec3, bool, GatherRow)> = target
            .vertices
            .par_iter()
            .enumerate()
            .map(|(v, vertex)| {
                let n = vertex.normal;
                let x = vertex.position + 0.01 * (centroid[v] - vertex.position);
                if let Some(g) = previous
                    && let Some(&i) = old.get(&keys[v])
                {
                    return (g.points[i], g.hidden[i], g.rows[i].clone());
                }
                let start = geometry.offset_point(x, n, x + n);
                let hidden = geometry
                    .closest_hit(&Ray::new(start, n), 0.0, f64::INFINITY)
                    .is_some_and(|h| !h.front_face);
                if hidden {
                    return (x, true, Vec::new());
                }
                let mut row = Vec::new();
                for (p, patch) in source.patches.iter().enumerate() {
                    if !(patch.area > 0.0) {
                        continue;
                    }
                    let f = form_factor_point_polygon(x, n, &patch.vertices).unwrap_or(0.0);
                    if !(f > 0.0) {
                        continue;
                    }
                    let k = if emits[p] { emitter_samples } else { samples };
                    let seed = hash64(options.seed ^ ((v as u64) << 24) ^ p as u64);
                    let seen = stratified(k, seed)
                        .iter()
                        .filter(|s| {
                            geometry.visible(x, n, triangle_sample(&patch.vertices, **s), true)
                        })
                        .count();
                    let fv = f * seen as f64 / k as f64;
                    if fv > 0.0 && fv.is_finite() {
                        row.push((p as u32, fv as f32));
                    }
                }
                (x, false, row)
            })
            .collect();
        let mut out = Self {
            rows: Vec::with_capacity(computed.len()),
            points: Vec::with_capacity(computed.len()),
            normals: target.vertices.iter().map(|v| v.normal).collect(),
            hidden: Vec::with_capacity(computed.len()),
            rho,
            emission,
            keys,
            options: options.clone(),
        };
        for (x, h, row) in computed {
            out.points.push(x);
            out.hidden.push(h);
            out.rows.push(row);
        }
        out
    }

    /// Non-zero entries of the matrix.
    pub fn entries(&self) -> usize {
        self.rows.iter().map(Vec::len).sum()
    }

    /// Vertices found inside a solid.
    pub fn hidden_count(&self) -> usize {
        self.hidden.iter().filter(|h| **h).count()
    }

    /// Per-vertex radiosity of `target` (the mesh this was built for) from
    /// the element exitance `source_values` of the source mesh (B with the
    /// ambient term) plus the direct light of `lights`. Missing or
    /// non-finite source values count as zero.
    pub fn apply(
        &self,
        source: &RadiosityMesh,
        source_values: &[DVec3],
        target: &RadiosityMesh,
        geometry: &SceneGeometry,
        lights: &[Light],
    ) -> Vec<DVec3> {
        let patch_values: Vec<DVec3> = source
            .patches
            .iter()
            .map(|p| {
                let mut b = DVec3::ZERO;
                for &e in &p.elements {
                    let v = source_values
                        .get(e as usize)
                        .copied()
                        .unwrap_or(DVec3::ZERO);
                    if v.is_finite() {
                        b += v * source.elements[e as usize].area;
                    }
                }
                let b = b / p.area;
                finite_or_zero(b)
            })
            .collect();
        let samples = self.options.emitter_samples.max(1);
        let gathered: Vec<DVec3> = (0..self.rows.len())
            .into_par_iter()
            .map(|v| {
                if self.hidden[v] {
                    return DVec3::ZERO;
                }
                let mut e = DVec3::ZERO;
                for &(p, f) in &self.rows[v] {
                    e += patch_values[p as usize] * f64::from(f);
                }
                for (i, l) in lights.iter().enumerate() {
                    let seed = hash64(self.options.seed ^ ((v as u64) << 8) ^ i as u64);
                    e += direct_irradiance(
                        l,
                        geometry,
                        self.points[v],
                        self.normals[v],
                        samples,
                        seed,
                    );
                }
                let out = self.emission[v] + self.rho[v] * e;
                finite_or_zero(out).max(DVec3::ZERO)
            })
            .collect();
        fill_hidden(target, gathered, &self.hidden)
    }
}

/// Per-vertex radiosity of `target` (indexed like `target.vertices`)
/// gathered from the patches of the solved mesh `source`, whose element
/// exitance is `source_values` (B with the ambient term), plus `lights`:
/// [`VertexGather::build`] then [`VertexGather::apply`].
pub fn gather_vertices(
    source: &RadiosityMesh,
    source_values: &[DVec3],
    target: &RadiosityMesh,
    geometry: &SceneGeometry,
    lights: &[Light],
    options: &GatherOptions,
) -> Vec<DVec3> {
    VertexGather::build(source, target, geometry, options, None).apply(
        source,
        source_values,
        target,
        geometry,
        lights,
    )
}

/// Split the elements of `target` whose corner values (per vertex) spread
/// more than `options.tolerance` times the area-weighted mean; returns how
/// many were split. Vertices are rebuilt.
pub fn refine_by_vertices(
    target: &mut RadiosityMesh,
    vertex_values: &[DVec3],
    options: &RefineOptions,
) -> usize {
    let value = |i: u32| {
        vertex_values
            .get(i as usize)
            .copied()
            .unwrap_or(DVec3::ZERO)
    };
    let (mut sum, mut area) = (0.0, 0.0);
    for e in &target.elements {
        let m = e.vertex_ids.iter().map(|&v| value(v)).sum::<DVec3>() / 3.0;
        sum += m.max_element() * e.area;
        area += e.area;
    }
    if !(area > 0.0 && sum > 0.0) {
        return 0;
    }
    let limit = options.tolerance * sum / area;
    let split: Vec<u32> = (0..target.elements.len() as u32)
        .filter(|&i| {
            let e = &target.elements[i as usize];
            if e.area / 4.0 < options.min_element_area {
                return false;
            }
            let v = e.vertex_ids.map(value);
            let (lo, hi) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
            (hi - lo).max_element() > limit
        })
        .collect();
    for &e in &split {
        target.split_element(e);
    }
    if !split.is_empty() {
        target.rebuild_vertices();
    }
    split.len()
}

/// Gather onto `target`, then refine it where the gathered values change
/// fast and gather the new vertices, for `refine.rounds` rounds. Returns
/// the last gather matrix and the per-vertex radiosity of the refined
/// `target`.
pub fn gather_adaptive(
    source: &RadiosityMesh,
    source_values: &[DVec3],
    target: &mut RadiosityMesh,
    geometry: &SceneGeometry,
    lights: &[Light],
    options: &GatherOptions,
    refine: &RefineOptions,
) -> (VertexGather, Vec<DVec3>) {
    let mut g = VertexGather::build(source, target, geometry, options, None);
    let mut values = g.apply(source, source_values, target, geometry, lights);
    for _ in 0..refine.rounds {
        if refine_by_vertices(target, &values, refine) == 0 {
            break;
        }
        g = VertexGather::build(source, target, geometry, options, Some(&g));
        values = g.apply(source, source_values, target, geometry, lights);
    }
    (g, values)
}

/// Give every hidden vertex the mean of its known neighbours (vertices
/// sharing an element), ring by ring, at most eight rings deep; hidden
/// vertices beyond keep zero.
fn fill_hidden(mesh: &RadiosityMesh, mut values: Vec<DVec3>, hidden: &[bool]) -> Vec<DVec3> {
    let mut known: Vec<bool> = hidden.iter().map(|h| !h).collect();
    for _ in 0..8 {
        let mut sum = vec![(DVec3::ZERO, 0u32); values.len()];
        for e in &mesh.elements {
            for &a in &e.vertex_ids {
                for &b in &e.vertex_ids {
                    let (a, b) = (a as usize, b as usize);
                    if a != b && !known[a] && known[b] {
                        sum[a].0 += values[b];
                        sum[a].1 += 1;
                    }
                }
            }
        }
        let mut changed = false;
        for (v, (s, n)) in sum.into_iter().enumerate() {
            if n > 0 {
                values[v] = s / f64::from(n);
                known[v] = true;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    values
}
