//! Showcase's renderer: the pure light-transport core with its CPU
//! reference renderers (`light`), the wgpu passes (`gpu`) that every
//! render node runs each frame, the cluster transport (`net`) shared by
//! nodes and the master, the node runtime (`node`), the simulated
//! showcase (`sim`) and reflectance-map math (`reflectance`).

pub mod gpu;
pub mod light;
pub mod mirror_view;
pub mod net;
pub mod node;
pub mod observer_view;
pub mod radiosity;
pub mod reflectance;
pub mod render;
pub mod sim;
#[cfg(feature = "window")]
pub mod window;
