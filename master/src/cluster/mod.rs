//! The cluster master: the show (frame states from tracking), the QUIC
//! server around the sans-IO core, and per-frame metrics.

pub mod capture_link;
pub mod capture_loopback;
pub mod check;
pub mod commands;
pub mod dashboard;
pub mod faults;
pub mod identity;
pub mod illumination;
pub mod live;
pub mod loopback;
pub mod metrics;
pub mod server;
pub mod show;
pub mod soak;
pub mod timer;

pub use identity::{Refusal, Roster};
pub use loopback::{LoopbackError, LoopbackPlan, LoopbackResult, RendererFactory, run_loopback};
pub use metrics::{FrameMetrics, NodeMetric};
pub use server::{ClusterRun, Server, ServerError, ServerSettings};
pub use show::{Show, Tracking};

/// Core settings the drivers use: the proto defaults with clock probes
/// every 20 ms, so offsets (and so swap-skew figures) settle within a few
/// frames of a join instead of seconds.
pub fn cluster_core_defaults() -> showcase_proto::session::MasterConfig {
    showcase_proto::session::MasterConfig {
        clock_probe_interval_ns: 20_000_000,
        ..Default::default()
    }
}
