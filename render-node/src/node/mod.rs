//! The render node's runtime: the tokio/quinn driver around the sans-IO
//! `NodeCore`, which drives one output through the [`Renderer`] seam
//! (declared in `crate::render::renderer`, re-exported here), the
//! renderer a real node runs, presenting and PNG output.

pub mod camera_node;
pub mod capture;
pub mod driver;
pub mod output;
pub mod png_out;
pub mod present;
pub mod renderer;
pub mod signal;

pub use camera_node::{CameraNode, CameraSpec, ManualCamera, V4l2NodeOptions, camera_node};
pub use capture::{CaptureDevices, CaptureHost, LightBus, SimCameraNode, SimProjectorNode};
pub use driver::{NodeLog, NodeRunError, NodeRuntime, run_node, run_node_with_devices};
pub use output::{OutputRenderer, observer_in_front};
pub use renderer::{OutputImage, RenderError, RenderOutput, Renderer, StateHashRenderer};
pub use signal::cancel_on_stop_signal;
