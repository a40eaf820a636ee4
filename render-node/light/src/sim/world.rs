//! The simulated world's light transport: Monte Carlo path tracing with
//! next-event estimation, independent of the product's radiosity solver.
//!
//! # Estimator
//! Each camera pixel sees the surface point hit by the ray through its
//! centre (no anti-aliasing, so the true albedo of a pixel is the albedo at
//! that one point). Surfaces are two-sided Lambertian reflectors with the
//! true albedo of [`Material::albedo_at`]. Radiance leaving the pixel's
//! point splits into
//! - `emitted`: the emission `Ke` of the surface when its front faces the
//!   camera and the world's emitters are on (with them off, a lamp is an
//!   ordinary reflector: it neither glows nor lights anything);
//! - `direct`: `rho / pi * E_direct` from the lights of [`SimLights`]: the
//!   projectors' and point and spot lights evaluated exactly (they are
//!   delta lights), area lights and emitting surfaces by next-event
//!   estimation (area lights one uniform point each per path, stratified
//!   over the pixel's paths; emitter triangles by uniform area sampling,
//!   weighted by area times peak radiance);
//! - `indirect`: everything scattered at least once more, by cosine-weighted
//!   path continuation (the first bounce stratified over the pixel's paths) with next-event estimation at every vertex and
//!   Russian roulette after the third bounce, plus the environment's
//!   radiance ([`SimLights::environment`]) along paths that leave the
//!   scene. Emission found by a continuation ray is not added (next-event
//!   estimation already counts it) unless the ray comes off a mirror, where
//!   next-event estimation cannot reach, so the estimator is unbiased.
//!
//! A reflective material ([`Material::reflective`]) is an ideal mirror
//! tinted by its albedo, about its geometric normal (the mesh as it is):
//! camera rays and paths follow it. Light from a point, spot or projector
//! light that reaches a diffuse surface by way of one mirror (a caustic of
//! a delta light, which no continuation ray can find) is added exactly at
//! every next-event estimate, facet by facet (`sim/mirrors.rs`); by way
//! of two or more mirrors it is left out. Every other mirror path is
//! counted.
//!
//! Every path has its own random stream, seeded from `(seed, pixel index,
//! path index)`, so a render is reproducible for a seed whatever the
//! thread count, and two worlds rendered with one seed use common random
//! numbers ([`SimWorld::trace`]).

use crate::finite::finite_or_zero;
use crate::{DeviceRays, Hit, Image, IntensityLight, ObjectFilter, Ray, RgbImage, SceneGeometry};
use glam::{DVec3, Vec3};
use rand::Rng;
use rayon::prelude::*;
use showcase_proto::{Material, Showcase};

use super::mirrors::{Facet, MirrorFacets};
use super::{SimError, SimLights};
use crate::geometry::face_forward;
use crate::sampling::{SplitMix64, cosine_direction, pixel_seed, stratified_point};

/// Longest path (in bounces) the estimator follows, and the most mirrors
/// a camera ray follows.
const MAX_DEPTH: u32 = 64;
/// Bounces before Russian roulette may end a path.
const ROULETTE_AFTER: u32 = 3;
/// The probability that a continuation path's vertex adds the delta
/// lights' light by way of a mirror ([`SimWorld::mirrored_on_path`]).
const MIRRORED_ON_PATHS: f64 = 1.0 / 32.0;
/// How far in front of the point (in [`SceneGeometry::epsilon`]) the ray
/// of [`SimWorld::exitance_at`] that finds its surface starts.
const EXITANCE_LIFT: f64 = 16.0;

/// What the estimator cannot find, in words for reports (see the module
/// docs).
pub const LEFT_OUT: &str = "light from a point, spot or projector light that reaches a diffuse surface only by way of two or more mirrors (a caustic of a delta light through a chain of mirrors)";

/// One emitting triangle (`Ke` radiance, front side only).
#[derive(Clone, Debug)]
struct Emitter {
    vertices: [DVec3; 3],
    normal: DVec3,
    area: f64,
    radiance: DVec3,
}

/// A point light at a projector's centre with per-pixel radiant intensity
/// (W/sr per channel): the sim's projector as seen by light transport.
#[derive(Clone, Debug)]
pub struct ProjectorLight {
    rays: DeviceRays,
    light: IntensityLight,
    intensity: RgbImage,
}

