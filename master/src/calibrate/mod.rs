//! Device calibration from fiducials (paper section 3.1): DLT, RQ, PnP, Levenberg-Marquardt, and Powell as the baseline.
//!
//! The paper marks the pixels of known 3D fiducials and solves the
//! perspective-n-point problem with Powell's method. We start linearly
//! (normalised DLT and RQ for unknown intrinsics; a plane homography or EPnP
//! for known intrinsics) and refine the reprojection error with
//! Levenberg-Marquardt; Powell stays available as the baseline.
//!
//! Stages of [`calibrate`]:
//! 1. validate: finite values, enough points, not collinear, a sane `camera_matrix`;
//! 2. linear start: unknown intrinsics need non-coplanar points (DLT, RQ);
//!    known intrinsics use a homography (coplanar) or EPnP;
//! 3. refinement of fx, fy, cx, cy, (skew), rotation, translation, (k1, k2),
//!    or of the pose alone when the intrinsics are known;
//! 4. every point must end in front of the device.

pub(crate) mod bench;
mod camera;
mod dlt;
mod io;
mod lm;
mod nullspace;
pub mod photometric;
mod pnp;
mod powell;
mod simulate;
pub mod structured_light;

pub use bench::{
    BENCH_CONFIGURATIONS, BENCH_NOISE_PX, BENCH_POINTS, BENCH_SEEDS, BenchRecord, HELDOUT_POINTS,
    Source, SyntheticCase, bench_calibration, bench_calibration_with, bench_configuration,
    heldout_rms, rotation_angle_deg, synthetic_case, write_bench_report,
};
pub use io::{DEVICE_FAR_M, DEVICE_NEAR_M};
pub use simulate::{
    RIG_CENTER, RIG_SIZE, fiducial_plate, fiducial_rig, projector_in_showcase, simulate_fiducials,
};

use camera::{CameraModel, Layout, Observation};
use nalgebra::{Matrix3, Vector2, Vector3};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;
use std::str::FromStr;

/// The refinement that follows the linear start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Levenberg-Marquardt with an analytic Jacobian (the default).
    #[default]
    Lm,
    /// Powell's direction-set method with Brent line searches, as in the paper.
    Powell,
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Method::Lm => "lm",
            Method::Powell => "powell",
        })
    }
}

impl FromStr for Method {
    type Err = CalibrationError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "lm" => Ok(Method::Lm),
            "powell" => Ok(Method::Powell),
            other => Err(CalibrationError::UnknownMethod {
                name: other.to_string(),
            }),
        }
    }
}

/// How [`calibrate`] solves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrateOptions {
    /// Refinement method.
    pub method: Method,
    /// Also estimate the skew of K (unknown intrinsics only); otherwise it is 0.
    pub estimate_skew: bool,
    /// Also estimate radial distortion k1, k2 (unknown intrinsics only).
    pub estimate_distortion: bool,
    /// Iteration limit: LM steps, or Powell direction-set sweeps.
    pub max_iterations: usize,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        Self {
            method: Method::Lm,
            estimate_skew: false,
            estimate_distortion: false,
            max_iterations: 200,
        }
    }
}

impl CalibrateOptions {
    /// The defaults with another method.
    pub fn with_method(method: Method) -> Self {
        Self {
            method,
            max_iterations: match method {
                Method::Lm => 200,
                Method::Powell => 2000,
            },
            ..Self::default()
        }
    }
}

/// One fiducial: a known world position and its marked pixel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Correspondence {
    /// World position in metres.
    pub world: [f64; 3],
    /// Pixel, origin at the top-left, pixel centres at integer + 0.5.
    pub pixel: [f64; 2],
}

/// Known intrinsics: only the pose is solved.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    /// K as three rows; must be upper triangular with positive focal lengths.
    pub camera_matrix: Vec<Vec<f64>>,
    /// Optional known distortion `[k1, k2, p1, p2, k3]`; only k1, k2 may be non-zero.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dist_coeffs: Option<Vec<f64>>,
}

