//! The calibration's files and its bridge to the scene model: JSON in and
//! out, and conversion to and from [`PinholeDevice`].

use super::camera::{CameraModel, Observation};
use super::lm::Refined;
use super::{CalibrateOptions, Calibration, CalibrationInput, Correspondence, Method, calibrate};
use anyhow::Context;
use glam::{DMat3, DVec3};
use nalgebra::{Matrix3, Vector2, Vector3};
use showcase_proto::scene::PinholeDevice;
use std::path::Path;

/// Near plane given to devices made from a calibration (metres).
pub const DEVICE_NEAR_M: f64 = 0.01;
/// Far plane given to devices made from a calibration (metres).
pub const DEVICE_FAR_M: f64 = 100.0;

fn rows3(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
}

fn to_dmat3(rows: &[[f64; 3]; 3]) -> DMat3 {
    DMat3::from_cols_array_2d(rows).transpose()
}

fn from_dmat3(m: &DMat3) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| m.col(c)[r])
}

impl Calibration {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn from_model(
        device: &str,
        width: u32,
        height: u32,
        model: &CameraModel,
        obs: &[Observation],
        method: Method,
        refined: &Refined,
        intrinsics_known: bool,
    ) -> Self {
        let k = model.k();
        let kr = k * model.rotation;
        let kt = k * model.translation;
        let residuals_px = model.residuals(obs);
        let rms_px = rms(&residuals_px);
        Self {
            device: device.to_string(),
            width,
            height,
            camera_matrix: rows3(&k),
            dist_coeffs: [model.k1, model.k2, 0.0, 0.0, 0.0],
            rotation: rows3(&model.rotation),
            translation: model.translation.into(),
            projection: std::array::from_fn(|r| [kr[(r, 0)], kr[(r, 1)], kr[(r, 2)], kt[r]]),
            rms_px,
            residuals_px,
            method,
            iterations: refined.iterations,
            evaluations: refined.evaluations,
            converged: refined.converged,
            intrinsics_known,
        }
    }

    /// The fitted model (internal form).
    pub(super) fn model(&self) -> CameraModel {
        let k = Matrix3::from_fn(|r, c| self.camera_matrix[r][c]);
        let mut m = CameraModel::from_k(
            &k,
            Matrix3::from_fn(|r, c| self.rotation[r][c]),
            Vector3::from(self.translation),
        );
        (m.k1, m.k2) = (self.dist_coeffs[0], self.dist_coeffs[1]);
        m
    }

    /// The scene model's device, with near/far planes [`DEVICE_NEAR_M`]
    /// and [`DEVICE_FAR_M`].
    pub fn to_device(&self) -> PinholeDevice {
        PinholeDevice {
            width: self.width,
            height: self.height,
            k: to_dmat3(&self.camera_matrix),
            rotation: to_dmat3(&self.rotation),
            translation: DVec3::from_array(self.translation),
            dist_coeffs: self.dist_coeffs,
            near: DEVICE_NEAR_M,
            far: DEVICE_FAR_M,
        }
    }

    /// A calibration describing `pinhole` exactly (method Lm, no
    /// iterations), with residuals measured on `points` (may be empty, then
    /// `rms_px` is 0).
    pub fn from_device(device: &str, pinhole: &PinholeDevice, points: &[Correspondence]) -> Self {
        let model = model_of_device(pinhole);
        let obs: Vec<Observation> = points
            .iter()
            .map(|p| Observation {
                world: Vector3::from(p.world),
                pixel: Vector2::from(p.pixel),
            })
            .collect();
        let refined = Refined {
            model: model.clone(),
            iterations: 0,
            evaluations: 0,
            converged: true,
        };
        Self::from_model(
            device,
            pinhole.width,
            pinhole.height,
            &model,
            &obs,
            Method::Lm,
            &refined,
            true,
        )
    }

    /// Pixel of a world point under this calibration (with its k1, k2
    /// distortion); `None` behind the device.
    pub fn project(&self, world: DVec3) -> Option<glam::DVec2> {
        let p = self
            .model()
            .project(&Vector3::new(world.x, world.y, world.z))?;
        Some(glam::DVec2::new(p.x, p.y))
    }
}

/// The internal model of a scene device (k1, k2 of its distortion).
pub(super) fn model_of_device(pinhole: &PinholeDevice) -> CameraModel {
    let mut m = CameraModel::from_k(
        &from_dmat3(&pinhole.k),
        from_dmat3(&pinhole.rotation),
        Vector3::new(
            pinhole.translation.x,
            pinhole.translation.y,
            pinhole.translation.z,
        ),
    );
    (m.k1, m.k2) = (pinhole.dist_coeffs[0], pinhole.dist_coeffs[1]);
    m
}

/// Root mean square of pixel distances (0 for none).
pub(super) fn rms(residuals: &[f64]) -> f64 {
    if residuals.is_empty() {
        return 0.0;
    }
    (residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len() as f64).sqrt()
}

pub(super) fn run_calibrate_file(
    points: &Path,
    out: &Path,
    method: Method,
) -> anyhow::Result<Calibration> {
    let text =
        std::fs::read_to_string(points).with_context(|| format!("reading {}", points.display()))?;
    let input: CalibrationInput = serde_json::from_str(&text)
        .map_err(|e| explain_input_error(&text, e))
        .with_context(|| format!("parsing calibration points {}", points.display()))?;
    let calibration = calibrate(&input, &CalibrateOptions::with_method(method))
        .with_context(|| format!("calibrating {} from {}", input.device, points.display()))?;
    let json = serde_json::to_string_pretty(&calibration).context("serialising the calibration")?;
    std::fs::write(out, json + "\n").with_context(|| format!("writing {}", out.display()))?;
    Ok(calibration)
}

/// The parse error of a points file, with the first malformed point named
/// (`points[3].pixel must be [u, v] ...`) where serde's message gives only
/// a line and column.
fn explain_input_error(text: &str, err: serde_json::Error) -> anyhow::Error {
    let fault = serde_json::from_str::<serde_json::Value>(text)
        .ok()
        .and_then(|doc| {
            let points = doc.get("points")?.as_array()?;
            points.iter().enumerate().find_map(|(i, p)| {
                [("world", 3, "[x, y, z]"), ("pixel", 2, "[u, v]")]
                    .into_iter()
                    .find_map(|(key, len, shape)| {
                        let v = p.get(key);
                        let ok = v
                            .and_then(|v| v.as_array())
                            .is_some_and(|a| a.len() == len && a.iter().all(|x| x.is_number()));
                        (!ok).then(|| {
                            let got = v.map_or("nothing".to_string(), |v| v.to_string());
                            format!("points[{i}].{key} must be {shape} ({len} numbers), got {got}")
                        })
                    })
            })
        });
    match fault {
        Some(fault) => anyhow::Error::new(err).context(fault),
        None => err.into(),
    }
}