impl ProjectorLight {
    /// A projector light emitting `intensity` (W/sr, one value per projector
    /// pixel) through the pixels of `rays`. Errors when the sizes differ.
    pub fn new(rays: DeviceRays, intensity: RgbImage) -> Result<Self, SimError> {
        let d = rays.device();
        if intensity.width != d.width || intensity.height != d.height {
            return Err(SimError::ImageSize {
                expected: (d.width, d.height),
                got: (intensity.width, intensity.height),
            });
        }
        let light = IntensityLight {
            position: rays.center(),
            color: DVec3::ONE,
            frustum: Some(rays.clone()),
        };
        let intensity = intensity.map(|v| finite_or_zero(*v).max(Vec3::ZERO));
        Ok(Self {
            rays,
            light,
            intensity,
        })
    }

    /// The centre the light leaves from.
    pub fn position(&self) -> DVec3 {
        self.light.position
    }

    /// Radiant intensity (W/sr) this light sends to surface point `q`
    /// (unit normal `normal`, on the projector's side), with true
    /// visibility: the pixel's value inside the image, zero outside it or
    /// when the segment is blocked.
    pub fn intensity_toward(&self, geometry: &SceneGeometry, q: DVec3, normal: DVec3) -> DVec3 {
        if !self.rays.sees(geometry, q, normal) {
            return DVec3::ZERO;
        }
        self.pixel_intensity(q)
    }

    /// True when every pixel emits nothing.
    pub fn is_dark(&self) -> bool {
        self.intensity.data.iter().all(|v| *v == Vec3::ZERO)
    }

    /// Irradiance (W/m^2) this light delivers to a surface point with the
    /// oriented geometric normal `facing` and shading normal `shading`,
    /// with true visibility.
    pub fn irradiance(
        &self,
        geometry: &SceneGeometry,
        point: DVec3,
        facing: DVec3,
        shading: DVec3,
    ) -> DVec3 {
        let Some(a) = self.light.attenuation(geometry, point, facing, shading) else {
            return DVec3::ZERO;
        };
        finite_or_zero(a * self.pixel_intensity(point))
    }

    /// The intensity (W/sr) of the pixel whose ray passes through `q`
    /// (zero outside the image), visibility not checked.
    fn pixel_intensity(&self, q: DVec3) -> DVec3 {
        self.rays
            .pixel_of(q)
            .and_then(|(x, y)| self.intensity.get(x, y))
            .map_or(DVec3::ZERO, |i| finite_or_zero(i.as_dvec3()))
    }
}

/// Linear radiance at each camera pixel, split by light path.
#[derive(Clone, Debug, PartialEq)]
pub struct TransportImage {
    /// Emission of the surface the pixel sees.
    pub emitted: RgbImage,
    /// Light reflected once (straight from the projector or an emitter).
    pub direct: RgbImage,
    /// Light reflected two or more times (secondary scattering).
    pub indirect: RgbImage,
}

impl TransportImage {
    /// All zeros.
    pub fn zero(width: u32, height: u32) -> Self {
        let z = Image::new(width, height, Vec3::ZERO);
        Self {
            emitted: z.clone(),
            direct: z.clone(),
            indirect: z,
        }
    }

    /// `emitted + direct + indirect`.
    pub fn total(&self) -> RgbImage {
        let mut t = self.emitted.clone();
        for (i, v) in t.data.iter_mut().enumerate() {
            *v += self.direct.data[i] + self.indirect.data[i];
        }
        t
    }
}

/// A path-traced exitance at one surface point ([`SimWorld::exitance_at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExitanceEstimate {
    /// Mean of the paths' estimates of `B` (W/m^2 per channel).
    pub exitance: DVec3,
    /// Standard error of [`Self::exitance`]: the standard deviation of the
    /// per-path estimates over `sqrt(spp)` (infinite for one path, zero
    /// for a black surface, whose exitance is exact).
    pub std_error: DVec3,
}

/// The physical world of the simulated showcase: geometry with its true
/// materials and the emitting triangles.
#[derive(Debug)]
pub struct SimWorld {
    geometry: SceneGeometry,
    materials: Vec<Material>,
    /// Per object: an ideal mirror ([`Material::reflective`]).
    mirrors: Vec<bool>,
    /// The mirrors' facets, for the delta lights' caustics.
    mirror_facets: MirrorFacets,
    emitters: Vec<Emitter>,
    /// Cumulative selection weights of `emitters`, ending at 1.
    emitter_cdf: Vec<f64>,
    /// Whether emitting surfaces glow at all: with the scene's lights off
    /// an emitter is an ordinary reflector, seen and lighting nothing of
    /// its own.
    emitters_on: bool,
}

