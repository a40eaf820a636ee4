//! End-to-end consistency of the projector role, direct light only (as
//! paper section 5 assumes): the projector's values drive a simulated
//! projector, a point light at its centre emitting
//! `eta * value^gamma + black_level` W/sr along each pixel's ray
//! (`cos / r^2`, true visibility), onto the real objects with their true
//! reflectance; a camera sees the radiance `rho / pi * E`. The target is
//! what the virtual lighting asks for: `rho / pi * E_target` with the
//! virtual shadows and ambient, evaluated independently at the camera's
//! surface point (not at the projector's pixel centre).
//!
//! Compared pixels: the camera sees a real surface that the projector
//! reaches (no type-1 shadow of the projector itself), the target is lit
//! (`E_target > 0`), and the projector pixel is unclipped, unmasked, not
//! in an occlusion shadow (the observer sees a virtual object there), and
//! not within one pixel of a silhouette, shadow or facet edge (a projector
//! pixel straddling an edge cannot be right on both sides).

use super::RenderSetupError;
use super::frame::FrameScene;
use super::projector::{IrradianceMap, Occluders, edge_mask, emitted_intensity, target_irradiance};
use crate::geometry::face_forward;
use crate::metrics::relative_rmse;
use crate::{DeviceRays, Image, MetricError, RgbImage};
use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;
use showcase_proto::{PinholeDevice, Projector};

/// The outcome of a consistency check.
#[derive(Clone, Debug)]
pub struct ConsistencyReport {
    /// Relative RMSE of `measured` against `target` over `mask`.
    pub rel_rmse: f64,
    /// Pixels compared.
    pub pixels: usize,
    /// Radiance the camera sees under the simulated projector.
    pub measured: RgbImage,
    /// Radiance the virtual lighting asks for.
    pub target: RgbImage,
    /// Compared pixels.
    pub mask: Image<bool>,
}

/// Why a consistency check failed.
#[derive(Debug, thiserror::Error)]
pub enum ConsistencyError {
    /// The scene cannot be set up.
    #[error(transparent)]
    Setup(#[from] RenderSetupError),
    /// The metric had nothing to compare.
    #[error("consistency metric: {0}")]
    Metric(#[from] MetricError),
    /// The map does not have the projector's size.
    #[error("map is {width}x{height} but the projector is {pw}x{ph}")]
    SizeMismatch {
        /// Map width.
        width: u32,
        /// Map height.
        height: u32,
        /// Projector width.
        pw: u32,
        /// Projector height.
        ph: u32,
    },
}

/// Run the check for `map` (its values are what the projector shows; its
/// state marks clipped, occluded and edge pixels) seen by `camera`.
pub fn direct_light_consistency(
    frame: &FrameScene,
    occluders: &Occluders,
    projector: &Projector,
    map: &IrradianceMap,
    camera: &PinholeDevice,
) -> Result<ConsistencyReport, ConsistencyError> {
    let proj = DeviceRays::new(&projector.device).map_err(RenderSetupError::from)?;
    let (pw, ph) = (projector.device.width, projector.device.height);
    if map.value.width != pw || map.value.height != ph || !map.value.same_size(&map.state) {
        return Err(ConsistencyError::SizeMismatch {
            width: map.value.width,
            height: map.value.height,
            pw,
            ph,
        });
    }
    let edges = edge_mask(&map.state, 1, true);
    let cam = DeviceRays::new(camera).map_err(RenderSetupError::from)?;
    let (w, h) = (camera.width, camera.height);
    let pixels: Vec<(Vec3, Vec3, bool)> =
        (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                let (cam, proj, edges) = (&cam, &proj, &edges);
                (0..w).map(move |x| {
                    camera_pixel(frame, occluders, projector, map, edges, cam, proj, x, y)
                        .unwrap_or((Vec3::ZERO, Vec3::ZERO, false))
                })
            })
            .collect();
    let mut measured = Image::new(w, h, Vec3::ZERO);
    let mut target = Image::new(w, h, Vec3::ZERO);
    let mut mask = Image::new(w, h, false);
    for (i, (m, t, ok)) in pixels.into_iter().enumerate() {
        measured.data[i] = m;
        target.data[i] = t;
        mask.data[i] = ok;
    }
    let pixels = mask.data.iter().filter(|m| **m).count();
    let rel_rmse = relative_rmse(&measured, &target, Some(&mask))?;
    Ok(ConsistencyReport {
        rel_rmse,
        pixels,
        measured,
        target,
        mask,
    })
}

#[allow(clippy::too_many_arguments)]
fn camera_pixel(
    frame: &FrameScene,
    occluders: &Occluders,
    projector: &Projector,
    map: &IrradianceMap,
    edges: &Image<bool>,
    cam: &DeviceRays,
    proj: &DeviceRays,
    x: u32,
    y: u32,
) -> Option<(Vec3, Vec3, bool)> {
    let ray = cam.pixel_ray(x, y)?;
    let hit = occluders.real_only.closest_hit(&ray, 0.0, f64::INFINITY)?;
    if hit.geometric_normal == DVec3::ZERO {
        return None;
    }
    let object = frame.showcase.objects.get(hit.object as usize)?;
    let rho = object
        .material
        .albedo_at(hit.uv.unwrap_or(Vec2::ZERO))
        .as_dvec3();
    // The side the projector lights.
    let to_proj = proj.center() - hit.point;
    let facing = face_forward(hit.geometric_normal, to_proj);
    let seen_side =
        hit.geometric_normal.dot(-ray.direction) * facing.dot(hit.geometric_normal) > 0.0;
    let (target_e, _) = target_irradiance(frame, occluders, hit.point, facing);
    let target = rho / std::f64::consts::PI * target_e;
    let Some((px, py)) = proj.pixel_of(hit.point) else {
        return Some((Vec3::ZERO, target.as_vec3(), false));
    };
    if !seen_side || !proj.sees(&occluders.real_only, hit.point, facing) {
        return Some((Vec3::ZERO, target.as_vec3(), false));
    }
    let value = map.value.get(px, py)?.as_dvec3();
    let state = map.state.get(px, py)?;
    let j = emitted_intensity(value, &projector.response);
    let r2 = to_proj.length_squared();
    let cos_p = facing.dot(to_proj) / r2.sqrt();
    let e = j * (cos_p / r2);
    let measured = rho / std::f64::consts::PI * e;
    let ok = !state.clipped
        && !state.masked
        && !state.occluded
        && !edges.get(px, py).copied().unwrap_or(true)
        && target.max_element() > 0.0
        && measured.is_finite();
    Some((measured.as_vec3(), target.as_vec3(), ok))
}
