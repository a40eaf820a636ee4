//! The projector role's CPU reference (paper sections 5.1 and 5.2): the
//! irradiance map `L` of one projector, with shadow types 4 and 5, the
//! ambient term, every observer's occlusion shadows, and device
//! compensation.
//!
//! # What `L` is, in units
//! A projector pixel whose value is `v` emits the radiant intensity
//! `J(v) = eta * v^gamma + black_level` (W/sr per channel,
//! `ProjectorResponse`) along its ray. A surface point `p` that the pixel
//! reaches at distance `r`, at angle `theta_p` to the (two-sided, flat)
//! surface normal, then receives the irradiance `J cos(theta_p) / r^2`.
//! That factor is the intensity image of equation 3.1 with `D_l = 1` and
//! `D_m = 1`: `I_int_projector = cos(theta_p) / r^2` (1/m^2).
//! The virtual lighting asks for the target irradiance `E(p)` (W/m^2): the
//! sum over every light sample of `I(dir) cos(theta) / r^2` where the
//! sample reaches `p` (real phantoms and virtual objects both occlude:
//! shadow types 4 and 5), plus the scene's ambient irradiance, which is
//! therefore what remains inside shadows. So
//!
//! `L = E(p) / I_int_projector(p)` in W/sr,
//!
//! the radiant intensity the pixel must emit; equation 5.1 with `D_m = 1`
//! (the reflectance cancels, as the paper shows). Pixels in an observer's
//! occlusion shadow have `L = 0`.
//!
//! # Floor (DESIGN section 8)
//! The quotient is taken only where `cos(theta_p) >= COS_FLOOR`; pixels
//! below it (grazing) and pixels that see no real surface are `L = 0`,
//! value 0, and are *masked*: not counted in the clipped fraction.
//!
//! # Device compensation
//! `v = clamp(((L - black_level) / eta)^(1/gamma), 0, 1)` per channel.
//! A pixel is *clipped* when any channel needed `L < black_level` or
//! `L > eta + black_level` (beyond [`CLIP_TOLERANCE`] relative), and the
//! clipped fraction is clipped pixels over unmasked surface pixels.
//! DLP colour-wheel slicing is not compensated: the eye integrates a whole
//! wheel turn per frame.

use super::RenderSetupError;
use super::blend::Blend;
use super::frame::FrameScene;
use crate::finite::finite_or_zero;
use crate::{DeviceRays, Image, ObjectFilter, RgbImage, SceneGeometry};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use showcase_proto::{ObjectKind, Projector, ProjectorResponse};

/// Smallest `cos(theta_p)` at which `L` is computed (about 88.9 degrees).
pub const COS_FLOOR: f64 = 0.02;

/// Relative slack before a value outside the device range counts as
/// clipped (rounding of an exact fit is not clipping).
pub const CLIP_TOLERANCE: f64 = 1e-6;

/// The light-blocking geometry of a frame.
#[derive(Clone, Debug)]
pub struct Occluders {
    /// Real phantoms and virtual objects: they occlude virtual lights.
    pub all: SceneGeometry,
    /// Virtual objects only: they cast occlusion shadows.
    pub virtual_only: SceneGeometry,
    /// Real phantoms only: what projectors light and cameras see.
    pub real_only: SceneGeometry,
}

impl Occluders {
    /// Build the three geometries of `frame`.
    pub fn new(frame: &FrameScene) -> Result<Self, RenderSetupError> {
        Ok(Self {
            all: frame.geometry(&ObjectFilter::All)?,
            virtual_only: frame.geometry(&ObjectFilter::Virtual)?,
            real_only: frame.geometry(&ObjectFilter::Real)?,
        })
    }
}

/// Target irradiance `E(p)` (W/m^2) at surface point `point` with unit
/// normal `facing` (the side being lit), and which light samples reach it
/// (bit `i` for sample `i < 64`). Ambient is included.
pub fn target_irradiance(
    frame: &FrameScene,
    occluders: &Occluders,
    point: DVec3,
    facing: DVec3,
) -> (DVec3, u64) {
    let mut e = frame.ambient();
    let mut lit = 0u64;
    for (i, s) in frame.samples.iter().enumerate() {
        let to_light = s.position - point;
        let r2 = to_light.length_squared();
        if !(r2 > 0.0) {
            continue;
        }
        let l = to_light / r2.sqrt();
        let cos_theta = facing.dot(l);
        if !(cos_theta > 0.0) || !occluders.all.visible(point, facing, s.position, false) {
            continue;
        }
        if i < 64 {
            lit |= 1 << i;
        }
        e += s.intensity_towards(-l) * (cos_theta / r2);
    }
    (finite_or_zero(e), lit)
}

