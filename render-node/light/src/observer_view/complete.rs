//! The physically complete view: what an eye (or the cabinet's camera)
//! sees when light bounces between the surfaces as it does in a real
//! cabinet, from the simulated showcase's path tracer
//! ([`crate::sim::SimWorld`]), which shares nothing with the product's
//! solvers.
//!
//! - **Real**: the real objects alone (the virtual ones do not exist in
//!   the cabinet), lit by the projectors showing the node outputs (each a
//!   point light with the true device and response, as in
//!   [`super::observer_view`]), every bounce between the real surfaces.
//! - **Target**: the scene as if the virtual lights and objects were real:
//!   every object, lit by the virtual lights in their true shapes and the
//!   ambient as an environment ([`SimLights::virtual_lights`]), every
//!   bounce between real and virtual surfaces; a reflective virtual object
//!   an ideal mirror tinted by its albedo.
//!
//! Each pixel averages the same `SUBSAMPLES x SUBSAMPLES` rays across it as
//! [`super::observer_view`], so the complete images line up with that
//! view's masks. Each image is made as two independent halves of the
//! paths, so its noise is measured, not guessed
//! ([`CompleteImage::noise_rel_rmse`]).
//!
//! Both images trace every pixel with the same random numbers (common
//! random numbers, [`SimWorld::trace`]): where the two worlds agree their
//! paths agree, so the noise of their *difference*, which the figures
//! judge, is far below either image's own
//! ([`CompleteView::difference_noise_rel_rmse`]). Neither image is biased
//! by it: each is still an unbiased estimate of its own world.

use super::{ObserverViewError, ProjectedLight, SUBSAMPLES, check_size};
use crate::finite::finite_or_zero;
use crate::metrics::{relative_rmse, rmse_and_reference_mean};
use crate::render::{FrameScene, RenderSetupError};
use crate::sampling::pixel_seed;
use crate::sim::devices::projector_intensity;
use crate::sim::{
    CacheOptions, IrradianceCache, ProjectorLight, RayEnd, SimLights, SimWorld, SurfacePoint,
};
use crate::{DeviceRays, Image, MetricError, ObjectFilter, RgbImage};
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;
use showcase_proto::PinholeDevice;

/// How many paths the complete view follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CompleteOptions {
    /// Paths per irradiance-cache point, both halves together (a pixel
    /// with no valid cache point spends as many over its subsample rays).
    pub paths_per_point: u32,
    /// Seed of every random draw.
    pub seed: u64,
}

/// Cache points are seeded at every `CACHE_STRIDE`-th pixel in each
/// direction.
pub const CACHE_STRIDE: u32 = 4;
/// Ward's `a` of the cache.
pub const CACHE_ACCURACY: f64 = 0.3;
/// Cache validity radii, as fractions of the scene's bounding diagonal.
const MIN_RADIUS: f64 = 1.0 / 500.0;
const MAX_RADIUS: f64 = 1.0 / 20.0;
/// Next-event estimates of the area lights and emitters per subsample ray
/// and half.
pub const DIRECT_SAMPLES: u32 = 16;

/// One path-traced image, the mean of two independent halves.
#[derive(Clone, Debug)]
pub struct CompleteImage {
    /// Linear radiance: the mean of [`Self::halves`].
    pub radiance: RgbImage,
    /// The part of [`Self::radiance`] reflected once (straight from a
    /// light), for the interreflection's share.
    pub direct: RgbImage,
    /// Two estimates from disjoint paths.
    pub halves: [RgbImage; 2],
}

impl CompleteImage {
    /// The noise of [`Self::radiance`] over `mask`, relative to its mean:
    /// the halves differ by twice the mean's noise (`rel RMSE(a, b) / 2`).
    pub fn noise_rel_rmse(&self, mask: Option<&Image<bool>>) -> Result<f64, MetricError> {
        Ok(relative_rmse(&self.halves[0], &self.halves[1], mask)? / 2.0)
    }
}

/// The physically complete view of one eye (see the module docs).
#[derive(Clone, Debug)]
pub struct CompleteView {
    /// The real objects under the projectors, every bounce.
    pub real: CompleteImage,
    /// Every object under the virtual lights, every bounce.
    pub target: CompleteImage,
}

