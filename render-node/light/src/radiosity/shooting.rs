//! Progressive refinement (Cohen et al. 1988): the patch with the most
//! unshot power shoots it to every element, until the unshot fraction of
//! all power ever injected falls below a threshold.
//!
//! Patches shoot, elements receive: element `j` gains
//! `rho_j * dB_p * F_pj * A_p / A_j`, and its patch's unshot exitance grows
//! by the area-weighted share. Shots may carry negative power, which is how
//! an incremental update removes the light of a source that moved.
//!
//! Form factors are cached per shooting patch (up to
//! [`SolveOptions::form_factor_cache_bytes`]): a patch shoots several times
//! in a solve (it keeps receiving), and every later shot reuses its row.
//! A row depends only on the mesh, the geometry and the patch (its jitter
//! and hemi-cube rotation are seeded by the patch index), so a cached row
//! equals a recomputed one, and an incremental update after a virtual light
//! moves reuses every row.
//! After a virtual object moves, [`Shooter::move_object`] corrects the rows
//! (only the entries whose rays may see the move) and shoots the difference
//! (see `moving`).
//!
//! Energy: the form factors of one shot are scaled down if they sum above 1,
//! and rho is at most [`MAX_REFLECTANCE`](super::mesh::MAX_REFLECTANCE), so
//! every shot passes on strictly less power than it takes: the unshot power
//! falls monotonically and B stays finite.
//!
//! Item buffers: the hemi-cube's item buffer is cast with rays on the CPU
//! ([`ItemBufferBackend::Cpu`]) or rasterised by an
//! [`ItemBufferRasteriser`] such as the GPU hemi-cube
//! ([`ItemBufferBackend::Raster`]). A rasteriser renders a batch of
//! shooters per call: when a shooter's row is missing, the rows of the
//! next patches by unshot power that have none yet are computed with it
//! and cached (rows do not depend on when they are computed).
//!
//! [`ItemBufferRasteriser`]: super::hemicube::ItemBufferRasteriser

use super::hemicube::{HemiCube, ItemBufferScene, ItemTriangle};
use super::mesh::RadiosityMesh;
use super::sources::direct_irradiance;
use crate::SceneGeometry;
use crate::finite::finite_or_zero;
use glam::DVec3;
use rayon::prelude::*;
use showcase_proto::Light;

mod form_factor_rows;
mod moving;
mod options;
mod ray_cast;
pub use moving::{MoveError, MoveStats};
pub use options::{FormFactorMethod, ItemBufferBackend, ShotProgress, SolveError, SolveOptions};
pub(crate) use ray_cast::RayMask;

/// One point of the convergence curve.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ConvergencePoint {
    /// Shots so far.
    pub shots: usize,
    /// Unshot power over injected power.
    pub unshot_fraction: f64,
}

/// Sum of the channels times area: the power measure of the solver.
fn power(v: DVec3, area: f64) -> f64 {
    (v.x.abs() + v.y.abs() + v.z.abs()) * area
}

/// A computed form-factor row: `(element, F)` sorted by element, the scale
/// it was normalised with, and its entries' [`RayMask`]s when every entry
/// was ray-cast.
type ComputedRow = (Vec<(u32, f64)>, f64, Option<Vec<RayMask>>);

