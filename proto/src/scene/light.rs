//! Virtual lights: point, spot and area sources with their intensities.

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// A virtual light source. Intensities are radiometric and linear RGB.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Light {
    /// An isotropic point light of radiant intensity `intensity` (W/sr).
    Point {
        /// Position in world space.
        position: Vec3,
        /// Radiant intensity per channel (W/sr).
        intensity: Vec3,
    },
    /// A spot light: a point light restricted to a cone with a smooth edge.
    Spot {
        /// Position in world space.
        position: Vec3,
        /// Axis of the cone (need not be normalised; must be non-zero).
        direction: Vec3,
        /// Radiant intensity on the axis (W/sr).
        intensity: Vec3,
        /// Full intensity inside this half-angle (degrees).
        inner_deg: f32,
        /// Zero intensity outside this half-angle (degrees).
        outer_deg: f32,
    },
    /// A one-sided parallelogram emitter `corner + s*edge_u + t*edge_v`,
    /// `s, t` in `[0, 1]`, emitting along `edge_u x edge_v`.
    Area {
        /// One corner.
        corner: Vec3,
        /// First edge.
        edge_u: Vec3,
        /// Second edge.
        edge_v: Vec3,
        /// Emitted radiance (W/m^2/sr).
        radiance: Vec3,
        /// Point samples used by interactive passes (at least 1).
        samples: u32,
    },
}

impl Light {
    /// A representative position (the centre of an area light).
    pub fn position(&self) -> Vec3 {
        match self {
            Light::Point { position, .. } | Light::Spot { position, .. } => *position,
            Light::Area {
                corner,
                edge_u,
                edge_v,
                ..
            } => *corner + 0.5 * (*edge_u + *edge_v),
        }
    }
}

/// A named light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightSource {
    /// Unique name.
    pub name: String,
    /// The light.
    pub light: Light,
}
