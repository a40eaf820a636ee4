//! Automatic projector calibration by structured light: each projector
//! shows Gray-code patterns of its columns and rows (with inverses, and a
//! white and a black reference), the calibrated camera captures them, and
//! every camera pixel that decodes to a projector pixel becomes a 2D-3D
//! correspondence through the known geometry (its ray meets the scene);
//! the DLT + LM solver of [`crate::calibrate`] fits the projector to them.
//!
//! Stages of [`calibrate_structured_light`]:
//! 1. capture: every pattern of [`patterns`], `frames` frames each, at an
//!    exposure of whole colour-wheel turns;
//! 2. reference checks ([`decode`]): a dark or saturated white reference,
//!    or a saturated black one, stops the job with what to change;
//! 3. decode with a per-pixel validity mask; too few valid pixels stop
//!    the job with the counts and what to check;
//! 4. correspondences ([`correspondences`]): ray casting, depth edges,
//!    neighbour consistency, thinning, a held-out tenth;
//! 5. the solve, twice more without the points beyond
//!    `max(outlier_px, 3 x median residual)`.
//!
//! Only the [`ProjectorDevice`] and [`CameraDevice`] traits are used (of
//! the projector, only its image size: its geometry is what is solved):
//! patterns go through `show_pattern` (a Gray-code bit is a few bytes to a
//! projector node) and each pattern's frames through `capture_series` (one
//! request to a camera node), so the cluster's `RemoteProjector` and
//! `RemoteCamera` plug in unchanged.

pub mod bench;
mod capture;
mod correspondences;
pub mod decode;
mod error;
mod job;
pub mod patterns;

pub use capture::{Captured, MAX_EXPOSURE_S, capture_and_decode};
pub use correspondences::{CorrespondenceSettings, Correspondences, Dropped, correspondences};
pub use decode::{DecodeSettings, Decoded};
pub use error::StructuredLightError;
pub use job::{
    ProjectorSummary, StructuredLightJob, StructuredLightSummary, Target, Targets, ThroughNodes,
    calibrate_targets, run_config_structured_light, run_structured_light,
    run_structured_light_on_nodes,
};
pub use patterns::{Axis, Pattern, PatternSet, bits_for, gray, gray_inverse};

use super::{CalibrateOptions, Calibration, CalibrationInput, calibrate};
use serde::Serialize;
use showcase_light::hardware::{CameraDevice, ProjectorDevice};
use showcase_light::{DeviceRays, SceneGeometry};
use std::time::Instant;

/// Paths per camera pixel of the simulated showcase's light transport for
/// a full-white pattern, in the job and the bench (the direct light is
/// exact whatever the count; the paths only estimate the interreflected
/// light).
pub const SIM_SAMPLES: u32 = 2;

/// Settings of a structured-light calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct StructuredLightOptions {
    /// Camera exposure in seconds, rounded to whole colour-wheel turns of a
    /// time-sliced projector; `None`: automatic, from the camera's own
    /// (halved while the white reference clips, lengthened up to
    /// [`MAX_EXPOSURE_S`] while it is dim).
    pub exposure_s: Option<f64>,
    /// Frames averaged per pattern (at least 1).
    pub frames: u32,
    /// Pixel value of the projector's lit pixels (0 to 1).
    pub level: f32,
    /// Fewest valid decoded camera pixels (and correspondences) accepted.
    pub min_valid_pixels: usize,
    /// Smallest outlier threshold of the robust refits, projector pixels.
    pub outlier_px: f64,
    /// Decode thresholds.
    pub decode: DecodeSettings,
    /// Correspondence selection.
    pub correspondences: CorrespondenceSettings,
    /// The solver.
    pub calibrate: CalibrateOptions,
}

impl Default for StructuredLightOptions {
    fn default() -> Self {
        Self {
            exposure_s: None,
            frames: 1,
            level: 1.0,
            min_valid_pixels: 2000,
            outlier_px: 1.5,
            decode: DecodeSettings::default(),
            correspondences: CorrespondenceSettings::default(),
            calibrate: CalibrateOptions::default(),
        }
    }
}

/// Seconds spent per stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StageSeconds {
    /// Showing and capturing the patterns (with the sim, its light transport).
    pub capture: f64,
    /// Decoding and the correspondences.
    pub decode: f64,
    /// The solves.
    pub solve: f64,
}