impl SimWorld {
    /// The objects of `scene` that pass `filter`, with their emitters when
    /// `emitters` is set.
    pub fn new(scene: &Showcase, filter: &ObjectFilter, emitters: bool) -> Result<Self, SimError> {
        let geometry = SceneGeometry::build(scene, filter)?;
        let materials: Vec<Material> = scene.objects.iter().map(|o| o.material.clone()).collect();
        let mirrors: Vec<bool> = materials.iter().map(|m| m.reflective).collect();
        let mirror_facets = MirrorFacets::new(
            geometry
                .triangles()
                .filter(|t| mirrors.get(t.object as usize).copied().unwrap_or(false))
                .filter_map(|t| Facet::new(&t))
                .collect(),
        );
        let mut list = Vec::new();
        if emitters {
            for t in geometry.triangles() {
                let m = &materials[t.object as usize];
                let radiance = m.emission.as_dvec3();
                if m.is_emitter() && t.area > 0.0 && radiance.is_finite() {
                    list.push(Emitter {
                        vertices: t.vertices,
                        normal: t.normal,
                        area: t.area,
                        radiance: radiance.max(DVec3::ZERO),
                    });
                }
            }
        }
        let weights: Vec<f64> = list
            .iter()
            .map(|e| e.area * e.radiance.max_element())
            .collect();
        let total: f64 = weights.iter().sum();
        let mut acc = 0.0;
        let emitter_cdf = if total > 0.0 && total.is_finite() {
            weights
                .iter()
                .map(|w| {
                    acc += w / total;
                    acc
                })
                .collect()
        } else {
            list.clear();
            Vec::new()
        };
        Ok(Self {
            geometry,
            materials,
            mirrors,
            mirror_facets,
            emitters: list,
            emitter_cdf,
            emitters_on: emitters,
        })
    }

    /// The ray-casting geometry.
    pub fn geometry(&self) -> &SceneGeometry {
        &self.geometry
    }

    /// Number of emitting triangles in use.
    pub fn emitter_count(&self) -> usize {
        self.emitters.len()
    }

    /// The true albedo at a hit, clamped to `[0, 1]` per channel.
    pub fn albedo(&self, hit: &Hit) -> DVec3 {
        let Some(m) = self.materials.get(hit.object as usize) else {
            return DVec3::ZERO;
        };
        let a = m.albedo_at(hit.uv.unwrap_or_default()).as_dvec3();
        finite_or_zero(a).clamp(DVec3::ZERO, DVec3::ONE)
    }

    /// The true albedo each camera pixel sees (pixel-centre ray) and the
    /// object index it belongs to (`None` for background).
    pub fn ground_truth(&self, camera: &DeviceRays) -> (RgbImage, Image<Option<u32>>) {
        let d = camera.device();
        let hits: Vec<Option<(Vec3, u32)>> = (0..d.width * d.height)
            .into_par_iter()
            .map(|i| {
                let ray = camera.pixel_ray(i % d.width, i / d.width)?;
                let hit = self.geometry.closest_hit(&ray, 0.0, f64::INFINITY)?;
                Some((self.albedo(&hit).as_vec3(), hit.object))
            })
            .collect();
        let albedo = Image {
            width: d.width,
            height: d.height,
            data: hits.iter().map(|h| h.map_or(Vec3::ZERO, |h| h.0)).collect(),
        };
        let object = Image {
            width: d.width,
            height: d.height,
            data: hits.iter().map(|h| h.map(|h| h.1)).collect(),
        };
        (albedo, object)
    }

