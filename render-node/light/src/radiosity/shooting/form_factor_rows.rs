//! Form-factor rows: a shooting patch's row computed (ray-cast, hemi-cube
//! or both, its item buffer cast on the CPU or rasterised in batches),
//! seeded by the patch so a row never depends on when it is computed,
//! and cached per patch within the cache's memory.

use super::ray_cast::{normalise, ray_cast_entry};
use super::{ComputedRow, FormFactorMethod, RayMask, Shooter, power};
use crate::radiosity::hemicube::{HemiCubeShot, NO_ITEM};
use crate::radiosity::mesh::Element;
use crate::sampling::{GOLDEN_GAMMA, hash64, stratified, unit};
use rayon::prelude::*;

impl<'a> Shooter<'a> {
    /// Seed of patch `p`'s hemi-cube rotation and sample jitter.
    pub(super) fn row_seed(&self, p: usize) -> u64 {
        hash64(self.options.seed ^ (p as u64 + 1).wrapping_mul(GOLDEN_GAMMA))
    }

    /// The hemi-cube of patch `p` (its centre, normal and seeded rotation).
    fn shot_of(&self, p: usize) -> HemiCubeShot {
        let patch = &self.mesh.patches[p];
        HemiCubeShot {
            origin: patch.center,
            normal: patch.normal,
            rotation: unit(self.row_seed(p)) * std::f64::consts::TAU,
        }
    }

    /// The row of `shooter` through the rasteriser, computed in one batch
    /// with the rows of the patches with most unshot power that have no
    /// cached row yet (those are cached here while the cache has room;
    /// without a cache the batch is the shooter alone).
    pub(super) fn rasterised_rows(&mut self, shooter: usize) -> ComputedRow {
        let Some(raster) = self.raster.as_ref() else {
            return self.form_factors(shooter, self.row_seed(shooter), None);
        };
        let mut batch = vec![shooter];
        if self.options.form_factor_cache_bytes > 0 {
            let mut others: Vec<(f64, usize)> = (0..self.mesh.patches.len())
                .filter(|&p| p != shooter && self.patch_active[p] && self.rows[p].is_none())
                .map(|p| (power(self.unshot[p], self.mesh.patches[p].area), p))
                .collect();
            others.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            batch.extend(
                others
                    .iter()
                    .take(raster.batch_size().max(1) - 1)
                    .map(|&(_, p)| p),
            );
        }
        let shots: Vec<HemiCubeShot> = batch.iter().map(|&p| self.shot_of(p)).collect();
        let buffers = match raster.render(&shots) {
            Ok(b) if b.len() == shots.len() => Some(b),
            Ok(b) => {
                tracing::warn!(
                    got = b.len(),
                    shots = shots.len(),
                    "item-buffer rasteriser returned the wrong number of buffers; casting rays"
                );
                None
            }
            Err(e) => {
                tracing::warn!(error = %e, "item-buffer rasteriser failed; casting rays");
                None
            }
        };
        let Some(buffers) = buffers else {
            self.raster_fallbacks += 1;
            self.rows_computed += 1;
            return self.form_factors(shooter, self.row_seed(shooter), None);
        };
        let rows: Vec<ComputedRow> = batch
            .iter()
            .zip(&buffers)
            .map(|(&p, items)| self.form_factors(p, self.row_seed(p), Some(items)))
            .collect();
        self.rows_computed += rows.len();
        let mut rows = rows.into_iter();
        let own = rows.next().unwrap_or((Vec::new(), 1.0, None));
        for (&p, row) in batch[1..].iter().zip(rows) {
            self.cache_row(p, row);
        }
        own
    }

    /// Keep `row` as patch `p`'s cached row while the cache has room.
    pub(super) fn cache_row(&mut self, p: usize, (row, scale, rays): ComputedRow) {
        let bytes = row.capacity() * std::mem::size_of::<(u32, f64)>()
            + rays
                .as_ref()
                .map_or(0, |r| r.capacity() * std::mem::size_of::<RayMask>());
        if self.options.form_factor_cache_bytes > 0
            && self.row_bytes + bytes <= self.options.form_factor_cache_bytes
        {
            self.row_bytes += bytes;
            self.rows[p] = Some(row);
            self.row_scale[p] = scale;
            self.row_rays[p] = rays;
        }
    }

