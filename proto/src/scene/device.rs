//! Projectors and cameras: the OpenCV pinhole model with its one mapping
//! to wgpu clip space, and each device's photometric response.

use crate::CrtResponse;
use glam::{DMat3, DMat4, DVec3, DVec4, Vec3};
use serde::{Deserialize, Serialize};

/// A pinhole device in the OpenCV convention: `x_cam = R X + t`,
/// pixel `~ K x_cam`, x right, y down, z forward, pixel centres at
/// integer + 0.5 with the origin at the top-left.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PinholeDevice {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Intrinsic matrix K (upper triangular, includes skew).
    pub k: DMat3,
    /// World-to-device rotation R.
    pub rotation: DMat3,
    /// World-to-device translation t.
    pub translation: DVec3,
    /// Distortion `[k1, k2, p1, p2, k3]` (OpenCV order).
    pub dist_coeffs: [f64; 5],
    /// Near plane distance (metres, along +z).
    pub near: f64,
    /// Far plane distance (metres, along +z).
    pub far: f64,
}

impl PinholeDevice {
    /// A device at `eye` looking at `target`, with `up` roughly up and a
    /// horizontal field of view of `fov_x_deg` degrees; square pixels, no
    /// skew, principal point at the image centre.
    pub fn look_at(
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        fov_x_deg: f64,
        width: u32,
        height: u32,
    ) -> Self {
        let z = (target - eye).normalize();
        // OpenCV y points down, so x = z x up points right.
        let x = z.cross(up).normalize();
        let y = z.cross(x);
        let rotation = DMat3::from_cols(x, y, z).transpose();
        let f = 0.5 * width as f64 / (0.5 * fov_x_deg.to_radians()).tan();
        let k = DMat3::from_cols(
            DVec3::new(f, 0.0, 0.0),
            DVec3::new(0.0, f, 0.0),
            DVec3::new(0.5 * width as f64, 0.5 * height as f64, 1.0),
        );
        Self {
            width,
            height,
            k,
            rotation,
            translation: -(rotation * eye),
            dist_coeffs: [0.0; 5],
            near: 0.01,
            far: 100.0,
        }
    }

    /// Centre of projection in world space, `-R^T t`.
    pub fn center(&self) -> DVec3 {
        -(self.rotation.transpose() * self.translation)
    }

    /// The 3x4 projection matrix `P = K [R | t]`, as rows.
    pub fn projection(&self) -> [[f64; 4]; 3] {
        let kr = self.k * self.rotation;
        let kt = self.k * self.translation;
        std::array::from_fn(|r| {
            let row = kr.row(r);
            [row.x, row.y, row.z, kt[r]]
        })
    }

    /// World point to device coordinates `x_cam = R X + t`.
    pub fn to_device(&self, world: DVec3) -> DVec3 {
        self.rotation * world + self.translation
    }

    /// Project a world point to a pixel (ignores distortion). `None` when
    /// the point is not in front of the device.
    pub fn project(&self, world: DVec3) -> Option<glam::DVec2> {
        let c = self.to_device(world);
        if c.z <= 0.0 {
            return None;
        }
        let p = self.k * (c / c.z);
        Some(glam::DVec2::new(p.x, p.y))
    }

    /// The world-space unit direction of the ray through `pixel` (ignores
    /// distortion). Rays start at [`Self::center`].
    pub fn unproject(&self, pixel: glam::DVec2) -> DVec3 {
        let d = self.k.inverse() * DVec3::new(pixel.x, pixel.y, 1.0);
        (self.rotation.transpose() * d).normalize()
    }

    /// World-to-device 4x4 matrix (OpenCV camera space).
    pub fn view_matrix(&self) -> DMat4 {
        let r = self.rotation;
        DMat4::from_cols(
            r.x_axis.extend(0.0),
            r.y_axis.extend(0.0),
            r.z_axis.extend(0.0),
            self.translation.extend(1.0),
        )
    }