/// A structured-light calibration and how it went.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StructuredLightOutcome {
    /// The calibration (its `rms_px` and residuals: the final fit points).
    pub calibration: Calibration,
    /// Patterns shown.
    pub patterns: usize,
    /// Camera frames taken.
    pub frames: usize,
    /// Exposure used (seconds).
    pub exposure_s: f64,
    /// Camera pixels the projector lights.
    pub lit_pixels: usize,
    /// Camera pixels with a valid decode.
    pub valid_pixels: usize,
    /// Valid pixels that passed the geometric tests.
    pub accepted_pixels: usize,
    /// Why valid pixels were dropped.
    pub dropped: Dropped,
    /// Correspondences fitted (after the outliers left).
    pub fit_points: usize,
    /// Outliers removed by the robust refits.
    pub outliers: usize,
    /// Held-out correspondences.
    pub heldout_points: usize,
    /// RMS distance of the held-out correspondences' decoded projector
    /// pixels from their reprojection (includes the decode's own
    /// quantisation, about 0.41 px).
    pub heldout_rms_px: f64,
    /// The held-out correspondences themselves.
    #[serde(skip)]
    pub heldout: Vec<super::Correspondence>,
    /// Time per stage.
    pub seconds: StageSeconds,
}

/// Calibrate the projector `name` by structured light seen by `camera`,
/// whose geometry (`camera.device()`) is trusted, in the known `geometry`.
/// `progress(done, total, what)` is told after each pattern and solve.
pub fn calibrate_structured_light<P: ProjectorDevice, C: CameraDevice>(
    name: &str,
    projector: &mut P,
    camera: &mut C,
    geometry: &SceneGeometry,
    options: &StructuredLightOptions,
    progress: &dyn Fn(usize, usize, &str),
) -> Result<StructuredLightOutcome, StructuredLightError> {
    let device = || name.to_string();
    let rays = DeviceRays::new(camera.device()).map_err(|source| StructuredLightError::Camera {
        device: device(),
        source,
    })?;
    let (pw, ph) = (projector.device().width, projector.device().height);
    let t = Instant::now();
    let Captured {
        decoded,
        patterns,
        frames,
        exposure_s: exposure,
    } = capture_and_decode(name, projector, camera, options, progress)?;
    let total = patterns + 1;
    let capture_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let valid = decoded.valid();
    if valid < options.min_valid_pixels {
        return Err(StructuredLightError::TooFewValid {
            device: device(),
            valid,
            needed: options.min_valid_pixels,
            lit: decoded.lit,
            unclear: decoded.unclear,
            out_of_range: decoded.out_of_range,
            exposure_s: exposure,
        });
    }
    let corr = correspondences(&decoded, &rays, geometry, &options.correspondences);
    if corr.accepted < options.min_valid_pixels {
        return Err(StructuredLightError::TooFewCorrespondences {
            device: device(),
            valid,
            accepted: corr.accepted,
            dropped: corr.dropped,
            needed: options.min_valid_pixels,
        });
    }
    let decode_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let solve = |points: Vec<super::Correspondence>| {
        let input = CalibrationInput {
            device: name.to_string(),
            width: pw,
            height: ph,
            points,
            intrinsics: None,
        };
        let n = input.points.len();
        calibrate(&input, &options.calibrate)
            .map(|c| (c, input.points))
            .map_err(|source| StructuredLightError::Solve {
                device: device(),
                points: n,
                source,
            })
    };
    let all = corr.fit.len();
    let (mut cal, mut points) = solve(corr.fit)?;
    for _ in 0..2 {
        let mut r = cal.residuals_px.clone();
        r.sort_by(f64::total_cmp);
        let threshold = options.outlier_px.max(3.0 * r[r.len() / 2]);
        if cal.residuals_px.iter().all(|r| *r <= threshold) {
            break;
        }
        let kept: Vec<_> = points
            .iter()
            .zip(&cal.residuals_px)
            .filter(|(_, r)| **r <= threshold)
            .map(|(p, _)| *p)
            .collect();
        (cal, points) = solve(kept)?;
    }
    progress(total, total, "solved");
    let heldout_rms_px = super::heldout_rms(&cal, &corr.heldout);
    Ok(StructuredLightOutcome {
        patterns,
        frames,
        exposure_s: exposure,
        lit_pixels: decoded.lit,
        valid_pixels: valid,
        accepted_pixels: corr.accepted,
        dropped: corr.dropped,
        fit_points: points.len(),
        outliers: all - points.len(),
        heldout_points: corr.heldout.len(),
        heldout_rms_px,
        heldout: corr.heldout,
        seconds: StageSeconds {
            capture: capture_s,
            decode: decode_s,
            solve: t.elapsed().as_secs_f64(),
        },
        calibration: cal,
    })
}
