//! Interreflection-corrected reflectance (beyond the paper): remove the
//! secondary scattering from a whole-scene capture by an inverse-radiosity
//! fixed point.
//!
//! The radiance map already measures the exitance `B = I_rad` of every
//! surface the camera sees, so the indirect irradiance of a seen point `x`
//! is a gather of measured exitance: `E_ind(x) = 1/N sum_j B(y_j)` over `N`
//! cosine-distributed rays from `x` hitting `y_j`, stratified (a jittered
//! grid over the hemisphere's unit square, as the sim's first bounce: the
//! gather's noise is most of the capture's error at demo sizes). Where `y_j` is hidden
//! from the camera (behind something, or a sliver that no pixel centre
//! lands on, such as the strip of a wall next to a corner), its exitance is
//! predicted from the current estimate,
//! `B(y) = rho_obj * (E_dir(y) + B(z))`, with `rho_obj` the object's
//! reflectance, `E_dir` the projector's direct irradiance at `y`, and
//! `B(z)` the exitance found by one more cosine-distributed ray from `y`
//! (measured where `z` is seen; `rho_obj(z) * (E_dir(z) + mean E_ind of
//! that object)` where it is hidden too). The per-object reflectance is
//! the ratio of summed measured exitance to summed irradiance
//! `I_int + E_ind` over the object's seen, lit pixels, grazing ones
//! included. Each iteration updates `E_ind` and the per-object values; the
//! seen part is fixed, so the iteration converges in a few steps. The
//! gather is the product's own estimator, seeded per pixel; the sim's
//! ground truth is an independent path tracer.

use super::{ReflectanceError, check_size};
use crate::finite::finite_or_zero;
use crate::geometry::face_forward;
use crate::sampling::{cosine_direction, pixel_seed, stratified_point};
use crate::{DeviceRays, Image, IntensityLight, Ray, RgbImage, SceneGeometry};
use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Parameters of the correction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CorrectionParams {
    /// Gather rays per pixel.
    pub gather_samples: u32,
    /// Fixed-point iterations.
    pub iterations: u32,
    /// Seed of the gather directions.
    pub seed: u64,
}

impl Default for CorrectionParams {
    fn default() -> Self {
        Self {
            gather_samples: 256,
            iterations: 4,
            seed: 7,
        }
    }
}

/// What the gather found from one pixel.
#[derive(Clone, Debug, Default)]
struct Gather {
    /// Sum of measured exitance over rays that hit a seen point.
    seen: DVec3,
    /// Per hidden object hit by a gather ray.
    hidden: Vec<HiddenHits>,
}

/// The gather rays of one pixel that hit hidden points of one object.
#[derive(Clone, Debug, Default)]
struct HiddenHits {
    object: u32,
    /// Sum of `E_dir` at the hidden points.
    e_dir: DVec3,
    /// Sum of the measured exitance their continuation rays found.
    seen: DVec3,
    /// Continuation rays that hit hidden points again: `(object, rays,
    /// sum of E_dir)`.
    hidden: Vec<(u32, f64, DVec3)>,
}

/// What a ray from a surface point finds.
enum Found {
    /// Nothing (it leaves the scene).
    Nothing,
    /// A seen point with this measured exitance.
    Seen(DVec3),
    /// A hidden point of `object` with this direct irradiance, its
    /// position and its normals (facing, shading).
    Hidden(u32, DVec3, DVec3, DVec3, DVec3),
}

/// A whole-scene capture to correct, all images from the camera's view.
#[derive(Clone, Copy, Debug)]
pub struct WholeCapture<'a> {
    /// The radiance map `I_rad`.
    pub i_rad: &'a RgbImage,
    /// The intensity image `I_int` of the light it was taken with.
    pub i_int: &'a RgbImage,
    /// Pixels whose extracted reflectance is valid (floor and phi_max).
    pub valid: &'a Image<bool>,
}

