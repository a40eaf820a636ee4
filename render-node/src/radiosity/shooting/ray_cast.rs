//! The ray-cast form factor of one patch-element pair
//! ([`FormFactorMethod::RayCast`](super::FormFactorMethod::RayCast)), its
//! visibility rays, and row normalisation: shared by the shooter and the
//! object-move update, which must compute the very same values.

use crate::light::{SceneGeometry, form_factor_point_polygon};
use crate::radiosity::mesh::{RadiosityMesh, barycentric_point, sub_centroids};
use crate::radiosity::sources::{triangle_sample, unit};
use glam::DVec3;

/// Scale `row` to sum to at most 1; returns the scale applied (1 when the
/// row sums to at most 1). Sums in row order.
pub(super) fn normalise(row: &mut [(u32, f64)]) -> f64 {
    let total: f64 = row.iter().map(|(_, f)| f).sum();
    if total > 1.0 {
        for (_, f) in row.iter_mut() {
            *f /= total;
        }
        1.0 / total
    } else {
        1.0
    }
}

/// The visibility rays of the ray-cast form factor from patch `shooter` to
/// element `j`: paired jittered points `(x on the receiver, y on the
/// patch)`, the receiver's centre for one sample.
pub(super) fn receiver_rays<'m>(
    mesh: &'m RadiosityMesh,
    shooter: usize,
    j: u32,
    samples: &'m [glam::DVec2],
    seed: u64,
) -> impl Iterator<Item = (DVec3, DVec3)> + 'm {
    let e = &mesh.elements[j as usize];
    let p = &mesh.patches[shooter];
    let k = samples.len();
    let shift = glam::DVec2::new(unit(seed ^ j as u64), unit(seed ^ !(j as u64)));
    (0..k).map(move |i| {
        let x = if k == 1 {
            e.center
        } else {
            triangle_sample(
                &e.vertices,
                (samples[i] + glam::DVec2::new(shift.y, shift.x)).fract(),
            )
        };
        let y = triangle_sample(&p.vertices, (samples[k - 1 - i] + shift).fract());
        (x, y)
    })
}

/// The raw (not normalised) ray-cast form factor `F_pj` from patch
/// `shooter` to element `j` (see the module docs), `None`
/// where it is zero.
pub(super) fn ray_cast_form_factor(
    mesh: &RadiosityMesh,
    geometry: &SceneGeometry,
    shooter: usize,
    j: u32,
    samples: &[glam::DVec2],
    seed: u64,
) -> Option<f64> {
    let e = &mesh.elements[j as usize];
    let p = &mesh.patches[shooter];
    // Unoccluded area-averaged form factor: the closed form at the
    // centroids of n^2 equal sub-triangles, n growing as the pair gets
    // close relative to its size.
    let closeness = (p.area.sqrt() + e.area.sqrt()) / (e.center - p.center).length();
    let n = (2.0 * closeness).ceil().clamp(1.0, 8.0) as u32;
    let points = sub_centroids(n);
    let unoccluded = points
        .iter()
        .map(|b| {
            let x = barycentric_point(&e.vertices, *b);
            form_factor_point_polygon(x, e.normal, &p.vertices).unwrap_or(0.0)
        })
        .sum::<f64>()
        / points.len() as f64;
    if !(unoccluded > 0.0) {
        return None;
    }
    // Visible fraction: rays between paired jittered points of the
    // receiver and the patch.
    let k = samples.len();
    let seen = receiver_rays(mesh, shooter, j, samples, seed)
        .filter(|(x, y)| geometry.visible(*x, e.normal, *y, true))
        .count();
    let f = unoccluded * seen as f64 / k as f64 * e.area / p.area;
    (f > 0.0 && f.is_finite()).then_some(f)
}
