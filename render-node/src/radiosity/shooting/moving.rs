//! Incremental update after an object moves (beyond the paper, which left
//! dynamic scenes for future work): correct the form factors the move
//! changed, shoot the difference of what every patch already shot, and let
//! progressive refinement go on with signed unshot energy.
//!
//! # Why it is exact
//! After any number of shots, element `j` holds
//! `B_j = D_j + rho_j * sum_i S_i F_ij A_i / A_j`, where `D_j` is what was
//! deposited (emission, direct light) and `S_i` the exitance patch `i` has
//! shot so far, and patch `p` holds `U_p = avg_p(B) - S_p` unshot. After the
//! move the form factors are `F'` and the deposits `D'`; keeping the shot
//! totals `S`, the state `B'_j = D'_j + rho_j sum_i S_i F'_ij A_i / A_j`,
//! `U'_p = avg_p(B') - S_p` is again such a state, so shooting on from it
//! converges to the solution of the moved scene. It is reached by adding
//! `D' - D` (signed deposits) and shooting `S_i (F'_i - F_i)` from every
//! patch that shot (negative and positive form-factor differences).
//!
//! # Which form factors change
//! A moved object changes `F_ij` only where `i` or `j` lies on it, or where
//! a visibility ray between `i` and `j` passes through the object's old or
//! new place. With ray-cast form factors ([`FormFactorMethod::RayCast`])
//! a static pair is re-computed only when the segment between the centres,
//! widened by the larger of the two triangles' radii, meets the bounding
//! box of the object's old or new place, and then only when one of its own
//! visibility rays may see a difference: a ray that certainly passes
//! through both places is blocked before and after, one that certainly
//! misses both sees the same as before (tested against the object's
//! triangles with a margin far above the ray offsets; when unsure, the
//! entry is recomputed). A pair whose rays all see no difference has the
//! very same value as before. The rows of the
//! object's own patches are recomputed whole. Re-computed entries use the
//! same seeds as a fresh solve, so a patched row equals a fresh row of the
//! moved scene (to round-off). With hemi-cube methods every row that is
//! needed is recomputed whole (correct, not faster).

use super::ray_cast::{normalise, ray_cast_form_factor, receiver_rays};
use super::{FormFactorMethod, Shooter};
use crate::light::SceneGeometry;
use crate::radiosity::mesh::RadiosityMesh;
use crate::radiosity::sources::stratified;
use glam::DVec3;
use rayon::prelude::*;
use showcase_proto::Light;

/// Why an object move cannot be applied to a solve.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MoveError {
    /// The moved scene's mesh has another structure (a move must only
    /// displace the object's elements).
    #[error(
        "the moved mesh has {got_patches} patches and {got_elements} elements, the solved one {patches} and {elements}"
    )]
    MeshMismatch {
        /// Patches of the solved mesh.
        patches: usize,
        /// Elements of the solved mesh.
        elements: usize,
        /// Patches of the moved mesh.
        got_patches: usize,
        /// Elements of the moved mesh.
        got_elements: usize,
    },
    /// No element belongs to the object.
    #[error("object {0} has no elements in the mesh")]
    NoSuchObject(u32),
    /// An element that is not on the moved object changed.
    #[error("element {element} changed but is not on the moved object {object}")]
    StaticElementChanged {
        /// The element.
        element: u32,
        /// The moved object.
        object: u32,
    },
}

/// What an incremental object update did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct MoveStats {
    /// Rows corrected entry by entry.
    pub rows_patched: usize,
    /// Rows recomputed whole (the object's patches, hemi-cube methods).
    pub rows_recomputed: usize,
    /// Static pairs whose centre segment met a bounding box.
    pub pairs_near: usize,
    /// Form-factor entries recomputed in patched rows.
    pub entries_recomputed: usize,
    /// Elements whose B changed by the shot difference.
    pub elements_corrected: usize,
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    lo: DVec3,
    hi: DVec3,
}

impl Bounds {
    fn of_object(mesh: &RadiosityMesh, object: u32) -> Option<Self> {
        let mut it = mesh
            .elements
            .iter()
            .filter(|e| e.object == object)
            .flat_map(|e| e.vertices);
        let first = it.next()?;
        let (lo, hi) = it.fold((first, first), |(lo, hi), v| (lo.min(v), hi.max(v)));
        Some(Self { lo, hi })
    }