/// The input file of `showcase-master calibrate`. Unknown keys are
/// errors: a misspelled `"intrinsics"` must not silently turn a pose-only
/// solve into a full one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationInput {
    /// Name of the device, e.g. `projector-0`.
    pub device: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The marked fiducials.
    pub points: Vec<Correspondence>,
    /// Known intrinsics, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intrinsics: Option<Intrinsics>,
}

/// The output file: OpenCV naming, `x_cam = R X + t`, `P = K [R | t]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Name of the device.
    pub device: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// K as rows.
    pub camera_matrix: [[f64; 3]; 3],
    /// `[k1, k2, p1, p2, k3]`.
    pub dist_coeffs: [f64; 5],
    /// R as rows (world to device).
    pub rotation: [[f64; 3]; 3],
    /// t (world to device), metres.
    pub translation: [f64; 3],
    /// `P = K [R | t]` as rows.
    pub projection: [[f64; 4]; 3],
    /// Root-mean-square pixel distance over the points.
    pub rms_px: f64,
    /// Pixel distance of each point, in input order.
    pub residuals_px: Vec<f64>,
    /// The refinement used.
    pub method: Method,
    /// Refinement iterations (LM steps or Powell sweeps).
    pub iterations: usize,
    /// Evaluations of the reprojection error during refinement.
    pub evaluations: usize,
    /// The refinement met its stopping test before the iteration limit.
    pub converged: bool,
    /// The intrinsics were given, and only the pose was solved.
    pub intrinsics_known: bool,
}

/// Why a calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// Fewer correspondences than the unknowns need.
    #[error("too few points: {found} given, at least {needed} needed {why}")]
    TooFewPoints {
        /// Points given.
        found: usize,
        /// Points needed.
        needed: usize,
        /// What the bound comes from.
        why: &'static str,
    },
    /// A NaN or infinite value in the input.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Where, e.g. `points[3].world`.
        what: String,
    },
    /// The world points lie on a line.
    #[error(
        "the fiducials are collinear (spread ratio {ratio:.3e}); no pose is determined by points on a line"
    )]
    Collinear {
        /// Second over first singular value of the centred points.
        ratio: f64,
    },
    /// The world points lie on a plane and no intrinsics were given.
    #[error(
        "the fiducials are coplanar (thickness ratio {ratio:.3e}); coplanar points need known intrinsics: add \"intrinsics\": {{\"camera_matrix\": [[fx, s, cx], [0, fy, cy], [0, 0, 1]]}} or use non-coplanar fiducials"
    )]
    CoplanarWithoutIntrinsics {
        /// Third over first singular value of the centred points.
        ratio: f64,
    },
    /// The given `camera_matrix` is not a usable K.
    #[error("invalid camera_matrix: {reason}")]
    InvalidCameraMatrix {
        /// What is wrong with it.
        reason: String,
    },
    /// The given `dist_coeffs` are not usable.
    #[error("invalid dist_coeffs: {reason}")]
    InvalidDistCoeffs {
        /// What is wrong with them.
        reason: String,
    },
    /// Width or height is zero.
    #[error("invalid image size {width}x{height}")]
    InvalidImageSize {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// The solved device has a fiducial behind it: the correspondences are inconsistent.
    #[error("point {index} at {world:?} is behind the device after the solve (depth {depth:.4} m)")]
    PointBehindDevice {
        /// Index into `points`.
        index: usize,
        /// Its world position.
        world: [f64; 3],
        /// Its depth along the optical axis.
        depth: f64,
    },
    /// The points admit no unique solution.
    #[error("degenerate configuration: {reason}")]
    Degenerate {
        /// Why.
        reason: String,
    },
    /// A method name other than `lm` or `powell`.
    #[error("unknown calibration method {name:?}; use lm or powell")]
    UnknownMethod {
        /// The name given.
        name: String,
    },
}