/// A progressive-refinement solve in progress over the active elements of
/// a mesh, with visibility in `geometry` (which must hold exactly the
/// active elements' objects, e.g. only the real ones for pass B1).
pub struct Shooter<'a> {
    mesh: &'a RadiosityMesh,
    geometry: &'a SceneGeometry,
    active: Vec<bool>,
    patch_active: Vec<bool>,
    options: SolveOptions,
    hemicube: Option<HemiCube>,
    radiosity: Vec<DVec3>,
    unshot: Vec<DVec3>,
    injected: f64,
    shots: usize,
    curve: Vec<ConvergencePoint>,
    /// Cached form-factor rows per patch.
    rows: Vec<Option<Vec<(u32, f64)>>>,
    /// The scale each cached row was normalised with (at most 1): the
    /// raw form factors are the row over it.
    row_scale: Vec<f64>,
    /// Per cached ray-cast row, the visibility of each entry's rays
    /// (aligned with the row's entries), which lets an object move update
    /// an entry from the rays it may change alone.
    row_rays: Vec<Option<Vec<RayMask>>>,
    /// Exitance each patch has shot so far (sum of its shots' deltas).
    shot: Vec<DVec3>,
    /// Bytes held in `rows`.
    row_bytes: usize,
    /// Rows computed (cache misses).
    rows_computed: usize,
    /// The active elements uploaded to the rasteriser, if one is used.
    raster: Option<Box<dyn ItemBufferScene>>,
    /// Rows whose rasterised item buffer failed and were cast on the CPU.
    raster_fallbacks: usize,
}