    fn grown(&self, by: f64) -> Self {
        Self {
            lo: self.lo - DVec3::splat(by),
            hi: self.hi + DVec3::splat(by),
        }
    }

    /// True when the segment `a`-`b` meets the box (slab test).
    fn meets_segment(&self, a: DVec3, b: DVec3) -> bool {
        let d = b - a;
        let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
        for k in 0..3 {
            let (o, dk, lo, hi) = (a[k], d[k], self.lo[k], self.hi[k]);
            if dk.abs() < 1e-300 {
                if o < lo || o > hi {
                    return false;
                }
                continue;
            }
            let (mut ta, mut tb) = ((lo - o) / dk, (hi - o) / dk);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 > t1 {
                return false;
            }
        }
        true
    }
}

/// Where a segment stands against an object's triangles, with a margin
/// far above round-off and the ray offsets of [`SceneGeometry::visible`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Crossing {
    /// It certainly passes through a triangle's interior.
    Hit,
    /// It certainly misses every triangle.
    Miss,
    /// Too close to an edge, an end or a plane to tell.
    Unsure,
}

/// Relative margin of [`crossing`] (in barycentric and segment units).
const CROSSING_MARGIN: f64 = 1e-6;

/// How the segment `a`-`b` meets `triangles` (Moller-Trumbore with a
/// margin on both sides).
fn crossing(triangles: &[[DVec3; 3]], a: DVec3, b: DVec3) -> Crossing {
    let d = b - a;
    let m = CROSSING_MARGIN;
    let mut all_miss = true;
    for [v0, v1, v2] in triangles {
        let (e1, e2) = (*v1 - *v0, *v2 - *v0);
        let p = d.cross(e2);
        let det = e1.dot(p);
        let scale = e1.length() * e2.length() * d.length();
        if !(det.abs() > 1e-9 * scale) {
            // Parallel to the plane (or degenerate): only sure when the
            // segment is far from the triangle's box.
            let lo = v0.min(*v1).min(*v2);
            let hi = v0.max(*v1).max(*v2);
            let pad = m * (1.0 + (hi - lo).max_element());
            let bounds = Bounds { lo, hi }.grown(pad);
            if bounds.meets_segment(a, b) {
                all_miss = false;
            }
            continue;
        }
        let inv = 1.0 / det;
        let s = a - *v0;
        let u = s.dot(p) * inv;
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        let t = e2.dot(q) * inv;
        if u > m && v > m && u + v < 1.0 - m && t > m && t < 1.0 - m {
            return Crossing::Hit;
        }
        let miss = u < -m || v < -m || u + v > 1.0 + m || t < -m || t > 1.0 + m;
        if !miss {
            all_miss = false;
        }
    }
    if all_miss {
        Crossing::Miss
    } else {
        Crossing::Unsure
    }
}

/// The moved object's old and new place.
struct Places {
    /// Bounding boxes (old, new), with a margin.
    boxes: [Bounds; 2],
    /// Triangles (old, new).
    triangles: [Vec<[DVec3; 3]>; 2],
    /// Each element's largest distance from its centre to a corner.
    radii: Vec<f64>,
}

impl Places {
    /// True unless the segment certainly meets both places or certainly
    /// neither (then its visibility is the same before and after).
    fn may_change(&self, a: DVec3, b: DVec3) -> bool {
        let [o, n] = [0, 1].map(|k| {
            if self.boxes[k].meets_segment(a, b) {
                crossing(&self.triangles[k], a, b)
            } else {
                Crossing::Miss
            }
        });
        !matches!(
            (o, n),
            (Crossing::Hit, Crossing::Hit) | (Crossing::Miss, Crossing::Miss)
        )
    }
}

/// A form-factor row (sorted by element) and the scale it was normalised
/// with.
type ScaledRow = (Vec<(u32, f64)>, f64);

/// A row after the move: the row, its scale, its difference from the old
/// row, and what it took.
type UpdatedRow = (Vec<(u32, f64)>, f64, Vec<(u32, f64)>, MoveStats);

/// Largest distance from `center` to a corner.
fn radius(center: DVec3, vertices: &[DVec3; 3]) -> f64 {
    vertices
        .iter()
        .map(|v| (*v - center).length())
        .fold(0.0, f64::max)
}

