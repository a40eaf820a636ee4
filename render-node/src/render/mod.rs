//! The real-time renderer of paper section 5 on the GPU: the projector
//! role's pipeline ([`projector_gpu`]) and the face role's
//! ([`face_gpu`]), the scene's GPU buffers ([`gpu_scene`]), the pass list
//! that skips what a frame does not need ([`passes`]), the GPU-against-CPU
//! map comparison ([`compare`]) and the render bench ([`bench`]). Their
//! CPU references and the frame model are `showcase_light::render`.
#![forbid(unsafe_code)]
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod compare;
pub mod face_gpu;
pub mod gpu_scene;
pub mod passes;
pub mod projector_gpu;

pub use showcase_light::render::RenderSetupError;

/// Why a GPU frame cannot be drawn or read back.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The frame's scene or inputs cannot be rendered.
    #[error(transparent)]
    Setup(#[from] RenderSetupError),
    /// A frame was read back before one was drawn.
    #[error("no frame has been drawn yet")]
    NothingDrawn,
    /// A GPU operation failed.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
}

impl From<showcase_light::GeometryError> for FrameError {
    fn from(e: showcase_light::GeometryError) -> Self {
        Self::Setup(e.into())
    }
}

impl From<showcase_light::DeviceError> for FrameError {
    fn from(e: showcase_light::DeviceError) -> Self {
        Self::Setup(e.into())
    }
}
