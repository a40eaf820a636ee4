//! Showcase's pure light transport: no IO, no GPU, no clock.
//!
//! - Ray casting and visibility: [`geometry`] (a `Showcase` as world-space
//!   triangles in a [`bvh`]), [`ray`], device projection ([`device`]), the
//!   intensity image of paper eq. 3.1 ([`intensity`]), closed-form
//!   polygon irradiance ([`lambert`]), the flat-Lambert rasteriser
//!   ([`raster`]).
//! - [`sampling`]: the one home of seeded hashes and sample patterns.
//! - [`finite`]: the one rule that turns NaN and infinities into zero.
//! - [`spot`]: the one spot-light cone, shared by [`render`] and
//!   [`radiosity`].
//! - [`sim`]: the simulated showcase, our ground truth, behind the
//!   [`hardware`] traits that real projectors and cameras implement too.
//! - [`reflectance`]: reflectance-map math (paper section 3).
//! - [`radiosity`]: augmented radiosity (paper section 4).
//! - [`render`]: the real-time renderer's pure half (paper section 5):
//!   the frame model and the CPU references every GPU pass is checked
//!   against.
//! - [`mirror_view`], [`observer_view`]: a CRT face seen through the beam
//!   splitter, and what an observer sees.
//! - [`metrics`] and [`image`]: the error metrics and images everything
//!   is measured with.
#![forbid(unsafe_code)]
// `!(x > 0.0)` is deliberate throughout: it is also true for NaN, which is
// how bad input is turned away instead of propagated.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bvh;
mod ciede2000;
pub mod device;
pub mod digest;
pub mod finite;
pub mod geometry;
pub mod hardware;
pub mod image;
pub mod intensity;
pub mod lambert;
pub mod metrics;
pub mod mirror_view;
pub mod observer_view;
pub mod radiosity;
pub mod raster;
pub mod ray;
pub mod reflectance;
pub mod render;
pub mod sampling;
pub mod sim;
pub mod spot;

pub use device::{DeviceError, DeviceRays};
pub use geometry::{
    GeometryError, Hit, ObjectFilter, Occluders, SceneGeometry, WorldTriangle, world_matrix,
};
pub use image::{Image, RgbImage};
pub use intensity::{IntensityImage, IntensityLight, SurfaceSample, render_intensity};
pub use lambert::{LambertError, form_factor_point_polygon, polygon_irradiance};
pub use metrics::MetricError;
pub use ray::{Aabb, Ray};
