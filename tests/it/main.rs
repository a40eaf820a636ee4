//! The one integration-test binary of the workspace (linking many binaries
//! of a wgpu + quinn workspace is slow). One module per area.

mod alloc_track;
mod browser;
mod calibration;
mod camera;
mod camera_node;
mod capture;
mod capture_chunks;
mod check;
mod cluster;
mod cluster_capture;
mod codec;
mod dashboard;
mod demo;
mod gi;
mod gpu;
mod hemicube;
mod light;
mod observer;
mod photometric;
mod probes;
mod radiosity;
mod render;
mod report_page;
mod scene_files;
mod session;
mod shutdown;
mod sim;
mod structured_light;
mod tracking;
mod transport;
