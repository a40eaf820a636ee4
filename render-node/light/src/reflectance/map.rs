//! The reflectance map of section 3.4 (reflectance image, camera matrix
//! `C`, object transforms `O_c`) and its re-rendering by projective
//! texturing from any view with object transforms `O_a`: a surface point
//! `p_a` of object `o` maps to `C * O_c[o] * O_a[o]^-1 * p_a` in the map.
//!
//! Projective texturing alone would also paint surfaces the map's camera
//! never saw (they lie behind what it saw), so each map keeps the depth and
//! object of every pixel, and a texel counts only when the same object was
//! seen at the projected depth (a shadow-map test). Several maps merge by
//! alpha blending with their blend weights (bilinearly filtered), so a
//! region blank in one map is filled by the others without seams.

use crate::finite::finite_or_zero;
use crate::{DeviceRays, Image, IntensityImage, RgbImage, SceneGeometry};
use glam::{DMat4, DVec2, DVec3, Vec3};
use rayon::prelude::*;
use showcase_proto::PinholeDevice;

use super::{ReflectanceError, check_size};

/// A stored reflectance map.
#[derive(Clone, Debug, PartialEq)]
pub struct ReflectanceMap {
    /// `I_ref`, linear RGB; 0 where blank.
    pub reflectance: RgbImage,
    /// Blend weight in `[0, 1]`; 0 where blank.
    pub weight: Image<f32>,
    /// Device depth (z, metres) of the surface each pixel saw; 0 for none.
    pub depth: Image<f32>,
    /// Object index each pixel saw.
    pub object: Image<Option<u32>>,
    /// The capturing camera `C`.
    pub camera: PinholeDevice,
    /// Object-to-world transform `O_c` of every object during capture, by
    /// object index.
    pub object_transforms: Vec<DMat4>,
}

impl ReflectanceMap {
    /// A map from an extracted reflectance image, its weights and the
    /// surfaces of the intensity image it was extracted with.
    pub fn new(
        reflectance: RgbImage,
        weight: Image<f32>,
        intensity: &IntensityImage,
        camera: PinholeDevice,
        object_transforms: Vec<DMat4>,
    ) -> Result<Self, ReflectanceError> {
        check_size("reflectance", &reflectance, &intensity.intensity)?;
        check_size("weight", &weight, &intensity.intensity)?;
        let depth = intensity.surface.map(|s| {
            s.map_or(0.0, |s| {
                let z = camera.to_device(s.point).z as f32;
                finite_or_zero(z)
            })
        });
        let object = intensity.surface.map(|s| s.map(|s| s.object));
        Ok(Self {
            reflectance,
            weight,
            depth,
            object,
            camera,
            object_transforms,
        })
    }

    /// The reflectance this map gives object `object` over the points
    /// `local` (in the object's own frame): the blend-weighted mean of
    /// their samples, `None` where the map saw none of them (or the map
    /// has no capture pose for the object).
    pub fn reflectance_at(&self, object: u32, local: &[DVec3]) -> Option<DVec3> {
        let o_c = self.object_transforms.get(object as usize)?;
        let (sum, weight) = local
            .iter()
            .map(|p| self.sample(object, o_c.transform_point3(*p)))
            .fold((DVec3::ZERO, 0.0), |a, s| (a.0 + s.0, a.1 + s.1));
        let rho = sum / weight;
        (weight > 1e-9 && rho.is_finite()).then_some(rho)
    }

    /// Premultiplied `(weight * reflectance, weight)` of object `object`
    /// at world point `p_c` (capture pose), bilinearly filtered over the
    /// texels that saw that object at that depth.
    fn sample(&self, object: u32, p_c: DVec3) -> (DVec3, f64) {
        let c = self.camera.to_device(p_c);
        let Some(px) = self.camera.project(p_c) else {
            return (DVec3::ZERO, 0.0);
        };
        if !(px.is_finite() && c.z > 0.0) {
            return (DVec3::ZERO, 0.0);
        }
        let f = self.camera.k.x_axis.x.abs().max(1e-9);
        // A texel's depth may differ by its footprint times the slope at
        // phi_max (tan 60 < 2), over the 2-pixel bilinear reach.
        let tol = c.z * (4.0 / f + 1e-3);
        let g = px - DVec2::splat(0.5);
        let (x0, y0) = (g.x.floor(), g.y.floor());
        let (fx, fy) = (g.x - x0, g.y - y0);
        let mut acc = (DVec3::ZERO, 0.0);
        for (dx, dy, b) in [
            (0.0, 0.0, (1.0 - fx) * (1.0 - fy)),
            (1.0, 0.0, fx * (1.0 - fy)),
            (0.0, 1.0, (1.0 - fx) * fy),
            (1.0, 1.0, fx * fy),
        ] {
            let (x, y) = (x0 + dx, y0 + dy);
            if x < 0.0 || y < 0.0 || x >= self.camera.width as f64 || y >= self.camera.height as f64
            {
                continue;
            }
            let i = y as usize * self.camera.width as usize + x as usize;
            if self.object.data.get(i).copied().flatten() != Some(object) {
                continue;
            }
            if (self.depth.data[i] as f64 - c.z).abs() > tol {
                continue;
            }
            let w = b * self.weight.data[i] as f64;
            acc.0 += w * self.reflectance.data[i].as_dvec3();
            acc.1 += w;
        }
        acc
    }
}

/// Re-render `maps` from `view`: `geometry` is the scene in its current
/// pose with object transforms `object_transforms` (`O_a`, by object
/// index). Returns the merged reflectance (0 where no map covers the
/// pixel) and the summed blend weight per pixel.
pub fn render_maps(
    maps: &[ReflectanceMap],
    view: &DeviceRays,
    geometry: &SceneGeometry,
    object_transforms: &[DMat4],
) -> (RgbImage, Image<f32>) {
    let d = view.device();
    let inverses: Vec<Option<DMat4>> = object_transforms
        .iter()
        .map(|m| {
            let inv = m.inverse();
            (m.determinant() != 0.0 && inv.is_finite()).then_some(inv)
        })
        .collect();
    let pixels: Vec<(Vec3, f32)> = (0..d.width * d.height)
        .into_par_iter()
        .map(|i| {
            let Some(ray) = view.pixel_ray(i % d.width, i / d.width) else {
                return (Vec3::ZERO, 0.0);
            };
            let Some(hit) = geometry.closest_hit(&ray, 0.0, f64::INFINITY) else {
                return (Vec3::ZERO, 0.0);
            };
            let Some(Some(inv_a)) = inverses.get(hit.object as usize) else {
                return (Vec3::ZERO, 0.0);
            };
            let local = inv_a.transform_point3(hit.point);
            let (mut sum, mut weight) = (DVec3::ZERO, 0.0);
            for map in maps {
                let Some(o_c) = map.object_transforms.get(hit.object as usize) else {
                    continue;
                };
                let (s, w) = map.sample(hit.object, o_c.transform_point3(local));
                sum += s;
                weight += w;
            }
            let rho = if weight > 1e-12 {
                sum / weight
            } else {
                DVec3::ZERO
            };
            if rho.is_finite() && weight.is_finite() {
                (rho.as_vec3(), weight as f32)
            } else {
                (Vec3::ZERO, 0.0)
            }
        })
        .collect();
    (
        Image {
            width: d.width,
            height: d.height,
            data: pixels.iter().map(|p| p.0).collect(),
        },
        Image {
            width: d.width,
            height: d.height,
            data: pixels.iter().map(|p| p.1).collect(),
        },
    )
}
