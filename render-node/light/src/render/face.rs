//! The face role's CPU reference (paper sections 5.1 and 5.2): what one
//! eye sees of the virtual objects through a CRT face and its beam
//! splitter. Implemented here: virtual objects shaded by the virtual
//! lights (`rho / pi * E`, radiance in W/m^2/sr, flat normals, two-sided)
//! with shadow types 2 and 3 (virtual objects and real phantoms occlude
//! the lights), the ambient term in shadows, and phantom depth (a pixel
//! whose first surface is a real phantom stays black: the real object is
//! seen through the mirror), except inside the occlusion shadows of the
//! other tracked eyes (other observers', and in stereo the observer's own
//! other eye, whose shadow lies beside what this eye sees of a virtual
//! object): there the real surface is dark (the projector leaves it
//! unlit for them), so this eye is shown the lit reflectance map instead,
//! `rho / pi * E` of the real surface under the virtual lights (occluding
//! occlusion shadows, paper section 5.4; the GPU does per fragment what
//! the paper's stencil pass does). A reflective virtual object shows its
//! cube map of the real environment instead of its diffuse shading
//! (paper section 5.3, [`super::cube_map`]): `rho * C(p, reflect(d, n))`
//! for the surface point `p`, the eye's ray direction `d` and the flat
//! normal `n` facing the eye, `C` the distance-corrected lookup
//! ([`CubeMap::reflection_direction`]).
//!
//! In global mode ([`FrameScene::indirect`]) every diffuse surface drawn
//! adds the field to `E`: on a virtual object its indirect light from
//! the real room and the other virtual objects, on a real surface in an
//! occluding occlusion shadow what the target's indirect light has beyond
//! the real surfaces' own interreflection, which still reaches the dark
//! surface in the cabinet ([`crate::radiosity::augmented::indirect_correction`]).
//! That interreflection also lights the real surface behind a virtual
//! object, inside the eye's occlusion shadow, and the observer sees it
//! through the mirror: the face shows the virtual object less it
//! (`real_seen_through`), clipped at black.
//!
//! Pixel `(u, v)` of the CRT is drawn at its centre: the eye's ray goes
//! through the pixel centre's *reflected* position (`mirror_view`), so a
//! drawn point lies on the line of sight through its reflection.

use super::RenderSetupError;
use super::cube_map::{CubeMap, DEFAULT_CUBE_RES, cube_maps_cpu, reflect};
use super::frame::FrameScene;
use super::projector::{Occluders, PixelState, in_occlusion_shadow, target_irradiance};
use crate::finite::finite_or_zero;
use crate::{Image, Ray, RgbImage};
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

/// The eyes whose occlusion shadows eye `k` of `eyes` (one observer's
/// eyes) fills in: every other observer's eye (`other_observers`) and the
/// observer's own other eye(s), whose shadows lie beside the virtual
/// objects this eye sees (the GPU pass uses the same set).
pub fn eyes_to_fill(eyes: &[DVec3], k: usize, other_observers: &[DVec3]) -> Vec<DVec3> {
    other_observers
        .iter()
        .copied()
        .chain(
            eyes.iter()
                .enumerate()
                .filter(|(i, _)| *i != k)
                .map(|(_, e)| *e),
        )
        .collect()
}

/// Render what the eye at `eye` sees through `face` on the CPU;
/// `other_eyes` are the other tracked eyes whose occlusion shadows this
/// view fills in ([`eyes_to_fill`]). Reflective objects use cube maps of
/// [`DEFAULT_CUBE_RES`] texels per side.
pub fn face_image_cpu(
    frame: &FrameScene,
    occluders: &Occluders,
    face: &CrtFace,
    eye: DVec3,
    other_eyes: &[DVec3],
) -> Result<FaceImage, RenderSetupError> {
    let cube_maps = cube_maps_cpu(frame, occluders, DEFAULT_CUBE_RES)?;
    face_image_cpu_with(frame, occluders, face, eye, other_eyes, &cube_maps)
}

