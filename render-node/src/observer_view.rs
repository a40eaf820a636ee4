//! What an observer sees in the Virtual Showcase, simulated from the
//! outputs the render nodes produced, and what it should see.
//!
//! The **composite** follows the light the way the cabinet does:
//! - the real objects, lit only by the projectors (each projector a point
//!   light at its centre emitting `eta * value^gamma + black_level` W/sr
//!   along each pixel's ray, nearest pixel, true visibility; direct light
//!   only, as paper section 5 assumes), with their true reflectance, seen
//!   straight through the half-silvered mirror;
//! - plus the CRT's image, reflected by the mirror: the eye's ray meets the
//!   mirror plane, is reflected, and meets the screen at the pixel whose
//!   radiance the face node drew (nearest pixel).
//!
//! The mirror is taken as an ideal combiner (transmission and reflection
//! 1), so the composite is comparable with the target without a common
//! attenuation factor.
//!
//! The **target** is the scene as if all lighting were virtual: the first
//! surface on the eye's ray, real or virtual, shaded `rho / pi * E` by the
//! virtual lights with every shadow (the irradiance the renderers aim
//! for, [`target_irradiance`]). A reflective virtual object is a mirror
//! tinted by its albedo, as the face view draws it
//! ([`crate::render::cube_map`]), but its reflection is traced exactly
//! from each surface point into the real environment: the cube map seen
//! from one centre is the approximation the target judges.
//!
//! Pure: no IO, no GPU.

// `!(x > 0.0)` is deliberate: it is also true for NaN (as in `light`).
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::light::{DeviceRays, Image, Ray, RgbImage, SceneGeometry};
use crate::render::cube_map::{environment, reflect};
use crate::render::projector::{Occluders, emitted_intensity, target_irradiance};
use crate::render::{FrameScene, RenderSetupError};
use glam::{DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;
use showcase_proto::{CrtFace, ObjectKind, PinholeDevice, Projector};
use std::f64::consts::PI;

/// Rays per eye pixel along each axis.
pub const SUBSAMPLES: u32 = 2;

/// One projector's output for a frame: the pixel values it shows.
#[derive(Clone, Copy, Debug)]
pub struct ProjectedLight<'a> {
    /// The projector (its device and response).
    pub projector: &'a Projector,
    /// Its pixel values in `0..=1`, projector-sized.
    pub value: &'a RgbImage,
}

/// The face image one eye sees through a mirror.
#[derive(Clone, Copy, Debug)]
pub struct MirrorImage<'a> {
    /// The CRT face.
    pub face: &'a CrtFace,
    /// The radiance the face node drew for this eye, face-sized.
    pub radiance: &'a RgbImage,
}

/// An observer's simulated view and its target.
#[derive(Clone, Debug)]
pub struct ObserverView {
    /// Real objects under projected light plus the reflected CRT image.
    pub composite: RgbImage,
    /// The real part of [`Self::composite`].
    pub real: RgbImage,
    /// The reflected CRT part of [`Self::composite`].
    pub reflected: RgbImage,
    /// All lighting virtual.
    pub target: RgbImage,
    /// Pixels where the eye sees some object (real or virtual).
    pub covered: Image<bool>,
    /// Pixels whose centre ray meets a virtual object first (the CRT
    /// image must show it; the projectors must leave the real surface
    /// behind it dark).
    pub sees_virtual: Image<bool>,
    /// Pixels of [`Self::sees_virtual`] whose object is reflective.
    pub sees_reflective: Image<bool>,
    /// The object (index into the scene's objects) the centre ray meets
    /// first, if any.
    pub first_object: Image<Option<u32>>,
    /// Pixels whose first real surface some projector reaches (the
    /// projectors can light only these).
    pub reachable: Image<bool>,
    /// Pixels next to a change of the target's first surface or of the
    /// virtual lights reaching it (silhouette, facet and shadow edges),
    /// where one nearest-pixel sample cannot be right on both sides.
    pub edge: Image<bool>,
}

/// The target's first surface on a pixel's ray: object, triangle and the
/// light samples reaching it.
type SurfaceKey = Option<(u32, u32, u64)>;

