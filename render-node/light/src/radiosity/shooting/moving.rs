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
//! the rows of the object's own patches are recomputed whole, and a
//! static row is patched entry by entry:
//! - the object's column: by reciprocity from the object's recomputed
//!   rows (`F_iq A_i = F_qi A_q`) where the object patch has a single
//!   element and the static patch is at most twice its area and does
//!   not emit, else ray-cast (see `Reciprocal`: a reciprocal entry is
//!   another estimate of the same form factor, equal to the ray-cast one
//!   to within the form factors' discretisation error);
//! - a static pair is re-computed only when one of its own visibility
//!   rays may see a difference. Culling, cheapest first: the receiver
//!   must lie in the shooter's penumbra of the box around the object's
//!   old and new place (a box in the frame that fits the object best,
//!   see `Bounds::of_places`; planes through an edge of one and a corner
//!   of the other that separate the patch from the box), the pair must
//!   face each
//!   other (a receiver in or behind the shooter's plane, or a shooter in
//!   or behind the receiver's, has a zero form factor wherever the object
//!   is: `facing_away`), where the union box holds a sizeable gap outside
//!   both boxes (`Places::segment_test`) the segment between the
//!   centres, widened by the larger of the two triangles' radii, must meet
//!   the old or new box, and then a ray must not be sure to see the same
//!   as before: a ray that certainly passes through both places is blocked
//!   before and after, one that certainly misses both sees the same as
//!   before (tested against the object's triangles with a margin far
//!   above the ray offsets; when unsure, the entry is recomputed). A pair
//!   whose rays all see no difference has the very same value as before.
//!   Re-computed entries use the same seeds as a fresh solve, so they
//!   equal a fresh row's entries of the moved scene (to round-off);
//! - a cached ray-cast row records which of each entry's rays saw the
//!   shooter ([`RayMask`]). An entry near the object is then not ray-cast
//!   again: a ray that the new place certainly blocks is blocked, a clear
//!   ray stays clear unless the new place may block it, a blocked ray
//!   that the old place certainly missed was blocked by the static scene
//!   and stays blocked, and only the other rays are traced again; the
//!   entry is rescaled by the visible count (its unoccluded form factor
//!   and areas are unchanged), which equals a fresh entry to round-off.
//!   So a ray meets the old place's test only when it was blocked and is
//!   not certainly blocked now. An entry that was zero stays zero when
//!   each of its rays is blocked by the new place or was not blocked by
//!   the old one; otherwise only its other rays are traced, and it is
//!   computed (its unoccluded form factor) only when one of them now sees
//!   the shooter. (Rows without masks use the rule above: an entry is
//!   recomputed when a ray may see a difference.)
//!
//! With hemi-cube methods every row that is needed is recomputed whole
//! (correct, not faster).

use super::ray_cast::{
    MASK_RAYS, RayMask, UNKNOWN_RAYS, entry_from_mask, facing_away, normalise, ray_cast_entry,
    receiver_rays, rescaled_entry,
};
use super::{ComputedRow, FormFactorMethod, Shooter};
use crate::SceneGeometry;
use crate::finite::finite_or_zero;
use crate::radiosity::mesh::RadiosityMesh;
use crate::sampling::stratified;
use cull::{
    Bounds, Crossing, Places, ball_outside_penumbra, outside_penumbra, penumbra_planes, radius,
    unchanged,
};
use glam::DVec3;
use rayon::prelude::*;
use showcase_proto::Light;

mod cull;

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
    /// Static receiver-row pairs the penumbra scan looked at (every
    /// active static element outside the row's own patch, in every
    /// patched row).
    pub receivers_scanned: usize,
    /// Static pairs whose rays were tested against the object: those in
    /// the shooter's penumbra of the object's box (and, where the box
    /// around both places holds a sizeable gap, whose centre segment,
    /// widened by the larger triangle radius, met the old or new box).
    pub pairs_near: usize,
    /// Form-factor entries computed anew in patched rows: ray-cast, or
    /// (an entry that was zero) from its rays once one of them sees the
    /// shooter.
    pub entries_recomputed: usize,
    /// Entries of patched rows updated from their rays' recorded
    /// visibility: only the rays the move may change were traced again
    /// (and none that the object certainly blocks now or certainly did
    /// not block before), and the entry rescaled by the visible count.
    pub entries_rescaled: usize,
    /// Entries of the object's column in patched rows taken from its own
    /// rows by reciprocity (single-element object patches).
    pub entries_reciprocal: usize,
    /// Visibility rays of the near pairs tested against the object's
    /// places (every ray of a pair whose rays' visibility was recorded;
    /// otherwise those up to the first that may see a difference).
    pub rays_tested: usize,
    /// Of those, rays that the places left open and that were traced
    /// again through the moved scene.
    pub rays_traced: usize,
    /// Elements whose B changed by the shot difference.
    pub elements_corrected: usize,
}