/// [`face_image_cpu`] with the reflective objects' cube maps given (from
/// [`super::cube_map::cube_maps_cpu`]); a reflective object without one
/// is shaded diffuse.
pub fn face_image_cpu_with(
    frame: &FrameScene,
    occluders: &Occluders,
    face: &CrtFace,
    eye: DVec3,
    other_eyes: &[DVec3],
    cube_maps: &[CubeMap],
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
                face_pixel(frame, occluders, cube_maps, eye, other_eyes, target)
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
    cube_maps: &[CubeMap],
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
    let facing = hit.facing_normal(dir);
    let occluded = o.kind == ObjectKind::Real
        && in_occlusion_shadow(&occluders.virtual_only, other_eyes, hit.point, facing);
    if o.kind == ObjectKind::Real && !occluded {
        return (Vec3::ZERO, PixelState { object, ..masked });
    }
    let state = PixelState {
        object,
        primitive: Some(hit.primitive),
        occluded,
        ..PixelState::default()
    };
    // What the real surface behind a virtual object shows through it.
    let seen_through = || match o.kind {
        ObjectKind::Virtual => real_seen_through(frame, occluders, &ray),
        ObjectKind::Real => DVec3::ZERO,
    };
    if let Some(map) = cube_maps.iter().find(|m| m.object == hit.object as usize) {
        let r = map.reflection_direction(hit.point, reflect(dir, facing));
        let rho = o.material.albedo_at(hit.uv.unwrap_or(Vec2::ZERO));
        let l = (rho * map.sample(r)).as_dvec3() - seen_through();
        // Edges of the reflected environment are edges of this view.
        let lit = reflected_state(map, r);
        return (
            finite_or_zero(l.max(DVec3::ZERO)).as_vec3(),
            PixelState { lit, ..state },
        );
    }
    let (mut e, lit) = target_irradiance(frame, occluders, hit.point, facing);
    if let Some(field) = &frame.indirect {
        e += field.at(&hit).add;
    }
    let rho = o
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    let l = rho / std::f64::consts::PI * e - seen_through();
    (
        finite_or_zero(l.max(DVec3::ZERO)).as_vec3(),
        PixelState { lit, ..state },
    )
}

/// In global mode, the radiance of the first real surface along `ray`
/// (from the eye, through a virtual object): in the cabinet the
/// projectors leave it dark for this eye (its occlusion shadow), but the
/// real surfaces' own interreflection still lights it, `rho / pi *
/// cabinet`, and the observer sees it through the half-silvered mirror
/// where the CRT shows the virtual object. The face shows the virtual
/// object less this (never below black: a CRT adds light only). Zero in
/// direct mode, where the real surfaces are taken to reflect no light of
/// their own.
fn real_seen_through(frame: &FrameScene, occluders: &Occluders, ray: &Ray) -> DVec3 {
    let Some(field) = &frame.indirect else {
        return DVec3::ZERO;
    };
    let Some(hit) = occluders.real_only.closest_hit(ray, 0.0, f64::INFINITY) else {
        return DVec3::ZERO;
    };
    let Some(o) = frame.showcase.objects.get(hit.object as usize) else {
        return DVec3::ZERO;
    };
    let rho = o
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    finite_or_zero(rho / std::f64::consts::PI * field.at(&hit).cabinet)
}

/// A digest of the states of the four texels a reflected sample along
/// `d` from the map's centre blends (their objects and lit samples), standing in for `lit` of a
/// reflective pixel: where it changes between neighbouring pixels, the
/// reflection crosses a silhouette or shadow edge of the environment.
fn reflected_state(map: &CubeMap, d: DVec3) -> u64 {
    let (face, c) = super::cube_map::world_to_face(d);
    if !(c.z > 0.0) {
        return 0;
    }
    let res = f64::from(map.res);
    let fx = ((c.x / c.z) * 0.5 + 0.5) * res - 0.5;
    let fy = (0.5 - (c.y / c.z) * 0.5) * res - 0.5;
    let mut h = crate::digest::Fnv64::default();
    for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        let x = (fx.floor() + dx).clamp(0.0, res - 1.0) as u32;
        let y = (fy.floor() + dy).clamp(0.0, res - 1.0) as u32;
        if let Some(s) = map.state.get(face).and_then(|st| st.get(x, y)) {
            h.write(&s.object.map_or(u64::MAX, u64::from).to_le_bytes());
            h.write(&s.lit.to_le_bytes());
        }
    }
    h.finish()
}
