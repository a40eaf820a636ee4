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
    /// The CRT's response and its beam splitter's transmission and
    /// reflection: in the simulated showcase the device itself, for a node
    /// the profile it encodes its output with at the device boundary
    /// (nominal until `calibrate --photometric` measures it).
    pub photometry: CrtPhotometry,
}

/// A half-silvered mirror's transmission and reflection per linear RGB
/// channel: an observer sees `T * real + R * CRT`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BeamSplitter {
    /// Fraction of the light from behind the mirror (the real objects)
    /// that passes, per channel.
    pub transmission: Vec3,
    /// Fraction of the CRT's light that the mirror reflects, per channel.
    pub reflection: Vec3,
}

impl BeamSplitter {
    /// The ideal combiner: transmission and reflection 1.
    pub const IDEAL: Self = Self {
        transmission: Vec3::ONE,
        reflection: Vec3::ONE,
    };
}

/// A CRT's light per drive value `d` in `0..=1`, per channel:
/// `black_level + peak * d^gamma` (radiance, W/m^2/sr). A projector's
/// per-channel photometry is the same curve in W/sr
/// ([`crate::ProjectorResponse::photometry`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CrtResponse {
    /// Exponent of the drive value, per channel.
    pub gamma: Vec3,
    /// Radiance at drive 1 above black, per channel (the white point).
    pub peak: Vec3,
    /// Radiance at drive 0, per channel.
    pub black_level: Vec3,
}

impl CrtResponse {
    /// A CRT of one `gamma`, peak radiance 1 and no black level.
    pub fn nominal(gamma: f32) -> Self {
        Self {
            gamma: Vec3::splat(gamma),
            peak: Vec3::ONE,
            black_level: Vec3::ZERO,
        }
    }

    /// The radiance the CRT emits at drive values `drive` (clamped to
    /// `0..=1`; a non-finite value counts as 0).
    pub fn emit(&self, drive: Vec3) -> Vec3 {
        let d = Vec3::from_array(drive.to_array().map(|x| {
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                0.0
            }
        }));
        let powf = |x: f32, g: f32| if x > 0.0 { x.powf(g) } else { 0.0 };
        self.black_level
            + self.peak
                * Vec3::new(
                    powf(d.x, self.gamma.x),
                    powf(d.y, self.gamma.y),
                    powf(d.z, self.gamma.z),
                )
    }
}

/// A face's photometric chain: its CRT and its beam splitter.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CrtPhotometry {
    /// The CRT.
    pub crt: CrtResponse,
    /// The beam splitter in front of it.
    pub splitter: BeamSplitter,
}

impl CrtPhotometry {
    /// An ideal combiner in front of a nominal CRT of `gamma`: what a node
    /// assumes before photometric calibration.
    pub fn nominal(gamma: f32) -> Self {
        Self {
            crt: CrtResponse::nominal(gamma),
            splitter: BeamSplitter::IDEAL,
        }
    }

    /// What an observer receives through the mirror from drive values
    /// `drive`, in the units of radiance behind the mirror (the mirror's
    /// reflection over its transmission times the CRT's light), so that
    /// it adds to what the observer sees of the real objects as it is.
    pub fn seen(&self, drive: Vec3) -> Vec3 {
        let t = self.splitter.transmission;
        let ratio = Vec3::from_array(std::array::from_fn(|c| {
            if t[c] > 0.0 {
                self.splitter.reflection[c] / t[c]
            } else {
                0.0
            }
        }));
        ratio * self.crt.emit(drive)
    }

    /// The drive values that make an observer see `radiance` through the
    /// mirror as if it were behind it ([`Self::seen`]'s inverse), clamped
    /// to what the CRT can show: its black level from below, drive 1 from
    /// above. Non-finite input shows black.
    pub fn drive(&self, radiance: Vec3) -> Vec3 {
        Vec3::from_array(std::array::from_fn(|c| {
            let (t, r) = (self.splitter.transmission[c], self.splitter.reflection[c]);
            let (peak, black, gamma) =
                (self.crt.peak[c], self.crt.black_level[c], self.crt.gamma[c]);
            let l = radiance[c];
            if !(l.is_finite() && r > 0.0 && peak > 0.0 && gamma > 0.0) {
                return 0.0;
            }
            let x = ((l * t / r - black) / peak).clamp(0.0, 1.0);
            if x > 0.0 { x.powf(1.0 / gamma) } else { 0.0 }
        }))
    }
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
