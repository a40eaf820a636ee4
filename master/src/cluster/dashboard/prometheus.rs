//! `/metrics`: the dashboard's snapshot in the Prometheus text exposition
//! format 0.0.4, in base units (seconds, metres).

use super::super::live::{LiveSnapshot, NodeState, Quantiles};
use std::fmt::Write;

/// The content type of the format.
pub const CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

/// A label value with `\`, `"` and newlines escaped.
fn escape(v: &str) -> String {
    v.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

struct Out(String);

impl Out {
    fn family(&mut self, name: &str, kind: &str, help: &str) {
        let _ = writeln!(self.0, "# HELP {name} {help}\n# TYPE {name} {kind}");
    }

    fn sample(&mut self, name: &str, labels: &[(&str, &str)], value: f64) {
        self.0.push_str(name);
        if !labels.is_empty() {
            self.0.push('{');
            for (i, (k, v)) in labels.iter().enumerate() {
                if i > 0 {
                    self.0.push(',');
                }
                let _ = write!(self.0, "{k}=\"{}\"", escape(v));
            }
            self.0.push('}');
        }
        let _ = if value.is_nan() {
            writeln!(self.0, " NaN")
        } else if value.is_infinite() {
            writeln!(self.0, " {}Inf", if value > 0.0 { '+' } else { '-' })
        } else {
            writeln!(self.0, " {value}")
        };
    }

    fn one(&mut self, name: &str, kind: &str, help: &str, value: f64) {
        self.family(name, kind, help);
        self.sample(name, &[], value);
    }

    /// A summary in seconds from quantiles in ms (the quantiles are over
    /// the whole run, from the live histograms).
    fn summary(&mut self, name: &str, help: &str, q: &Quantiles) {
        self.family(name, "summary", help);
        for (label, v) in [("0.5", q.p50), ("0.9", q.p90), ("0.99", q.p99)] {
            self.sample(
                name,
                &[("quantile", label)],
                v.map_or(f64::NAN, |v| v / 1e3),
            );
        }
        self.sample(&format!("{name}_sum"), &[], q.sum_ms / 1e3);
        self.sample(&format!("{name}_count"), &[], q.count as f64);
    }
}

/// The snapshot as Prometheus text.
pub fn render(s: &LiveSnapshot) -> String {
    let mut o = Out(String::with_capacity(4096 + 1024 * s.nodes.len()));
    o.one(
        "showcase_frame_clock_running",
        "gauge",
        "1 once the frame clock has started.",
        f64::from(u8::from(s.frame_clock_started)),
    );
    o.one(
        "showcase_target_hz",
        "gauge",
        "The target frame rate.",
        f64::from(s.target_hz),
    );
    o.one(
        "showcase_scene_version",
        "gauge",
        "The scene version the frames refer to.",
        s.scene_version as f64,
    );
    o.one(
        "showcase_frames_submitted_total",
        "counter",
        "Frames sent to the nodes.",
        s.frames_submitted as f64,
    );
    o.one(
        "showcase_frames_presented_total",
        "counter",
        "Frames whose present reports are in.",
        s.frames_presented as f64,
    );
    o.one(
        "showcase_ticks_dropped_total",
        "counter",
        "Frame-clock ticks at which no frame could be submitted.",
        s.ticks_dropped as f64,
    );
    o.one(
        "showcase_evictions_total",
        "counter",
        "Nodes evicted for missing a swap deadline.",
        s.evictions as f64,
    );
    o.one(
        "showcase_dashboard_snapshots_total",
        "counter",
        "Snapshots the frame loop made for the dashboard.",
        s.dashboard.snapshots as f64,
    );
    o.one(
        "showcase_dashboard_snapshot_seconds_total",
        "counter",
        "Time the frame loop spent making and publishing the dashboard's snapshots.",
        s.dashboard.snapshot_s,
    );
    o.summary(
        "showcase_swap_skew_seconds",
        "Spread of the nodes' present times per frame.",
        &s.swap_skew_ms,
    );
    o.summary(
        "showcase_tracking_to_swap_seconds",
        "From the newest tracking sample to the swap.",
        &s.tracking_to_swap_ms,
    );

    let per_node: [(&str, &str, &str); 9] = [
        (
            "showcase_node_state",
            "gauge",
            "1 for the node's state (waiting, joined, rejoining, evicted, left).",
        ),
        (
            "showcase_node_render_seconds",
            "gauge",
            "The node's latest render time.",
        ),
        (
            "showcase_node_render_p99_seconds",
            "gauge",
            "The node's 99th percentile render time over the run.",
        ),
        (
            "showcase_node_barrier_wait_seconds",
            "gauge",
            "The node's latest wait from its Ready to the Swap.",
        ),
        (
            "showcase_node_present_offset_seconds",
            "gauge",
            "The node's latest present time minus the swap time (master clock).",
        ),
        (
            "showcase_node_frames_presented_total",
            "counter",
            "Frames the node presented.",
        ),
        (
            "showcase_node_frames_dropped_total",
            "counter",
            "Frames the cluster presented without the node since it first joined.",
        ),
        (
            "showcase_node_evictions_total",
            "counter",
            "Times the node was evicted.",
        ),
        (
            "showcase_node_joins_total",
            "counter",
            "Times the node joined.",
        ),
    ];
    let secs = |v: Option<f64>| v.map_or(f64::NAN, |v| v / 1e3);
    for (name, kind, help) in per_node {
        o.family(name, kind, help);
        for n in &s.nodes {
            let l = [("node", n.name.as_str()), ("role", n.role.as_str())];
            if name == "showcase_node_state" {
                for st in NodeState::ALL {
                    o.sample(
                        name,
                        &[l[0], l[1], ("state", st.as_str())],
                        f64::from(u8::from(n.state == st)),
                    );
                }
                continue;
            }
            let v = match name {
                "showcase_node_render_seconds" => secs(n.render_ms),
                "showcase_node_render_p99_seconds" => secs(n.render_ms_p99),
                "showcase_node_barrier_wait_seconds" => secs(n.barrier_wait_ms),
                "showcase_node_present_offset_seconds" => secs(n.present_offset_ms),
                "showcase_node_frames_presented_total" => n.frames_presented as f64,
                "showcase_node_frames_dropped_total" => n.frames_dropped as f64,
                "showcase_node_evictions_total" => n.evictions as f64,
                _ => n.joins as f64,
            };
            o.sample(name, &l, v);
        }
    }

    o.one(
        "showcase_tracked_bodies",
        "gauge",
        "Tracked bodies (observers, lights, moved objects) in the newest frame.",
        s.bodies.len() as f64,
    );
    o.family(
        "showcase_body_position_metres",
        "gauge",
        "A tracked body's world position in the newest frame.",
    );
    for b in &s.bodies {
        for (axis, v) in ["x", "y", "z"].iter().zip(b.position) {
            o.sample(
                "showcase_body_position_metres",
                &[("kind", b.kind), ("name", &b.name), ("axis", axis)],
                f64::from(v),
            );
        }
    }
    o.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_values_are_escaped() {
        assert_eq!(escape("a\"b\\c\nd"), "a\\\"b\\\\c\\nd");
        let mut o = Out(String::new());
        o.sample("m", &[("n", "x\"y")], f64::NAN);
        o.sample("m", &[], f64::NEG_INFINITY);
        o.sample("m", &[], 0.25);
        assert_eq!(o.0, "m{n=\"x\\\"y\"} NaN\nm -Inf\nm 0.25\n");
    }
}
