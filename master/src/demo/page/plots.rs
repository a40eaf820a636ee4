//! The page's plots, drawn with [`crate::plot`] from what the demo wrote:
//! per-frame swap skew and tracking-to-swap latency (`metrics.jsonl`),
//! radiosity convergence (every `*/summary.json` with a convergence curve)
//! and the calibration residuals ([`super::Histories`]).

use super::figures;
use crate::plot::{Plot, Point, Scale, Series, series_colour};
use anyhow::{Context, Result};
use std::path::Path;

/// One plot for the page: its caption and its SVG text.
pub(super) struct PagePlot {
    /// File name under the page's folder.
    pub file: &'static str,
    /// What it shows.
    pub caption: String,
    /// The SVG document.
    pub svg: String,
}

/// A horizontal line at `figure`'s target across `xs`, as a series, or
/// none when the figure has no target.
fn target_line(figure: &str, xs: (f64, f64)) -> Option<Series> {
    let f = figures::figure(figure)?;
    let t = f.target?.value();
    Some(Series {
        name: format!("target {}", figures::target_text(f)),
        colour: "#d62728".into(),
        joined: true,
        points: vec![Point::at(xs.0, t), Point::at(xs.1, t)],
    })
}

/// What the page plots of one line of `metrics.jsonl`
/// (`cluster::metrics::FrameMetrics`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct FrameLine {
    /// Frame number.
    pub frame: f64,
    /// Swap skew (ms), if measured.
    pub skew_ms: Option<f64>,
    /// Tracking to swap (ms), if measured.
    pub latency_ms: Option<f64>,
}

/// Per-frame plots of swap skew and tracking-to-swap latency; frames
/// without a value are left out.
pub(super) fn frame_plots(lines: &[FrameLine]) -> Vec<PagePlot> {
    let mut plots = Vec::new();
    let first = lines.first().map_or(0.0, |l| l.frame);
    let last = lines.last().map_or(0.0, |l| l.frame);
    for (file, title, figure, pick) in [
        (
            "swap_skew.svg",
            "Swap skew per frame",
            "swap_skew_ms_p99",
            (|l: &FrameLine| l.skew_ms) as fn(&FrameLine) -> Option<f64>,
        ),
        (
            "tracking_to_swap.svg",
            "Tracking-to-swap latency per frame",
            "tracking_to_swap_ms_p99",
            |l| l.latency_ms,
        ),
    ] {
        let points: Vec<Point> = lines
            .iter()
            .filter_map(|l| pick(l).map(|v| Point::at(l.frame, v)))
            .collect();
        if points.is_empty() {
            continue;
        }
        let mut series = vec![Series {
            name: "measured".into(),
            colour: series_colour(0).into(),
            joined: true,
            points,
        }];
        series.extend(target_line(figure, (first, last)));
        plots.push(PagePlot {
            file,
            caption: format!(
                "{title} (ms; the p99 is the figure {figure}{})",
                figures::figure(figure)
                    .filter(|f| f.target.is_some())
                    .map_or(String::new(), |f| format!(
                        ", target {}",
                        figures::target_text(f)
                    ))
            ),
            svg: Plot {
                title: title.into(),
                x_label: "frame".into(),
                y_label: "ms".into(),
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                series,
                note: String::new(),
            }
            .to_svg(),
        });
    }
    plots
}

/// Each line of a `metrics.jsonl`.
pub(super) fn read_frame_metrics(path: &Path) -> Result<Vec<FrameLine>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .enumerate()
        .map(|(i, l)| {
            let v: serde_json::Value = serde_json::from_str(l)
                .with_context(|| format!("{} line {}", path.display(), i + 1))?;
            let frame = v["frame"]
                .as_f64()
                .with_context(|| format!("{} line {}: no frame", path.display(), i + 1))?;
            Ok(FrameLine {
                frame,
                skew_ms: v["swap_skew_ms"].as_f64(),
                latency_ms: v["tracking_to_swap_ms"].as_f64(),
            })
        })
        .collect()
}

