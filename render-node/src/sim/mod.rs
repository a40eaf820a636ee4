//! The simulated showcase (DESIGN section 4): projectors and cameras that
//! behave like real hardware behind the [`Projector`] and [`Camera`]
//! traits, over one shared physical world whose light transport
//! (path tracing with next-event estimation, [`world`]) is independent of
//! the product's radiosity solver. It knows the true albedo of every real
//! object, so it is the ground truth every capture is judged against.
#![forbid(unsafe_code)]
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod devices;
pub mod pfm;
pub mod world;

pub use devices::{SimCamera, SimConfig, SimProjector, SimShowcase, wheel_weights};
pub use pfm::{PfmError, decode_pfm, encode_pfm, encode_pfm_grey, read_pfm, write_pfm};
pub use world::{
    ProjectorLight, SimWorld, TransportImage, cosine_direction, pixel_seed, stratified_point,
};

use crate::light::{DeviceError, DeviceRays, GeometryError, Image, ObjectFilter, RgbImage};
use showcase_proto::{CameraResponse, PinholeDevice, Showcase};

/// Why the simulated showcase refused a request.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The scene could not be turned into ray-casting geometry.
    #[error("scene geometry: {0}")]
    Geometry(#[from] GeometryError),
    /// A device cannot cast rays.
    #[error("device: {0}")]
    Device(#[from] DeviceError),
    /// An image does not have the device's size.
    #[error("image is {got:?} pixels, the device has {expected:?}")]
    ImageSize {
        /// The device's `(width, height)`.
        expected: (u32, u32),
        /// The image's `(width, height)`.
        got: (u32, u32),
    },
    /// A device index past the scene's devices.
    #[error("no {what} with index {index}")]
    NoDevice {
        /// `projector` or `camera`.
        what: &'static str,
        /// The index asked for.
        index: usize,
    },
    /// An exposure start or duration that is not finite or is negative.
    #[error(
        "exposure start {start_s} s / duration {duration_s} s is not a finite non-negative time"
    )]
    BadExposure {
        /// Exposure start in seconds.
        start_s: f64,
        /// Exposure duration in seconds.
        duration_s: f64,
    },
}

/// A video projector: shows an image of pixel values in `[0, 1]` (values
/// outside are clamped).
pub trait Projector {
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
pub struct Frame {
    /// Codes in `0..=2^bits - 1`.
    pub codes: Image<[u16; 3]>,
    /// Bits per channel.
    pub bits: u32,
}

/// A video camera: captures a frame with a given exposure start and
/// duration.
pub trait Camera {
    /// Error type of the device.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Geometry of the camera.
    fn device(&self) -> &PinholeDevice;
    /// Photometric calibration (response curve, gain, bits), used to turn
    /// codes back into radiance.
    fn response(&self) -> &CameraResponse;
    /// Capture one frame exposed from `start_s` for `exposure_s` seconds.
    fn capture(&mut self, start_s: f64, exposure_s: f64) -> Result<Frame, Self::Error>;
}

/// Render `scene` from `device` as linear radiance (W/m^2/sr), lit only by
/// its own emitters (`Material::emission`, e.g. OBJ `Ke`), with every
/// object (real and virtual) present. `samples_per_pixel` paths per pixel;
/// the result depends only on `seed`.
pub fn render_view(
    scene: &Showcase,
    device: &PinholeDevice,
    samples_per_pixel: u32,
    seed: u64,
) -> Result<RgbImage, SimError> {
    let world = SimWorld::new(scene, &ObjectFilter::All, true)?;
    let rays = DeviceRays::new(device)?;
    Ok(world.render(&rays, None, samples_per_pixel, seed).total())
}
