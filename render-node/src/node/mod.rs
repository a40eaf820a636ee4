//! The render node's runtime: the [`Renderer`] seam and the tokio/quinn
//! driver around the sans-IO `NodeCore`.

pub mod renderer;

pub use renderer::{
    Fnv64, OutputImage, RenderError, RenderOutput, Renderer, StateHashRenderer, hash_pixels,
};