/// The signed difference `new - old` of two rows sorted by element.
fn row_difference(old: &[(u32, f64)], new: &[(u32, f64)]) -> Vec<(u32, f64)> {
    let (mut a, mut b) = (old.iter().peekable(), new.iter().peekable());
    let mut out = Vec::new();
    loop {
        let d = match (a.peek(), b.peek()) {
            (Some(&&(ja, fa)), Some(&&(jb, fb))) => {
                if ja == jb {
                    a.next();
                    b.next();
                    (ja, fb - fa)
                } else if ja < jb {
                    a.next();
                    (ja, -fa)
                } else {
                    b.next();
                    (jb, fb)
                }
            }
            (Some(&&(ja, fa)), None) => {
                a.next();
                (ja, -fa)
            }
            (None, Some(&&(jb, fb))) => {
                b.next();
                (jb, fb)
            }
            (None, None) => break,
        };
        if d.1 != 0.0 {
            out.push(d);
        }
    }
    out
}

/// `row` (sorted by element) with the entries of `changes` (sorted, a
/// zero value removes the entry) put in.
fn merge_changes(row: &[(u32, f64)], changes: &[(u32, f64)]) -> Vec<(u32, f64)> {
    let mut out = Vec::with_capacity(row.len() + changes.len());
    let mut c = changes.iter().peekable();
    for &(j, f) in row {
        while let Some(&&(jc, fc)) = c.peek() {
            if jc > j {
                break;
            }
            c.next();
            if jc < j && fc != 0.0 {
                out.push((jc, fc));
            }
        }
        match changes.binary_search_by_key(&j, |x| x.0) {
            Ok(k) => {
                if changes[k].1 != 0.0 {
                    out.push(changes[k]);
                }
            }
            Err(_) => out.push((j, f)),
        }
    }
    for &(jc, fc) in c {
        if fc != 0.0 {
            out.push((jc, fc));
        }
    }
    out
}