/// K from the input rows, checked: 3x3, finite, upper triangular, `K[2][2] > 0`
/// (scaled to 1), positive focal lengths.
fn parse_camera_matrix(rows: &[Vec<f64>]) -> Result<Matrix3<f64>, CalibrationError> {
    let invalid = |reason: String| CalibrationError::InvalidCameraMatrix { reason };
    if rows.len() != 3 || rows.iter().any(|r| r.len() != 3) {
        let shape: Vec<usize> = rows.iter().map(Vec::len).collect();
        return Err(invalid(format!(
            "expected 3 rows of 3, got rows of lengths {shape:?}"
        )));
    }
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(CalibrationError::NonFinite {
            what: "intrinsics.camera_matrix".to_string(),
        });
    }
    let k = Matrix3::from_fn(|r, c| rows[r][c]);
    let scale = k[(2, 2)];
    if scale.is_nan() || scale <= 0.0 {
        return Err(invalid(format!("K[2][2] is {scale}, expected 1")));
    }
    let k = k / scale;
    let magnitude = k.abs().max();
    for (r, c) in [(1, 0), (2, 0), (2, 1)] {
        if k[(r, c)].abs() > 1e-12 * magnitude {
            return Err(invalid(format!(
                "K[{r}][{c}] is {}, expected 0 (K is upper triangular)",
                k[(r, c)]
            )));
        }
    }
    if !(k[(0, 0)] > 0.0 && k[(1, 1)] > 0.0) {
        return Err(invalid(format!(
            "focal lengths fx = {}, fy = {} must be positive (the matrix is singular or mirrored)",
            k[(0, 0)],
            k[(1, 1)]
        )));
    }
    Ok(Matrix3::from_fn(|r, c| if r > c { 0.0 } else { k[(r, c)] }))
}

fn parse_dist_coeffs(coeffs: &[f64]) -> Result<(f64, f64), CalibrationError> {
    let invalid = |reason: String| CalibrationError::InvalidDistCoeffs { reason };
    if coeffs.is_empty() || coeffs.len() > 5 {
        return Err(invalid(format!(
            "expected 1 to 5 values [k1, k2, p1, p2, k3], got {}",
            coeffs.len()
        )));
    }
    if coeffs.iter().any(|v| !v.is_finite()) {
        return Err(CalibrationError::NonFinite {
            what: "intrinsics.dist_coeffs".to_string(),
        });
    }
    if coeffs.iter().skip(2).any(|&v| v != 0.0) {
        return Err(invalid(format!(
            "only k1 and k2 are modelled; p1, p2, k3 must be 0, got {coeffs:?}"
        )));
    }
    Ok((coeffs[0], coeffs.get(1).copied().unwrap_or(0.0)))
}

/// Validated observations and, if given, the known intrinsics as a model
/// (with an identity pose).
fn validate(
    input: &CalibrationInput,
) -> Result<(Vec<Observation>, Option<CameraModel>), CalibrationError> {
    if input.width == 0 || input.height == 0 {
        return Err(CalibrationError::InvalidImageSize {
            width: input.width,
            height: input.height,
        });
    }
    let mut obs = Vec::with_capacity(input.points.len());
    for (i, p) in input.points.iter().enumerate() {
        if p.world.iter().any(|v| !v.is_finite()) {
            return Err(CalibrationError::NonFinite {
                what: format!("points[{i}].world"),
            });
        }
        if p.pixel.iter().any(|v| !v.is_finite()) {
            return Err(CalibrationError::NonFinite {
                what: format!("points[{i}].pixel"),
            });
        }
        let [u, v] = p.pixel;
        if !(0.0..=input.width as f64).contains(&u) || !(0.0..=input.height as f64).contains(&v) {
            tracing::warn!(
                point = i,
                u,
                v,
                "fiducial pixel lies outside the {}x{} image",
                input.width,
                input.height
            );
        }
        obs.push(Observation {
            world: Vector3::from(p.world),
            pixel: Vector2::from(p.pixel),
        });
    }
    let known = match &input.intrinsics {
        None => None,
        Some(intr) => {
            let k = parse_camera_matrix(&intr.camera_matrix)?;
            let mut model = CameraModel::from_k(&k, Matrix3::identity(), Vector3::zeros());
            if let Some(d) = &intr.dist_coeffs {
                (model.k1, model.k2) = parse_dist_coeffs(d)?;
            }
            Some(model)
        }
    };
    Ok((obs, known))
}