/// Why a view cannot be simulated.
#[derive(Debug, thiserror::Error)]
pub enum ObserverViewError {
    /// The scene or a device cannot be set up.
    #[error(transparent)]
    Setup(#[from] RenderSetupError),
    /// An output image does not have its device's size.
    #[error("{what} is {width}x{height} but its device is {dw}x{dh}")]
    SizeMismatch {
        /// Which image.
        what: String,
        /// Image width.
        width: u32,
        /// Image height.
        height: u32,
        /// Device width.
        dw: u32,
        /// Device height.
        dh: u32,
    },
}

/// Simulate what the eye camera `eye` sees (see the module docs).
pub fn observer_view(
    frame: &FrameScene,
    occluders: &Occluders,
    eye: &PinholeDevice,
    projected: &[ProjectedLight<'_>],
    mirror: Option<MirrorImage<'_>>,
) -> Result<ObserverView, ObserverViewError> {
    let eye_rays = DeviceRays::new(eye).map_err(RenderSetupError::from)?;
    let mut projectors = Vec::with_capacity(projected.len());
    for p in projected {
        let d = &p.projector.device;
        check_size(&p.projector.name, p.value, d.width, d.height)?;
        projectors.push((
            DeviceRays::new(d).map_err(RenderSetupError::from)?,
            p.value,
            p.projector,
        ));
    }
    if let Some(m) = &mirror {
        check_size(&m.face.name, m.radiance, m.face.width, m.face.height)?;
    }
    let (w, h) = (eye.width, eye.height);
    let pixels: Vec<([Vec3; 3], SurfaceKey, bool)> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let (eye_rays, projectors) = (&eye_rays, &projectors);
            (0..w).map(move |x| {
                let Some(ray) = eye_rays.pixel_ray(x, y) else {
                    return ([Vec3::ZERO, Vec3::ZERO, Vec3::NAN], None, false);
                };
                // The pixel's own surface (its centre ray) decides what it
                // shows and its edge key; its radiance is the mean over
                // SUBSAMPLES x SUBSAMPLES rays across the pixel, as a
                // camera pixel integrates its footprint (point samples of
                // two pixel grids alias).
                let (centre_target, key) = match target_radiance(frame, occluders, &ray) {
                    Some((t, key)) => (Some(t), key),
                    None => (None, None),
                };
                let (_, reachable) = real_radiance(frame, &occluders.real_only, projectors, &ray);
                let (mut real, mut reflected, mut target) = (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO);
                let n = SUBSAMPLES * SUBSAMPLES;
                for k in 0..n {
                    let offset = DVec2::new(
                        ((k % SUBSAMPLES) as f64 + 0.5) / SUBSAMPLES as f64,
                        ((k / SUBSAMPLES) as f64 + 0.5) / SUBSAMPLES as f64,
                    );
                    let Some(sub) = eye_rays.ray_through(DVec2::new(x as f64, y as f64) + offset)
                    else {
                        continue;
                    };
                    real += real_radiance(frame, &occluders.real_only, projectors, &sub).0;
                    reflected += mirror
                        .and_then(|m| reflected_radiance(&m, &sub))
                        .unwrap_or(DVec3::ZERO);
                    target += target_radiance(frame, occluders, &sub).map_or(DVec3::ZERO, |t| t.0);
                }
                let scale = 1.0 / n as f64;
                let (real, reflected) = (real * scale, reflected * scale);
                let target = centre_target.map_or(Vec3::NAN, |_| (target * scale).as_vec3());
                (
                    [real.as_vec3(), reflected.as_vec3(), target],
                    key,
                    reachable,
                )
            })
        })
        .collect();
    let mut view = ObserverView {
        composite: Image::new(w, h, Vec3::ZERO),
        real: Image::new(w, h, Vec3::ZERO),
        reflected: Image::new(w, h, Vec3::ZERO),
        target: Image::new(w, h, Vec3::ZERO),
        covered: Image::new(w, h, false),
        sees_virtual: Image::new(w, h, false),
        sees_reflective: Image::new(w, h, false),
        first_object: Image::new(w, h, None),
        edge: Image::new(w, h, false),
        reachable: Image::new(w, h, false),
    };
    let mut keys = Image::new(w, h, None);
    for (i, ([real, reflected, target], key, reachable)) in pixels.into_iter().enumerate() {
        keys.data[i] = key;
        let seen = key.and_then(|(object, _, _)| frame.showcase.objects.get(object as usize));
        let virtual_ = seen.filter(|o| o.kind == ObjectKind::Virtual);
        view.first_object.data[i] = key.map(|(object, _, _)| object);
        view.sees_virtual.data[i] = virtual_.is_some();
        view.sees_reflective.data[i] = virtual_.is_some_and(|o| o.material.reflective);
        view.reachable.data[i] = reachable;
        view.real.data[i] = real;
        view.reflected.data[i] = reflected;
        view.composite.data[i] = real + reflected;
        view.covered.data[i] = !target.is_nan();
        view.target.data[i] = if target.is_nan() { Vec3::ZERO } else { target };
    }
    for y in 0..h {
        for x in 0..w {
            let k = keys.get(x, y).copied().flatten();
            let differs = |dx: i64, dy: i64| {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                nx >= 0
                    && ny >= 0
                    && keys
                        .get(nx as u32, ny as u32)
                        .is_some_and(|n| n.map(|n| (n.0, n.2)) != k.map(|k| (k.0, k.2)))
            };
            let on_edge = (-1..=1).any(|dy| (-1..=1).any(|dx| differs(dx, dy)));
            if let Some(e) = view.edge.get_mut(x, y) {
                *e = on_edge;
            }
        }
    }
    Ok(view)
}

