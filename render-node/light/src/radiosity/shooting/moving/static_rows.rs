//! A static patch's row after a move, patched entry by entry: the
//! object's column, and the static entries whose rays may see the move,
//! culled cheapest first and updated from their rays' recorded
//! visibility (see the parent module's docs).

use super::MoveStats;
use super::cull::{
    Crossing, Places, ball_outside_penumbra, outside_penumbra, penumbra_planes, radius, unchanged,
};
use super::reciprocal::Reciprocal;
use crate::radiosity::shooting::ray_cast::{
    MASK_RAYS, RayMask, UNKNOWN_RAYS, entry_from_mask, facing_away, ray_cast_entry, receiver_rays,
    rescaled_entry,
};
use crate::radiosity::shooting::{ComputedRow, Shooter};
use crate::sampling::stratified;
use glam::DVec3;

impl<'a> Shooter<'a> {
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
    pub(super) fn changed_entries(
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
