//! The ray-cast form factor of one patch-element pair
//! ([`FormFactorMethod::RayCast`](super::FormFactorMethod::RayCast)), its
//! visibility rays, and row normalisation: shared by the shooter and the
//! object-move update, which must compute the very same values.

use crate::radiosity::mesh::{Element, Patch, RadiosityMesh, barycentric_point, sub_centroids};
use crate::sampling::{triangle_sample, unit};
use crate::{SceneGeometry, form_factor_point_polygon};
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
                wrap(samples[i] + glam::DVec2::new(shift.y, shift.x)),
            )
        };
        let y = triangle_sample(&p.vertices, wrap(samples[k - 1 - i] + shift));
        (x, y)
    })
}

/// The fractional part of a sum of two numbers in `[0, 1)` (so in
/// `[0, 2)`): bit for bit `fract`, which compiles to a library call on
/// the baseline x86-64 target, where this is a compare and a subtraction
/// (exact: `x - 1` for `x` in `[1, 2)` is representable).
fn wrap(v: glam::DVec2) -> glam::DVec2 {
    let w = |x: f64| if x >= 1.0 { x - 1.0 } else { x };
    glam::DVec2::new(w(v.x), w(v.y))
}

/// Relative height below which a point counts as lying in a plane in
/// [`facing_away`] (in units of the pair's extent): far above round-off,
/// far below any form factor that matters.
const IN_PLANE: f64 = 1e-9;

/// True when the ray-cast form factor from patch `p` to element `e` is
/// zero whatever lies between them, to round-off: every corner of the
/// receiver lies on or behind the patch's plane, or every corner of the
/// patch on or behind the receiver's (within [`IN_PLANE`] of the pair's
/// extent). The closed form is zero behind the emitter and where the
/// emitter is below the receiver's horizon; a receiver within a sliver of
/// the plane gets a form factor of the order of that sliver. Coplanar
/// pairs (a floor seen from the floor) are the common case.
pub(super) fn facing_away(p: &Patch, e: &Element) -> bool {
    let extent = (e.center - p.center).length() + p.area.sqrt() + e.area.sqrt();
    let tol = IN_PLANE * extent;
    let below = |n: DVec3, origin: DVec3, points: &[DVec3; 3]| {
        points.iter().all(|x| n.dot(*x - origin) <= tol)
    };
    below(p.normal, p.center, &e.vertices) || below(e.normal, e.center, &p.vertices)
}

/// The largest n of [`unoccluded_form_factor`]'s n-fold split.
const MAX_SPLIT: u32 = 8;

/// [`sub_centroids`] for n = 1 to [`MAX_SPLIT`], made once: every
/// form-factor entry takes one of them.
static SUB_CENTROIDS: std::sync::LazyLock<Vec<Vec<glam::DVec2>>> =
    std::sync::LazyLock::new(|| (1..=MAX_SPLIT).map(sub_centroids).collect());

/// The unoccluded point-to-polygon form factor from element `e` to patch
/// `p`, averaged over `e`: the closed form at the centroids of n^2 equal
/// sub-triangles, n growing as the pair gets close relative to its size.
fn unoccluded_form_factor(p: &Patch, e: &Element) -> f64 {
    let closeness = (p.area.sqrt() + e.area.sqrt()) / (e.center - p.center).length();
    // A NaN closeness (a degenerate pair) casts to 0: one point, as before.
    let n = ((2.0 * closeness).ceil() as usize).clamp(1, MAX_SPLIT as usize);
    let points = &SUB_CENTROIDS[n - 1];
    points
        .iter()
        .map(|b| {
            let x = barycentric_point(&e.vertices, *b);
            form_factor_point_polygon(x, e.normal, &p.vertices).unwrap_or(0.0)
        })
        .sum::<f64>()
        / points.len() as f64
}

/// Rays per entry whose visibility a [`RayMask`] records: bit `r` is ray
/// `r` of [`receiver_rays`]. Entries with more rays get [`UNKNOWN_RAYS`].
pub(super) const MASK_RAYS: usize = 31;

/// Which of an entry's visibility rays saw the shooter (bit `r` for ray
/// `r`), so that a move can update the entry from the rays the move may
/// change alone (see `moving`).
pub(crate) type RayMask = u32;

/// The mask of an entry whose rays were not recorded (more than
/// [`MASK_RAYS`] rays, or an entry not cast, such as a reciprocal one).
pub(super) const UNKNOWN_RAYS: RayMask = u32::MAX;

