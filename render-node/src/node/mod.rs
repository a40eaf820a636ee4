//! The render node's runtime: the [`Renderer`] seam and the tokio/quinn
//! driver around the sans-IO `NodeCore`.

pub mod driver;
pub mod output;
pub mod png_out;
pub mod present;
pub mod renderer;

pub use driver::{NodeLog, NodeRunError, NodeRuntime, run_node};
pub use output::{OutputRenderer, observer_in_front};
pub use renderer::{
    Fnv64, OutputImage, RenderError, RenderOutput, Renderer, StateHashRenderer, hash_pixels,
};