/// The indirect irradiance `E_ind` at each camera pixel (module docs) for
/// a capture taken with `light` (the light of `I_int`). 0 for pixels that
/// see nothing.
pub fn indirect_irradiance(
    geometry: &SceneGeometry,
    camera: &DeviceRays,
    light: &IntensityLight,
    capture: &WholeCapture<'_>,
    params: &CorrectionParams,
) -> Result<RgbImage, ReflectanceError> {
    let WholeCapture {
        i_rad,
        i_int,
        valid,
    } = *capture;
    let d = camera.device();
    let (w, h) = (d.width, d.height);
    if i_rad.width != w || i_rad.height != h {
        return Err(ReflectanceError::SizeMismatch {
            what: "i_rad",
            got: (i_rad.width, i_rad.height),
            expected: (w, h),
        });
    }
    check_size("i_int", i_int, i_rad)?;
    check_size("valid", valid, i_rad)?;
    let n = params.gather_samples.max(1);
    // What the camera sees: (object, device depth) per pixel.
    let seen: Vec<Option<(u32, f64, DVec3, DVec3)>> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let ray = camera.pixel_ray(i % w, i / w)?;
            let hit = geometry.closest_hit(&ray, 0.0, f64::INFINITY)?;
            if hit.geometric_normal == DVec3::ZERO {
                return None;
            }
            let facing = hit.facing_normal(ray.direction);
            Some((hit.object, d.to_device(hit.point).z, hit.point, facing))
        })
        .collect();
    let f = d.k.x_axis.x.abs().max(1e-9);
    // Follow a ray from `point` (geometric normal `facing`) along `dir`.
    let trace = |point: DVec3, facing: DVec3, dir: DVec3| -> Found {
        let origin = geometry.offset_point(point, facing, point + dir);
        let Some(hit) = geometry.closest_hit(&Ray::new(origin, dir), 0.0, f64::INFINITY) else {
            return Found::Nothing;
        };
        if hit.geometric_normal == DVec3::ZERO {
            return Found::Nothing;
        }
        let hf = hit.facing_normal(dir);
        // Seen by the camera: the side the ray hits faces the camera, and
        // the pixel it projects to sees the same object at the same depth
        // (within the footprint times the slope at phi_max) with a normal
        // within 45 degrees (so the unlit side of a box next to its lit
        // front, or its hidden back, never borrows the front's exitance):
        // use the measured exitance there.
        let z = d.to_device(hit.point).z;
        let faces_camera = hf.dot(camera.center() - hit.point) > 0.0;
        let same = |q: usize| {
            seen[q].is_some_and(|(o, zq, _, nq)| {
                o == hit.object
                    && (zq - z).abs() <= z * (4.0 / f + 1e-3)
                    && nq.dot(hf) > std::f64::consts::FRAC_1_SQRT_2
            })
        };
        if faces_camera
            && let Some((qx, qy)) = camera.pixel_of(hit.point)
            && same((qy * w + qx) as usize)
        {
            // Bilinear over the neighbouring pixels that see the same
            // surface.
            let px = camera.project(hit.point).unwrap_or_default() - glam::DVec2::splat(0.5);
            let (x0, y0) = (px.x.floor(), px.y.floor());
            let (fx, fy) = (px.x - x0, px.y - y0);
            let (mut b, mut wsum) = (DVec3::ZERO, 0.0);
            for (dx, dy, wt) in [
                (0.0, 0.0, (1.0 - fx) * (1.0 - fy)),
                (1.0, 0.0, fx * (1.0 - fy)),
                (0.0, 1.0, (1.0 - fx) * fy),
                (1.0, 1.0, fx * fy),
            ] {
                let (x, y) = (x0 + dx, y0 + dy);
                if x < 0.0 || y < 0.0 || x >= w as f64 || y >= h as f64 {
                    continue;
                }
                let q = y as usize * w as usize + x as usize;
                if same(q) {
                    b += wt * i_rad.data[q].as_dvec3();
                    wsum += wt;
                }
            }
            if wsum > 0.0 {
                return Found::Seen(b / wsum);
            }
        }
        let hs = face_forward(hit.shading_normal, hf);
        let e = light.intensity_at(geometry, hit.point, hf, hs);
        Found::Hidden(hit.object, e, hit.point, hf, hs)
    };
    let gathers: Vec<Gather> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let Some((_, _, point, facing)) = seen[i as usize] else {
                return Gather::default();
            };
            let mut rng = ChaCha8Rng::seed_from_u64(pixel_seed(params.seed, i as u64));
            let mut g = Gather::default();
            for s in 0..n {
                let u = stratified_point(s, n, (rng.random(), rng.random()));
                let dir = cosine_direction(facing, u);
                let (object, e_dir, y, yf, ys) = match trace(point, facing, dir) {
                    Found::Nothing => continue,
                    Found::Seen(b) => {
                        g.seen += finite_or_zero(b);
                        continue;
                    }
                    Found::Hidden(o, e, y, yf, ys) => (o, e, y, yf, ys),
                };
                let k = match g.hidden.iter().position(|h| h.object == object) {
                    Some(k) => k,
                    None => {
                        g.hidden.push(HiddenHits {
                            object,
                            ..HiddenHits::default()
                        });
                        g.hidden.len() - 1
                    }
                };
                let hh = &mut g.hidden[k];
                hh.e_dir += finite_or_zero(e_dir);
                let dir2 = cosine_direction(ys, (rng.random(), rng.random()));
                if !(dir2.dot(yf) > 0.0) {
                    continue;
                }
                match trace(y, yf, dir2) {
                    Found::Nothing => {}
                    Found::Seen(b) => hh.seen += finite_or_zero(b),
                    Found::Hidden(o2, e2, ..) => match hh.hidden.iter_mut().find(|h| h.0 == o2) {
                        Some(h) => {
                            h.1 += 1.0;
                            h.2 += finite_or_zero(e2);
                        }
                        None => hh.hidden.push((o2, 1.0, finite_or_zero(e2))),
                    },
                }
            }
            g
        })
        .collect();
    let objects = seen
        .iter()
        .flatten()
        .map(|s| s.0 as usize + 1)
        .max()
        .unwrap_or(0)
        .max(
            gathers
                .iter()
                .flat_map(|g| {
                    g.hidden.iter().flat_map(|h| {
                        std::iter::once(h.object as usize + 1)
                            .chain(h.hidden.iter().map(|h2| h2.0 as usize + 1))
                    })
                })
                .max()
                .unwrap_or(0),
        );
    // Pixels whose object reflectance can be measured: seen, lit above the
    // floor (grazing ones too: the phi_max cut is for the stored map, the
    // mean of an object only needs its exitance and irradiance).
    let floor = 1e-3
        * i_int
            .data
            .iter()
            .map(|v| v.max_element() as f64)
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
    let usable: Vec<bool> = (0..seen.len())
        .map(|i| {
            seen[i].is_some()
                && (valid.data[i]
                    || (i_int.data[i].min_element() as f64 > floor && i_rad.data[i].is_finite()))
        })
        .collect();
    let mut e_ind = Image::new(w, h, Vec3::ZERO);
    for _ in 0..params.iterations.max(1) {
        // Per object: reflectance as the ratio of summed exitance to summed
        // irradiance, and the mean indirect irradiance.
        let mut b_sum = vec![DVec3::ZERO; objects];
        let mut e_sum = vec![DVec3::ZERO; objects];
        let mut ind_sum = vec![(DVec3::ZERO, 0.0); objects];
        for (i, s) in seen.iter().enumerate() {
            let Some((o, ..)) = s else { continue };
            let o = *o as usize;
            if usable[i] {
                b_sum[o] += i_rad.data[i].as_dvec3().max(DVec3::ZERO);
                e_sum[o] += (i_int.data[i] + e_ind.data[i]).as_dvec3();
            }
            ind_sum[o].0 += e_ind.data[i].as_dvec3();
            ind_sum[o].1 += 1.0;
        }
        let ratio = |b: DVec3, e: DVec3| {
            let r = b / e;
            DVec3::from(r.to_array().map(|c| {
                if c.is_finite() {
                    c.clamp(0.0, 1.0)
                } else {
                    f64::NAN
                }
            }))
        };
        let global = ratio(b_sum.iter().sum(), e_sum.iter().sum());
        let global = DVec3::from(global.to_array().map(|c| if c.is_nan() { 0.5 } else { c }));
        let global_ind = mean(
            ind_sum
                .iter()
                .fold((DVec3::ZERO, 0.0), |a, b| (a.0 + b.0, a.1 + b.1)),
            DVec3::ZERO,
        );
        let rho_obj: Vec<DVec3> = b_sum
            .iter()
            .zip(&e_sum)
            .map(|(b, e)| {
                let r = ratio(*b, *e);
                DVec3::from(std::array::from_fn::<f64, 3, _>(|c| {
                    if r[c].is_nan() { global[c] } else { r[c] }
                }))
            })
            .collect();
        let ind_obj: Vec<DVec3> = ind_sum.iter().map(|s| mean(*s, global_ind)).collect();
        for (i, g) in gathers.iter().enumerate() {
            if seen[i].is_none() {
                continue;
            }
            let mut b = g.seen;
            for hh in &g.hidden {
                let mut e = hh.e_dir + hh.seen;
                for &(o2, count, e_dir) in &hh.hidden {
                    e += rho_obj[o2 as usize] * (e_dir + count * ind_obj[o2 as usize]);
                }
                b += rho_obj[hh.object as usize] * e;
            }
            let e = b / n as f64;
            e_ind.data[i] = finite_or_zero(e).max(DVec3::ZERO).as_vec3();
        }
    }
    Ok(e_ind)
}

fn mean((sum, count): (DVec3, f64), fallback: DVec3) -> DVec3 {
    if count > 0.0 { sum / count } else { fallback }
}
