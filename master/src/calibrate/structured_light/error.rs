//! Why a structured-light calibration stops, in words a technician acts on.

use super::Dropped;
use crate::calibrate::CalibrationError;

/// Why a structured-light calibration stopped; every message says what to
/// change.
#[derive(Debug, thiserror::Error)]
pub enum StructuredLightError {
    /// The white reference is too dark to decode.
    #[error(
        "{device}: the white reference frame is too dark: its brightest pixels reach {:.1} % of the camera's full scale, at least {:.0} % is needed; raise the camera exposure (now {exposure_s:.4} s, --exposure) or its gain, or the projector level (now {level}, --level), and check that the projector is on and that the camera sees what it lights",
        100.0 * peak,
        100.0 * needed
    )]
    Dark {
        /// The projector.
        device: String,
        /// The white frame's 99th-percentile largest channel, 0 to 1.
        peak: f64,
        /// The least accepted.
        needed: f64,
        /// Exposure used.
        exposure_s: f64,
        /// Projector level used.
        level: f32,
    },
    /// A reference frame clips.
    #[error(
        "{device}: the {frame} reference frame is saturated: {:.1} % of {} pixels clip; lower the camera exposure (now {exposure_s:.4} s, --exposure) or its gain{}",
        100.0 * fraction,
        if *frame == "white" { "the projector-lit" } else { "its" },
        if *frame == "white" { format!(", or the projector level (now {level}, --level)") } else { ", and darken the room: the black frame shows light that is not the projector's".to_string() }
    )]
    Saturated {
        /// The projector.
        device: String,
        /// `white` or `black`.
        frame: &'static str,
        /// Fraction of the pixels that clip.
        fraction: f64,
        /// Exposure used.
        exposure_s: f64,
        /// Projector level used.
        level: f32,
    },
    /// Too few camera pixels decoded a projector pixel.
    #[error(
        "{device}: only {valid} camera pixels decoded a projector pixel, at least {needed} are needed ({lit} pixels lit by the projector, {unclear} of them with a pattern bit too faint to read, {out_of_range} outside its image); check that the camera sees what the projector lights (aim, focus, lens cap), that the room is dark, and the exposure (now {exposure_s:.4} s, --exposure; more --frames per pattern lower the noise)"
    )]
    TooFewValid {
        /// The projector.
        device: String,
        /// Valid pixels.
        valid: usize,
        /// The least accepted.
        needed: usize,
        /// Pixels the projector lights.
        lit: usize,
        /// Lit pixels with an unclear bit.
        unclear: usize,
        /// Lit pixels decoded outside the projector's image.
        out_of_range: usize,
        /// Exposure used.
        exposure_s: f64,
    },
    /// Too few decoded pixels land on the known geometry.
    #[error(
        "{device}: {valid} camera pixels decoded, but only {accepted} of them give a usable point on the scene's geometry ({dropped:?}), at least {needed} are needed; check that the scene file describes the cabinet as it stands and that the camera's calibration is current"
    )]
    TooFewCorrespondences {
        /// The projector.
        device: String,
        /// Valid decoded pixels.
        valid: usize,
        /// Those that passed the geometric tests.
        accepted: usize,
        /// Why the others were dropped.
        dropped: Dropped,
        /// The least accepted.
        needed: usize,
    },
    /// The projector or camera failed.
    #[error("{device}: the {what} failed: {source}")]
    Device {
        /// The projector.
        device: String,
        /// `projector` or `camera`.
        what: &'static str,
        /// The device's error.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The camera's geometry is unusable.
    #[error("{device}: the camera's calibration is unusable: {source}")]
    Camera {
        /// The projector.
        device: String,
        /// Why.
        source: showcase_light::DeviceError,
    },
    /// The solver failed.
    #[error("{device}: the solve from {points} structured-light correspondences failed: {source}")]
    Solve {
        /// The projector.
        device: String,
        /// Fit points.
        points: usize,
        /// Why.
        source: CalibrationError,
    },
}
