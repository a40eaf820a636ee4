//! From decoded camera pixels to 2D-3D correspondences of the projector:
//! each valid camera pixel's ray (the calibrated camera) meets the known
//! geometry at the world point the projector pixel lit.
//!
//! A pixel is dropped when its ray meets nothing, meets the surface at a
//! grazing angle, lies on a depth edge (a 4-neighbour more than
//! [`CorrespondenceSettings::depth_edge`] deeper or shallower, on another
//! object, or seeing nothing), or decodes more than
//! [`CorrespondenceSettings::max_neighbour_px`] projector pixels from the
//! median of its valid 8-neighbours (a wrong bit, or a pixel on an
//! occlusion boundary of the projector). The rest are gathered per
//! projector pixel: one correspondence at the pixel's centre
//! `(column + 0.5, row + 0.5)` and the centroid of the world points of the
//! camera pixels that decoded to it. (Taking one camera pixel per
//! projector pixel instead, the first in scan order, biased the fit by half
//! a pixel: that camera pixel lies at one edge of the projector pixel's
//! footprint.) Beyond [`CorrespondenceSettings::max_points`] a hashed
//! subset is kept, and a hashed tenth of the projector pixels is held out
//! of the fit.

use super::decode::Decoded;
use crate::calibrate::Correspondence;
use rayon::prelude::*;
use showcase_light::sampling::hash64;
use showcase_light::{DeviceRays, SceneGeometry};
use std::collections::HashMap;

/// How correspondences are chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CorrespondenceSettings {
    /// Largest angle between the camera ray and the surface normal, degrees.
    pub max_incidence_deg: f64,
    /// Largest depth step to a 4-neighbour, relative to the depth.
    pub depth_edge: f64,
    /// Largest distance of the decode from its neighbours' median, projector pixels.
    pub max_neighbour_px: f64,
    /// Most correspondences kept (fit and held out); beyond, a hashed
    /// subset of the projector pixels.
    pub max_points: usize,
    /// One projector pixel in this many is held out of the fit (0: none).
    pub heldout_every: u64,
}

impl Default for CorrespondenceSettings {
    fn default() -> Self {
        Self {
            max_incidence_deg: 80.0,
            depth_edge: 0.02,
            max_neighbour_px: 3.0,
            max_points: 100_000,
            heldout_every: 10,
        }
    }
}

/// Why decoded pixels were dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Dropped {
    /// The camera ray met no surface.
    pub no_surface: usize,
    /// Seen at a grazing angle.
    pub grazing: usize,
    /// On a depth edge.
    pub depth_edge: usize,
    /// Decoded far from its neighbours.
    pub inconsistent: usize,
}

/// The correspondences of one projector.
#[derive(Clone, Debug, PartialEq)]
pub struct Correspondences {
    /// For the fit.
    pub fit: Vec<Correspondence>,
    /// Held out.
    pub heldout: Vec<Correspondence>,
    /// Decoded pixels that passed every test (before gathering).
    pub accepted: usize,
    /// Decoded pixels dropped, by reason.
    pub dropped: Dropped,
}

#[derive(Clone, Copy)]
struct Seen {
    depth: f64,
    point: glam::DVec3,
    object: u32,
    grazing: bool,
}

/// The correspondences of `decoded`, seen by the camera `camera` in
/// `geometry`.
pub fn correspondences(
    decoded: &Decoded,
    camera: &DeviceRays,
    geometry: &SceneGeometry,
    settings: &CorrespondenceSettings,
) -> Correspondences {
    let (w, h) = (decoded.width, decoded.height);
    let cos_max = settings.max_incidence_deg.to_radians().cos();
    let seen: Vec<Option<Seen>> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let ray = camera.pixel_ray(i % w, i / w)?;
            let hit = geometry.closest_hit(&ray, 0.0, f64::INFINITY)?;
            let cos = hit.geometric_normal.dot(ray.direction).abs();
            Some(Seen {
                depth: hit.t,
                point: hit.point,
                object: hit.object,
                grazing: cos < cos_max,
            })
        })
        .collect();
    let idx = |x: i64, y: i64| -> Option<usize> {
        (x >= 0 && y >= 0 && x < w as i64 && y < h as i64).then(|| (y * w as i64 + x) as usize)
    };
    let mut dropped = Dropped::default();
    let mut gathered: HashMap<(u32, u32), (glam::DVec3, u32)> = HashMap::new();
    let mut accepted = 0;
    for i in 0..(w * h) as usize {
        let Some((px, py)) = decoded.pixels[i] else {
            continue;
        };
        let Some(s) = seen[i] else {
            dropped.no_surface += 1;
            continue;
        };
        if s.grazing {
            dropped.grazing += 1;
            continue;
        }
        let (x, y) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
        let edge = [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().any(|(dx, dy)| {
            idx(x + dx, y + dy).is_some_and(|j| match seen[j] {
                None => true,
                Some(n) => {
                    n.object != s.object
                        || (n.depth - s.depth).abs() > settings.depth_edge * s.depth
                }
            })
        });
        if edge {
            dropped.depth_edge += 1;
            continue;
        }
        let mut cols = Vec::with_capacity(8);
        let mut rows = Vec::with_capacity(8);
        for dy in -1..=1 {
            for dx in -1..=1 {
                if (dx, dy) == (0, 0) {
                    continue;
                }
                if let Some((c, r)) = idx(x + dx, y + dy).and_then(|j| decoded.pixels[j]) {
                    cols.push(c as f64);
                    rows.push(r as f64);
                }
            }
        }
        let consistent = cols.len() >= 3
            && (median(&mut cols) - px as f64).abs() <= settings.max_neighbour_px
            && (median(&mut rows) - py as f64).abs() <= settings.max_neighbour_px;
        if !consistent {
            dropped.inconsistent += 1;
            continue;
        }
        accepted += 1;
        let e = gathered.entry((px, py)).or_insert((glam::DVec3::ZERO, 0));
        e.0 += s.point;
        e.1 += 1;
    }
    let hashed = |(px, py): (u32, u32)| hash64(((px as u64) << 32) | py as u64);
    let mut keys: Vec<_> = gathered.keys().copied().collect();
    if keys.len() > settings.max_points {
        keys.sort_unstable_by_key(|k| hashed(*k).rotate_left(17));
        keys.truncate(settings.max_points);
    }
    keys.sort_unstable();
    let (mut fit, mut heldout) = (Vec::new(), Vec::new());
    for key in keys {
        let (sum, n) = gathered[&key];
        let c = Correspondence {
            world: (sum / n as f64).to_array(),
            pixel: [key.0 as f64 + 0.5, key.1 as f64 + 0.5],
        };
        let held = settings.heldout_every > 0 && hashed(key).is_multiple_of(settings.heldout_every);
        if held {
            heldout.push(c);
        } else {
            fit.push(c);
        }
    }
    Correspondences {
        fit,
        heldout,
        accepted,
        dropped,
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}