/// A row after the move: the row, its scale, its difference from the old
/// row, and what it took.
type UpdatedRow = (ComputedRow, Vec<(u32, f64)>, MoveStats);

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

/// The signed difference `new - old` where `new` is `old` (sorted by
/// element) with `changes` (sorted) put in: as [`row_difference`] of the
/// merged row, touching only the changed entries.
fn changes_difference(old: &[(u32, f64)], changes: &[(u32, f64)]) -> Vec<(u32, f64)> {
    let mut rest = old;
    let mut out = Vec::with_capacity(changes.len());
    for &(j, f) in changes {
        let k = rest.partition_point(|e| e.0 < j);
        let before = match rest.get(k) {
            Some(&(jo, fo)) if jo == j => fo,
            _ => 0.0,
        };
        rest = &rest[k..];
        if f - before != 0.0 {
            out.push((j, f - before));
        }
    }
    out
}

/// `row` (sorted by element) with the entries of `changes` (sorted, a
/// zero value removes the entry) put in, and the rows' [`RayMask`]s
/// merged alike (`rays` aligned with `row`, `change_rays` with `changes`;
/// none when `row` has none).
fn merge_changes(
    row: &[(u32, f64)],
    rays: Option<&[RayMask]>,
    changes: &[(u32, f64)],
    change_rays: &[RayMask],
) -> (Vec<(u32, f64)>, Option<Vec<RayMask>>) {
    let mut out = Vec::with_capacity(row.len() + changes.len());
    let mut out_rays = rays.map(|_| Vec::with_capacity(row.len() + changes.len()));
    let ray_of = |k: usize| rays.map_or(UNKNOWN_RAYS, |r| r[k]);
    let (mut a, mut c) = (0, 0);
    loop {
        let (next, mask) = match (row.get(a), changes.get(c)) {
            (Some(&(j, f)), Some(&(jc, fc))) => {
                if jc < j {
                    c += 1;
                    ((jc, fc), change_rays[c - 1])
                } else if jc == j {
                    a += 1;
                    c += 1;
                    ((jc, fc), change_rays[c - 1])
                } else {
                    a += 1;
                    ((j, f), ray_of(a - 1))
                }
            }
            (Some(&x), None) => {
                a += 1;
                (x, ray_of(a - 1))
            }
            (None, Some(&x)) => {
                c += 1;
                (x, change_rays[c - 1])
            }
            (None, None) => break,
        };
        if next.1 != 0.0 {
            out.push(next);
            if let Some(r) = out_rays.as_mut() {
                r.push(mask);
            }
        }
    }
    (out, out_rays)
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
        let Some([old_box, new_box]) = Bounds::of_places(old_mesh, mesh, object) else {
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
        let places = Places::new(
            [old_box, new_box],
            margin,
            [triangles_of(old_mesh), triangles_of(mesh)],
            mesh,
            object,
            &self.active,
        );

        // The old rows of every patch that shot or has a cached row.
        let n = old_mesh.patches.len();
        let mut old_rows: Vec<Option<ComputedRow>> = vec![None; n];
        for (i, slot) in old_rows.iter_mut().enumerate() {
            if let Some(row) = self.rows[i].take() {
                *slot = Some((row, self.row_scale[i], self.row_rays[i].take()));
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
            row_rays: vec![None; n],
            shot: self.shot,
            row_bytes: 0,
            rows_computed: self.rows_computed,
            raster: None,
            raster_fallbacks: self.raster_fallbacks,
        };
        let ray_cast = new.options.method == FormFactorMethod::RayCast;
        // Rows recomputed whole: the object's own (also where there was no
        // old row, when reciprocity needs it), every row for hemi-cubes.
        let own: Vec<Option<ComputedRow>> = (0..n)
            .into_par_iter()
            .map(|i| {
                let p = &mesh.patches[i];
                let on_object = p.object == object;
                let reciprocal = ray_cast && on_object && p.elements.len() == 1;
                let needed = old_rows[i].is_some() || (reciprocal && new.patch_active[i]);
                (needed && (!ray_cast || on_object))
                    .then(|| new.form_factors(i, new.row_seed(i), None))
            })
            .collect();
        let reciprocal = Reciprocal::new(mesh, object, &own, ray_cast);
        let updated: Vec<Option<UpdatedRow>> = own
            .into_par_iter()
            .zip(old_rows.par_iter())
            .enumerate()
            .map(|(i, (own, old))| {
                let mut stats = MoveStats::default();
                let (row, diff) = match own {
                    Some(recomputed) => {
                        stats.rows_recomputed = 1;
                        let diff = old.as_ref().map_or_else(Vec::new, |(old_row, _, _)| {
                            row_difference(old_row, &recomputed.0)
                        });
                        (recomputed, diff)
                    }
                    None => {
                        let old = old.as_ref()?;
                        let (old_row, old_scale, old_rays) = old;
                        stats.rows_patched = 1;
                        let (changes, change_rays) =
                            new.changed_entries(i, &places, &reciprocal, old, &mut stats);
                        let (mut row, rays) = if *old_scale == 1.0 {
                            merge_changes(old_row, old_rays.as_deref(), &changes, &change_rays)
                        } else {
                            let raw: Vec<(u32, f64)> =
                                old_row.iter().map(|&(j, f)| (j, f / old_scale)).collect();
                            merge_changes(&raw, old_rays.as_deref(), &changes, &change_rays)
                        };
                        let scale = normalise(&mut row);
                        // Unscaled before and after, only the changed
                        // entries differ.
                        let diff = if *old_scale == 1.0 && scale == 1.0 {
                            changes_difference(old_row, &changes)
                        } else {
                            row_difference(old_row, &row)
                        };
                        ((row, scale, rays), diff)
                    }
                };
                Some((row, diff, stats))
            })
            .collect();

        let mut stats = MoveStats::default();
        let mut corrected = vec![false; mesh.elements.len()];
        for (i, u) in updated.into_iter().enumerate() {
            let Some((row, diff, s)) = u else {
                continue;
            };
            stats.rows_patched += s.rows_patched;
            stats.rows_recomputed += s.rows_recomputed;
            stats.pairs_near += s.pairs_near;
            stats.entries_recomputed += s.entries_recomputed;
            stats.entries_reciprocal += s.entries_reciprocal;
            stats.entries_rescaled += s.entries_rescaled;
            stats.receivers_scanned += s.receivers_scanned;
            stats.rays_tested += s.rays_tested;
            stats.rays_traced += s.rays_traced;
            new.rows_computed += s.rows_recomputed;
            let shot = new.shot[i];
            if shot != DVec3::ZERO {
                let p_area = mesh.patches[i].area;
                for &(j, df) in &diff {
                    let e = &mesh.elements[j as usize];
                    let gain = finite_or_zero(e.reflectance * shot * (df * p_area / e.area));
                    new.radiosity[j as usize] += gain;
                    let q = &mesh.patches[e.patch as usize];
                    new.unshot[e.patch as usize] += gain * (e.area / q.area);
                    corrected[j as usize] = true;
                }
            }
            new.cache_row(i, row);
        }
        stats.elements_corrected = corrected.iter().filter(|c| **c).count();
        for (l, old) in lights.iter().zip(&old_deposits) {
            let moved = new.light_deposits(l, 1.0);
            let diff: Vec<DVec3> = moved.iter().zip(old).map(|(a, b)| *a - *b).collect();
            new.deposit(&diff);
        }
        Ok((new, stats))
    }

    /// The entries of ray-cast row `i` (a static patch, its row before
    /// the move `old`) that the move of `object` (old and new place in
    /// `places`) may change, on the moved scene: `(element, raw F)`,
    /// sorted, zero where it is now zero, and each entry's [`RayMask`]. The
    /// object's column comes from its own rows by reciprocity where
    /// `reciprocal` has them, else it is ray-cast like the static entries
    /// whose rays may see the move. A static entry whose rays' visibility
    /// the old row recorded is updated from the rays that may see the move
    /// ([`Self::moved_rays`]); one with no old entry (zero) is unchanged
    /// when each of its rays is certainly blocked by the new place or was
    /// certainly not blocked by the old one (so the static scene, which
    /// did not move, blocked it); any other is ray-cast.
    fn changed_entries(
        &self,
        i: usize,
        places: &Places,
        reciprocal: &Reciprocal,
        (old_row, old_scale, old_rays): &ComputedRow,
        stats: &mut MoveStats,
    ) -> (Vec<(u32, f64)>, Vec<RayMask>) {
        let mesh = self.mesh;
        let p = &mesh.patches[i];
        let rp = radius(p.center, &p.vertices);
        let seed = self.row_seed(i);
        let samples = stratified(self.options.visibility_samples, seed);
        let k = samples.len();
        let mut planes = penumbra_planes(&p.vertices, &places.union);
        // The scan below looks at every receiver but the row's own
        // (active, static) elements.
        let own = p
            .elements
            .iter()
            .filter(|&&e| self.active[e as usize])
            .count();
        stats.receivers_scanned += places.receivers.len() - own;
        let mut hints = [0; 2];
        let mut out: Vec<(u32, f64, RayMask)> = Vec::new();
        let cast = |j: u32, stats: &mut MoveStats| {
            stats.entries_recomputed += 1;
            let (f, mask) =
                ray_cast_entry(mesh, self.geometry, i, j, &samples, seed).unwrap_or((0.0, 0));
            (j, f, mask)
        };
        for &j in &places.object_elements {
            if !self.active[j as usize] {
                continue;
            }
            if let Some(f) = reciprocal.entry(mesh, i, j) {
                stats.entries_reciprocal += 1;
                out.push((j, f, UNKNOWN_RAYS));
            } else {
                out.push(cast(j, stats));
            }
        }
        // Receivers come in element order, like the old row's entries.
        let mut cursor = 0;
        for &(center, rj, j, patch) in &places.receivers {
            if patch as usize == i || ball_outside_penumbra(&mut planes, center, rj, places.margin)
            {
                continue;
            }
            let e = &mesh.elements[j as usize];
            if facing_away(p, e) || outside_penumbra(&planes, &e.vertices, places.margin) {
                continue;
            }
            if places.segment_test && !places.near_segment(p.center, center, rp.max(rj)) {
                continue;
            }
            stats.pairs_near += 1;
            let mut rays = receiver_rays(mesh, i, j, &samples, seed);
            let old = if k > MASK_RAYS {
                None
            } else {
                while old_row.get(cursor).is_some_and(|entry| entry.0 < j) {
                    cursor += 1;
                }
                match old_row.get(cursor) {
                    Some(&(jo, f)) if jo == j => Some((
                        f / old_scale,
                        old_rays.as_ref().map_or(UNKNOWN_RAYS, |r| r[cursor]),
                    )),
                    _ => Some((0.0, 0)),
                }
            };
            match old {
                Some((f, mask)) if f > 0.0 && mask != UNKNOWN_RAYS => {
                    let new_mask = self.moved_rays(e.normal, rays, places, &mut hints, mask, stats);
                    if new_mask != mask {
                        stats.entries_rescaled += 1;
                        let f = rescaled_entry(f, mask.count_ones(), new_mask.count_ones());
                        out.push((j, f.unwrap_or(0.0), new_mask));
                    }
                }
                // Zero before: every ray was blocked (or the entry is zero
                // wherever the object is). A ray stays blocked when the
                // object's new place blocks it, or when the old place did
                // not (the static scene did); only the others are traced,
                // and the entry is computed only when one of them now
                // sees the shooter.
                Some((_, 0)) => {
                    let mask = self.moved_rays(e.normal, rays, places, &mut hints, 0, stats);
                    if mask != 0 {
                        stats.entries_recomputed += 1;
                        let f = entry_from_mask(mesh, i, j, mask, k);
                        out.push((j, f.unwrap_or(0.0), mask));
                    }
                }
                // Rays not recorded: re-cast when one may see a difference.
                _ => {
                    if rays.any(|(x, y)| {
                        stats.rays_tested += 1;
                        !unchanged(places.classify(x, y, &mut hints))
                    }) {
                        out.push(cast(j, stats));
                    }
                }
            }
        }
        out.sort_unstable_by_key(|e| e.0);
        out.into_iter().map(|(j, f, m)| ((j, f), m)).unzip()
    }

    /// Which of an entry's `rays` (receiver point, patch point; the
    /// receiver's normal `normal`) see the shooter after the move, from
    /// which saw it before (`mask`) and how each meets the object's new
    /// and, where needed, old place (`places`; `hints` as in
    /// [`Places::classify`]): a ray that the new place certainly blocks is
    /// blocked; one that was clear stays clear when the new place
    /// certainly misses it (the static scene did not block it); one that
    /// was blocked while the old place certainly missed it was blocked by
    /// the static scene and stays blocked; every other ray is traced again
    /// in the moved scene. Equal to tracing every ray, given that the
    /// crossings are sure where they say so. The rays tested and traced
    /// are counted in `stats`.
    fn moved_rays(
        &self,
        normal: DVec3,
        rays: impl Iterator<Item = (DVec3, DVec3)>,
        places: &Places,
        hints: &mut [usize; 2],
        mask: RayMask,
        stats: &mut MoveStats,
    ) -> RayMask {
        let (mut out, mut tested, mut traced) = (0, 0, 0);
        let mut trace = |x, y| {
            traced += 1;
            self.geometry.visible(x, normal, y, true)
        };
        for (r, (x, y)) in rays.enumerate() {
            tested += 1;
            let was_clear = mask & (1 << r) != 0;
            let s = places.segment(x, y);
            let clear = match (was_clear, places.crossing(1, &s, &mut hints[1])) {
                (_, Crossing::Hit) => false,
                (true, Crossing::Miss) => true,
                (true, Crossing::Unsure) => trace(x, y),
                (false, _) => {
                    places.crossing(0, &s, &mut hints[0]) != Crossing::Miss && trace(x, y)
                }
            };
            if clear {
                out |= 1 << r;
            }
        }
        stats.rays_tested += tested;
        stats.rays_traced += traced;
        out
    }
}

/// Reciprocity is used only where the static patch is at most this many
/// times larger than the object's patch: the reciprocal estimate samples
/// points on the static patch, the ray-cast one on the object's, and
/// point sampling was taken to be the more accurate on the smaller of
/// the two. Measured against a 64-ray reference (the object records of
/// `bench radiosity`), that premise is not what decides: the small cube's
/// column at 0.02 m^2 (ratio 11, refused) is about as close by
/// reciprocity as ray-cast (0.169 vs 0.167 over the cube). What does
/// decide is whether the static patch emits (see [`Reciprocal`]).
const RECIPROCAL_AREA_RATIO: f64 = 2.0;

/// The object's column by reciprocity: for an object patch `q` with a
/// single element (the element is the patch) and its recomputed row,
/// `F_iq A_i = F_qi A_q` gives the entry of static patch `i`'s row as
/// `F_iq = (A_q / A_i) sum_{e in i} F_qe` (raw form factors). Both sides
/// are estimates of the same integral from different sample points, so
/// the entry differs from a ray-cast one by the discretisation error of
/// the form factors, not by more (see [`RECIPROCAL_AREA_RATIO`]).
///
/// Not for a static patch that emits: its entries carry the direct light,
/// which dominates the object's radiosity, and the reciprocal estimate
/// takes it from point samples on the emitter where the ray-cast one
/// integrates the emitter exactly. Measured on the Cornell short block at
/// 0.005 m^2, the reciprocal light entries were 0.9 % low on average
/// (weighted by shot power, against 256-ray, 64-point entries; ray-cast:
/// 0.1 % high) and the object's error against the 64-ray reference
/// doubled (0.0365 vs a full re-solve's 0.0181; ray-casting the emitters'
/// entries alone: 0.0207).
struct Reciprocal {
    /// Per element (indexed by element; `None` but for the elements of
    /// single-element object patches): the raw form factor from its patch
    /// to every patch (`sum_{e in i} F_qe`).
    to_patch: Vec<Option<Vec<f64>>>,
    /// Per patch: one of its elements emits.
    emits: Vec<bool>,
}

impl Reciprocal {
    /// The table from the recomputed rows `own` (empty unless `ray_cast`).
    fn new(mesh: &RadiosityMesh, object: u32, own: &[Option<ComputedRow>], ray_cast: bool) -> Self {
        let mut to_patch = vec![None; mesh.elements.len()];
        if ray_cast {
            for (q, row) in own.iter().enumerate() {
                let p = &mesh.patches[q];
                let (Some((row, scale, _)), true, [e]) =
                    (row, p.object == object, p.elements.as_slice())
                else {
                    continue;
                };
                let mut sums = vec![0.0; mesh.patches.len()];
                for &(j, f) in row {
                    sums[mesh.elements[j as usize].patch as usize] += f / scale;
                }
                to_patch[*e as usize] = Some(sums);
            }
        }
        let emits = mesh
            .patches
            .iter()
            .map(|p| {
                p.elements
                    .iter()
                    .any(|&e| mesh.elements[e as usize].emission != DVec3::ZERO)
            })
            .collect();
        Self { to_patch, emits }
    }

    /// The raw form factor from static patch `i` to object element `j`,
    /// `None` where the table has no row for it or `i` emits.
    fn entry(&self, mesh: &RadiosityMesh, i: usize, j: u32) -> Option<f64> {
        if self.emits[i] {
            return None;
        }
        let sums = self.to_patch.get(j as usize)?.as_ref()?;
        let q = &mesh.patches[mesh.elements[j as usize].patch as usize];
        let p_area = mesh.patches[i].area;
        if !(p_area <= RECIPROCAL_AREA_RATIO * q.area) {
            return None;
        }
        let f = sums[i] * q.area / p_area;
        Some(finite_or_zero(f))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block turned 30 degrees about the vertical is boxed in its own
    /// frame: both places' boxes hold every vertex and have the block's
    /// volume, not the 1.87 times larger one of its axis-aligned box.
    #[test]
    fn a_turned_block_is_boxed_in_its_own_frame() {
        use crate::radiosity::moving_tests::{box_with_block, mesh_of};
        let turned = |shift: glam::Vec3| {
            let mut s = box_with_block(shift);
            s.objects[2].transform.rotation =
                glam::Quat::from_rotation_y(std::f32::consts::FRAC_PI_6);
            s
        };
        let (m0, _) = mesh_of(&turned(glam::Vec3::ZERO));
        let (m1, _) = mesh_of(&turned(glam::Vec3::new(0.05, 0.0, 0.03)));
        let boxes = Bounds::of_places(&m0, &m1, 2).unwrap();
        for (b, m) in boxes.iter().zip([&m0, &m1]) {
            let volume = (b.hi - b.lo).element_product();
            assert!(
                (volume / 0.25_f64.powi(3) - 1.0).abs() < 1e-6,
                "volume {volume}"
            );
            for v in m
                .elements
                .iter()
                .filter(|e| e.object == 2)
                .flat_map(|e| e.vertices)
            {
                let x = DVec3::new(b.axes[0].dot(v), b.axes[1].dot(v), b.axes[2].dot(v));
                assert!(x.cmpge(b.lo - 1e-12).all() && x.cmple(b.hi + 1e-12).all());
            }
        }
        assert!(Bounds::of_places(&m0, &m1, 9).is_none());
    }

    #[test]
    fn row_merge_and_difference_are_exact() {
        let old = [(1, 0.1), (3, 0.3), (5, 0.5)];
        let changes = [(0, 0.05), (3, 0.0), (5, 0.25), (7, 0.7)];
        // The rays' masks follow their entries; a removed entry drops its
        // mask, and a row without masks gets none.
        let (new, rays) = merge_changes(&old, Some(&[0b01, 0b11, 0b11]), &changes, &[1, 0, 2, 3]);
        assert_eq!(new, vec![(0, 0.05), (1, 0.1), (5, 0.25), (7, 0.7)]);
        assert_eq!(rays, Some(vec![1, 0b01, 2, 3]));
        assert_eq!(
            merge_changes(&old, None, &changes, &[1, 0, 2, 3]),
            (new.clone(), None)
        );
        let d = row_difference(&old, &new);
        assert_eq!(d, vec![(0, 0.05), (3, -0.3), (5, -0.25), (7, 0.7)]);
        assert_eq!(changes_difference(&old, &changes), d);
        assert!(changes_difference(&new, &[(1, 0.1), (5, 0.25)]).is_empty());
        assert!(row_difference(&new, &new).is_empty());
    }
}
