//! The real-time renderer of paper section 5, its pure half: the frame
//! model every role draws from ([`frame`]: lights resolved into samples,
//! eyes, occluders), and the CPU references that the GPU passes which
//! compute a result are checked against: the projector role's irradiance maps with shadows,
//! ambient, occlusion shadows and device compensation ([`projector`]),
//! the face role's views through the beam splitter ([`face`]) with
//! cube-map reflections ([`cube_map`]), projector blending ([`blend`]) and
//! the direct-light consistency check ([`consistency`]).
#![forbid(unsafe_code)]
// `!(x > 0.0)` is deliberate: it is also true for NaN, which is how bad
// input is turned away instead of propagated.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod blend;
pub mod consistency;
pub mod cube_map;
pub mod face;
pub mod frame;
pub mod indirect;
pub mod projector;

pub use frame::{FrameScene, LightSample, Lobe};
pub use indirect::{FieldPiece, IndirectField, IndirectFieldError, IndirectLight};
pub use projector::{IrradianceMap, Occluders, PixelState, ProjectorOptions, irradiance_map_cpu};

use crate::{DeviceError, GeometryError};

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
}