/// True when a virtual object lies between `point` and one of `eyes` that
/// is on the `facing` side: the point is in that observer's occlusion
/// shadow.
pub fn in_occlusion_shadow(
    virtual_only: &SceneGeometry,
    eyes: &[DVec3],
    point: DVec3,
    facing: DVec3,
) -> bool {
    eyes.iter().any(|&eye| {
        facing.dot(eye - point) > 0.0 && !virtual_only.visible(point, facing, eye, false)
    })
}

/// Device compensation of one pixel: the value that makes the projector
/// emit `l` (W/sr per channel), clamped to `0..=1`, and whether any
/// channel was clipped.
pub fn compensate(l: DVec3, response: &ProjectorResponse) -> (DVec3, bool) {
    let eta = f64::from(response.eta);
    let black = f64::from(response.black_level);
    let gamma = f64::from(response.gamma);
    if !(eta > 0.0 && gamma > 0.0 && black.is_finite() && eta.is_finite() && gamma.is_finite()) {
        return (DVec3::ZERO, true);
    }
    let mut clipped = false;
    let value = DVec3::from_array(l.to_array().map(|c| {
        let linear = (c - black) / eta;
        let slack = CLIP_TOLERANCE * (1.0 + black / eta);
        if !(linear >= -slack && linear <= 1.0 + slack) {
            clipped = true;
        }
        let v = linear.clamp(0.0, 1.0).powf(1.0 / gamma);
        finite_or_zero(v)
    }));
    (value, clipped)
}

/// The radiant intensity (W/sr) a projector emits for pixel value `value`:
/// `eta * value^gamma + black_level` per channel.
pub fn emitted_intensity(value: DVec3, response: &ProjectorResponse) -> DVec3 {
    let gamma = f64::from(response.gamma);
    let j = DVec3::from_array(
        value
            .to_array()
            .map(|v| f64::from(response.eta) * v.clamp(0.0, 1.0).powf(gamma)),
    ) + f64::from(response.black_level);
    finite_or_zero(j)
}

/// The radiant intensity (W/sr) a projector device emits at device values
/// `value`: its per-channel photometry where it has one
/// ([`ProjectorResponse::light`]), else the model ([`emitted_intensity`],
/// the same numbers).
pub fn device_intensity(value: DVec3, response: &ProjectorResponse) -> DVec3 {
    if response.photometry.is_none() {
        return emitted_intensity(value, response);
    }
    finite_or_zero(response.light(value.as_vec3()).as_dvec3())
}

/// What produced a pixel of the map; neighbouring pixels whose states
/// differ lie on a silhouette or shadow edge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PixelState {
    /// The real object the pixel lights, if any.
    pub object: Option<u32>,
    /// The triangle it lights (`SceneGeometry` numbering), if any.
    pub primitive: Option<u32>,
    /// Bit `i`: light sample `i` reaches the point.
    pub lit: u64,
    /// In some observer's occlusion shadow.
    pub occluded: bool,
    /// Below the floor or no surface: `L = 0`, not counted.
    pub masked: bool,
    /// Some channel's value was clamped.
    pub clipped: bool,
}

/// A projector's irradiance map and its device values.
#[derive(Clone, Debug)]
pub struct IrradianceMap {
    /// `L`, W/sr per channel (module docs).
    pub irradiance: RgbImage,
    /// Compensated pixel values in `0..=1`.
    pub value: RgbImage,
    /// Per-pixel state.
    pub state: Image<PixelState>,
    /// Clipped pixels over unmasked pixels (0 when there are none).
    pub clipped_fraction: f64,
}

/// What the projector map includes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProjectorOptions {
    /// Shadow types 4 and 5 (off: every light reaches every facing point).
    pub shadows: bool,
    /// Occlusion shadows of the frame's eyes.
    pub occlusion: bool,
    /// Share the light with the scene's other projectors where they
    /// overlap ([`super::blend`]); off, this projector alone delivers the
    /// whole target everywhere it reaches.
    pub blend: bool,
}