/// The raw (not normalised) ray-cast form factor `F_pj` from patch
/// `shooter` to element `j` (see the module docs) and the [`RayMask`] of
/// its rays, `None` where it is zero.
pub(super) fn ray_cast_entry(
    mesh: &RadiosityMesh,
    geometry: &SceneGeometry,
    shooter: usize,
    j: u32,
    samples: &[glam::DVec2],
    seed: u64,
) -> Option<(f64, RayMask)> {
    let e = &mesh.elements[j as usize];
    let p = &mesh.patches[shooter];
    if facing_away(p, e) {
        return None;
    }
    let unoccluded = unoccluded_form_factor(p, e);
    if !(unoccluded > 0.0) {
        return None;
    }
    // Visible fraction: rays between paired jittered points of the
    // receiver and the patch.
    let k = samples.len();
    let mut mask: RayMask = 0;
    let mut seen = 0;
    for (r, (x, y)) in receiver_rays(mesh, shooter, j, samples, seed).enumerate() {
        if geometry.visible(x, e.normal, y, true) {
            seen += 1;
            if r < MASK_RAYS {
                mask |= 1 << r;
            }
        }
    }
    let f = entry_value(unoccluded, seen, k, e.area, p.area);
    let mask = if k <= MASK_RAYS { mask } else { UNKNOWN_RAYS };
    (f > 0.0 && f.is_finite()).then_some((f, mask))
}

/// [`ray_cast_entry`] of an entry whose rays' visibility is known: `mask`
/// has bit `r` set for each of its `k` rays that sees the shooter (`k` at
/// most [`MASK_RAYS`]). The same value as `ray_cast_entry` where `mask` is
/// what its rays see, computed without tracing them; `None` where it is
/// zero.
pub(super) fn entry_from_mask(
    mesh: &RadiosityMesh,
    shooter: usize,
    j: u32,
    mask: RayMask,
    k: usize,
) -> Option<f64> {
    let e = &mesh.elements[j as usize];
    let p = &mesh.patches[shooter];
    if mask == 0 || facing_away(p, e) {
        return None;
    }
    let unoccluded = unoccluded_form_factor(p, e);
    if !(unoccluded > 0.0) {
        return None;
    }
    let f = entry_value(unoccluded, mask.count_ones(), k, e.area, p.area);
    (f > 0.0 && f.is_finite()).then_some(f)
}

/// The raw form factor of an entry whose unoccluded form factor is
/// `unoccluded` and whose `seen` of `k` rays are visible (receiver area
/// `e_area`, patch area `p_area`).
fn entry_value(unoccluded: f64, seen: u32, k: usize, e_area: f64, p_area: f64) -> f64 {
    unoccluded * seen as f64 / k as f64 * e_area / p_area
}

/// The raw form factor of an entry that was `old` with `seen_old` visible
/// rays, now that `seen_new` are: the unoccluded form factor and the areas
/// are unchanged, so it is `old * seen_new / seen_old` (equal to a fresh
/// [`ray_cast_entry`] to round-off); `None` where it is now zero.
pub(super) fn rescaled_entry(old: f64, seen_old: u32, seen_new: u32) -> Option<f64> {
    let f = old * seen_new as f64 / seen_old as f64;
    (f > 0.0 && f.is_finite()).then_some(f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radiosity::moving_tests::{box_with_block, mesh_of};
    use glam::Vec3;

    /// [`wrap`] is `fract` bit for bit on sums of two numbers in `[0, 1)`.
    #[test]
    fn wrap_is_fract_on_sums_of_unit_numbers() {
        let edge = [0.0, f64::EPSILON, 0.5, 1.0 - f64::EPSILON / 2.0];
        let random = (0..2000).map(|k| unit(k as u64));
        for a in edge.into_iter().chain(random.clone()) {
            for b in edge.into_iter().chain(random.clone().take(50)) {
                let v = glam::DVec2::new(a + b, b + a / 2.0);
                let (w, f) = (wrap(v), v.fract());
                assert_eq!(
                    (w.x.to_bits(), w.y.to_bits()),
                    (f.x.to_bits(), f.y.to_bits())
                );
            }
        }
    }

    /// [`facing_away`] culls only pairs whose unoccluded form factor is
    /// zero (to round-off), on every pair of a closed box with a block in
    /// it, and it does cull every coplanar pair.
    #[test]
    fn facing_away_culls_only_zero_form_factors() {
        let (mesh, _) = mesh_of(&box_with_block(Vec3::ZERO));
        let (mut culled, mut coplanar) = (0, 0);
        for (i, p) in mesh.patches.iter().enumerate() {
            for e in mesh.elements.iter().filter(|e| e.patch as usize != i) {
                let away = facing_away(p, e);
                let f = unoccluded_form_factor(p, e);
                if away {
                    culled += 1;
                    assert!(f < 1e-12, "culled pair with form factor {f}");
                }
                let in_plane = e
                    .vertices
                    .iter()
                    .all(|v| p.normal.dot(*v - p.center).abs() < 1e-12);
                if in_plane && p.normal.dot(e.normal) > 0.5 {
                    coplanar += 1;
                    assert!(away, "coplanar pair not culled");
                }
            }
        }
        assert!(
            coplanar > 100 && culled > coplanar,
            "{culled} culled, {coplanar} coplanar"
        );
    }
}
