//! The real-time renderer of paper section 5 on the GPU: the projector
//! role's pipeline ([`projector_gpu`]) and the face role's
//! ([`face_gpu`]), each its own passes after the GPU frame layer both
//! draw through ([`gpu_frame`]: frame inputs, scene buffers, the shadow
//! stage, the timed encoder), the pass list that skips what a frame does
//! not need ([`passes`]), the GPU-against-CPU map comparison
//! ([`compare`]), the render bench ([`bench`](mod@bench)) and the [`Renderer`] seam
//! a node drives them through ([`renderer`]). Their CPU references and
//! the frame model are `showcase_light::render`.
#![forbid(unsafe_code)]
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod compare;
pub mod face_gpu;
pub mod gpu_frame;
pub mod illumination;
pub mod passes;
pub mod projector_gpu;
pub mod renderer;

pub use renderer::{RenderError, Renderer};
pub use showcase_light::render::RenderSetupError;
