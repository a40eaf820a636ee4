//! Showcase's render node: the wgpu passes (`gpu`) and the real-time
//! renderer's GPU pipelines (`render`) that every render node runs each
//! frame, the cluster transport (`net`) shared by nodes and the master,
//! the node runtime (`node`), the optional full-screen window and the
//! real cameras (`camera`: frame decoding, V4L2, recorded replay). The
//! pure light transport they draw is `showcase_light`.

pub mod camera;
pub mod gpu;
pub mod net;
pub mod node;
pub mod render;
#[cfg(feature = "window")]
pub mod window;
