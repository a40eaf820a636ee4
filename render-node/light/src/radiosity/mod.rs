//! Radiosity (paper section 4): a patch/element mesh, hemi-cube and
//! ray-cast form factors, progressive refinement with an ambient term,
//! adaptive element refinement, augmented radiosity (B0..B3) and projector
//! irradiance maps. Pure: no IO, no GPU.
//!
//! # Conventions
//! B is exitance (W/m^2, linear RGB); a material's `emission` is radiance,
//! so its exitance is `pi * emission`; B = rho * E + emission.
//!
//! # Which form factor where
//! - **Hemi-cube** ([`hemicube`]): at the shooting patch's centre, one
//!   item buffer per shot, rotated by a seeded random angle about the normal
//!   against aliasing. Cheap per receiver when receivers are many and far.
//!   It assumes the shooter is a point and that each receiver covers many
//!   pixels.
//! - **Ray-cast area-to-point** (Wallace-style): the closed-form
//!   point-to-polygon form factor to the shooting patch (exact for an
//!   unoccluded patch, at any distance), averaged over up to 64 points of
//!   the receiver (more as the pair gets closer), times the visible
//!   fraction of `visibility_samples` rays between jittered points of the
//!   receiver and the patch. Used where the
//!   hemi-cube is known to fail: receivers closer than
//!   `proximity * sqrt(A_shooter)` (the point assumption breaks down) and
//!   receivers expected to cover fewer than `min_pixels` hemi-cube pixels
//!   (aliasing). [`FormFactorMethod::Hybrid`] applies exactly that rule;
//!   `HemiCube` and `RayCast` force one method everywhere.
//!
//! # Hierarchy
//! Two levels, as in Cohen et al. 1986: patches (at most `max_patch_area`)
//! shoot, elements (`4^element_depth` per patch, then refined adaptively
//! where neighbouring vertex values differ by more than a tolerance, which
//! finds shadow boundaries and corners) receive. Refinement splits
//! elements only, so patches and their unshot energy are unchanged.
#![forbid(unsafe_code)]
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod augmented;
#[cfg(test)]
mod augmented_tests;
pub mod gather;
pub mod hemicube;
pub mod hierarchy;
pub mod live;
pub mod mesh;
pub mod shooting;
pub mod sources;

pub use augmented::{
    AugmentedSolution, B1Pass, IrradianceMap, augmented_radiosity,
    augmented_radiosity_hierarchical, augmented_radiosity_with, gathered_b2_vertices,
    irradiance_map,
};
pub use gather::{
    GatherOptions, VertexGather, gather_adaptive, gather_vertices, refine_by_vertices,
};
pub use hemicube::{HemiCube, HemiCubeError};
pub use hierarchy::{
    Hierarchy, HierarchyError, HierarchyMove, HierarchyOptions, HierarchyPoint, HierarchyProgress,
    HierarchySolution, LINK_BYTES, MIN_LINKS_PER_ELEMENT, MoveError as HierarchyMoveError,
    ObjectMove, estimate_bytes, solve_hierarchical,
};
pub use mesh::{Element, MeshError, MeshOptions, Patch, RadiosityMesh};
pub use shooting::{
    ConvergencePoint, FormFactorMethod, MoveError, MoveStats, Shooter, ShotProgress, SolveError,
    SolveOptions,
};

use crate::SceneGeometry;
use glam::DVec3;
use showcase_proto::Light;

/// Why a radiosity solve failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RadiosityError {
    /// Meshing failed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The solver settings are invalid.
    #[error(transparent)]
    Solve(#[from] SolveError),
}

/// Adaptive element refinement settings.
#[derive(Clone, Debug, PartialEq)]
pub struct RefineOptions {
    /// Refinement rounds (each followed by a re-solve); 0 disables.
    pub rounds: u32,
    /// Split an element when its corner values spread more than this
    /// fraction of the area-weighted mean B.
    pub tolerance: f64,
    /// Never split below this element area (m^2).
    pub min_element_area: f64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            rounds: 1,
            tolerance: 0.2,
            min_element_area: 1e-5,
        }
    }
}

/// A converged (or stopped) solve.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// B per element (W/m^2).
    pub radiosity: Vec<DVec3>,
    /// B plus the ambient term, per element.
    pub display: Vec<DVec3>,
    /// Shots taken (all rounds).
    pub shots: usize,
    /// Unshot fraction at the end.
    pub unshot_fraction: f64,
    /// Unshot fraction after each shot of the last round.
    pub convergence: Vec<ConvergencePoint>,
}

/// Solve all elements lit by their own emission and `lights`.
pub fn solve(
    mesh: &RadiosityMesh,
    geometry: &SceneGeometry,
    lights: &[Light],
    options: &SolveOptions,
) -> Result<Solution, SolveError> {
    let mut s = Shooter::new(mesh, geometry, None, options)?;
    s.add_surface_emission();
    for l in lights {
        s.add_light(l, 1.0);
    }
    s.run();
    Ok(Solution {
        radiosity: s.radiosity().to_vec(),
        display: s.display_radiosity(),
        shots: s.shots(),
        unshot_fraction: s.unshot_fraction(),
        convergence: s.convergence().to_vec(),
    })
}