    /// Path-trace the radiance every pixel of `camera` sees, lit by
    /// `lights` and this world's emitters, with `samples_per_pixel` paths
    /// per pixel (at least 1).
    pub fn render(
        &self,
        camera: &DeviceRays,
        lights: &SimLights<'_>,
        samples_per_pixel: u32,
        seed: u64,
    ) -> TransportImage {
        let d = camera.device();
        let (w, h) = (d.width, d.height);
        let pixels: Vec<[Vec3; 3]> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let r = camera
                    .pixel_ray(i % w, i / w)
                    .map_or([DVec3::ZERO; 3], |ray| {
                        self.trace(&ray, lights, samples_per_pixel, pixel_seed(seed, i as u64))
                    });
                r.map(|v| finite_or_zero(v).as_vec3())
            })
            .collect();
        let mut out = TransportImage::zero(w, h);
        for (i, [e, d, ind]) in pixels.into_iter().enumerate() {
            out.emitted.data[i] = e;
            out.direct.data[i] = d;
            out.indirect.data[i] = ind;
        }
        out
    }

    /// `[emitted, direct, indirect]` radiance (the split of
    /// [`TransportImage`]) arriving along `ray`, lit by `lights` and this
    /// world's emitters, from `spp` paths (at least 1); the result depends
    /// only on `seed` (no threads). A ray that leaves the scene
    /// brings the environment's radiance, counted as emitted.
    pub fn trace(&self, ray: &Ray, lights: &SimLights<'_>, spp: u32, seed: u64) -> [DVec3; 3] {
        let spp = spp.max(1);
        let end = self.follow(ray, lights);
        let Some(seen) = end.seen else {
            return [end.emitted, DVec3::ZERO, DVec3::ZERO];
        };
        let mut direct = self.delta_irradiance(&seen, lights);
        let (mut sampled, mut indirect) = (DVec3::ZERO, DVec3::ZERO);
        self.sample_paths(&seen, lights, spp, seed, |e, i| {
            sampled += e;
            indirect += i;
        });
        direct += sampled / spp as f64;
        [
            end.emitted,
            end.tint * seen.rho * std::f64::consts::FRAC_1_PI * direct,
            end.tint * indirect / spp as f64,
        ]
    }

    /// Where `ray` ends: past the mirrors it meets, at a diffuse surface
    /// (with what it collected on the way), or out of the scene.
    pub fn surface_along(&self, ray: &Ray, lights: &SimLights<'_>) -> RayEnd {
        let end = self.follow(ray, lights);
        RayEnd {
            emitted: end.emitted,
            tint: end.tint,
            surface: end.seen.map(|s| SurfacePoint {
                point: s.point,
                facing: s.frame.facing,
                shading: s.frame.shading,
                object: s.object,
                rho: s.rho,
            }),
        }
    }

    /// Follow `ray` through the mirrors it meets to a diffuse surface.
    fn follow(&self, ray: &Ray, lights: &SimLights<'_>) -> Followed {
        let (mut ray, mut tint, mut emitted) = (*ray, DVec3::ONE, DVec3::ZERO);
        let mut mirrors = 0;
        loop {
            let Some(seen) = self.seen(&ray, f64::INFINITY) else {
                return Followed {
                    emitted: emitted + tint * lights.environment(),
                    tint,
                    seen: None,
                };
            };
            emitted += tint * seen.emitted;
            if !self.is_mirror(seen.object) {
                return Followed {
                    emitted,
                    tint,
                    seen: Some(seen),
                };
            }
            tint *= seen.rho;
            mirrors += 1;
            if tint == DVec3::ZERO || mirrors > MAX_DEPTH {
                return Followed {
                    emitted,
                    tint,
                    seen: None,
                };
            }
            let dir = mirror_direction(ray.direction, seen.frame.facing);
            let origin =
                self.geometry
                    .offset_point(seen.point, seen.frame.facing, seen.point + dir);
            ray = Ray::new(origin, dir);
        }
    }

    /// The direct irradiance (W/m^2) at `surface` that is exact, the same
    /// for every seed: the projectors and the point and spot lights,
    /// straight and by way of one mirror. With
    /// [`Self::sampled_irradiance`] it is the whole direct irradiance.
    pub fn exact_irradiance(&self, surface: &SurfacePoint, lights: &SimLights<'_>) -> DVec3 {
        self.delta_irradiance(&surface.seen(), lights)
    }

    /// The direct irradiance (W/m^2) at `surface` that is estimated: the
    /// area lights and emitters by `samples` next-event estimates (at
    /// least 1, stratified over the area lights) on the streams of `seed`
    /// ([`Self::trace`]'s); zero without any.
    pub fn sampled_irradiance(
        &self,
        surface: &SurfacePoint,
        lights: &SimLights<'_>,
        samples: u32,
        seed: u64,
    ) -> DVec3 {
        if !lights.has_areas() && self.emitters.is_empty() {
            return DVec3::ZERO;
        }
        let frame = surface.seen().frame;
        let samples = samples.max(1);
        let mut sum = DVec3::ZERO;
        for s in 0..samples {
            let start = PathStart::new(s, samples, seed);
            sum += self.sample_emitters(surface.point, &frame, start.emitter);
            sum += lights.sample_areas(
                &self.geometry,
                surface.point,
                surface.facing,
                surface.shading,
                start.area,
            );
        }
        sum / f64::from(samples)
    }

    /// The indirect irradiance (W/m^2) at `surface`, everything but its
    /// direct light, from `paths` paths (at least 1; the first bounce
    /// stratified) on the streams of `seed` ([`Self::trace`]'s), and the
    /// harmonic mean of the paths' first hit distances (how far the
    /// surfaces that light it are; infinite when every path leaves the
    /// scene).
    pub fn indirect_irradiance(
        &self,
        surface: &SurfacePoint,
        lights: &SimLights<'_>,
        paths: u32,
        seed: u64,
    ) -> (DVec3, f64) {
        let seen = surface.seen();
        let paths = paths.max(1);
        let (mut sum, mut inverse) = (DVec3::ZERO, 0.0);
        for s in 0..paths {
            let mut start = PathStart::new(s, paths, seed);
            let (l, distance) = self.trace_path(
                surface.point,
                seen.frame,
                DVec3::ONE,
                lights,
                start.first,
                &mut start.rng,
            );
            sum += l;
            if distance > 0.0 {
                inverse += 1.0 / distance;
            }
        }
        let harmonic = if inverse > 0.0 {
            f64::from(paths) / inverse
        } else {
            f64::INFINITY
        };
        (
            finite_or_zero(std::f64::consts::PI * sum / f64::from(paths)),
            harmonic,
        )
    }

    /// Path-trace the exitance `B` (W/m^2 per channel) leaving the front
    /// side of the surface at `point`, whose unit front normal is
    /// `normal`: `pi` times the outgoing radiance of the Lambertian
    /// surface, so `pi Ke` of its own emission (when this world's
    /// emitters are on) plus `rho E`, with `E` the irradiance from
    /// `lights` and everything this world emits or reflects.
    /// `spp` paths (at least 1), the estimator of [`Self::render`]; the
    /// result depends only on `seed` (no threads), and distinct
    /// seeds give independent estimates.
    ///
    /// The surface is found by a ray that starts a few
    /// [`SceneGeometry::epsilon`] in front of `point` and points back at
    /// it; `None` when it finds none (a point off every surface) or the
    /// input is not finite.
    ///
    /// [`ExitanceEstimate::std_error`] treats the paths as independent;
    /// the first bounce is stratified, which only lowers the true error,
    /// so it is an upper estimate.
    pub fn exitance_at(
        &self,
        point: DVec3,
        normal: DVec3,
        lights: &SimLights<'_>,
        spp: u32,
        seed: u64,
    ) -> Option<ExitanceEstimate> {
        let n = normal.normalize_or_zero();
        if !(point.is_finite() && n != DVec3::ZERO && n.is_finite()) {
            return None;
        }
        let lift = EXITANCE_LIFT * self.geometry.epsilon();
        let seen = self.seen(&Ray::new(point + lift * n, -n), 2.0 * lift)?;
        let spp = spp.max(1);
        // Per path: pi Ke + rho (E_delta + E_sampled) + pi L_indirect.
        let fixed =
            std::f64::consts::PI * seen.emitted + seen.rho * self.delta_irradiance(&seen, lights);
        let (mut sum, mut sum_sq) = (DVec3::ZERO, DVec3::ZERO);
        let mut paths = 0u32;
        self.sample_paths(&seen, lights, spp, seed, |e, i| {
            let b = fixed + seen.rho * e + std::f64::consts::PI * i;
            sum += b;
            sum_sq += b * b;
            paths += 1;
        });
        if paths == 0 {
            // A black surface: its own emission only, exactly.
            return Some(ExitanceEstimate {
                exitance: finite_or_zero(fixed),
                std_error: DVec3::ZERO,
            });
        }
        let count = f64::from(paths);
        let mean = sum / count;
        let std_error = if paths > 1 {
            let variance = (sum_sq - sum * mean) / (count - 1.0);
            (variance.max(DVec3::ZERO) / count).map(f64::sqrt)
        } else {
            DVec3::INFINITY
        };
        Some(ExitanceEstimate {
            exitance: finite_or_zero(mean),
            std_error,
        })
    }

    /// True when object `object` is an ideal mirror.
    fn is_mirror(&self, object: u32) -> bool {
        self.mirrors.get(object as usize).copied().unwrap_or(false)
    }

    /// Emitted radiance of the surface at `hit` toward a ray that hit it
    /// (zero from the back or with the emitters off).
    fn emission(&self, hit: &Hit) -> DVec3 {
        match self.materials.get(hit.object as usize) {
            Some(m) if hit.front_face && self.emitters_on => {
                finite_or_zero(m.emission.as_dvec3().max(DVec3::ZERO))
            }
            _ => DVec3::ZERO,
        }
    }

    /// The surface point `ray` sees first, within `t_max`.
    fn seen(&self, ray: &Ray, t_max: f64) -> Option<Seen> {
        let hit = self.geometry.closest_hit(ray, 0.0, t_max)?;
        let frame = SurfaceFrame::at(&hit, ray.direction)?;
        let emitted = self.emission(&hit);
        let rho = self.albedo(&hit);
        Some(Seen {
            point: hit.point,
            object: hit.object,
            frame,
            emitted,
            rho,
        })
    }

    /// The delta lights' irradiance (W/m^2) at a seen point: straight
    /// ([`SimLights::delta_irradiance`]) and by way of one mirror.
    fn delta_irradiance(&self, seen: &Seen, lights: &SimLights<'_>) -> DVec3 {
        let (point, frame) = (seen.point, &seen.frame);
        let straight = lights.delta_irradiance(&self.geometry, point, frame.facing, frame.shading);
        straight + self.mirrored_irradiance(point, frame, lights)
    }

    /// [`Self::mirrored_irradiance`] at a vertex of a continuation path:
    /// found with probability [`MIRRORED_ON_PATHS`] and weighted by its
    /// inverse, so the estimate stays unbiased while most vertices skip
    /// the facets. There it is light after a mirror and at least one
    /// diffuse bounce: on the demo scene, found at every vertex, it took
    /// `bench gi` from 34 to 89 s and moved no figure in its third digit.
    /// The choice hashes the vertex's position: it draws nothing from the
    /// path's stream, and two worlds whose surfaces agree choose alike
    /// (common random numbers).
    fn mirrored_on_path(
        &self,
        point: DVec3,
        frame: &SurfaceFrame,
        lights: &SimLights<'_>,
    ) -> DVec3 {
        if self.mirror_facets.is_empty() {
            return DVec3::ZERO;
        }
        let key = point.x.to_bits()
            ^ point.y.to_bits().rotate_left(21)
            ^ point.z.to_bits().rotate_left(42);
        if SplitMix64::new(key).random::<f64>() >= MIRRORED_ON_PATHS {
            return DVec3::ZERO;
        }
        self.mirrored_irradiance(point, frame, lights) / MIRRORED_ON_PATHS
    }

    /// The delta lights' irradiance (W/m^2) at a surface point by way of
    /// one mirror facet, exactly, with true visibility on both legs
    /// ([`super::mirrors`]).
    fn mirrored_irradiance(
        &self,
        point: DVec3,
        frame: &SurfaceFrame,
        lights: &SimLights<'_>,
    ) -> DVec3 {
        if self.mirror_facets.is_empty() {
            return DVec3::ZERO;
        }
        let mut e = DVec3::ZERO;
        for source in lights.delta_sources() {
            let from = source.position();
            self.mirror_facets.for_each_candidate(point, from, |facet| {
                let Some(r) = facet.reflection(point, from) else {
                    return;
                };
                let l = (r.point - point).normalize_or_zero();
                let cos = frame.shading.dot(l);
                if !(cos > 0.0 && frame.facing.dot(l) > 0.0) {
                    return;
                }
                // The first leg: the facet is the first surface the ray
                // from the point meets.
                let origin = self.geometry.offset_point(point, frame.facing, r.point);
                let ray = Ray::new(origin, (r.point - origin).normalize_or_zero());
                let Some(hit) = self.geometry.closest_hit(&ray, 0.0, f64::INFINITY) else {
                    return;
                };
                if hit.object != facet.object || hit.triangle != facet.triangle {
                    return;
                }
                let i = source.intensity_toward(&self.geometry, r.point, r.facing);
                e += self.albedo(&hit) * i * (cos / r.distance2);
            });
        }
        finite_or_zero(e)
    }

    /// `spp` paths from a seen point (none when its albedo is zero): each
    /// gives `path(e, l)`, one next-event estimate `e` of the irradiance
    /// from the emitters and area lights and one estimate `l` of the
    /// indirect radiance (already times the point's albedo), in path
    /// order.
    ///
    /// Each path starts from [`PathStart`] and draws the same numbers at
    /// each vertex whatever the world holds (an emitter pick, a point on
    /// the area lights, a direction), so two worlds traced with one seed
    /// follow the same paths as long as their surfaces agree: their
    /// difference is then far less noisy than either (common random
    /// numbers).
    fn sample_paths(
        &self,
        seen: &Seen,
        lights: &SimLights<'_>,
        spp: u32,
        seed: u64,
        mut path: impl FnMut(DVec3, DVec3),
    ) {
        if seen.rho == DVec3::ZERO {
            return;
        }
        let point = seen.point;
        let (facing, shading) = (seen.frame.facing, seen.frame.shading);
        for s in 0..spp {
            let mut start = PathStart::new(s, spp, seed);
            let mut e = self.sample_emitters(point, &seen.frame, start.emitter);
            if lights.has_areas() {
                e += lights.sample_areas(&self.geometry, point, facing, shading, start.area);
            }
            let (l, _) = self.trace_path(
                point,
                seen.frame,
                seen.rho,
                lights,
                start.first,
                &mut start.rng,
            );
            path(e, l);
        }
    }

    /// One continuation path from a surface point: the radiance it brings
    /// back, already multiplied by the first point's albedo `beta`. `first`
    /// is the point of the unit square that picks the first direction.
    fn trace_path(
        &self,
        start: DVec3,
        start_frame: SurfaceFrame,
        mut beta: DVec3,
        lights: &SimLights<'_>,
        first: (f64, f64),
        rng: &mut SplitMix64,
    ) -> (DVec3, f64) {
        let mut sum = DVec3::ZERO;
        let mut first_distance = f64::INFINITY;
        let (mut point, mut facing) = (start, start_frame.facing);
        let mut dir = cosine_direction(start_frame.shading, first);
        // Whether the ray leaves a mirror (emission it finds counts).
        let mut off_mirror = false;
        for depth in 1..=MAX_DEPTH {
            if !(dir.dot(facing) > 0.0) {
                break;
            }
            let origin = self.geometry.offset_point(point, facing, point + dir);
            let Some(hit) = self
                .geometry
                .closest_hit(&Ray::new(origin, dir), 0.0, f64::INFINITY)
            else {
                sum += beta * lights.environment();
                break;
            };
            if depth == 1 {
                first_distance = (hit.point - point).length();
            }
            let Some(next) = SurfaceFrame::at(&hit, dir) else {
                break;
            };
            if off_mirror {
                sum += beta * self.emission(&hit);
            }
            let rho = self.albedo(&hit);
            if rho == DVec3::ZERO {
                break;
            }
            off_mirror = self.is_mirror(hit.object);
            if !off_mirror {
                let mut e = self.sample_emitters(hit.point, &next, rng.random());
                e += lights.delta_irradiance(&self.geometry, hit.point, next.facing, next.shading);
                e += self.mirrored_on_path(hit.point, &next, lights);
                let u = (rng.random(), rng.random());
                if lights.has_areas() {
                    e += lights.sample_areas(
                        &self.geometry,
                        hit.point,
                        next.facing,
                        next.shading,
                        u,
                    );
                }
                sum += beta * rho * std::f64::consts::FRAC_1_PI * e;
            }
            beta *= rho;
            if depth >= ROULETTE_AFTER {
                let q = beta.max_element().min(0.95);
                if !(q > 0.0) || rng.random::<f64>() >= q {
                    break;
                }
                beta /= q;
            }
            dir = if off_mirror {
                mirror_direction(dir, next.facing)
            } else {
                cosine_direction(next.shading, (rng.random(), rng.random()))
            };
            point = hit.point;
            facing = next.facing;
        }
        (finite_or_zero(sum), first_distance)
    }

    /// One next-event estimate of the irradiance from the emitters, picked
    /// by the three numbers `[u, r1, r2]` in `[0, 1)`.
    fn sample_emitters(&self, point: DVec3, frame: &SurfaceFrame, [u, r1, r2]: [f64; 3]) -> DVec3 {
        if self.emitters.is_empty() {
            return DVec3::ZERO;
        }
        let k = self
            .emitter_cdf
            .partition_point(|c| *c < u)
            .min(self.emitters.len() - 1);
        let e = &self.emitters[k];
        let p_select = self.emitter_cdf[k] - if k == 0 { 0.0 } else { self.emitter_cdf[k - 1] };
        let s = r1.sqrt();
        let [a, b, c] = e.vertices;
        let y = (1.0 - s) * a + s * (1.0 - r2) * b + s * r2 * c;
        let d = y - point;
        let dist2 = d.length_squared();
        if !(dist2 > 0.0 && p_select > 0.0) {
            return DVec3::ZERO;
        }
        let l = d / dist2.sqrt();
        let cos_x = frame.shading.dot(l);
        let cos_y = -e.normal.dot(l);
        if !(cos_x > 0.0 && cos_y > 0.0 && frame.facing.dot(l) > 0.0) {
            return DVec3::ZERO;
        }
        if !self.geometry.visible(point, frame.facing, y, true) {
            return DVec3::ZERO;
        }
        finite_or_zero(e.radiance * (cos_x * cos_y / dist2 * e.area / p_select))
    }
}