impl<'a> Shooter<'a> {
    /// Apply a move of `object` to this solve: `mesh` and `geometry` are
    /// the moved scene's (the same mesh options, so every element keeps its
    /// index and only the object's elements moved), `lights` the virtual
    /// lights added with [`Self::add_light`] (scale 1; their direct light
    /// changes where the object shadows it). Returns the solve on the moved
    /// scene, ready to shoot on (e.g. [`Self::run_to_power`]) to the
    /// tolerance the old one reached; see the module docs for why the
    /// result is the moved scene's solution. Cached rows are corrected and
    /// kept; a row with a rasterised item buffer is recomputed on the CPU.
    pub fn move_object<'b>(
        mut self,
        mesh: &'b RadiosityMesh,
        geometry: &'b SceneGeometry,
        object: u32,
        lights: &[Light],
    ) -> Result<(Shooter<'b>, MoveStats), MoveError> {
        let old_mesh = self.mesh;
        if mesh.patches.len() != old_mesh.patches.len()
            || mesh.elements.len() != old_mesh.elements.len()
        {
            return Err(MoveError::MeshMismatch {
                patches: old_mesh.patches.len(),
                elements: old_mesh.elements.len(),
                got_patches: mesh.patches.len(),
                got_elements: mesh.elements.len(),
            });
        }
        for (j, (a, b)) in old_mesh.elements.iter().zip(&mesh.elements).enumerate() {
            let same_place = a.object == b.object
                && a.patch == b.patch
                && a.primitive == b.primitive
                && (a.object == object || a.vertices == b.vertices);
            if !same_place {
                return Err(MoveError::StaticElementChanged {
                    element: j as u32,
                    object,
                });
            }
        }
        let (Some(old_box), Some(new_box)) = (
            Bounds::of_object(old_mesh, object),
            Bounds::of_object(mesh, object),
        ) else {
            return Err(MoveError::NoSuchObject(object));
        };
        // Wider than any ray offset, so the box test is conservative.
        let extent = (old_box.hi - old_box.lo)
            .max(new_box.hi - new_box.lo)
            .max_element();
        let margin = 1e-6 * (1.0 + extent);
        let triangles_of = |m: &RadiosityMesh| -> Vec<[DVec3; 3]> {
            m.primitives
                .iter()
                .filter(|p| p.object == object)
                .map(|p| p.vertices)
                .collect()
        };
        let places = Places {
            boxes: [old_box.grown(margin), new_box.grown(margin)],
            triangles: [triangles_of(old_mesh), triangles_of(mesh)],
            radii: mesh
                .elements
                .iter()
                .map(|e| radius(e.center, &e.vertices))
                .collect(),
        };

        // The old rows of every patch that shot or has a cached row.
        let n = old_mesh.patches.len();
        let mut old_rows: Vec<Option<ScaledRow>> = vec![None; n];
        for (i, slot) in old_rows.iter_mut().enumerate() {
            if let Some(row) = self.rows[i].take() {
                *slot = Some((row, self.row_scale[i]));
            } else if self.shot[i] != DVec3::ZERO && self.patch_active[i] {
                self.rows_computed += 1;
                *slot = Some(self.form_factors(i, self.row_seed(i), None));
            }
        }
        let old_deposits: Vec<Vec<DVec3>> =
            lights.iter().map(|l| self.light_deposits(l, 1.0)).collect();

        let mut new = Shooter {
            mesh,
            geometry,
            active: self.active,
            patch_active: self.patch_active,
            options: self.options,
            hemicube: self.hemicube,
            radiosity: self.radiosity,
            unshot: self.unshot,
            injected: self.injected,
            shots: self.shots,
            curve: self.curve,
            rows: vec![None; n],
            row_scale: vec![1.0; n],
            shot: self.shot,
            row_bytes: 0,
            rows_computed: self.rows_computed,
            raster: None,
            raster_fallbacks: self.raster_fallbacks,
        };
        let ray_cast = new.options.method == FormFactorMethod::RayCast;
        let updated: Vec<Option<UpdatedRow>> = old_rows
            .par_iter()
            .enumerate()
            .map(|(i, old)| {
                let (old_row, old_scale) = old.as_ref()?;
                let seed = new.row_seed(i);
                let mut stats = MoveStats::default();
                let (row, scale) = if !ray_cast || mesh.patches[i].object == object {
                    stats.rows_recomputed = 1;
                    new.form_factors(i, seed, None)
                } else {
                    stats.rows_patched = 1;
                    let changes = new.changed_entries(i, object, &places, &mut stats);
                    let mut row = if *old_scale == 1.0 {
                        merge_changes(old_row, &changes)
                    } else {
                        let raw: Vec<(u32, f64)> =
                            old_row.iter().map(|&(j, f)| (j, f / old_scale)).collect();
                        merge_changes(&raw, &changes)
                    };
                    let scale = normalise(&mut row);
                    (row, scale)
                };
                let diff = row_difference(old_row, &row);
                Some((row, scale, diff, stats))
            })
            .collect();

        let mut stats = MoveStats::default();
        let mut corrected = vec![false; mesh.elements.len()];
        for (i, u) in updated.into_iter().enumerate() {
            let Some((row, scale, diff, s)) = u else {
                continue;
            };
            stats.rows_patched += s.rows_patched;
            stats.rows_recomputed += s.rows_recomputed;
            stats.pairs_near += s.pairs_near;
            stats.entries_recomputed += s.entries_recomputed;
            new.rows_computed += s.rows_recomputed;
            let shot = new.shot[i];
            if shot != DVec3::ZERO {
                let p_area = mesh.patches[i].area;
                for &(j, df) in &diff {
                    let e = &mesh.elements[j as usize];
                    let gain = super::finite(e.reflectance * shot * (df * p_area / e.area));
                    new.radiosity[j as usize] += gain;
                    let q = &mesh.patches[e.patch as usize];
                    new.unshot[e.patch as usize] += gain * (e.area / q.area);
                    corrected[j as usize] = true;
                }
            }
            let bytes = row.capacity() * std::mem::size_of::<(u32, f64)>();
            if new.options.form_factor_cache_bytes > 0
                && new.row_bytes + bytes <= new.options.form_factor_cache_bytes
            {
                new.row_bytes += bytes;
                new.rows[i] = Some(row);
                new.row_scale[i] = scale;
            }
        }
        stats.elements_corrected = corrected.iter().filter(|c| **c).count();
        for (l, old) in lights.iter().zip(&old_deposits) {
            let moved = new.light_deposits(l, 1.0);
            let diff: Vec<DVec3> = moved.iter().zip(old).map(|(a, b)| *a - *b).collect();
            new.deposit(&diff);
        }
        Ok((new, stats))
    }

    /// The entries of ray-cast row `i` (a static patch) that the move of
    /// `object` (old and new place in `places`) may change, recomputed
    /// on the moved scene: `(element, raw F)`, sorted, zero where it is
    /// now zero.
    fn changed_entries(
        &self,
        i: usize,
        object: u32,
        places: &Places,
        stats: &mut MoveStats,
    ) -> Vec<(u32, f64)> {
        let mesh = self.mesh;
        let p = &mesh.patches[i];
        let rp = radius(p.center, &p.vertices);
        let seed = self.row_seed(i);
        let samples = stratified(self.options.visibility_samples, seed);
        let mut out = Vec::new();
        for (j, e) in mesh.elements.iter().enumerate() {
            if !self.active[j] || e.patch as usize == i {
                continue;
            }
            let j = j as u32;
            let recompute = if e.object == object {
                true
            } else {
                let widen = rp.max(places.radii[j as usize]);
                if !places
                    .boxes
                    .iter()
                    .any(|b| b.grown(widen).meets_segment(p.center, e.center))
                {
                    continue;
                }
                stats.pairs_near += 1;
                receiver_rays(mesh, i, j, &samples, seed).any(|(x, y)| places.may_change(x, y))
            };
            if recompute {
                stats.entries_recomputed += 1;
                let f = ray_cast_form_factor(mesh, self.geometry, i, j, &samples, seed);
                out.push((j, f.unwrap_or(0.0)));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_box_test_matches_hand_cases() {
        let b = Bounds {
            lo: DVec3::ZERO,
            hi: DVec3::ONE,
        };
        let x = DVec3::X;
        assert!(b.meets_segment(DVec3::new(-1.0, 0.5, 0.5), DVec3::new(2.0, 0.5, 0.5)));
        assert!(!b.meets_segment(DVec3::new(-1.0, 1.5, 0.5), DVec3::new(2.0, 1.5, 0.5)));
        // Stops short of the box.
        assert!(!b.meets_segment(DVec3::new(-2.0, 0.5, 0.5), DVec3::new(-0.1, 0.5, 0.5)));
        // Axis-parallel, inside the slab on the other axes.
        assert!(b.meets_segment(0.5 * DVec3::ONE, 0.5 * DVec3::ONE + x));
        // Diagonal past a corner.
        assert!(!b.meets_segment(DVec3::new(1.5, -0.5, 0.5), DVec3::new(2.5, 0.5, 0.5)));
    }

    #[test]
    fn crossing_is_sure_only_away_from_edges_and_ends() {
        let tri = [[DVec3::ZERO, DVec3::X, DVec3::Y]];
        let down = |x: f64, y: f64| crossing(&tri, DVec3::new(x, y, 1.0), DVec3::new(x, y, -1.0));
        assert_eq!(down(0.2, 0.2), Crossing::Hit);
        assert_eq!(down(0.7, 0.7), Crossing::Miss);
        assert_eq!(down(-0.1, 0.2), Crossing::Miss);
        assert_eq!(down(0.5, 0.5), Crossing::Unsure);
        assert_eq!(down(0.0, 0.3), Crossing::Unsure);
        // Ending on the plane, short of it, and in the plane.
        let at = |z: f64| crossing(&tri, DVec3::new(0.2, 0.2, 1.0), DVec3::new(0.2, 0.2, z));
        assert_eq!(at(0.0), Crossing::Unsure);
        assert_eq!(at(0.5), Crossing::Miss);
        assert_eq!(
            crossing(&tri, DVec3::new(-1.0, 0.2, 0.0), DVec3::new(2.0, 0.2, 0.0)),
            Crossing::Unsure
        );
        assert_eq!(
            crossing(&tri, DVec3::new(-1.0, 0.2, 0.5), DVec3::new(2.0, 0.2, 0.5)),
            Crossing::Miss
        );
    }

    #[test]
    fn row_merge_and_difference_are_exact() {
        let old = [(1, 0.1), (3, 0.3), (5, 0.5)];
        let changes = [(0, 0.05), (3, 0.0), (5, 0.25), (7, 0.7)];
        let new = merge_changes(&old, &changes);
        assert_eq!(new, vec![(0, 0.05), (1, 0.1), (5, 0.25), (7, 0.7)]);
        let d = row_difference(&old, &new);
        assert_eq!(d, vec![(0, 0.05), (3, -0.3), (5, -0.25), (7, 0.7)]);
        assert!(row_difference(&new, &new).is_empty());
    }
}
