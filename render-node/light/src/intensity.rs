//! The CPU reference renderer of the intensity image `I_int` (paper
//! section 3.3, equation 3.1): the scene seen from a camera, lit by a point
//! light at the projector's centre with `D_l = C_p * eta` and `D_m = 1`,
//! with hard shadows from true visibility:
//!
//! `I = cos(theta) / r^2 * C_p * eta`
//!
//! Background pixels, shadowed pixels, and pixels outside the projector's
//! image are exactly 0. One ray per pixel, through the pixel centre.
//!
//! # Faces and normals
//! Surfaces are two-sided. The normal at a pixel is oriented towards the
//! camera: the geometric normal flipped if the camera sees the back face,
//! and the shading normal flipped into the same hemisphere. A point is lit
//! only when the light is on the side the camera sees (oriented geometric
//! normal), the projector sees it (in front, inside its image, unoccluded),
//! and `cos(theta)`, taken with the oriented shading normal, is positive.
//! `phi` is the angle between the oriented shading normal and the
//! direction to the camera, for the phi_max cut of section 3.5.

use super::device::{DeviceError, DeviceRays};
use super::geometry::{ObjectFilter, SceneGeometry, face_forward};
use super::image::{Image, RgbImage};
use crate::finite::finite_or_zero;
use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;
use showcase_proto::PinholeDevice;

/// The point light of equation 3.1.
#[derive(Clone, Debug)]
pub struct IntensityLight {
    /// Position of the light (the projector's centre of projection).
    pub position: DVec3,
    /// Diffuse light colour `D_l = C_p * eta`.
    pub color: DVec3,
    /// When set, the light only reaches points inside this device's image.
    pub frustum: Option<DeviceRays>,
}

impl IntensityLight {
    /// The light of a projector showing colour `c_p` at intensity `eta`:
    /// at its centre, limited to its image.
    pub fn projector(device: &PinholeDevice, c_p: Vec3, eta: f64) -> Result<Self, DeviceError> {
        let rays = DeviceRays::new(device)?;
        Ok(Self {
            position: rays.center(),
            color: finite_or_zero(c_p.as_dvec3() * eta),
            frustum: Some(rays),
        })
    }

    /// An unrestricted isotropic point light of colour `color` (W/sr).
    pub fn point(position: DVec3, color: DVec3) -> Self {
        Self {
            position,
            color: finite_or_zero(color),
            frustum: None,
        }
    }

    /// Equation 3.1 at a surface point: `cos(theta) / r^2 * D_l` with the
    /// visibility rules of the module docs. `facing` is the geometric
    /// normal oriented to the viewer's side, `shading` the shading normal in
    /// the same hemisphere (both unit). Returns 0 when unlit.
    pub fn intensity_at(
        &self,
        geometry: &SceneGeometry,
        point: DVec3,
        facing: DVec3,
        shading: DVec3,
    ) -> DVec3 {
        self.attenuation(geometry, point, facing, shading)
            .map_or(DVec3::ZERO, |a| finite_or_zero(a * self.color))
    }

    /// `cos(theta) / r^2` where the light reaches the point, `None` where it
    /// does not (behind the surface, outside the projector's image, or
    /// occluded).
    pub fn attenuation(
        &self,
        geometry: &SceneGeometry,
        point: DVec3,
        facing: DVec3,
        shading: DVec3,
    ) -> Option<f64> {
        let to_light = self.position - point;
        let r2 = to_light.length_squared();
        if !(r2 > 0.0 && r2.is_finite() && point.is_finite()) {
            return None;
        }
        let l = to_light / r2.sqrt();
        let cos_theta = shading.dot(l);
        if !(facing.dot(l) > 0.0 && cos_theta > 0.0) {
            return None;
        }
        let lit = match &self.frustum {
            Some(device) => device.sees(geometry, point, facing),
            None => geometry.visible(point, facing, self.position, false),
        };
        let a = cos_theta / r2;
        (lit && a.is_finite()).then_some(a)
    }
}

/// What a camera pixel sees, for reflectance capture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    /// Index into `Showcase::objects`.
    pub object: u32,
    /// Triangle index within that object's mesh.
    pub triangle: u32,
    /// World-space hit point.
    pub point: DVec3,
    /// Unit shading normal oriented towards the camera.
    pub normal: DVec3,
    /// Angle (radians) between `normal` and the direction to the camera.
    pub phi: f64,
    /// Interpolated texture coordinate, if the mesh has them.
    pub uv: Option<Vec2>,
    /// True when the light reaches the point (its `I_int` may still be 0
    /// for a zero light colour).
    pub lit: bool,
}

/// The intensity image and the per-pixel surface data behind it.
#[derive(Clone, Debug, PartialEq)]
pub struct IntensityImage {
    /// `I_int`, linear RGB.
    pub intensity: RgbImage,
    /// The surface each pixel sees; `None` for background and for surfaces
    /// of objects the `lit` filter excludes.
    pub surface: Image<Option<SurfaceSample>>,
}

