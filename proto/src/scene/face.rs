//! The beam splitter and its CRT faces, and the head-tracked observers
//! who look through them.

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

/// A planar rectangle `origin + s*right + t*down`, `s, t` in `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rect3 {
    /// The top-left corner (pixel `(0, 0)` of a screen).
    pub origin: Vec3,
    /// The top edge, left to right.
    pub right: Vec3,
    /// The left edge, top to bottom.
    pub down: Vec3,
}

impl Rect3 {
    /// Unit normal, `down x right` (towards the viewer of a screen).
    pub fn normal(&self) -> Vec3 {
        self.down.cross(self.right).normalize_or_zero()
    }
}

/// A plane `normal . x = offset` with a unit normal.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plane {
    /// Unit normal.
    pub normal: Vec3,
    /// Signed distance of the plane from the origin along `normal`.
    pub offset: f32,
}

impl Plane {
    /// The plane through `point` with normal `normal` (normalised here).
    pub fn from_point_normal(point: Vec3, normal: Vec3) -> Self {
        let n = normal.normalize_or_zero();
        Self {
            normal: n,
            offset: n.dot(point),
        }
    }

    /// Mirror image of a point in this plane.
    pub fn reflect_point(&self, p: Vec3) -> Vec3 {
        p - 2.0 * (self.normal.dot(p) - self.offset) * self.normal
    }
}

/// A CRT screen seen through a half-silvered mirror.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CrtFace {
    /// Unique name, e.g. `face-0`.
    pub name: String,
    /// The screen's displayed area in world coordinates.
    pub screen: Rect3,
    /// The beam-splitter plane that reflects the screen.
    pub mirror: Plane,
    /// Horizontal resolution.
    pub width: u32,
    /// Vertical resolution.
    pub height: u32,
    /// Display gamma applied at the device boundary.
    pub gamma: f32,
}

/// A rigid pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position in metres.
    pub position: Vec3,
    /// Orientation; the head looks along its local -z with y up.
    pub orientation: Quat,
}

impl Default for Pose {
    fn default() -> Self {
        Self {
            position: Vec3::ZERO,
            orientation: Quat::IDENTITY,
        }
    }
}

/// A head-tracked observer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Observer {
    /// Unique name.
    pub name: String,
    /// Head pose (centre between the eyes).
    pub head: Pose,
    /// Interpupillary distance in metres.
    pub ipd: f32,
}

impl Observer {
    /// Interpupillary distance (metres) of an observer whose scene does
    /// not give one, and of tracked heads beyond the scene's observers:
    /// the adult mean.
    pub const DEFAULT_IPD: f32 = 0.064;

    /// Left and right eye positions for a head pose.
    pub fn eyes(head: &Pose, ipd: f32) -> [Vec3; 2] {
        let right = head.orientation * Vec3::X;
        [
            head.position - 0.5 * ipd * right,
            head.position + 0.5 * ipd * right,
        ]
    }
}
