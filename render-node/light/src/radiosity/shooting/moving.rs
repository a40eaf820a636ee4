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
//!
//! [`RayMask`]: super::ray_cast::RayMask

use super::ray_cast::normalise;
use super::{ComputedRow, FormFactorMethod, Shooter};
use crate::SceneGeometry;
use crate::finite::finite_or_zero;
use crate::radiosity::mesh::RadiosityMesh;
use cull::{Bounds, Places};
use glam::DVec3;
use rayon::prelude::*;
use reciprocal::Reciprocal;
use row_merge::{changes_difference, merge_changes, row_difference};
use showcase_proto::Light;

mod cull;
mod reciprocal;
mod row_merge;
mod static_rows;

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
}