/// What path `s` of `count` from one surface point draws before it leaves
/// it, on its own stream seeded from `(seed, s)`, in the one order every
/// estimator uses (so all of them share a path's numbers for one seed):
/// an emitter pick, a point on the area lights, and the point of the unit
/// square that picks the first direction. The last two are stratified
/// (an n x n jittered grid, n = floor(sqrt(count)), the paths past n^2
/// not): the first bounce carries most of the indirect light.
struct PathStart {
    rng: SplitMix64,
    emitter: [f64; 3],
    area: (f64, f64),
    first: (f64, f64),
}

impl PathStart {
    fn new(s: u32, count: u32, seed: u64) -> Self {
        let mut rng = SplitMix64::new(pixel_seed(seed, u64::from(s)));
        let emitter = rng.random();
        let area = stratified_point(s, count, (rng.random(), rng.random()));
        let first = stratified_point(s, count, (rng.random(), rng.random()));
        Self {
            rng,
            emitter,
            area,
            first,
        }
    }
}

/// A diffuse surface point, as [`SimWorld::surface_along`] finds it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// The point (world metres).
    pub point: DVec3,
    /// Unit geometric normal on the side the ray arrived at.
    pub facing: DVec3,
    /// Unit shading normal, in the same hemisphere.
    pub shading: DVec3,
    /// Index of its object in the scene.
    pub object: u32,
    /// Its true albedo.
    pub rho: DVec3,
}