    /// The one documented mapping of this device to wgpu clip space:
    /// OpenCV camera space (y down, z forward) to clip space (y up, depth
    /// `0..1` from `near` to `far`), such that the device's pixel position
    /// `(u, v)` maps to the framebuffer position `(u, v)` of a
    /// `width x height` target, so pixel centres `(i + 0.5, j + 0.5)` line
    /// up on both sides.
    pub fn clip_from_world(&self) -> DMat4 {
        let (w, h) = (self.width as f64, self.height as f64);
        let (n, f) = (self.near, self.far);
        let k = self.k;
        let (fx, s, cx) = (k.x_axis.x, k.y_axis.x, k.z_axis.x);
        let (fy, cy) = (k.y_axis.y, k.z_axis.y);
        // ndc_x = 2u/w - 1, ndc_y = 1 - 2v/h, ndc_z = f(z - n) / (z (f - n)).
        let proj = DMat4::from_cols(
            DVec4::new(2.0 * fx / w, 0.0, 0.0, 0.0),
            DVec4::new(2.0 * s / w, -2.0 * fy / h, 0.0, 0.0),
            DVec4::new(2.0 * cx / w - 1.0, 1.0 - 2.0 * cy / h, f / (f - n), 1.0),
            DVec4::new(0.0, 0.0, -f * n / (f - n), 0.0),
        );
        proj * self.view_matrix()
    }
}

/// Projector photometry: radiance out = `eta * response(pixel) + black_level`.
///
/// `gamma`, `eta` and `black_level` are the model the product computes
/// pixel values in (one curve for every channel). [`Self::photometry`],
/// when given, is the projector's light per pixel value and channel: in
/// the simulated showcase the device itself, for a node the profile it
/// encodes its values with at the device boundary (the light the model
/// wants of a value, shown by the device value that gives it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProjectorResponse {
    /// Exponent of the pixel-value response curve (`value^gamma`).
    pub gamma: f32,
    /// Peak intensity eta (W/sr at pixel value 1).
    pub eta: f32,
    /// Light emitted at pixel value 0 (W/sr).
    pub black_level: f32,
    /// DLP colour-wheel segments as RGB transmissions over one wheel turn;
    /// empty for a projector without time slicing.
    pub wheel_segments: Vec<Vec3>,
    /// Duration of one wheel turn in seconds.
    pub wheel_period_s: f32,
    /// The light per device value, per channel (W/sr): `black_level +
    /// peak * value^gamma`; `None`: exactly the model above (see the
    /// type's docs).
    #[serde(default)]
    pub photometry: Option<CrtResponse>,
}

impl ProjectorResponse {
    /// The model's light (W/sr) for pixel values `value` (clamped to
    /// `0..=1`; non-finite counts as 0): `eta * value^gamma +
    /// black_level` per channel.
    pub fn model(&self, value: Vec3) -> Vec3 {
        self.model_curve().emit(value)
    }

    /// The model as a per-channel curve.
    pub fn model_curve(&self) -> CrtResponse {
        CrtResponse {
            gamma: Vec3::splat(self.gamma),
            peak: Vec3::splat(self.eta),
            black_level: Vec3::splat(self.black_level),
        }
    }

    /// The light the device emits (W/sr) at device values `value`: its
    /// [`Self::photometry`], or the model where there is none.
    pub fn light(&self, value: Vec3) -> Vec3 {
        self.photometry
            .unwrap_or_else(|| self.model_curve())
            .emit(value)
    }

    /// The device values a node sends for the model's pixel values
    /// `value`: through [`Self::photometry`] the values whose light is the
    /// model's (clamped to what the device can show), else `value`
    /// itself. Non-finite values show black.
    pub fn encode(&self, value: Vec3) -> Vec3 {
        match &self.photometry {
            None => value,
            Some(curve) => crate::CrtPhotometry {
                crt: *curve,
                splitter: crate::BeamSplitter::IDEAL,
            }
            .drive(self.model(value)),
        }
    }
}