    /// Form factors `F_pj` from patch `shooter` to the active receivers,
    /// scaled to sum to at most 1, and the scale applied. `raster_items` is
    /// the shooter's rasterised item buffer (active elements seen front-on),
    /// or `None` to cast it on the CPU.
    pub(super) fn form_factors(
        &self,
        shooter: usize,
        seed: u64,
        raster_items: Option<&[u32]>,
    ) -> ComputedRow {
        let mesh = self.mesh;
        let p = &mesh.patches[shooter];
        let method = self.options.method;
        let pixels = self
            .hemicube
            .as_ref()
            .map_or(1.0, |h| h.pixel_count() as f64);
        let near2 = self.options.proximity * self.options.proximity * p.area;
        let small = self.options.min_pixels / pixels;
        let use_ray = |e: &Element| -> bool {
            match method {
                FormFactorMethod::RayCast => true,
                FormFactorMethod::HemiCube => false,
                FormFactorMethod::Hybrid => {
                    let d = e.center - p.center;
                    let r2 = d.length_squared();
                    if r2 < near2 {
                        return true;
                    }
                    let r = r2.sqrt();
                    let estimate =
                        (p.normal.dot(d) / r).max(0.0) * (-e.normal.dot(d) / r).max(0.0) * e.area
                            / (std::f64::consts::PI * r2);
                    estimate > 0.0 && estimate < small
                }
            }
        };
        let receivers: Vec<u32> = (0..mesh.elements.len() as u32)
            .filter(|&j| {
                let e = &mesh.elements[j as usize];
                self.active[j as usize] && e.patch as usize != shooter && use_ray(e)
            })
            .collect();
        let samples = stratified(self.options.visibility_samples, seed);
        let cast: Vec<(u32, f64, RayMask)> = receivers
            .par_iter()
            .filter_map(|&j| {
                ray_cast_entry(mesh, self.geometry, shooter, j, &samples, seed)
                    .map(|(f, mask)| (j, f, mask))
            })
            .collect();
        let rays = (method == FormFactorMethod::RayCast)
            .then(|| cast.iter().map(|&(_, _, mask)| mask).collect());
        let mut out: Vec<(u32, f64)> = cast.into_iter().map(|(j, f, _)| (j, f)).collect();
        if let (Some(h), false) = (&self.hemicube, method == FormFactorMethod::RayCast) {
            let rotation = unit(seed) * std::f64::consts::TAU;
            let active = &self.active;
            let keep = |e: u32| -> bool {
                let Some(el) = mesh.elements.get(e as usize) else {
                    return false;
                };
                active[e as usize] && el.patch as usize != shooter && !use_ray(el)
            };
            let items = match raster_items {
                Some(items) => items
                    .iter()
                    .map(|&e| if keep(e) { e } else { NO_ITEM })
                    .collect(),
                None => h.item_buffer(self.geometry, p.center, p.normal, rotation, |hit| {
                    if !hit.front_face {
                        return None;
                    }
                    let prim = mesh.primitive_of(hit.object, hit.triangle)?;
                    let (e, _) = mesh.locate(prim, hit.barycentric)?;
                    keep(e).then_some(e)
                }),
            };
            let mut ff = vec![0.0; mesh.elements.len()];
            debug_assert!(
                items
                    .iter()
                    .all(|&i| i == NO_ITEM || (i as usize) < ff.len())
            );
            for j in h.accumulate(&items, &mut ff) {
                out.push((j, ff[j as usize]));
            }
        }
        let scale = normalise(&mut out);
        (out, scale, rays)
    }

    /// Form-factor rows computed so far (shots that found no cached row,
    /// plus rows computed ahead in a rasterised batch).
    pub fn rows_computed(&self) -> usize {
        self.rows_computed
    }

    /// Rows whose rasterised item buffer failed and that were cast on the
    /// CPU instead (0 unless the rasteriser failed).
    pub fn item_buffer_fallbacks(&self) -> usize {
        self.raster_fallbacks
    }

    /// The form-factor row of patch `p`: `(element, F_pj)` for every
    /// active receiver with a non-zero form factor, from the cache or
    /// computed now (not cached); `None` for an inactive or missing patch.
    pub fn form_factor_row(&self, p: usize) -> Option<Vec<(u32, f64)>> {
        if !self.patch_active.get(p).copied().unwrap_or(false) {
            return None;
        }
        if let Some(row) = &self.rows[p] {
            return Some(row.clone());
        }
        let items = match &self.raster {
            Some(r) => match r.render(&[self.shot_of(p)]) {
                Ok(mut b) if b.len() == 1 => b.pop(),
                _ => None,
            },
            None => None,
        };
        Some(self.form_factors(p, self.row_seed(p), items.as_deref()).0)
    }

    /// The [`RayMask`] of each entry of [`Self::form_factor_row`] (bit `r`:
    /// ray `r` saw the shooter), from the cache or computed now; `None`
    /// where the row has none (not every entry was ray-cast).
    #[cfg(test)]
    pub(crate) fn row_rays(&self, p: usize) -> Option<Vec<RayMask>> {
        if self.rows[p].is_some() {
            return self.row_rays[p].clone();
        }
        self.form_factors(p, self.row_seed(p), None).2
    }
}
