//! Showcase's renderer: the pure light-transport core with its CPU
//! reference renderers (`light`), the wgpu passes (`gpu`) that every
//! render node runs each frame, and the cluster transport (`net`) shared by
//! nodes and the master.

pub mod gpu;
pub mod light;
pub mod mirror_view;
pub mod net;
pub mod node;
pub mod render;