impl CompleteView {
    /// The noise of `real - target` over `mask`, relative to the target's
    /// mean: the halves' differences differ by twice the mean's noise.
    /// This is the noise in what the figures compare.
    pub fn difference_noise_rel_rmse(
        &self,
        mask: Option<&Image<bool>>,
    ) -> Result<f64, MetricError> {
        let diff = |h: usize| {
            let (r, t) = (&self.real.halves[h], &self.target.halves[h]);
            Image {
                width: r.width,
                height: r.height,
                data: r
                    .data
                    .iter()
                    .zip(&t.data)
                    .map(|(r, t)| *r - *t)
                    .collect::<Vec<Vec3>>(),
            }
        };
        let (rmse, _) = rmse_and_reference_mean(&diff(0), &diff(1), mask)?;
        let target = &self.target.radiance;
        let (_, mean) = rmse_and_reference_mean(target, target, mask)?;
        if !(mean > 0.0) {
            return Err(MetricError::NonPositiveReferenceMean { mean });
        }
        Ok(rmse / 2.0 / mean)
    }
}

/// Simulate what `eye` sees in the physically complete world of `frame`
/// under `projected` (see the module docs).
pub fn complete_view(
    frame: &FrameScene,
    eye: &PinholeDevice,
    projected: &[ProjectedLight<'_>],
    options: CompleteOptions,
) -> Result<CompleteView, ObserverViewError> {
    complete_view_with_target(frame, eye, projected, options, None)
}

/// [`complete_view`] with its target already traced (`target`: the
/// [`CompleteView::target`] of a complete view of the same frame, eye and
/// options under other projector images; `None`: trace it). The target
/// does not depend on the projectors, and every random stream is keyed by
/// the seed and the pixel alone, so the view is the one [`complete_view`]
/// gives, bit for bit.
pub fn complete_view_with_target(
    frame: &FrameScene,
    eye: &PinholeDevice,
    projected: &[ProjectedLight<'_>],
    options: CompleteOptions,
    target: Option<CompleteImage>,
) -> Result<CompleteView, ObserverViewError> {
    let eye_rays = DeviceRays::new(eye).map_err(RenderSetupError::from)?;
    let real = complete_real(frame, eye, projected, options)?;
    let scene = &frame.showcase;
    let fits = |t: &CompleteImage| (t.radiance.width, t.radiance.height) == (eye.width, eye.height);
    let target = match target.filter(fits) {
        Some(t) => t,
        None => {
            let full_world = SimWorld::new(scene, &ObjectFilter::All, true)?;
            let virtual_lights = SimLights::virtual_lights(&scene.lights, scene.ambient)?;
            trace_image(&full_world, &virtual_lights, &eye_rays, options)
        }
    };
    Ok(CompleteView { real, target })
}

/// [`CompleteView::real`] alone: the real objects under `projected`,
/// every bounce (the same image, bit for bit).
pub fn complete_real(
    frame: &FrameScene,
    eye: &PinholeDevice,
    projected: &[ProjectedLight<'_>],
    options: CompleteOptions,
) -> Result<CompleteImage, ObserverViewError> {
    let eye_rays = DeviceRays::new(eye).map_err(RenderSetupError::from)?;
    let mut lights = Vec::with_capacity(projected.len());
    for p in projected {
        let d = &p.projector.device;
        check_size(&p.projector.name, p.value, d.width, d.height)?;
        let intensity = p
            .value
            .map(|v| projector_intensity(&p.projector.response, *v));
        let rays = DeviceRays::new(d).map_err(RenderSetupError::from)?;
        lights.push(ProjectorLight::new(rays, intensity)?);
    }
    let real_world = SimWorld::new(&frame.showcase, &ObjectFilter::Real, true)?;
    Ok(trace_image(
        &real_world,
        &SimLights::projectors(&lights),
        &eye_rays,
        options,
    ))
}

/// Every pixel of `eye` in `world` under `lights`, as two halves: each
/// subsample ray's end gets its direct light (exact for delta lights,
/// [`DIRECT_SAMPLES`] next-event estimates of area lights and emitters)
/// and its indirect light from an irradiance cache seeded at the centre
/// ray of every [`CACHE_STRIDE`]-th pixel in each direction, or computed
/// at the point where no cache point is valid. Every random stream is
/// keyed by `options.seed` and the pixel alone (whatever the world).
fn trace_image(
    world: &SimWorld,
    lights: &SimLights<'_>,
    eye: &DeviceRays,
    options: CompleteOptions,
) -> CompleteImage {
    let d = eye.device();
    let (w, h) = (d.width, d.height);
    let n = SUBSAMPLES * SUBSAMPLES;
    let key = |i: u32, k: u32| pixel_seed(options.seed, u64::from(i) * u64::from(n) + u64::from(k));
    let ends: Vec<Vec<Option<RayEnd>>> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            (0..n)
                .map(|k| {
                    let offset = DVec2::new(
                        ((k % SUBSAMPLES) as f64 + 0.5) / SUBSAMPLES as f64,
                        ((k / SUBSAMPLES) as f64 + 0.5) / SUBSAMPLES as f64,
                    );
                    let ray = eye.ray_through(DVec2::new(x as f64, y as f64) + offset)?;
                    Some(world.surface_along(&ray, lights))
                })
                .collect()
        })
        .collect();
    let seeds: Vec<(SurfacePoint, u64)> = (0..w * h)
        .filter(|i| {
            i % w % CACHE_STRIDE == CACHE_STRIDE / 2 && i / w % CACHE_STRIDE == CACHE_STRIDE / 2
        })
        .filter_map(|i| {
            let end = ends[i as usize].first()?.as_ref()?;
            Some((end.surface?, key(i, 0)))
        })
        .collect();
    let diagonal = {
        let b = world.geometry().bounds();
        (b.max - b.min).length()
    };
    let cache = IrradianceCache::build(
        world,
        lights,
        &seeds,
        CacheOptions {
            paths: options.paths_per_point,
            accuracy: CACHE_ACCURACY,
            min_radius: diagonal * MIN_RADIUS,
            max_radius: diagonal * MAX_RADIUS,
        },
    );
    let fallback_paths = (options.paths_per_point / (2 * n)).max(1);
    let pixels: Vec<[DVec3; 3]> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let mut halves = [DVec3::ZERO; 2];
            let mut direct = DVec3::ZERO;
            for (k, end) in ends[i as usize].iter().enumerate() {
                let Some(end) = end else {
                    continue;
                };
                let Some(s) = &end.surface else {
                    halves[0] += end.emitted;
                    halves[1] += end.emitted;
                    continue;
                };
                let key = key(i, k as u32);
                let cached = cache.lookup(s);
                // Direct light: the delta lights' part is exact, so once
                // for both halves; the sampled part per half.
                let exact = world.exact_irradiance(s, lights);
                for (half, sum) in halves.iter_mut().enumerate() {
                    let stream = pixel_seed(key, 2 + half as u64);
                    let e_direct = finite_or_zero(
                        exact + world.sampled_irradiance(s, lights, DIRECT_SAMPLES, stream),
                    );
                    let e_indirect = cached.map_or_else(
                        || {
                            world
                                .indirect_irradiance(s, lights, fallback_paths, stream)
                                .0
                        },
                        |c| c[half],
                    );
                    let reflect = end.tint * s.rho * std::f64::consts::FRAC_1_PI;
                    *sum += end.emitted + reflect * (e_direct + e_indirect);
                    direct += 0.5 * reflect * e_direct;
                }
            }
            let scale = 1.0 / f64::from(n);
            [halves[0] * scale, halves[1] * scale, direct * scale]
        })
        .collect();
    let image = |f: &dyn Fn(&[DVec3; 3]) -> DVec3| Image {
        width: w,
        height: h,
        data: pixels.iter().map(|p| f(p).as_vec3()).collect::<Vec<Vec3>>(),
    };
    CompleteImage {
        radiance: image(&|p| 0.5 * (p[0] + p[1])),
        direct: image(&|p| p[2]),
        halves: [image(&|p| p[0]), image(&|p| p[1])],
    }
}

#[cfg(test)]
mod tests;
