//! `bench soak`: a loopback cluster of 4 state-hash nodes at 120 Hz for
//! many frames, run as a live show runs (no per-frame metrics kept in
//! memory), sampling this process's resident memory as it goes. The
//! growth per 1000 frames says what an exhibition day would cost.

use super::commands::walk_plan;
use super::loopback::{LoopbackPlan, run_loopback};
use anyhow::Result;
use serde::Serialize;
use showcase_proto::Showcase;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

const NODES: usize = 4;
const HZ: f32 = 120.0;

/// One sample of the run.
#[derive(Clone, Debug, Serialize)]
pub struct SoakSample {
    /// Frames presented so far.
    pub frames: u64,
    /// Resident memory of the process (MB), where the OS reports it.
    pub rss_mb: Option<f64>,
}

/// The record `bench soak --json` prints.
#[derive(Clone, Debug, Serialize)]
pub struct SoakRecord {
    /// Render nodes (tasks of this process, as the master's).
    pub nodes: usize,
    /// Frame rate.
    pub hz: f32,
    /// Frames run.
    pub frames: u64,
    /// Samples every half second.
    pub samples: Vec<SoakSample>,
    /// Least-squares slope of RSS over the second half of the run, in KB
    /// per 1000 frames (the first half includes start-up).
    pub rss_growth_kb_per_1000_frames: Option<f64>,
    /// The same, as MB over a 10-hour day at 60 Hz.
    pub rss_growth_mb_per_day_at_60hz: Option<f64>,
    /// The frame count RSS is compared from: 10,000, or a tenth of a
    /// shorter run (start-up is over by then).
    pub reference_frames: u64,
    /// RSS at the first sample past `reference_frames` (MB).
    pub rss_mb_at_reference: Option<f64>,
    /// RSS at the last sample (MB).
    pub rss_mb_at_end: Option<f64>,
    /// `rss_mb_at_end - rss_mb_at_reference`: the target is at
    /// most 5 MB from 10,000 to 100,000 frames.
    pub rss_growth_mb_from_reference: Option<f64>,
}

/// Resident memory of this process (MB): `VmRSS` of `/proc/self/status`.
pub fn rss_mb() -> Option<f64> {
    status_mb("VmRSS:")
}

/// The `key` line of `/proc/self/status` (in kB there), in MB.
fn status_mb(key: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Peak resident memory of this process (MB) since the last
/// [`reset_peak_rss`]: `VmHWM` of `/proc/self/status`.
pub fn peak_rss_mb() -> Option<f64> {
    status_mb("VmHWM:")
}

/// Start [`peak_rss_mb`] afresh from the present resident memory (Linux:
/// `5` to `/proc/self/clear_refs`); false where that is refused.
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// Counts the metrics lines the master writes: one per presented frame.
struct LineCounter(Arc<AtomicU64>);

impl std::io::Write for LineCounter {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        let lines = b.iter().filter(|&&c| c == b'\n').count() as u64;
        self.0.fetch_add(lines, Ordering::Relaxed);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Least-squares slope of `y` against `x`.
fn slope(points: &[(f64, f64)]) -> Option<f64> {
    let n = points.len() as f64;
    if points.len() < 2 {
        return None;
    }
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxx: f64 = points.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Run the soak for `frames` frames on `scene`.
pub async fn bench_soak(scene: &Showcase, frames: u64) -> Result<SoakRecord> {
    let presented = Arc::new(AtomicU64::new(0));
    let plan = LoopbackPlan {
        metrics: Some(Box::new(LineCounter(presented.clone()))),
        ..walk_plan(scene, NODES, HZ, frames)?
    };
    let run = tokio::spawn(run_loopback(plan));
    let mut samples = Vec::new();
    let mut last_print = 0;
    while !run.is_finished() {
        let done = presented.load(Ordering::Relaxed);
        samples.push(SoakSample {
            frames: done,
            rss_mb: rss_mb(),
        });
        if done >= last_print + frames / 10 {
            last_print = done;
            eprintln!(
                "bench soak: {done} of {frames} frames, RSS {}",
                rss_mb().map_or("unknown".into(), |m| format!("{m:.1} MB"))
            );
        }
        tokio::time::sleep(Duration::from_millis(500)).await;
    }
    run.await??;
    let late: Vec<(f64, f64)> = samples
        .iter()
        .filter(|s| s.frames >= frames / 2)
        .filter_map(|s| Some((s.frames as f64, s.rss_mb?)))
        .collect();
    let per_frame_mb = slope(&late);
    let reference_frames = (frames / 10).min(10_000);
    let rss_mb_at_reference = samples
        .iter()
        .find(|s| s.frames >= reference_frames)
        .and_then(|s| s.rss_mb);
    let rss_mb_at_end = samples.last().and_then(|s| s.rss_mb);
    Ok(SoakRecord {
        nodes: NODES,
        hz: HZ,
        frames,
        samples,
        rss_growth_kb_per_1000_frames: per_frame_mb.map(|s| s * 1024.0 * 1000.0),
        rss_growth_mb_per_day_at_60hz: per_frame_mb.map(|s| s * 60.0 * 3600.0 * 10.0),
        reference_frames,
        rss_mb_at_reference,
        rss_mb_at_end,
        rss_growth_mb_from_reference: rss_mb_at_end.zip(rss_mb_at_reference).map(|(e, r)| e - r),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_line_and_of_too_few_points() {
        let pts: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, 3.0 + 0.5 * i as f64)).collect();
        assert!((slope(&pts).unwrap() - 0.5).abs() < 1e-12);
        assert_eq!(slope(&pts[..1]), None);
        assert_eq!(slope(&[(1.0, 2.0), (1.0, 3.0)]), None);
    }
}
