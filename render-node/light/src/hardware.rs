//! The hardware seam: what the capture and calibration jobs need of a
//! projector and a camera. The simulated showcase ([`crate::sim`])
//! implements these traits, and so does real hardware; the names say
//! "device" so that they do not clash with the scene model's
//! `showcase_proto::Projector` and `showcase_proto::Camera`, which only
//! describe a device.

use crate::{Image, RgbImage};
use glam::Vec3;
use showcase_proto::capture::{Pattern, frame_start_s};
use showcase_proto::{CameraResponse, PinholeDevice};

/// The image a projector of `width x height` pixels shows for `pattern`
/// (a mask at its own size, so that a wrong size is the device's error).
pub fn pattern_image(pattern: &Pattern, width: u32, height: u32) -> RgbImage {
    let (w, h) = match pattern {
        Pattern::Mask { width, height, .. } => (*width, *height),
        _ => (width, height),
    };
    Image {
        width: w,
        height: h,
        data: pattern
            .pixels(w, h)
            .into_iter()
            .map(Vec3::from_array)
            .collect(),
    }
}

/// The pattern that shows exactly `image`, when one does: every pixel one
/// level ([`Pattern::Full`]), or each pixel black or one level
/// ([`Pattern::Mask`]). `None` for any other image.
pub fn pattern_of(image: &RgbImage) -> Option<Pattern> {
    let first = *image.data.first()?;
    if image.data.iter().all(|v| *v == first) {
        return Some(Pattern::Full {
            level: first.to_array(),
        });
    }
    let level = *image.data.iter().find(|v| **v != Vec3::ZERO)?;
    if !image.data.iter().all(|v| *v == Vec3::ZERO || *v == level) {
        return None;
    }
    Some(Pattern::mask(
        image.width,
        image.height,
        image.data.iter().map(|v| *v == level),
        level.to_array(),
    ))
}

/// A video projector: shows an image of pixel values in `[0, 1]` (values
/// outside are clamped).
pub trait ProjectorDevice {
    /// Error type of the device.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Geometry of the projector.
    fn device(&self) -> &PinholeDevice;
    /// Show `image` (linear pixel values, RGB) until the next call.
    fn show(&mut self, image: &RgbImage) -> Result<(), Self::Error>;
    /// Show a pattern (a level, a piece's mask, a Gray-code bit) until the
    /// next call: by default the image of [`pattern_image`] through
    /// [`Self::show`]; a projector behind a network sends the pattern
    /// itself.
    fn show_pattern(&mut self, pattern: &Pattern) -> Result<(), Self::Error> {
        let d = self.device();
        let image = pattern_image(pattern, d.width, d.height);
        self.show(&image)
    }
    /// Duration of one colour-wheel turn (the display period) in seconds, as
    /// known from the projector's refresh rate; 0 for a projector without
    /// time slicing.
    fn wheel_period_s(&self) -> f64;
}

/// One frame of a camera: quantised codes per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraFrame {
    /// Codes in `0..=2^bits - 1`.
    pub codes: Image<[u16; 3]>,
    /// Bits per channel.
    pub bits: u32,
}

/// A video camera: captures a frame with a given exposure start and
/// duration.
pub trait CameraDevice {
    /// Error type of the device.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Geometry of the camera.
    fn device(&self) -> &PinholeDevice;
    /// Photometric calibration (response curve, gain, bits), used to turn
    /// codes back into radiance.
    fn response(&self) -> &CameraResponse;
    /// Capture one frame exposed from `start_s` for `exposure_s` seconds.
    fn capture(&mut self, start_s: f64, exposure_s: f64) -> Result<CameraFrame, Self::Error>;
    /// Capture `count` frames exposed for `exposure_s` each, their starts
    /// spread over the display period `period_s` (the DLP averaging of
    /// paper 3.2, [`frame_start_s`]): by default one [`Self::capture`] per
    /// frame; a camera behind a network asks for them all at once.
    fn capture_series(
        &mut self,
        exposure_s: f64,
        period_s: f64,
        count: u32,
    ) -> Result<Vec<CameraFrame>, Self::Error> {
        (0..count)
            .map(|k| self.capture(frame_start_s(k, count, period_s), exposure_s))
            .collect()
    }
}