impl Default for ProjectorOptions {
    fn default() -> Self {
        Self {
            shadows: true,
            occlusion: true,
            blend: true,
        }
    }
}

/// Render `projector`'s irradiance map of `frame` on the CPU: one ray per
/// pixel centre onto the real phantoms, shadows by visibility rays.
pub fn irradiance_map_cpu(
    frame: &FrameScene,
    occluders: &Occluders,
    projector: &Projector,
    options: ProjectorOptions,
) -> Result<IrradianceMap, RenderSetupError> {
    let rays = DeviceRays::new(&projector.device)?;
    let (w, h) = (projector.device.width, projector.device.height);
    let unshadowed;
    let occ = if options.shadows {
        occluders
    } else {
        // No occluder at all: an empty geometry for the light tests.
        unshadowed = Occluders {
            all: SceneGeometry::build(&frame.showcase, &ObjectFilter::Indices(Vec::new()))?,
            virtual_only: occluders.virtual_only.clone(),
            real_only: occluders.real_only.clone(),
        };
        &unshadowed
    };
    let blend = match super::blend::index_of(&frame.showcase.projectors, projector) {
        Some(i) if options.blend && frame.showcase.projectors.len() > 1 => {
            Some((Blend::new(&frame.showcase.projectors)?, i))
        }
        _ => None,
    };
    let pixels: Vec<(Vec3, Vec3, PixelState)> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let (rays, blend) = (&rays, &blend);
            (0..w).map(move |x| {
                let (l, state) = pixel_irradiance(frame, occ, rays, options, blend, x, y);
                let (value, clipped) = if state.masked {
                    (DVec3::ZERO, false)
                } else {
                    compensate(l, &projector.response)
                };
                (
                    l.as_vec3(),
                    value.as_vec3(),
                    PixelState { clipped, ..state },
                )
            })
        })
        .collect();
    let mut irradiance = Image::new(w, h, Vec3::ZERO);
    let mut value = Image::new(w, h, Vec3::ZERO);
    let mut state = Image::new(w, h, PixelState::default());
    for (i, (l, v, s)) in pixels.into_iter().enumerate() {
        irradiance.data[i] = l;
        value.data[i] = v;
        state.data[i] = s;
    }
    let counted = state.data.iter().filter(|s| !s.masked).count();
    let clipped = state.data.iter().filter(|s| s.clipped).count();
    Ok(IrradianceMap {
        irradiance,
        value,
        state,
        clipped_fraction: if counted == 0 {
            0.0
        } else {
            clipped as f64 / counted as f64
        },
    })
}

fn pixel_irradiance(
    frame: &FrameScene,
    occluders: &Occluders,
    rays: &DeviceRays,
    options: ProjectorOptions,
    blend: &Option<(Blend, usize)>,
    x: u32,
    y: u32,
) -> (DVec3, PixelState) {
    let masked = PixelState {
        masked: true,
        ..PixelState::default()
    };
    let Some(ray) = rays.pixel_ray(x, y) else {
        return (DVec3::ZERO, masked);
    };
    let Some(hit) = occluders.real_only.closest_hit(&ray, 0.0, f64::INFINITY) else {
        return (DVec3::ZERO, masked);
    };
    if occluders.real_only.object_kind(hit.object) != Some(ObjectKind::Real)
        || hit.geometric_normal == DVec3::ZERO
    {
        return (DVec3::ZERO, masked);
    }
    let facing = hit.facing_normal(ray.direction);
    let object = Some(hit.object);
    let primitive = Some(hit.primitive);
    let cos_p = -facing.dot(ray.direction);
    let r2 = hit.t * hit.t;
    if !(cos_p >= COS_FLOOR && r2 > 0.0) {
        return (
            DVec3::ZERO,
            PixelState {
                object,
                primitive,
                ..masked
            },
        );
    }
    let occluded = options.occlusion
        && in_occlusion_shadow(&occluders.virtual_only, &frame.eyes, hit.point, facing);
    if occluded {
        return (
            DVec3::ZERO,
            PixelState {
                object,
                primitive,
                occluded,
                ..PixelState::default()
            },
        );
    }
    let (mut e, lit) = target_irradiance(frame, occluders, hit.point, facing);
    if let Some(field) = &frame.indirect {
        e += field.at(&hit).add;
    }
    let share = blend.as_ref().map_or(1.0, |(b, i)| {
        b.weight(*i, &occluders.real_only, hit.point, facing)
    });
    let l = e * (share * r2 / cos_p);
    (
        finite_or_zero(l),
        PixelState {
            object,
            primitive,
            lit,
            ..PixelState::default()
        },
    )
}

