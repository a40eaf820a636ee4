//! Pure light transport: no IO, no GPU. Ray casting, device projection,
//! visibility and the CPU reference renderers that every GPU pass is
//! checked against.
#![forbid(unsafe_code)]
// `!(x > 0.0)` is deliberate throughout: it is also true for NaN, which is
// how bad input is turned away instead of propagated.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bvh;
mod ciede2000;
pub mod device;
pub mod geometry;
pub mod image;
pub mod intensity;
pub mod lambert;
pub mod metrics;
pub mod raster;
pub mod ray;

pub use device::{DeviceError, DeviceRays};
pub use geometry::{GeometryError, Hit, ObjectFilter, SceneGeometry, WorldTriangle, world_matrix};
pub use image::{Image, RgbImage};
pub use intensity::{IntensityImage, IntensityLight, SurfaceSample, render_intensity};
pub use lambert::{LambertError, form_factor_point_polygon, polygon_irradiance};
pub use metrics::MetricError;
pub use ray::{Aabb, Ray};
