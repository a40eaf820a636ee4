//! Per-frame cluster measurements: one JSON line per presented frame
//! (`--metrics FILE`), and summaries (percentiles) for reports and the
//! cluster benchmark.

use serde::Serialize;
use showcase_proto::FrameState;
use showcase_proto::session::{PresentReport, SwapReport};

/// One node's figures for one frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeMetric {
    /// Node name.
    pub name: String,
    /// Render time (ms).
    pub render_ms: f32,
    /// Time between its Ready and the Swap (ms).
    pub barrier_wait_ms: f32,
    /// Its present time minus the swap time, on the master clock (ms).
    pub present_offset_ms: Option<f64>,
}

/// One line of `--metrics`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameMetrics {
    /// Frame number.
    pub frame: u64,
    /// Wall-clock time of the swap (ms since the Unix epoch, the master's
    /// clock), to line frames up with logs and outside events.
    pub swap_unix_ms: f64,
    /// Head positions.
    pub heads: Vec<[f32; 3]>,
    /// Light positions.
    pub lights: Vec<[f32; 3]>,
    /// Per-node figures.
    pub nodes: Vec<NodeMetric>,
    /// Spread of the nodes' present times (ms).
    pub swap_skew_ms: Option<f64>,
    /// From the newest tracking sample to the swap (ms).
    pub tracking_to_swap_ms: Option<f64>,
    /// Nodes evicted at this frame's swap.
    pub evicted: Vec<String>,
}

/// The wall clock now, in ms since the Unix epoch (0 if the clock is set
/// before it): the time base of `swap_unix_ms`.
pub fn unix_ms() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1e3)
}

/// Frames presented per second: the swaps after the first over the time
/// from the first swap to the last. `None` with fewer than two swaps. Not
/// frames over the run's length, which holds the start-up, the wait for the
/// last reports and any global-illumination solve, and so is not a rate of
/// presenting.
pub fn swap_rate_hz(frames: &[FrameMetrics]) -> Option<f64> {
    let (first, last) = (frames.first()?, frames.last()?);
    let span_s = (last.swap_unix_ms - first.swap_unix_ms) / 1e3;
    (frames.len() >= 2 && span_s > 0.0).then(|| (frames.len() - 1) as f64 / span_s)
}

/// Build a frame's metrics from its state, swap and present reports;
/// `origin_unix_ms` is the wall-clock time of master-clock zero.
pub fn frame_metrics(
    state: &FrameState,
    swap: &SwapReport,
    present: &PresentReport,
    origin_unix_ms: f64,
) -> FrameMetrics {
    FrameMetrics {
        frame: present.frame,
        swap_unix_ms: origin_unix_ms + swap.swap_at_ns as f64 / 1e6,
        heads: state.heads.iter().map(|h| h.position.to_array()).collect(),
        lights: state
            .lights
            .iter()
            .map(|l| l.light.position().to_array())
            .collect(),
        nodes: present
            .nodes
            .iter()
            .map(|n| NodeMetric {
                name: n.node.clone(),
                render_ms: n.render_ms,
                barrier_wait_ms: n.barrier_wait_ms,
                present_offset_ms: n.present_offset_ns.map(|o| o as f64 / 1e6),
            })
            .collect(),
        swap_skew_ms: present.swap_skew_ns.map(|s| s as f64 / 1e6),
        tracking_to_swap_ms: swap
            .tracking_time_ns
            .map(|t| swap.swap_at_ns.saturating_sub(t) as f64 / 1e6),
        evicted: swap.evicted.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_swap_rate_counts_intervals_between_swaps() {
        let at = |ms: f64| FrameMetrics {
            frame: 0,
            swap_unix_ms: ms,
            heads: Vec::new(),
            lights: Vec::new(),
            nodes: Vec::new(),
            swap_skew_ms: None,
            tracking_to_swap_ms: None,
            evicted: Vec::new(),
        };
        // 241 swaps 1/60 s apart: 4 s of presenting at 60 Hz.
        let frames: Vec<FrameMetrics> = (0..241).map(|i| at(1e6 + i as f64 * 1e3 / 60.0)).collect();
        let hz = swap_rate_hz(&frames).unwrap();
        assert!((hz - 60.0).abs() < 1e-9, "{hz}");
        // A gap of one tick (a dropped frame) lowers the rate.
        let mut dropped = frames.clone();
        dropped.remove(120);
        assert!(swap_rate_hz(&dropped).unwrap() < 59.8);
        assert_eq!(swap_rate_hz(&frames[..1]), None);
        assert_eq!(swap_rate_hz(&[]), None);
    }
}
