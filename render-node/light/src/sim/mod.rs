//! The simulated showcase (DESIGN section 4): projectors and cameras that
//! behave like real hardware behind the [`crate::hardware`] traits
//! ([`ProjectorDevice`], [`CameraDevice`]), over one shared physical world whose light transport
//! (path tracing with next-event estimation, [`world`]) is independent of
//! the product's radiosity solver. It knows the true albedo of every real
//! object, so it is the ground truth every capture is judged against.
#![forbid(unsafe_code)]
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod devices;
pub mod irradiance_cache;
pub mod lights;
mod mirrors;
pub mod quantiser;
pub mod world;

pub use devices::{SimCamera, SimConfig, SimProjector, SimShowcase, wheel_weights};
pub use irradiance_cache::{CacheOptions, IrradianceCache};
pub use lights::SimLights;
pub use world::{ExitanceEstimate, ProjectorLight, RayEnd, SimWorld, SurfacePoint, TransportImage};

use crate::{DeviceError, DeviceRays, GeometryError, ObjectFilter, RgbImage};
use showcase_proto::{PinholeDevice, Showcase};

#[cfg(doc)]
use crate::hardware::{CameraDevice, ProjectorDevice};

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
    /// A light that is not finite, a spot without an axis, or an area
    /// light without an area.
    #[error(
        "light `{name}` is not a usable light: give it finite values, a spot a direction, an area light two non-parallel edges"
    )]
    BadLight {
        /// The light's name (`ambient` for the scene's ambient).
        name: String,
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
    Ok(world
        .render(&rays, &SimLights::none(), samples_per_pixel, seed)
        .total())
}
