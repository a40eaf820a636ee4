//! The cluster master: the show (frame states from tracking), the QUIC
//! server around the sans-IO core, and per-frame metrics.

pub mod commands;
pub mod loopback;
pub mod metrics;
pub mod server;
pub mod show;

pub use loopback::{LoopbackError, LoopbackPlan, LoopbackResult, RendererFactory, run_loopback};
pub use metrics::{FrameMetrics, NodeMetric, percentile};
pub use server::{ClusterRun, Server, ServerError, ServerSettings};
pub use show::{Show, Tracking};