/// Calibrate one device from its fiducial correspondences.
///
/// Errors, never a wrong answer, for too few points, collinear points,
/// coplanar points without intrinsics, non-finite values, a bad
/// `camera_matrix`, and a point that ends behind the device.
pub fn calibrate(
    input: &CalibrationInput,
    opts: &CalibrateOptions,
) -> Result<Calibration, CalibrationError> {
    let (obs, known) = validate(input)?;
    let layout = Layout {
        intrinsics: known.is_none(),
        skew: opts.estimate_skew,
        distortion: opts.estimate_distortion,
    };
    let (needed, why) = if known.is_some() {
        (4, "for a pose with known intrinsics")
    } else {
        (
            6.max(layout.len() / 2 + 1),
            "for a DLT with unknown intrinsics",
        )
    };
    if obs.len() < needed {
        return Err(CalibrationError::TooFewPoints {
            found: obs.len(),
            needed,
            why,
        });
    }
    let spread = dlt::spread(&obs);
    if spread.line_ratio < dlt::COLLINEAR_RATIO {
        return Err(CalibrationError::Collinear {
            ratio: spread.line_ratio,
        });
    }
    let coplanar = spread.plane_ratio < dlt::COPLANAR_RATIO;
    let mut start = match &known {
        None if coplanar => {
            return Err(CalibrationError::CoplanarWithoutIntrinsics {
                ratio: spread.plane_ratio,
            });
        }
        None => dlt::decompose_projection(&dlt::projection_dlt(&obs, &spread)?, &obs)?,
        Some(k) if coplanar => pnp::pose_from_homography(k, &obs, &spread)?,
        Some(k) => pnp::epnp(k, &obs, &spread)?,
    };
    if layout.intrinsics && !layout.skew {
        start.skew = 0.0;
    }
    let refined = match opts.method {
        Method::Lm => lm::refine(&start, &obs, layout, opts.max_iterations),
        Method::Powell => powell::refine(
            &start,
            &obs,
            layout,
            powell::PowellSettings {
                ftol: 1e-12,
                line_tol: 1e-7,
                max_sweeps: opts.max_iterations,
            },
        ),
    };
    let model = &refined.model;
    for (index, o) in obs.iter().enumerate() {
        let depth = model.to_device(&o.world).z;
        if depth.is_nan() || depth <= 0.0 {
            return Err(CalibrationError::PointBehindDevice {
                index,
                world: o.world.into(),
                depth,
            });
        }
    }
    if !(model.is_finite() && model.fx > 0.0 && model.fy > 0.0) {
        return Err(CalibrationError::Degenerate {
            reason: format!(
                "the refinement ended at an invalid K (fx {}, fy {})",
                model.fx, model.fy
            ),
        });
    }
    Ok(Calibration::from_model(
        &input.device,
        input.width,
        input.height,
        model,
        &obs,
        opts.method,
        &refined,
        known.is_some(),
    ))
}

/// Read a points file, calibrate, and write the result as JSON to `out`.
/// Errors name the file.
pub fn run_calibrate_file(
    points: &Path,
    out: &Path,
    method: Method,
) -> anyhow::Result<Calibration> {
    io::run_calibrate_file(points, out, method)
}
