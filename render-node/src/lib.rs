//! Showcase's renderer: the pure light-transport core with its CPU
//! reference renderers (`light`), and the wgpu passes (`gpu`) that every
//! render node runs each frame.

pub mod gpu;
pub mod light;