impl Default for ProjectorResponse {
    fn default() -> Self {
        Self {
            gamma: 2.2,
            eta: 1.0,
            black_level: 0.0,
            wheel_segments: Vec::new(),
            wheel_period_s: 1.0 / 120.0,
            photometry: None,
        }
    }
}

/// Camera photometry: value = response(exposure * radiance + noise), then
/// quantisation to `bits`. The response per channel is a power curve with
/// a knee, as video cameras compress their highlights: `u =
/// signal^(1/gamma)` is amplified by `g` up to `knee`, above which the
/// slope drops to `shoulder` times its own (`knee + (g u - knee) *
/// shoulder`); `g` makes the full signal reach the top code (`g = knee +
/// (1 - knee) / shoulder`), clipped to `0..=1` ([`Self::encode`],
/// [`Self::decode`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraResponse {
    /// Exponent applied to the normalised signal, per channel.
    pub gamma: Vec3,
    /// Normalised value where the shoulder begins (1: none).
    pub knee: f32,
    /// Slope above the knee relative to the curve's own (1: none).
    pub shoulder: f32,
    /// Signal per unit radiance and second.
    pub gain: f32,
    /// Exposure time in seconds.
    pub exposure_s: f32,
    /// Standard deviation of read noise, as a fraction of full scale.
    pub read_noise: f32,
    /// Shot-noise scale: the variance is `shot_noise * signal`.
    pub shot_noise: f32,
    /// Bits per channel of the quantised output.
    pub bits: u32,
}

impl CameraResponse {
    /// The knee, the shoulder's slope and the gain before the knee (see
    /// the type's docs); a shoulder of 0 or less counts as none.
    fn knee(&self) -> (f64, f64, f64) {
        let knee = f64::from(self.knee).clamp(0.0, 1.0);
        let shoulder = f64::from(self.shoulder);
        if knee >= 1.0 || shoulder.is_nan() || shoulder <= 0.0 {
            return (1.0, 1.0, 1.0);
        }
        (knee, shoulder, knee + (1.0 - knee) / shoulder)
    }

    /// The normalised value (`0..=1`, before quantisation) of `signal` in
    /// `channel`; non-finite or negative signal gives 0.
    pub fn encode(&self, channel: usize, signal: f64) -> f64 {
        let s = if signal.is_finite() {
            signal.max(0.0)
        } else {
            0.0
        };
        let gamma = f64::from(self.gamma[channel.min(2)]).max(1e-3);
        let (knee, shoulder, g) = self.knee();
        let v = g * s.powf(1.0 / gamma);
        let v = if v > knee {
            knee + (v - knee) * shoulder
        } else {
            v
        };
        if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// The signal whose normalised value in `channel` is `value`
    /// ([`Self::encode`]'s inverse; a clipped value gives the least signal
    /// that clips).
    pub fn decode(&self, channel: usize, value: f64) -> f64 {
        let v = if value.is_finite() {
            value.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (knee, shoulder, g) = self.knee();
        let v = if v > knee {
            knee + (v - knee) / shoulder
        } else {
            v
        };
        (v / g).powf(f64::from(self.gamma[channel.min(2)]).max(1e-3))
    }
}

impl Default for CameraResponse {
    fn default() -> Self {
        Self {
            gamma: Vec3::ONE,
            knee: 1.0,
            shoulder: 1.0,
            gain: 1.0,
            exposure_s: 1.0 / 30.0,
            read_noise: 0.0,
            shot_noise: 0.0,
            bits: 8,
        }
    }
}

/// A video projector.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Projector {
    /// Unique name, e.g. `projector-0`.
    pub name: String,
    /// Geometry.
    pub device: PinholeDevice,
    /// Photometry.
    pub response: ProjectorResponse,
}

/// A video camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Unique name, e.g. `camera-0`.
    pub name: String,
    /// Geometry.
    pub device: PinholeDevice,
    /// Photometry.
    pub response: CameraResponse,
}
