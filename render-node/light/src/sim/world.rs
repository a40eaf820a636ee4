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
//! - `direct`: `rho / pi * E_direct`, the projector's point light evaluated
//!   exactly (it is a delta light) plus emitters by next-event estimation
//!   (uniform area sampling of emitter triangles, weighted by area times
//!   peak radiance);
//! - `indirect`: everything scattered at least once more, by cosine-weighted
//!   path continuation (the first bounce stratified over the pixel's paths) with next-event estimation at every vertex and
//!   Russian roulette after the third bounce. Emission found by a
//!   continuation ray is not added (next-event estimation already counts
//!   it), so the estimator is unbiased.
//!
//! Every pixel has its own random stream seeded from `(seed, pixel index)`,
//! so a render is reproducible for a seed whatever the thread count.

use crate::finite::finite_or_zero;
use crate::{DeviceRays, Hit, Image, IntensityLight, ObjectFilter, Ray, RgbImage, SceneGeometry};
use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use showcase_proto::{Material, Showcase};

use super::SimError;
use crate::geometry::face_forward;
use crate::sampling::{cosine_direction, pixel_seed, stratified_point};

/// Longest path (in bounces) the estimator follows.
const MAX_DEPTH: u32 = 64;
/// Bounces before Russian roulette may end a path.
const ROULETTE_AFTER: u32 = 3;
/// How far in front of the point (in [`SceneGeometry::epsilon`]) the ray
/// of [`SimWorld::exitance_at`] that finds its surface starts.
const EXITANCE_LIFT: f64 = 16.0;

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
        let Some((x, y)) = self.rays.pixel_of(point) else {
            return DVec3::ZERO;
        };
        let i = self.intensity.get(x, y).copied().unwrap_or(Vec3::ZERO);
        finite_or_zero(a * i.as_dvec3())
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
    /// `projector` (if any) and this world's emitters, with
    /// `samples_per_pixel` paths per pixel (at least 1).
    pub fn render(
        &self,
        camera: &DeviceRays,
        projector: Option<&ProjectorLight>,
        samples_per_pixel: u32,
        seed: u64,
    ) -> TransportImage {
        let d = camera.device();
        let (w, h) = (d.width, d.height);
        let projector = projector.filter(|p| !p.is_dark());
        let spp = samples_per_pixel.max(1);
        let pixels: Vec<[Vec3; 3]> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let mut rng = ChaCha8Rng::seed_from_u64(pixel_seed(seed, i as u64));
                let ray = camera.pixel_ray(i % w, i / w);
                let r = ray.map_or([DVec3::ZERO; 3], |ray| {
                    self.trace_pixel(&ray, projector, spp, &mut rng)
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

    /// `[emitted, direct, indirect]` radiance along a camera ray.
    fn trace_pixel(
        &self,
        ray: &Ray,
        projector: Option<&ProjectorLight>,
        spp: u32,
        rng: &mut ChaCha8Rng,
    ) -> [DVec3; 3] {
        let Some(seen) = self.seen(ray, f64::INFINITY) else {
            return [DVec3::ZERO; 3];
        };
        let mut direct = self.projector_irradiance(&seen, projector);
        let (mut emitter_direct, mut indirect) = (DVec3::ZERO, DVec3::ZERO);
        self.sample_paths(&seen, projector, spp, rng, |e, i| {
            emitter_direct += e;
            indirect += i;
        });
        direct += emitter_direct / spp as f64;
        [
            seen.emitted,
            seen.rho * std::f64::consts::FRAC_1_PI * direct,
            indirect / spp as f64,
        ]
    }

    /// Path-trace the exitance `B` (W/m^2 per channel) leaving the front
    /// side of the surface at `point`, whose unit front normal is
    /// `normal`: `pi` times the outgoing radiance of the Lambertian
    /// surface, so `pi Ke` of its own emission (when this world's
    /// emitters are on) plus `rho E`, with `E` the irradiance from
    /// `projector` (if any) and everything this world emits or reflects.
    /// `spp` paths (at least 1), the estimator of [`Self::render`]; the
    /// result depends only on `seed` (one stream, no threads), and distinct
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
        projector: Option<&ProjectorLight>,
        spp: u32,
        seed: u64,
    ) -> Option<ExitanceEstimate> {
        let n = normal.normalize_or_zero();
        if !(point.is_finite() && n != DVec3::ZERO && n.is_finite()) {
            return None;
        }
        let lift = EXITANCE_LIFT * self.geometry.epsilon();
        let seen = self.seen(&Ray::new(point + lift * n, -n), 2.0 * lift)?;
        let projector = projector.filter(|p| !p.is_dark());
        let spp = spp.max(1);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // Per path: pi Ke + rho (E_projector + E_emitters) + pi L_indirect.
        let fixed = std::f64::consts::PI * seen.emitted
            + seen.rho * self.projector_irradiance(&seen, projector);
        let (mut sum, mut sum_sq) = (DVec3::ZERO, DVec3::ZERO);
        let mut paths = 0u32;
        self.sample_paths(&seen, projector, spp, &mut rng, |e, i| {
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

    /// The surface point `ray` sees first, within `t_max`.
    fn seen(&self, ray: &Ray, t_max: f64) -> Option<Seen> {
        let hit = self.geometry.closest_hit(ray, 0.0, t_max)?;
        let frame = SurfaceFrame::at(&hit, ray.direction)?;
        let material = &self.materials[hit.object as usize];
        let emitted = if hit.front_face && self.emitters_on {
            finite_or_zero(material.emission.as_dvec3().max(DVec3::ZERO))
        } else {
            DVec3::ZERO
        };
        let rho = self.albedo(&hit);
        Some(Seen {
            hit,
            frame,
            emitted,
            rho,
        })
    }

    /// The projector's irradiance (W/m^2) at a seen point.
    fn projector_irradiance(&self, seen: &Seen, projector: Option<&ProjectorLight>) -> DVec3 {
        projector.map_or(DVec3::ZERO, |p| {
            p.irradiance(
                &self.geometry,
                seen.hit.point,
                seen.frame.facing,
                seen.frame.shading,
            )
        })
    }

    /// `spp` paths from a seen point (none when its albedo is zero): each
    /// gives `path(e, l)`, one next-event estimate `e` of the emitters'
    /// irradiance and one estimate `l` of the indirect radiance (already
    /// times the point's albedo), in path order.
    fn sample_paths(
        &self,
        seen: &Seen,
        projector: Option<&ProjectorLight>,
        spp: u32,
        rng: &mut ChaCha8Rng,
        mut path: impl FnMut(DVec3, DVec3),
    ) {
        if seen.rho == DVec3::ZERO {
            return;
        }
        let point = seen.hit.point;
        // The first bounce, which carries most of the indirect light, is
        // stratified: an n x n jittered grid over the cosine hemisphere's
        // unit square (n = floor(sqrt(spp))), the paths past n^2
        // unstratified.
        for s in 0..spp {
            let e = self.sample_emitters(point, &seen.frame, rng);
            let first = stratified_point(s, spp, (rng.random(), rng.random()));
            let l = self.trace_path(point, seen.frame, seen.rho, projector, first, rng);
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
        projector: Option<&ProjectorLight>,
        first: (f64, f64),
        rng: &mut ChaCha8Rng,
    ) -> DVec3 {
        let mut sum = DVec3::ZERO;
        let (mut point, mut frame) = (start, start_frame);
        for depth in 1..=MAX_DEPTH {
            let u = if depth == 1 {
                first
            } else {
                (rng.random(), rng.random())
            };
            let dir = cosine_direction(frame.shading, u);
            if !(dir.dot(frame.facing) > 0.0) {
                break;
            }
            let origin = self.geometry.offset_point(point, frame.facing, point + dir);
            let Some(hit) = self
                .geometry
                .closest_hit(&Ray::new(origin, dir), 0.0, f64::INFINITY)
            else {
                break;
            };
            let Some(next) = SurfaceFrame::at(&hit, dir) else {
                break;
            };
            let rho = self.albedo(&hit);
            if rho == DVec3::ZERO {
                break;
            }
            let mut e = self.sample_emitters(hit.point, &next, rng);
            if let Some(p) = projector {
                e += p.irradiance(&self.geometry, hit.point, next.facing, next.shading);
            }
            sum += beta * rho * std::f64::consts::FRAC_1_PI * e;
            beta *= rho;
            if depth >= ROULETTE_AFTER {
                let q = beta.max_element().min(0.95);
                if !(q > 0.0) || rng.random::<f64>() >= q {
                    break;
                }
                beta /= q;
            }
            point = hit.point;
            frame = next;
        }
        finite_or_zero(sum)
    }

    /// One next-event estimate of the irradiance from the emitters.
    fn sample_emitters(&self, point: DVec3, frame: &SurfaceFrame, rng: &mut ChaCha8Rng) -> DVec3 {
        if self.emitters.is_empty() {
            return DVec3::ZERO;
        }
        let u: f64 = rng.random();
        let k = self
            .emitter_cdf
            .partition_point(|c| *c < u)
            .min(self.emitters.len() - 1);
        let e = &self.emitters[k];
        let p_select = self.emitter_cdf[k] - if k == 0 { 0.0 } else { self.emitter_cdf[k - 1] };
        let (r1, r2): (f64, f64) = (rng.random(), rng.random());
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

/// The surface point a ray sees, as the estimator needs it.
struct Seen {
    hit: Hit,
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
