//! The real-time renderer of paper section 5, as CPU references (pure)
//! and the GPU pipeline every render node runs: the projector role's
//! irradiance maps with shadows, ambient, occlusion shadows and device
//! compensation ([`projector`], [`projector_gpu`]), the face role's views
//! through the beam splitter ([`face`], [`face_gpu`]) with cube-map
//! reflections ([`cube_map`]), the direct-light consistency check
//! ([`consistency`]), and the pass list that skips what a frame does not
//! need ([`passes`]).
#![forbid(unsafe_code)]
// `!(x > 0.0)` is deliberate: it is also true for NaN, which is how bad
// input is turned away instead of propagated (as in `light`).
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod blend;
pub mod compare;
pub mod consistency;
pub mod cube_map;
pub mod face;
pub mod face_gpu;
pub mod frame;
pub mod gpu_scene;
pub mod passes;
pub mod projector;
pub mod projector_gpu;

pub use frame::{FrameScene, LightSample, Lobe};
pub use projector::{IrradianceMap, Occluders, PixelState, ProjectorOptions, irradiance_map_cpu};

use crate::light::{DeviceError, GeometryError};

/// Why a frame cannot be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderSetupError {
    /// The scene's geometry is broken.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// A device cannot cast rays.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// A light has non-finite or degenerate parameters.
    #[error("light {name} has non-finite or degenerate parameters")]
    BadLight {
        /// The light's name.
        name: String,
    },
    /// A frame's object transform names an object the scene lacks.
    #[error("frame moves object {object} but the scene has {count} objects")]
    ObjectOutOfRange {
        /// The index in the frame.
        object: u32,
        /// Objects in the scene.
        count: usize,
    },
    /// An eye position or the ambient term is not finite.
    #[error("an eye position or the ambient irradiance is not finite")]
    NonFinite,
    /// The scene has no projector of this index.
    #[error("the scene has no projector {index}")]
    NoProjector {
        /// The requested index.
        index: usize,
    },
    /// A frame was read back before one was drawn.
    #[error("no frame has been drawn yet")]
    NothingDrawn,
    /// A GPU operation failed.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
}