/// Split the elements where B changes fast; returns how many were split.
pub fn refine(mesh: &mut RadiosityMesh, radiosity: &[DVec3], options: &RefineOptions) -> usize {
    let vertex = mesh.vertex_values(radiosity);
    let (mut sum, mut area) = (0.0, 0.0);
    for (e, b) in mesh.elements.iter().zip(radiosity) {
        sum += b.max_element() * e.area;
        area += e.area;
    }
    if !(area > 0.0 && sum > 0.0) {
        return 0;
    }
    let limit = options.tolerance * sum / area;
    let to_split: Vec<u32> = mesh
        .elements
        .iter()
        .zip(radiosity)
        .enumerate()
        .filter(|(_, (e, b))| {
            if e.area / 4.0 < options.min_element_area {
                return false;
            }
            let mut lo = **b;
            let mut hi = **b;
            for &v in &e.vertex_ids {
                let x = vertex.get(v as usize).copied().unwrap_or(**b);
                lo = lo.min(x);
                hi = hi.max(x);
            }
            (hi - lo).max_element() > limit
        })
        .map(|(i, _)| i as u32)
        .collect();
    for &e in &to_split {
        mesh.split_element(e);
    }
    if !to_split.is_empty() {
        mesh.rebuild_vertices();
    }
    to_split.len()
}

/// Solve, refine where B changes fast, re-solve, for `refine.rounds` rounds.
pub fn solve_adaptive(
    mesh: &mut RadiosityMesh,
    geometry: &SceneGeometry,
    lights: &[Light],
    options: &SolveOptions,
    refine_options: &RefineOptions,
) -> Result<Solution, SolveError> {
    let mut solution = solve(mesh, geometry, lights, options)?;
    let mut shots = solution.shots;
    for _ in 0..refine_options.rounds {
        if refine(mesh, &solution.radiosity, refine_options) == 0 {
            break;
        }
        solution = solve(mesh, geometry, lights, options)?;
        shots += solution.shots;
    }
    solution.shots = shots;
    Ok(solution)
}

/// An indexed triangle mesh with per-vertex values, ready to draw or export.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct VertexMesh {
    /// Vertex positions (m).
    pub positions: Vec<DVec3>,
    /// Unit vertex normals.
    pub normals: Vec<DVec3>,
    /// Per-vertex value (B, W/m^2).
    pub values: Vec<DVec3>,
    /// Counter-clockwise triangles (front side).
    pub triangles: Vec<[u32; 3]>,
}

/// The elements passing `keep` as an indexed mesh with interpolated
/// per-vertex values of `element_values`. The light map of a virtual object
/// is this with its B0 and `keep = |e| e.object == object`.
pub fn vertex_mesh(
    mesh: &RadiosityMesh,
    element_values: &[DVec3],
    keep: impl Fn(&Element) -> bool,
) -> VertexMesh {
    vertex_mesh_from_vertices(mesh, &mesh.vertex_values(element_values), keep)
}

/// [`vertex_mesh`] from per-vertex values (indexed like `mesh.vertices`,
/// e.g. from [`gather_vertices`]); missing values are zero.
pub fn vertex_mesh_from_vertices(
    mesh: &RadiosityMesh,
    values: &[DVec3],
    keep: impl Fn(&Element) -> bool,
) -> VertexMesh {
    let mut remap = vec![u32::MAX; mesh.vertices.len()];
    let mut out = VertexMesh::default();
    for e in mesh.elements.iter().filter(|e| keep(e)) {
        let mut tri = [0u32; 3];
        for (k, &v) in e.vertex_ids.iter().enumerate() {
            let slot = &mut remap[v as usize];
            if *slot == u32::MAX {
                *slot = out.positions.len() as u32;
                out.positions.push(mesh.vertices[v as usize].position);
                out.normals.push(mesh.vertices[v as usize].normal);
                out.values
                    .push(values.get(v as usize).copied().unwrap_or(DVec3::ZERO));
            }
            tri[k] = *slot;
        }
        out.triangles.push(tri);
    }
    out
}

/// Area-weighted relative RMS difference of two solutions on possibly
/// different meshes of the same scene: `rmse / mean(reference)` over all
/// channels, sampled at `samples_per_primitive` points per scene triangle
/// (weighted by area) with interpolated (per-vertex) values.
pub fn relative_error(
    test_mesh: &RadiosityMesh,
    test: &[DVec3],
    reference_mesh: &RadiosityMesh,
    reference: &[DVec3],
    samples_per_side: u32,
) -> Option<f64> {
    relative_error_vertices(
        test_mesh,
        &test_mesh.vertex_values(test),
        reference_mesh,
        &reference_mesh.vertex_values(reference),
        samples_per_side,
    )
}

/// [`relative_error`] of per-vertex solutions (indexed like the meshes'
/// `vertices`, e.g. from [`gather_vertices`]).
pub fn relative_error_vertices(
    test_mesh: &RadiosityMesh,
    tv: &[DVec3],
    reference_mesh: &RadiosityMesh,
    rv: &[DVec3],
    samples_per_side: u32,
) -> Option<f64> {
    let n = samples_per_side.max(1);
    let (mut sq, mut sum, mut weight) = (0.0, 0.0, 0.0);
    for (pi, prim) in reference_mesh.primitives.iter().enumerate() {
        let Some(ti) = test_mesh.primitive_of(prim.object, prim.triangle) else {
            continue;
        };
        let w = prim.area() / (n * n) as f64;
        for b in mesh::sub_centroids(n) {
            let (Some(r), Some(t)) = (
                reference_mesh.interpolate(pi as u32, b, rv),
                test_mesh.interpolate(ti, b, tv),
            ) else {
                continue;
            };
            sq += w * (t - r).length_squared();
            sum += w * (r.x + r.y + r.z);
            weight += w;
        }
    }
    if !(weight > 0.0 && sum > 0.0) {
        return None;
    }
    let rmse = (sq / (3.0 * weight)).sqrt();
    let e = rmse / (sum / (3.0 * weight));
    e.is_finite().then_some(e)
}

#[cfg(test)]
mod moving_tests;
#[cfg(test)]
mod tests;
