//! The hardware seam: what the capture and calibration jobs need of a
//! projector and a camera. The simulated showcase ([`crate::sim`])
//! implements these traits, and so does real hardware; the names say
//! "device" so that they do not clash with the scene model's
//! `showcase_proto::Projector` and `showcase_proto::Camera`, which only
//! describe a device.

use crate::{Image, RgbImage};
use showcase_proto::{CameraResponse, PinholeDevice};

/// A video projector: shows an image of pixel values in `[0, 1]` (values
/// outside are clamped).
pub trait ProjectorDevice {
    /// Error type of the device.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Geometry of the projector.
    fn device(&self) -> &PinholeDevice;
    /// Show `image` (linear pixel values, RGB) until the next call.
    fn show(&mut self, image: &RgbImage) -> Result<(), Self::Error>;
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
}
