//! Blending overlapping projectors: where several projectors light the
//! same real surface, each must deliver only its share of the target
//! irradiance, or the overlap shows several times too bright.
//!
//! Projector `i`'s pixel lighting surface point `p` is scaled by
//! `w_i(p) = f_i(p) / sum_j f_j(p)`, over every projector `j` that sees `p`
//! on the side `i` lights (in its image, facing it, nothing real between
//! them), with
//! `f_j(p) = cos(theta_j) / r_j^2 * s(d_j / m_j)`:
//! - `cos(theta_j) / r_j^2` favours the projector that delivers the most
//!   irradiance per unit of intensity (it clips least);
//! - `d_j` is the distance in pixels from `p`'s image in projector `j` to
//!   that image's nearest border, `m_j` is [`BORDER_FRACTION`] of the
//!   image's smaller side, and `s` is smoothstep: a projector fades out
//!   towards its border, so a small calibration error shifts light
//!   smoothly instead of opening a seam where its frustum ends.
//!
//! The weights sum to 1 over the projectors that see `p` (a point only
//! one projector sees gets weight 1 from it), so the projectors together
//! deliver exactly the target. They depend only on the real geometry and
//! the projectors, which are static in a show: the GPU renderer computes
//! them once per scene and keeps them as a texture.

use super::RenderSetupError;
use crate::finite::finite_or_zero;
use crate::{DeviceRays, Image, SceneGeometry};
use glam::DVec3;
use rayon::prelude::*;
use showcase_proto::{ObjectKind, Projector};

/// Fade-out margin at a projector's image border, as a fraction of the
/// image's smaller side.
pub const BORDER_FRACTION: f64 = 0.05;

/// The projectors of a scene, ready to cast rays, for blending.
#[derive(Clone, Debug)]
pub struct Blend {
    projectors: Vec<DeviceRays>,
}

/// The index of `projector` among `projectors` (same name and device):
/// which one's share a map takes; `None` for a projector not among them.
pub fn index_of(projectors: &[Projector], projector: &Projector) -> Option<usize> {
    projectors
        .iter()
        .position(|p| p.name == projector.name && p.device == projector.device)
}

impl Blend {
    /// Set up the blend between `projectors`.
    pub fn new(projectors: &[Projector]) -> Result<Self, RenderSetupError> {
        Ok(Self {
            projectors: projectors
                .iter()
                .map(|p| DeviceRays::new(&p.device))
                .collect::<Result<_, _>>()?,
        })
    }

    /// Projectors blended.
    pub fn len(&self) -> usize {
        self.projectors.len()
    }

    /// True with no projector.
    pub fn is_empty(&self) -> bool {
        self.projectors.is_empty()
    }

    /// `f_j(p)` of the module docs for surface point `point` whose lit side
    /// has unit normal `facing`; 0 when projector `j` does not see it.
    fn preference(&self, j: usize, real_only: &SceneGeometry, point: DVec3, facing: DVec3) -> f64 {
        let Some(rays) = self.projectors.get(j) else {
            return 0.0;
        };
        let Some(px) = rays.project(point) else {
            return 0.0;
        };
        if !rays.in_image(px) {
            return 0.0;
        }
        let to = rays.center() - point;
        let r2 = to.length_squared();
        let cos = facing.dot(to) / r2.sqrt();
        if !(cos > 0.0 && r2 > 0.0 && real_only.visible(point, facing, rays.center(), false)) {
            return 0.0;
        }
        let d = rays.device();
        let (w, h) = (d.width as f64, d.height as f64);
        let border = px.x.min(w - px.x).min(px.y).min(h - px.y);
        let t = (border / (BORDER_FRACTION * w.min(h))).clamp(0.0, 1.0);
        let f = cos / r2 * t * t * (3.0 - 2.0 * t);
        finite_or_zero(f)
    }

    /// Weight of projector `i` at surface point `point` (lit side
    /// `facing`), which projector `i` lights: 1 with no other projector
    /// seeing the point.
    pub fn weight(&self, i: usize, real_only: &SceneGeometry, point: DVec3, facing: DVec3) -> f64 {
        if self.projectors.len() < 2 {
            return 1.0;
        }
        let own = self.preference(i, real_only, point, facing);
        let total: f64 = (0..self.projectors.len())
            .map(|j| {
                if j == i {
                    own
                } else {
                    self.preference(j, real_only, point, facing)
                }
            })
            .sum();
        if total > 0.0 && own.is_finite() {
            (own / total).clamp(0.0, 1.0)
        } else {
            // Only `i` lights the point, at the very edge of its image.
            1.0
        }
    }

    /// The weight of every pixel of projector `i`: its pixel centre's ray
    /// onto the real surfaces, as the irradiance map is drawn (1 where the
    /// ray meets nothing: nothing is lit there anyway).
    pub fn weight_image(
        &self,
        i: usize,
        real_only: &SceneGeometry,
    ) -> Result<Image<f32>, RenderSetupError> {
        let Some(rays) = self.projectors.get(i) else {
            return Err(RenderSetupError::NoProjector { index: i });
        };
        let (w, h) = (rays.device().width, rays.device().height);
        let data: Vec<f32> = (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                (0..w).map(move |x| {
                    let Some(ray) = rays.pixel_ray(x, y) else {
                        return 1.0;
                    };
                    let Some(hit) = real_only.closest_hit(&ray, 0.0, f64::INFINITY) else {
                        return 1.0;
                    };
                    if real_only.object_kind(hit.object) != Some(ObjectKind::Real)
                        || hit.geometric_normal == DVec3::ZERO
                    {
                        return 1.0;
                    }
                    let facing = hit.facing_normal(ray.direction);
                    self.weight(i, real_only, hit.point, facing) as f32
                })
            })
            .collect();
        Ok(Image {
            width: w,
            height: h,
            data,
        })
    }
}