/// Radiosity convergence: unshot fraction against shots, one series per
/// solve (`(name, [(shots, unshot fraction)])`).
pub(super) fn convergence_plot(solves: &[(String, Vec<(f64, f64)>)]) -> Option<PagePlot> {
    if solves.iter().all(|(_, c)| c.is_empty()) {
        return None;
    }
    let series = solves
        .iter()
        .enumerate()
        .map(|(i, (name, curve))| Series {
            name: name.clone(),
            colour: series_colour(i).into(),
            joined: true,
            points: curve.iter().map(|&(x, y)| Point::at(x, y)).collect(),
        })
        .collect();
    Some(PagePlot {
        file: "radiosity_convergence.svg",
        caption: "Radiosity convergence: unshot power over injected power against shots (B0 solve, last refinement round)".into(),
        svg: Plot {
            title: "Radiosity convergence".into(),
            x_label: "shots".into(),
            y_label: "unshot fraction".into(),
            x_scale: Scale::Linear,
            y_scale: Scale::Log,
            series,
            note: String::new(),
        }
        .to_svg(),
    })
}

/// The convergence curve of a radiosity `summary.json`, if it has one.
pub(super) fn read_convergence(path: &Path) -> Option<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(path).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    v["convergence"]
        .as_array()?
        .iter()
        .map(|p| Some((p["shots"].as_f64()?, p["unshot_fraction"].as_f64()?)))
        .collect()
}

/// Calibration: per device, the fraction of marks whose reprojection
/// residual is at most x px (sorted residuals against rank).
pub(super) fn calibration_plot(devices: &[super::DeviceResiduals]) -> Option<PagePlot> {
    if devices.iter().all(|d| d.residuals_px.is_empty()) {
        return None;
    }
    let series = devices
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let n = d.residuals_px.len() as f64;
            Series {
                name: format!(
                    "{}: rms {}",
                    d.device,
                    figures::format_value(d.rms_px, "px")
                ),
                colour: series_colour(i).into(),
                joined: true,
                points: d
                    .residuals_px
                    .iter()
                    .enumerate()
                    .map(|(k, &r)| Point::at(r, (k + 1) as f64 / n))
                    .collect(),
            }
        })
        .collect();
    Some(PagePlot {
        file: "calibration_residuals.svg",
        caption: "Calibration error: share of the fiducial marks reprojected within x px, per device (marks at 0.5 px noise)".into(),
        svg: Plot {
            title: "Calibration reprojection residuals".into(),
            x_label: "residual (px)".into(),
            y_label: "fraction of marks".into(),
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
            series,
            note: String::new(),
        }
        .to_svg(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_plots_skip_missing_values_and_draw_the_skew_target() {
        let line = |frame, skew_ms, latency_ms| FrameLine {
            frame,
            skew_ms,
            latency_ms,
        };
        let lines = [
            line(0.0, Some(0.2), None),
            line(1.0, None, Some(12.0)),
            line(2.0, Some(0.4), Some(11.0)),
        ];
        let plots = frame_plots(&lines);
        assert_eq!(plots.len(), 2);
        let skew = &plots[0].svg;
        // Two measured frames plus the two ends of the 1 ms target line.
        assert_eq!(skew.matches("<circle").count(), 4);
        assert!(skew.contains("target ≤ 1 ms"));
        // Tracking-to-swap has no stated target: no line.
        assert_eq!(plots[1].svg.matches("<circle").count(), 2);
        assert!(!plots[1].svg.contains("target") && !plots[1].caption.contains("target"));
        assert!(frame_plots(&[line(0.0, None, None)]).is_empty());
    }

    #[test]
    fn calibration_plot_ranks_the_residuals() {
        let d = super::super::DeviceResiduals {
            device: "cam".into(),
            rms_px: 0.5,
            residuals_px: vec![0.1, 0.4, 0.9, 1.2],
        };
        let plot = calibration_plot(std::slice::from_ref(&d)).unwrap();
        assert_eq!(plot.svg.matches("<circle").count(), 4);
        assert!(plot.svg.contains("cam: rms 0.500 px"));
        let empty = super::super::DeviceResiduals {
            residuals_px: Vec::new(),
            ..d
        };
        assert!(calibration_plot(&[empty]).is_none());
    }
}
