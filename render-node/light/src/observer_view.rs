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
//!   mirror plane, is reflected, and meets the screen at a pixel (nearest
//!   pixel), which emits what the face's CRT makes of the drive value the
//!   face node sent it ([`CrtResponse::emit`](showcase_proto::CrtResponse::emit)).
//!
//! Besides the figures' usual masks ([`ObserverView::edge`],
//! [`ObserverView::reachable`]) the view marks what the method cannot
//! get right by design, for a comparable figure that leaves it out:
//! pixels next to a change of reachability ([`ObserverView::reach_edge`]),
//! occlusion shadows of other eyes that the mirror image cannot fill
//! ([`ObserverView::unfillable`]) and, given the projectors' edge masks,
//! surfaces lit by a projector pixel that straddles an edge
//! ([`projector_edge_pixels`]).
//!
//! The eye looks through the beam splitter of the face that serves it
//! ([`ObserverView::glass`]): it sees the real objects, and the target,
//! attenuated by the splitter's transmission, and the CRT by its
//! reflection (`T * real + R * CRT`). Without a face there is no glass.
//! [`crt_drive`] is the face node's side of the same boundary: its
//! radiance encoded as 8-bit drive values with its own photometric
//! profile.
//!
//! The **target** is the scene as if all lighting were virtual: the first
//! surface on the eye's ray, real or virtual, shaded `rho / pi * E` by the
//! virtual lights with every shadow (the irradiance the renderers aim
//! for, [`target_irradiance`]). A reflective virtual object is a mirror
//! tinted by its albedo, as the face view draws it
//! ([`crate::render::cube_map`]), but its reflection is traced exactly
//! from each surface point into the real environment: the cube map and
//! its distance-corrected lookup (texel resolution, what the map's centre
//! cannot see) are the approximation the target judges.
//!
//! [`complete`] is the physically complete counterpart of the composite's
//! real part and of the target: every bounce, from the simulated
//! showcase's path tracer.
//!
//! Pure: no IO, no GPU.

// `!(x > 0.0)` is deliberate: it is also true for NaN (as in `light`).
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::finite::finite_or_zero;
use crate::render::cube_map::{environment, reflect};
use crate::render::projector::{
    Occluders, device_intensity, in_occlusion_shadow, target_irradiance,
};
use crate::render::{FrameScene, RenderSetupError};
use crate::{DeviceRays, Image, Ray, RgbImage, SceneGeometry};
use glam::{DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;
use showcase_proto::{BeamSplitter, CrtFace, CrtPhotometry, ObjectKind, PinholeDevice, Projector};
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
    /// The CRT face, with its true photometry (its CRT turns the drive
    /// values into light, its splitter reflects and transmits).
    pub face: &'a CrtFace,
    /// The drive values the face node sent for this eye, face-sized
    /// ([`crt_drive`]).
    pub drive: &'a RgbImage,
}

/// Bits per channel of a CRT's drive values.
pub const CRT_DRIVE_BITS: u32 = 8;

/// A face node's radiance image as the drive values it sends its CRT:
/// encoded with the node's photometric profile `profile`
/// ([`CrtPhotometry::drive`]) and quantised to [`CRT_DRIVE_BITS`].
pub fn crt_drive(profile: &CrtPhotometry, radiance: &RgbImage) -> RgbImage {
    let levels = ((1u32 << CRT_DRIVE_BITS) - 1) as f32;
    Image {
        width: radiance.width,
        height: radiance.height,
        data: radiance
            .data
            .iter()
            .map(|l| (profile.drive(*l) * levels).round() / levels)
            .collect(),
    }
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
    /// All lighting virtual, seen through the same glass.
    pub target: RgbImage,
    /// The beam splitter the eye looks through: [`Self::real`] and
    /// [`Self::target`] carry its transmission, [`Self::reflected`] its
    /// reflection.
    pub glass: BeamSplitter,
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
    /// Pixels next to a change of [`Self::reachable`]: reachability is
    /// decided by the centre ray, but the pixel's radiance averages rays
    /// across it, some of which meet surfaces no projector reaches.
    pub reach_edge: Image<bool>,
    /// Pixels whose first surface is real and lies in another tracked
    /// eye's occlusion shadow (the projectors leave it dark) where the
    /// mirror image cannot fill it in: this eye's ray through the mirror
    /// misses the face's screen, or no face serves this eye.
    pub unfillable: Image<bool>,
    /// Pixels whose first surface is real and lies in another tracked
    /// eye's occlusion shadow, which this eye sees through the mirror: the
    /// face draws the real surface there (occluding occlusion shadows,
    /// paper section 5.4), next to the real surface itself.
    pub filled: Image<bool>,
}

