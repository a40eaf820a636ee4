//! The object's column of a static row by reciprocity
//! (`F_iq A_i = F_qi A_q`), from the object's own recomputed rows.

use crate::finite::finite_or_zero;
use crate::radiosity::mesh::RadiosityMesh;
use crate::radiosity::shooting::ComputedRow;
use glam::DVec3;

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
pub(super) struct Reciprocal {
    /// Per element (indexed by element; `None` but for the elements of
    /// single-element object patches): the raw form factor from its patch
    /// to every patch (`sum_{e in i} F_qe`).
    to_patch: Vec<Option<Vec<f64>>>,
    /// Per patch: one of its elements emits.
    emits: Vec<bool>,
}

impl Reciprocal {
    /// The table from the recomputed rows `own` (empty unless `ray_cast`).
    pub(super) fn new(
        mesh: &RadiosityMesh,
        object: u32,
        own: &[Option<ComputedRow>],
        ray_cast: bool,
    ) -> Self {
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
    pub(super) fn entry(&self, mesh: &RadiosityMesh, i: usize, j: u32) -> Option<f64> {
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