impl SurfacePoint {
    fn seen(&self) -> Seen {
        Seen {
            point: self.point,
            object: self.object,
            frame: SurfaceFrame {
                facing: self.facing,
                shading: self.shading,
            },
            emitted: DVec3::ZERO,
            rho: self.rho,
        }
    }
}

/// Where a ray ends ([`SimWorld::surface_along`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayEnd {
    /// Radiance collected on the way: emitting surfaces it met and, when
    /// it leaves the scene, the environment, times the mirrors' tint.
    pub emitted: DVec3,
    /// The product of the albedos of the mirrors it met.
    pub tint: DVec3,
    /// The diffuse surface it ends at; `None` when it leaves the scene or
    /// a black mirror stops it.
    pub surface: Option<SurfacePoint>,
}

/// [`SimWorld::follow`]'s result: a [`RayEnd`] with the seen point.
struct Followed {
    emitted: DVec3,
    tint: DVec3,
    seen: Option<Seen>,
}

/// `dir` reflected about the unit normal `facing` of the side it arrives
/// at.
fn mirror_direction(dir: DVec3, facing: DVec3) -> DVec3 {
    dir - 2.0 * dir.dot(facing) * facing
}

/// The surface point a ray sees, as the estimator needs it.
struct Seen {
    point: DVec3,
    /// Index of its object in the scene.
    object: u32,
    frame: SurfaceFrame,
    /// Emitted radiance toward the ray (zero from the back or with the
    /// emitters off).
    emitted: DVec3,
    /// True albedo.
    rho: DVec3,
}

/// Normals at a hit, oriented to the side a ray arriving along `incoming`
/// sees.
#[derive(Clone, Copy, Debug)]
struct SurfaceFrame {
    /// Geometric normal on the seen side.
    facing: DVec3,
    /// Shading normal flipped into the same hemisphere.
    shading: DVec3,
}

impl SurfaceFrame {
    fn at(hit: &Hit, incoming: DVec3) -> Option<Self> {
        if hit.geometric_normal == DVec3::ZERO {
            return None;
        }
        let facing = hit.facing_normal(incoming);
        let shading = face_forward(hit.shading_normal, facing);
        Some(Self { facing, shading })
    }
}

#[cfg(test)]
#[path = "world_tests.rs"]
mod tests;