impl<'a> Shooter<'a> {
    /// A solve with no energy yet. `active` (one flag per element, all when
    /// `None`) selects the receivers and shooters.
    pub fn new(
        mesh: &'a RadiosityMesh,
        geometry: &'a SceneGeometry,
        active: Option<Vec<bool>>,
        options: &SolveOptions,
    ) -> Result<Self, SolveError> {
        if !(options.threshold > 0.0 && options.threshold < 1.0) {
            return Err(SolveError::BadThreshold(options.threshold));
        }
        let active = active.unwrap_or_else(|| vec![true; mesh.elements.len()]);
        if active.len() != mesh.elements.len() {
            return Err(SolveError::MaskLength {
                got: active.len(),
                elements: mesh.elements.len(),
            });
        }
        let hemicube = match options.method {
            FormFactorMethod::RayCast => None,
            _ => Some(HemiCube::new(options.hemicube)?),
        };
        let raster = match (&hemicube, &options.item_buffer) {
            (Some(h), ItemBufferBackend::Raster(r)) => {
                let triangles: Vec<ItemTriangle> = mesh
                    .elements
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| active[*j])
                    .map(|(j, e)| ItemTriangle {
                        item: j as u32,
                        vertices: e.vertices,
                        normal: e.normal,
                    })
                    .collect();
                Some(r.upload(h.resolution(), &triangles)?)
            }
            _ => None,
        };
        let patch_active = mesh
            .patches
            .iter()
            .map(|p| p.elements.iter().any(|&e| active[e as usize]))
            .collect();
        Ok(Self {
            mesh,
            geometry,
            active,
            patch_active,
            options: options.clone(),
            hemicube,
            radiosity: vec![DVec3::ZERO; mesh.elements.len()],
            unshot: vec![DVec3::ZERO; mesh.patches.len()],
            injected: 0.0,
            shots: 0,
            curve: Vec::new(),
            rows: vec![None; mesh.patches.len()],
            row_scale: vec![1.0; mesh.patches.len()],
            row_rays: vec![None; mesh.patches.len()],
            shot: vec![DVec3::ZERO; mesh.patches.len()],
            row_bytes: 0,
            rows_computed: 0,
            raster,
            raster_fallbacks: 0,
        })
    }

    /// Add self-emitted exitance per element (W/m^2) to B and to the unshot
    /// energy, scaled by `scale` (-1 removes it). Inactive elements and
    /// non-finite values are skipped.
    pub fn add_emission(&mut self, exitance: &[DVec3], scale: f64) {
        let deposits: Vec<DVec3> = exitance
            .iter()
            .map(|e| finite_or_zero(*e * scale))
            .collect();
        self.deposit(&deposits);
    }

    /// Add the elements' own emission (`Element::emission`).
    pub fn add_surface_emission(&mut self) {
        let e: Vec<DVec3> = self.mesh.elements.iter().map(|e| e.emission).collect();
        self.add_emission(&e, 1.0);
    }

    /// Shoot a virtual light directly to every active element (at its
    /// centre): B gains `scale * rho * E_direct`, which also becomes unshot.
    pub fn add_light(&mut self, light: &Light, scale: f64) {
        let deposits = self.light_deposits(light, scale);
        self.deposit(&deposits);
    }

    /// What [`Self::add_light`] deposits per element.
    fn light_deposits(&self, light: &Light, scale: f64) -> Vec<DVec3> {
        let samples = self.options.visibility_samples.max(16);
        let seed = self.options.seed;
        self.mesh
            .elements
            .par_iter()
            .enumerate()
            .map(|(j, e)| {
                if !self.active[j] {
                    return DVec3::ZERO;
                }
                let irradiance = direct_irradiance(
                    light,
                    self.geometry,
                    e.center,
                    e.normal,
                    samples,
                    seed ^ j as u64,
                );
                finite_or_zero(scale * e.reflectance * irradiance)
            })
            .collect()
    }

    fn deposit(&mut self, deposits: &[DVec3]) {
        for (j, d) in deposits.iter().enumerate() {
            if !self.active.get(j).copied().unwrap_or(false) || *d == DVec3::ZERO {
                continue;
            }
            let e = &self.mesh.elements[j];
            let p = &self.mesh.patches[e.patch as usize];
            self.radiosity[j] += *d;
            self.unshot[e.patch as usize] += *d * (e.area / p.area);
            self.injected += power(*d, e.area);
        }
    }

    /// Forget all energy (B, unshot, injected, shots, curve) but keep the
    /// cached form-factor rows: a fresh solve of the same geometry.
    pub fn restart(&mut self) {
        self.radiosity.iter_mut().for_each(|b| *b = DVec3::ZERO);
        self.unshot.iter_mut().for_each(|u| *u = DVec3::ZERO);
        self.shot.iter_mut().for_each(|u| *u = DVec3::ZERO);
        self.injected = 0.0;
        self.shots = 0;
        self.curve.clear();
    }

    /// Power injected so far (sum of channels, W).
    pub fn injected_power(&self) -> f64 {
        self.injected
    }

    /// Unshot power now (sum of channels, W).
    pub fn unshot_power(&self) -> f64 {
        self.mesh
            .patches
            .iter()
            .zip(&self.unshot)
            .map(|(p, u)| power(*u, p.area))
            .sum()
    }

    /// Unshot power over injected power (0 when nothing was injected).
    pub fn unshot_fraction(&self) -> f64 {
        if self.injected > 0.0 {
            self.unshot_power() / self.injected
        } else {
            0.0
        }
    }

    /// Shoot until the unshot power is at most `threshold * reference` (W),
    /// or the shot limit. Returns the shots taken.
    pub fn run_to_power(&mut self, limit: f64) -> usize {
        let start = self.shots;
        while self.shots < self.options.max_shots && self.unshot_power() > limit {
            if !self.step() {
                break;
            }
        }
        self.shots - start
    }

    /// Shoot until the unshot fraction is below the threshold of the
    /// options. Returns the shots taken.
    pub fn run(&mut self) -> usize {
        let limit = self.options.threshold * self.injected;
        self.run_to_power(limit)
    }

    /// One shot from the patch with the most unshot power; false when no
    /// patch has any.
    pub fn step(&mut self) -> bool {
        let mut best = None;
        let mut best_power = 0.0;
        for (i, (p, u)) in self.mesh.patches.iter().zip(&self.unshot).enumerate() {
            let w = power(*u, p.area);
            if self.patch_active[i] && w > best_power {
                best_power = w;
                best = Some(i);
            }
        }
        match best {
            Some(shooter) => self.shoot_patch(shooter),
            None => false,
        }
    }

    /// One bounce of the current unshot energy: every patch shoots what it
    /// holds now, and what arrives stays unshot (it is not passed on in
    /// this call). Afterwards B holds `B + K U` for the unshot `U` before.
    pub fn shoot_each_once(&mut self) {
        let before = self.unshot.clone();
        self.unshot.iter_mut().for_each(|u| *u = DVec3::ZERO);
        for (p, initial) in before.iter().enumerate() {
            if *initial == DVec3::ZERO {
                continue;
            }
            let received = self.unshot[p];
            self.unshot[p] = *initial;
            self.shoot_patch(p);
            self.unshot[p] += received;
        }
    }

    /// Shoot the unshot energy of patch `shooter` now (false when it has
    /// none, is inactive or does not exist).
    pub fn shoot_patch(&mut self, shooter: usize) -> bool {
        if !self.patch_active.get(shooter).copied().unwrap_or(false) {
            return false;
        }
        let delta = self.unshot[shooter];
        if delta == DVec3::ZERO {
            return false;
        }
        self.unshot[shooter] = DVec3::ZERO;
        self.shot[shooter] += delta;
        let ((ff, scale, rays), cached) = match self.rows[shooter].take() {
            Some(row) => {
                let rays = self.row_rays[shooter].take();
                ((row, self.row_scale[shooter], rays), true)
            }
            None if self.raster.is_some() => (self.rasterised_rows(shooter), false),
            None => {
                self.rows_computed += 1;
                (
                    self.form_factors(shooter, self.row_seed(shooter), None),
                    false,
                )
            }
        };
        let p_area = self.mesh.patches[shooter].area;
        for &(j, f) in &ff {
            let e = &self.mesh.elements[j as usize];
            let gain = finite_or_zero(e.reflectance * delta * (f * p_area / e.area));
            self.radiosity[j as usize] += gain;
            let q = &self.mesh.patches[e.patch as usize];
            self.unshot[e.patch as usize] += gain * (e.area / q.area);
        }
        if cached {
            self.rows[shooter] = Some(ff);
            self.row_rays[shooter] = rays;
        } else {
            self.cache_row(shooter, (ff, scale, rays));
        }
        self.shots += 1;
        let point = ConvergencePoint {
            shots: self.shots,
            unshot_fraction: self.unshot_fraction(),
        };
        self.curve.push(point);
        self.options.progress.report(point);
        true
    }

    /// Element radiosity B (exitance, W/m^2) so far.
    pub fn radiosity(&self) -> &[DVec3] {
        &self.radiosity
    }

    /// Unshot exitance per patch.
    pub fn unshot(&self) -> &[DVec3] {
        &self.unshot
    }

    /// Shots so far.
    pub fn shots(&self) -> usize {
        self.shots
    }

    /// The unshot fraction after every shot.
    pub fn convergence(&self) -> &[ConvergencePoint] {
        &self.curve
    }

    /// The ambient exitance estimate of Cohen et al. (1988): the unshot
    /// power spread evenly over the active area, times the interreflection
    /// factor `1 / (1 - rho_avg)`.
    pub fn ambient(&self) -> DVec3 {
        let (mut area, mut rho_area, mut unshot) = (0.0, DVec3::ZERO, DVec3::ZERO);
        for (j, e) in self.mesh.elements.iter().enumerate() {
            if self.active[j] {
                area += e.area;
                rho_area += e.reflectance * e.area;
            }
        }
        for (i, p) in self.mesh.patches.iter().enumerate() {
            if self.patch_active[i] {
                unshot += self.unshot[i] * p.area;
            }
        }
        if !(area > 0.0) {
            return DVec3::ZERO;
        }
        let rho = (rho_area / area).min(DVec3::splat(super::mesh::MAX_REFLECTANCE));
        finite_or_zero(unshot / area / (DVec3::ONE - rho))
    }

    /// B plus the reflected ambient term, for display before convergence.
    pub fn display_radiosity(&self) -> Vec<DVec3> {
        let ambient = self.ambient();
        self.mesh
            .elements
            .iter()
            .zip(&self.radiosity)
            .enumerate()
            .map(|(j, (e, b))| {
                if self.active[j] {
                    *b + e.reflectance * ambient
                } else {
                    *b
                }
            })
            .collect()
    }
}