fn check_size(what: &str, image: &RgbImage, dw: u32, dh: u32) -> Result<(), ObserverViewError> {
    if image.width != dw || image.height != dh {
        return Err(ObserverViewError::SizeMismatch {
            what: what.into(),
            width: image.width,
            height: image.height,
            dw,
            dh,
        });
    }
    Ok(())
}

/// The side of a hit surface facing the ray's origin.
fn facing_origin(normal: DVec3, ray: &Ray) -> DVec3 {
    if normal.dot(ray.direction) <= 0.0 {
        normal
    } else {
        -normal
    }
}

/// Radiance of the first real surface on `ray` under the projectors, and
/// whether any projector reaches that surface.
fn real_radiance(
    frame: &FrameScene,
    real_only: &SceneGeometry,
    projectors: &[(DeviceRays, &RgbImage, &Projector)],
    ray: &Ray,
) -> (DVec3, bool) {
    let Some(hit) = real_only.closest_hit(ray, 0.0, f64::INFINITY) else {
        return (DVec3::ZERO, false);
    };
    if hit.geometric_normal == DVec3::ZERO
        || real_only.object_kind(hit.object) != Some(ObjectKind::Real)
    {
        return (DVec3::ZERO, false);
    }
    let Some(object) = frame.showcase.objects.get(hit.object as usize) else {
        return (DVec3::ZERO, false);
    };
    let facing = facing_origin(hit.geometric_normal, ray);
    let rho = object
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    let mut e = DVec3::ZERO;
    let mut reachable = false;
    for (rays, value, projector) in projectors {
        // Light reaches the side the eye sees only from a projector on
        // that side (`sees` checks the side, the image and visibility).
        if !rays.sees(real_only, hit.point, facing) {
            continue;
        }
        reachable = true;
        let Some((px, py)) = rays.pixel_of(hit.point) else {
            continue;
        };
        let Some(v) = value.get(px, py) else {
            continue;
        };
        let j = emitted_intensity(v.as_dvec3(), &projector.response);
        let to = rays.center() - hit.point;
        let r2 = to.length_squared();
        e += j * (facing.dot(to) / r2.sqrt() / r2);
    }
    let l = rho / PI * e;
    (if l.is_finite() { l } else { DVec3::ZERO }, reachable)
}

/// Radiance of the CRT pixel the eye sees along `ray` via the mirror.
fn reflected_radiance(m: &MirrorImage<'_>, ray: &Ray) -> Option<DVec3> {
    let pixel = mirror_pixel(m.face, ray)?;
    m.radiance
        .get(pixel.x as u32, pixel.y as u32)
        .map(|c| c.as_dvec3())
}

/// The CRT pixel coordinates (continuous) that `ray` from an eye sees by
/// way of the face's mirror: the ray meets the mirror plane, is
/// reflected, and meets the screen. `None` when it misses the screen.
pub fn mirror_pixel(face: &CrtFace, ray: &Ray) -> Option<DVec2> {
    let n = face.mirror.normal.as_dvec3();
    let denom = n.dot(ray.direction);
    if denom == 0.0 {
        return None;
    }
    let t = (f64::from(face.mirror.offset) - n.dot(ray.origin)) / denom;
    if !(t > 0.0) {
        return None;
    }
    let at = ray.at(t);
    let dir = ray.direction - 2.0 * denom * n;
    let s = face.screen;
    let (origin, right, down) = (s.origin.as_dvec3(), s.right.as_dvec3(), s.down.as_dvec3());
    let sn = down.cross(right);
    let dd = sn.dot(dir);
    if dd == 0.0 {
        return None;
    }
    let ts = sn.dot(origin - at) / dd;
    if !(ts > 0.0) {
        return None;
    }
    let q = at + ts * dir - origin;
    // Solve q = a * right + b * down (least squares on the plane).
    let (rr, rd, dd2) = (right.dot(right), right.dot(down), down.dot(down));
    let det = rr * dd2 - rd * rd;
    if !(det > 0.0) {
        return None;
    }
    let (qr, qd) = (q.dot(right), q.dot(down));
    let a = (qr * dd2 - qd * rd) / det;
    let b = (qd * rr - qr * rd) / det;
    let pixel = DVec2::new(a * face.width as f64, b * face.height as f64);
    (pixel.x >= 0.0
        && pixel.y >= 0.0
        && pixel.x < face.width as f64
        && pixel.y < face.height as f64)
        .then_some(pixel)
}