/// Pixels within `radius` pixels (Chebyshev) of a pixel whose state
/// differs from its neighbour's (ignoring `clipped`): silhouette, shadow
/// and occlusion-shadow edges, where a shadow map and a ray may disagree;
/// with `facets`, also edges between triangles (normal discontinuities of
/// the flat phantom, where one projector pixel cannot suit both sides).
pub fn edge_mask(state: &Image<PixelState>, radius: u32, facets: bool) -> Image<bool> {
    let key = |s: &PixelState| {
        (
            s.object,
            s.lit,
            s.occluded,
            s.masked,
            if facets { s.primitive } else { None },
        )
    };
    let (w, h) = (state.width, state.height);
    let mut edge = Image::new(w, h, false);
    for y in 0..h {
        for x in 0..w {
            let here = key(&state.data[(y * w + x) as usize]);
            let right = x + 1 < w && key(&state.data[(y * w + x + 1) as usize]) != here;
            let down = y + 1 < h && key(&state.data[((y + 1) * w + x) as usize]) != here;
            if right || down {
                let r = radius as i64;
                for dy in -r..=r + i64::from(down) {
                    for dx in -r..=r + i64::from(right) {
                        let (px, py) = (x as i64 + dx, y as i64 + dy);
                        if px >= 0 && py >= 0 && px < w as i64 && py < h as i64 {
                            edge.data[(py as u32 * w + px as u32) as usize] = true;
                        }
                    }
                }
            }
        }
    }
    edge
}

#[cfg(test)]
mod tests {
    use super::*;

    fn response() -> ProjectorResponse {
        ProjectorResponse {
            gamma: 2.2,
            eta: 2.0,
            black_level: 0.05,
            ..ProjectorResponse::default()
        }
    }

    #[test]
    fn compensation_inverts_the_response() {
        let r = response();
        for l in [0.05, 0.3, 1.0, 2.05] {
            let (v, clipped) = compensate(DVec3::splat(l), &r);
            assert!(!clipped, "{l}");
            let j = emitted_intensity(v, &r);
            assert!(
                (j - DVec3::splat(l)).abs().max_element() < 1e-6 * l,
                "{l} -> {j}"
            );
        }
    }

    #[test]
    fn out_of_range_clips_and_stays_finite() {
        let r = response();
        let (v, clipped) = compensate(DVec3::new(0.0, 5.0, 1.0), &r);
        assert!(clipped);
        assert_eq!((v.x, v.y), (0.0, 1.0));
        let (v, clipped) = compensate(DVec3::splat(f64::NAN), &r);
        assert!(clipped && v.is_finite());
        let bad = ProjectorResponse {
            eta: 0.0,
            ..response()
        };
        assert_eq!(compensate(DVec3::ONE, &bad), (DVec3::ZERO, true));
    }

    proptest::proptest! {
        #[test]
        fn compensation_never_leaves_nan_or_range(
            l in proptest::num::f64::ANY,
            gamma in proptest::num::f32::ANY,
            eta in proptest::num::f32::ANY,
            black in proptest::num::f32::ANY,
        ) {
            let r = ProjectorResponse { gamma, eta, black_level: black, ..ProjectorResponse::default() };
            let (v, _) = compensate(DVec3::splat(l), &r);
            proptest::prop_assert!(v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= 1.0);
            proptest::prop_assert!(emitted_intensity(v, &r).is_finite());
        }
    }

    #[test]
    fn edge_mask_marks_both_sides_of_a_change() {
        let state = Image::from_fn(6, 1, |x, _| PixelState {
            lit: u64::from(x >= 3),
            ..PixelState::default()
        });
        let m = edge_mask(&state, 0, false);
        assert_eq!(m.data, vec![false, false, true, true, false, false]);
        let m = edge_mask(&state, 1, false);
        assert_eq!(m.data, vec![false, true, true, true, true, false]);
    }
}