impl ObserverView {
    /// The occluding-occlusion seams: covered pixels whose first surface
    /// is real, 2 to [`SEAM_REACH`] steps (8-connected, over such pixels
    /// only) from the border of [`Self::filled`], off the [`Self::edge`]s:
    /// the CRT's rendering of a real surface on one side, the real surface
    /// on the other, both sides marked. The border's own pixels (a real
    /// neighbour on the other side) are left out: their rays straddle it,
    /// so they mix the two sides' light whatever the photometry; and a
    /// virtual object's image between two pixels parts them.
    pub fn seams(&self) -> Image<bool> {
        let (w, h) = (self.filled.width, self.filled.height);
        let real = |x: i64, y: i64| -> Option<bool> {
            if x < 0 || y < 0 || x >= i64::from(w) || y >= i64::from(h) {
                return None;
            }
            let i = (y as u32 * w + x as u32) as usize;
            (self.covered.data[i] && !self.sees_virtual.data[i]).then_some(self.filled.data[i])
        };
        let steps = [
            (-1, -1),
            (0, -1),
            (1, -1),
            (-1, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ];
        // Breadth first from the border (step 1) over real pixels.
        let mut step = vec![u32::MAX; (w * h) as usize];
        let mut front = Vec::new();
        for y in 0..i64::from(h) {
            for x in 0..i64::from(w) {
                let Some(side) = real(x, y) else {
                    continue;
                };
                if steps
                    .iter()
                    .any(|(dx, dy)| real(x + dx, y + dy).is_some_and(|n| n != side))
                {
                    step[(y * i64::from(w) + x) as usize] = 1;
                    front.push((x, y));
                }
            }
        }
        for k in 2..=SEAM_REACH {
            let mut next = Vec::new();
            for (x, y) in front {
                for (dx, dy) in steps {
                    let (nx, ny) = (x + dx, y + dy);
                    if real(nx, ny).is_none() {
                        continue;
                    }
                    let s = &mut step[(ny * i64::from(w) + nx) as usize];
                    if *s == u32::MAX {
                        *s = k;
                        next.push((nx, ny));
                    }
                }
            }
            front = next;
        }
        Image {
            width: w,
            height: h,
            data: step
                .iter()
                .zip(&self.edge.data)
                .map(|(s, e)| (2..=SEAM_REACH).contains(s) && !e)
                .collect(),
        }
    }
}

/// How far from an occluding-occlusion border [`ObserverView::seams`]
/// reaches, in pixels.
pub const SEAM_REACH: u32 = 4;

/// The target's first surface on a pixel's ray: object, triangle and the
/// light samples reaching it.
type SurfaceKey = Option<(u32, u32, u64)>;

/// Why a view cannot be simulated.
#[derive(Debug, thiserror::Error)]
pub enum ObserverViewError {
    /// The scene or a device cannot be set up.
    #[error(transparent)]
    Setup(#[from] RenderSetupError),
    /// The simulated showcase cannot set up the complete view.
    #[error("simulated showcase: {0}")]
    Sim(#[from] crate::sim::SimError),
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
        check_size(&m.face.name, m.drive, m.face.width, m.face.height)?;
    }
    let (w, h) = (eye.width, eye.height);
    // The eyes whose occlusion shadows the projectors leave dark: every
    // tracked eye but this one.
    let others: Vec<DVec3> = frame
        .eyes
        .iter()
        .copied()
        .filter(|e| (*e - eye_rays.center()).length() > 1e-9)
        .collect();
    let glass = mirror.map_or(BeamSplitter::IDEAL, |m| m.face.photometry.splitter);
    let (t, r) = (glass.transmission.as_dvec3(), glass.reflection.as_dvec3());
    let pixels: Vec<([Vec3; 3], SurfaceKey, bool, Option<bool>)> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let (eye_rays, projectors, others) = (&eye_rays, &projectors, &others);
            (0..w).map(move |x| {
                let Some(ray) = eye_rays.pixel_ray(x, y) else {
                    return ([Vec3::ZERO, Vec3::ZERO, Vec3::NAN], None, false, None);
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
                let fill = occlusion_fill(frame, occluders, others, mirror.as_ref(), &ray);
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
                let (real, reflected) = (real * scale * t, reflected * scale * r);
                let target = centre_target.map_or(Vec3::NAN, |_| (target * scale * t).as_vec3());
                (
                    [real.as_vec3(), reflected.as_vec3(), target],
                    key,
                    reachable,
                    fill,
                )
            })
        })
        .collect();
    let mut view = ObserverView {
        composite: Image::new(w, h, Vec3::ZERO),
        real: Image::new(w, h, Vec3::ZERO),
        reflected: Image::new(w, h, Vec3::ZERO),
        target: Image::new(w, h, Vec3::ZERO),
        glass,
        covered: Image::new(w, h, false),
        sees_virtual: Image::new(w, h, false),
        sees_reflective: Image::new(w, h, false),
        first_object: Image::new(w, h, None),
        edge: Image::new(w, h, false),
        reachable: Image::new(w, h, false),
        reach_edge: Image::new(w, h, false),
        unfillable: Image::new(w, h, false),
        filled: Image::new(w, h, false),
    };
    let mut keys = Image::new(w, h, None);
    for (i, ([real, reflected, target], key, reachable, fill)) in pixels.into_iter().enumerate() {
        view.unfillable.data[i] = fill == Some(false);
        view.filled.data[i] = fill == Some(true);
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
    view.reach_edge = next_to_change(&view.reachable);
    Ok(view)
}

/// Pixels with a 3x3 neighbour whose value differs from their own.
pub fn next_to_change(mask: &Image<bool>) -> Image<bool> {
    Image::from_fn(mask.width, mask.height, |x, y| {
        let here = mask.get(x, y).copied().unwrap_or(false);
        (-1i64..=1).any(|dy| {
            (-1i64..=1).any(|dx| {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                nx >= 0 && ny >= 0 && mask.get(nx as u32, ny as u32).is_some_and(|n| *n != here)
            })
        })
    })
}

/// True when `ray`'s first surface is real, lies in the occlusion shadow
/// of one of `other_eyes`, and the mirror image cannot show it (no face,
/// or the ray through the mirror misses the screen).
fn occlusion_fill(
    frame: &FrameScene,
    occluders: &Occluders,
    other_eyes: &[DVec3],
    mirror: Option<&MirrorImage<'_>>,
    ray: &Ray,
) -> Option<bool> {
    let hit = occluders.all.closest_hit(ray, 0.0, f64::INFINITY)?;
    let real = frame
        .showcase
        .objects
        .get(hit.object as usize)
        .is_some_and(|o| o.kind == ObjectKind::Real);
    let shadowed = real
        && hit.geometric_normal != DVec3::ZERO
        && in_occlusion_shadow(
            &occluders.virtual_only,
            other_eyes,
            hit.point,
            hit.facing_normal(ray.direction),
        );
    shadowed.then(|| mirror.is_some_and(|m| mirror_pixel(m.face, ray).is_some()))
}

/// The eye pixels whose first real surface some projector lights from a
/// pixel marked in that projector's `edges` (for example
/// [`crate::render::projector::edge_mask`] of the map it showed: one
/// projector pixel cannot be right on both sides of a silhouette, shadow
/// or occlusion-shadow edge). Each entry pairs a projector (its true
/// device: which pixel physically lights a point) with its edge mask.
pub fn projector_edge_pixels(
    occluders: &Occluders,
    eye: &PinholeDevice,
    projectors: &[(&Projector, &Image<bool>)],
) -> Result<Image<bool>, ObserverViewError> {
    let eye_rays = DeviceRays::new(eye).map_err(RenderSetupError::from)?;
    let mut rays = Vec::with_capacity(projectors.len());
    for (p, edges) in projectors {
        let d = &p.device;
        if edges.width != d.width || edges.height != d.height {
            return Err(ObserverViewError::SizeMismatch {
                what: format!("{} edge mask", p.name),
                width: edges.width,
                height: edges.height,
                dw: d.width,
                dh: d.height,
            });
        }
        rays.push((DeviceRays::new(d).map_err(RenderSetupError::from)?, *edges));
    }
    let (w, h) = (eye.width, eye.height);
    let data: Vec<bool> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let (eye_rays, rays) = (&eye_rays, &rays);
            (0..w).map(move |x| {
                let Some(ray) = eye_rays.pixel_ray(x, y) else {
                    return false;
                };
                let Some(hit) = occluders.real_only.closest_hit(&ray, 0.0, f64::INFINITY) else {
                    return false;
                };
                if hit.geometric_normal == DVec3::ZERO {
                    return false;
                }
                let facing = hit.facing_normal(ray.direction);
                rays.iter().any(|(r, edges)| {
                    r.sees(&occluders.real_only, hit.point, facing)
                        && r.pixel_of(hit.point)
                            .is_some_and(|(px, py)| edges.get(px, py).copied().unwrap_or(false))
                })
            })
        })
        .collect();
    Ok(Image {
        width: w,
        height: h,
        data,
    })
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
    let facing = hit.facing_normal(ray.direction);
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
        // The device's own light (the simulated showcase's truth).
        let j = device_intensity(v.as_dvec3(), &projector.response);
        let to = rays.center() - hit.point;
        let r2 = to.length_squared();
        e += j * (facing.dot(to) / r2.sqrt() / r2);
    }
    let l = rho / PI * e;
    (finite_or_zero(l), reachable)
}

/// Radiance of the CRT pixel the eye sees along `ray` via the mirror.
fn reflected_radiance(m: &MirrorImage<'_>, ray: &Ray) -> Option<DVec3> {
    let pixel = mirror_pixel(m.face, ray)?;
    m.drive
        .get(pixel.x as u32, pixel.y as u32)
        .map(|d| m.face.photometry.crt.emit(*d).as_dvec3())
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
    let facing = hit.facing_normal(ray.direction);
    let rho = object
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    let (e, lit) = target_irradiance(frame, occluders, hit.point, facing);
    let l = if object.material.reflective && object.kind == ObjectKind::Virtual {
        // A mirror tinted by its albedo (render::cube_map's model), traced
        // exactly from the surface point: the cube map's distance-corrected
        // lookup is the approximation under test.
        let dir = reflect(ray.direction, facing);
        let from = hit.point + facing * 1e-6;
        rho * environment(frame, occluders, from, dir).0.as_dvec3()
    } else {
        rho / PI * e
    };
    Some((finite_or_zero(l), Some((hit.object, hit.primitive, lit))))
}

pub mod complete;
pub mod photometer;

#[cfg(test)]
mod tests;
