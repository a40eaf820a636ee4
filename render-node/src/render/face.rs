//! The face role's CPU reference (paper sections 5.1 and 5.2): what one
//! eye sees of the virtual objects through a CRT face and its beam
//! splitter. Implemented here: virtual objects shaded by the virtual
//! lights (`rho / pi * E`, radiance in W/m^2/sr, flat normals, two-sided)
//! with shadow types 2 and 3 (virtual objects and real phantoms occlude
//! the lights), the ambient term in shadows, and phantom depth (a pixel
//! whose first surface is a real phantom stays black: the real object is
//! seen through the mirror), except inside other observers' occlusion
//! shadows: there the real surface is dark (the projector leaves it
//! unlit for them), so this eye is shown the lit reflectance map instead,
//! `rho / pi * E` of the real surface under the virtual lights (occluding
//! occlusion shadows, paper section 5.4; the GPU does per fragment what
//! the paper's stencil pass does). Not yet implemented: cube-map
//! reflections (paper section 5.3).
//!
//! Pixel `(u, v)` of the CRT is drawn at its centre: the eye's ray goes
//! through the pixel centre's *reflected* position (`mirror_view`), so a
//! drawn point lies on the line of sight through its reflection.

use super::RenderSetupError;
use super::frame::FrameScene;
use super::projector::{Occluders, PixelState, in_occlusion_shadow, target_irradiance};
use crate::light::{Image, Ray, RgbImage};
use glam::{DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;
use showcase_proto::{CrtFace, ObjectKind};

/// One eye's view through a face.
#[derive(Clone, Debug)]
pub struct FaceImage {
    /// Linear radiance drawn on the CRT (0 where nothing virtual is seen).
    pub radiance: RgbImage,
    /// Per-pixel state: `object` is the first surface's object, `lit` the
    /// light samples reaching it, `occluded` set on a phantom filled in
    /// for another observer's occlusion shadow, `masked` set for
    /// background and phantoms left black.
    pub state: Image<PixelState>,
}

/// The reflected position of CRT pixel coordinate `pixel` (continuous).
pub fn reflected_pixel(face: &CrtFace, pixel: DVec2) -> DVec3 {
    let p = crate::mirror_view::screen_point(face, pixel);
    let n = face.mirror.normal.as_dvec3();
    p - 2.0 * (n.dot(p) - f64::from(face.mirror.offset)) * n
}

/// Render what the eye at `eye` sees through `face` on the CPU;
/// `other_eyes` are the eyes of the other observers, whose occlusion
/// shadows this view fills in.
pub fn face_image_cpu(
    frame: &FrameScene,
    occluders: &Occluders,
    face: &CrtFace,
    eye: DVec3,
    other_eyes: &[DVec3],
) -> Result<FaceImage, RenderSetupError> {
    if !eye.is_finite() {
        return Err(RenderSetupError::NonFinite);
    }
    let (w, h) = (face.width, face.height);
    let pixels: Vec<(Vec3, PixelState)> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).map(move |x| {
                let target = reflected_pixel(face, DVec2::new(x as f64 + 0.5, y as f64 + 0.5));
                face_pixel(frame, occluders, eye, other_eyes, target)
            })
        })
        .collect();
    let mut radiance = Image::new(w, h, Vec3::ZERO);
    let mut state = Image::new(w, h, PixelState::default());
    for (i, (r, s)) in pixels.into_iter().enumerate() {
        radiance.data[i] = r;
        state.data[i] = s;
    }
    Ok(FaceImage { radiance, state })
}

fn face_pixel(
    frame: &FrameScene,
    occluders: &Occluders,
    eye: DVec3,
    other_eyes: &[DVec3],
    through: DVec3,
) -> (Vec3, PixelState) {
    let masked = PixelState {
        masked: true,
        ..PixelState::default()
    };
    let dir = (through - eye).normalize_or_zero();
    if dir == DVec3::ZERO || !dir.is_finite() {
        return (Vec3::ZERO, masked);
    }
    let ray = Ray::new(eye, dir);
    let Some(hit) = occluders.all.closest_hit(&ray, 0.0, f64::INFINITY) else {
        return (Vec3::ZERO, masked);
    };
    let object = Some(hit.object);
    let Some(o) = frame.showcase.objects.get(hit.object as usize) else {
        return (Vec3::ZERO, masked);
    };
    if hit.geometric_normal == DVec3::ZERO {
        return (Vec3::ZERO, PixelState { object, ..masked });
    }
    let facing = if hit.geometric_normal.dot(dir) <= 0.0 {
        hit.geometric_normal
    } else {
        -hit.geometric_normal
    };
    let occluded = o.kind == ObjectKind::Real
        && in_occlusion_shadow(&occluders.virtual_only, other_eyes, hit.point, facing);
    if o.kind == ObjectKind::Real && !occluded {
        return (Vec3::ZERO, PixelState { object, ..masked });
    }
    let (e, lit) = target_irradiance(frame, occluders, hit.point, facing);
    let rho = o
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    let l = rho / std::f64::consts::PI * e;
    (
        if l.is_finite() {
            l.as_vec3()
        } else {
            Vec3::ZERO
        },
        PixelState {
            object,
            primitive: Some(hit.primitive),
            lit,
            occluded,
            ..PixelState::default()
        },
    )
}