/// Render `I_int` from `camera`'s view. Everything in `geometry` is seen
/// and casts shadows; only pixels whose first hit is an object accepted by
/// `lit` are shaded (the others are 0), which is how piecewise capture
/// renders one piece while the rest of the scene still occludes.
pub fn render_intensity(
    geometry: &SceneGeometry,
    camera: &DeviceRays,
    light: &IntensityLight,
    lit: &ObjectFilter,
) -> IntensityImage {
    let (w, h) = (camera.device().width, camera.device().height);
    let rows: Vec<Vec<(Vec3, Option<SurfaceSample>)>> = (0..h)
        .into_par_iter()
        .map(|y| {
            (0..w)
                .map(|x| shade_pixel(geometry, camera, light, lit, x, y))
                .collect()
        })
        .collect();
    let mut intensity = Image::new(w, h, Vec3::ZERO);
    let mut surface = Image::new(w, h, None);
    for (i, (value, sample)) in rows.into_iter().flatten().enumerate() {
        intensity.data[i] = value;
        surface.data[i] = sample;
    }
    IntensityImage { intensity, surface }
}

fn shade_pixel(
    geometry: &SceneGeometry,
    camera: &DeviceRays,
    light: &IntensityLight,
    lit: &ObjectFilter,
    x: u32,
    y: u32,
) -> (Vec3, Option<SurfaceSample>) {
    let Some(ray) = camera.pixel_ray(x, y) else {
        return (Vec3::ZERO, None);
    };
    let Some(hit) = geometry.closest_hit(&ray, 0.0, f64::INFINITY) else {
        return (Vec3::ZERO, None);
    };
    let accepted = geometry
        .object_kind(hit.object)
        .is_some_and(|kind| lit.accepts(hit.object as usize, kind));
    if !accepted || hit.geometric_normal == DVec3::ZERO {
        return (Vec3::ZERO, None);
    }
    let to_camera = -ray.direction;
    let facing = hit.facing_normal(ray.direction);
    let shading = face_forward(hit.shading_normal, facing);
    let attenuation = light.attenuation(geometry, hit.point, facing, shading);
    let value = attenuation.map_or(DVec3::ZERO, |a| finite_or_zero(a * light.color));
    let phi = shading.dot(to_camera).clamp(-1.0, 1.0).acos();
    let sample = SurfaceSample {
        object: hit.object,
        triangle: hit.triangle,
        point: hit.point,
        normal: shading,
        phi,
        uv: hit.uv,
        lit: attenuation.is_some(),
    };
    (value.as_vec3(), Some(sample))
}

#[cfg(test)]
mod tests {
    use super::*;
    use showcase_proto::{Material, Mesh, Object, ObjectKind, Showcase, Transform};

    /// The unit square on `y = 0`, front side up.
    fn plate() -> Showcase {
        let mut s = Showcase::default();
        let id = s.add_mesh(Mesh {
            positions: vec![Vec3::ZERO, Vec3::Z, Vec3::new(1.0, 0.0, 1.0), Vec3::X],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        });
        s.objects.push(Object {
            name: "plate".into(),
            mesh: id,
            material: Material::diffuse(Vec3::ONE),
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
        s
    }

    #[test]
    fn surfaces_are_two_sided_and_lit_only_from_the_side_the_camera_sees() {
        let s = plate();
        let geometry = SceneGeometry::build(&s, &ObjectFilter::All).unwrap();
        let centre = DVec3::new(0.5, 0.0, 0.5);
        let render = |eye: DVec3, light: DVec3| {
            let camera = PinholeDevice::look_at(eye, centre, DVec3::Z, 30.0, 9, 9);
            let light = IntensityLight::point(light, DVec3::ONE);
            let img = render_intensity(
                &geometry,
                &DeviceRays::new(&camera).unwrap(),
                &light,
                &ObjectFilter::All,
            );
            (
                img.intensity.get(4, 4).copied().unwrap(),
                img.surface.get(4, 4).copied().unwrap().unwrap(),
            )
        };
        let above = DVec3::new(0.5, 1.0, 0.5);
        let below = DVec3::new(0.5, -1.0, 0.5);
        let (front, sample) = render(above, DVec3::new(0.5, 2.0, 0.5));
        assert!(
            (front.x as f64 - 0.25).abs() < 1e-6,
            "cos 1 / r^2 4 = 0.25, got {front}"
        );
        assert!((sample.normal - DVec3::Y).length() < 1e-12);
        let (back_unlit, sample) = render(below, DVec3::new(0.5, 2.0, 0.5));
        assert_eq!(back_unlit, Vec3::ZERO, "light behind the seen side");
        assert!(!sample.lit && (sample.normal + DVec3::Y).length() < 1e-12);
        let (back_lit, _) = render(below, DVec3::new(0.5, -2.0, 0.5));
        assert!((back_lit.x as f64 - 0.25).abs() < 1e-6);
        // A light exactly in the plane: grazing, 0 and finite.
        let (grazing, _) = render(above, DVec3::new(3.0, 0.0, 0.5));
        assert_eq!(grazing, Vec3::ZERO);
    }
}