/// Radiance of the first surface (real or virtual) on `ray` with all
/// lighting virtual, and the surface's key; `None` when the ray meets
/// nothing.
fn target_radiance(
    frame: &FrameScene,
    occluders: &Occluders,
    ray: &Ray,
) -> Option<(DVec3, SurfaceKey)> {
    let hit = occluders.all.closest_hit(ray, 0.0, f64::INFINITY)?;
    if hit.geometric_normal == DVec3::ZERO {
        return Some((DVec3::ZERO, None));
    }
    let object = frame.showcase.objects.get(hit.object as usize)?;
    let facing = facing_origin(hit.geometric_normal, ray);
    let rho = object
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    let (e, lit) = target_irradiance(frame, occluders, hit.point, facing);
    let l = if object.material.reflective && object.kind == ObjectKind::Virtual {
        // A mirror tinted by its albedo (render::cube_map's model), traced
        // exactly from the surface point: the cube map's single centre is
        // the approximation under test.
        let dir = reflect(ray.direction, facing);
        let from = hit.point + facing * 1e-6;
        rho * environment(frame, occluders, from, dir).0.as_dvec3()
    } else {
        rho / PI * e
    };
    Some((
        if l.is_finite() { l } else { DVec3::ZERO },
        Some((hit.object, hit.primitive, lit)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::face::reflected_pixel;
    use showcase_proto::{Plane, Rect3};

    /// The demo cabinet's front face (deploy/scenes/showcase.toml).
    fn face() -> CrtFace {
        CrtFace {
            name: "face-0".into(),
            screen: Rect3 {
                origin: Vec3::new(0.3125, 0.6696, 0.6402),
                right: Vec3::new(-0.625, 0.0, 0.0),
                down: Vec3::new(0.0, -0.25, 0.4330),
            },
            mirror: Plane::from_point_normal(
                Vec3::new(0.0, 0.0, 0.6),
                Vec3::new(0.0, 0.5, 0.866_025_4),
            ),
            width: 64,
            height: 48,
            gamma: 2.2,
        }
    }

    /// Every CRT pixel is found again along the eye's line of sight through
    /// its reflected position, whatever the eye: the composite reads the
    /// face image the way the mirror shows it.
    #[test]
    fn the_mirror_shows_each_crt_pixel_on_its_line_of_sight() {
        let face = face();
        let radiance = Image::from_fn(face.width, face.height, |x, y| {
            Vec3::new(x as f32, y as f32, 1.0)
        });
        let m = MirrorImage {
            face: &face,
            radiance: &radiance,
        };
        for eye in [
            DVec3::new(0.0, 0.45, 1.4),
            DVec3::new(0.3, 0.6, 1.2),
            DVec3::new(-0.2, 0.3, 1.6),
        ] {
            for (x, y) in [(0, 0), (63, 47), (10, 40), (32, 24), (50, 5)] {
                let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let seen = reflected_pixel(&face, centre);
                let ray = Ray::new(eye, (seen - eye).normalize());
                let got = reflected_radiance(&m, &ray);
                assert_eq!(
                    got,
                    Some(DVec3::new(x as f64, y as f64, 1.0)),
                    "eye {eye}, pixel ({x}, {y})"
                );
            }
        }
        // The face renderer's projection (mirror_view) draws a world point
        // at the pixel this lookup finds on the eye's ray to that point.
        for eye in [DVec3::new(0.0, 0.45, 1.4), DVec3::new(0.3, 0.6, 1.2)] {
            let view = crate::mirror_view::FaceView::new(&face, eye, 0.01, 10.0).unwrap();
            for world in [
                DVec3::new(-0.10, 0.045, 0.10),
                DVec3::new(0.10, 0.06, -0.10),
                DVec3::new(0.013, 0.021, 0.017),
            ] {
                let px = view.pixel(world, face.width, face.height).unwrap();
                let ray = Ray::new(eye, (world - eye).normalize());
                let got = reflected_radiance(&m, &ray);
                assert_eq!(
                    got,
                    Some(DVec3::new(px.x.floor(), px.y.floor(), 1.0)),
                    "eye {eye}, world {world}: renderer pixel {px}"
                );
            }
        }
        // A ray that misses the screen's image sees nothing.
        let ray = Ray::new(DVec3::new(0.0, 0.45, 1.4), DVec3::new(0.0, 1.0, 0.0));
        assert_eq!(reflected_radiance(&m, &ray), None);
    }
}
