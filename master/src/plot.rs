//! Log-log scatter plots as SVG: the one writer behind the figures of the
//! bench reports (calibration, reflectance capture, radiosity), written by
//! hand so that no plotting crate has to be built.
//!
//! Both axes are logarithmic and span whole decades, with a grid line and a
//! `1eN` label at each. Points that are not positive and finite cannot sit
//! on a log axis and are left out, from the markers and from the lines.

use std::fmt::Write as _;

/// Width of every plot, in SVG user units.
const WIDTH: f64 = 720.0;
/// Height of every plot.
const HEIGHT: f64 = 480.0;
/// Space around the plot area for ticks, labels and the title.
const MARGIN: f64 = 60.0;

/// The colours given to series in turn by [`series_colour`].
const PALETTE: [&str; 12] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf", "#000000", "#aa4499",
];

/// The colour of the `i`-th series, cycling through a palette of twelve.
pub fn series_colour(i: usize) -> &'static str {
    PALETTE[i % PALETTE.len()]
}

/// How a point is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Marker {
    /// A filled dot.
    #[default]
    Circle,
    /// An open square.
    Square,
}

/// One point of a [`Series`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Point {
    /// Horizontal value (must be positive and finite to be drawn).
    pub x: f64,
    /// Vertical value (must be positive and finite to be drawn).
    pub y: f64,
    /// Its shape.
    pub marker: Marker,
    /// Text shown on hover (an SVG `<title>`); empty for none.
    pub tooltip: String,
    /// Text written beside the point; empty for none.
    pub label: String,
}

impl Point {
    /// A circle at `(x, y)` with no text.
    pub fn at(x: f64, y: f64) -> Self {
        Self {
            x,
            y,
            ..Self::default()
        }
    }
}

/// Points drawn in one colour.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// Legend entry; empty for none.
    pub name: String,
    /// SVG colour of the markers, the line and the legend entry.
    pub colour: String,
    /// Join the points by a line, in their order.
    pub joined: bool,
    /// The points.
    pub points: Vec<Point>,
}

/// A scatter plot on log-log axes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LogLogPlot {
    /// Heading above the plot; empty for none.
    pub title: String,
    /// Horizontal axis label.
    pub x_label: String,
    /// Vertical axis label.
    pub y_label: String,
    /// The data, drawn in order.
    pub series: Vec<Series>,
    /// A line of text under the legend (what the markers mean); empty for
    /// none.
    pub note: String,
}

impl LogLogPlot {
    /// The plot as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let (w, h, m) = (WIDTH, HEIGHT, MARGIN);
        let drawn = |p: &&Point| p.x > 0.0 && p.y > 0.0 && p.x.is_finite() && p.y.is_finite();
        let all = || {
            self.series
                .iter()
                .flat_map(|s| s.points.iter().filter(drawn))
        };
        let (x0, x1) = decades(all().map(|p| p.x));
        let (y0, y1) = decades(all().map(|p| p.y));
        let sx = |x: f64| m + (x.log10() - x0) / (x1 - x0) * (w - 2.0 * m);
        let sy = |y: f64| h - m - (y.log10() - y0) / (y1 - y0) * (h - 2.0 * m);
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
        );
        let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
        if !self.title.is_empty() {
            let _ = writeln!(
                s,
                r#"<text x="{}" y="24" text-anchor="middle" font-size="16">{}</text>"#,
                w / 2.0,
                escape(&self.title)
            );
        }
        let _ = writeln!(
            s,
            r#"<rect x="{m}" y="{m}" width="{}" height="{}" fill="none" stroke="black"/>"#,
            w - 2.0 * m,
            h - 2.0 * m
        );
        for d in x0 as i32..=x1 as i32 {
            let x = sx(10f64.powi(d));
            let _ = writeln!(
                s,
                r##"<line x1="{x:.1}" y1="{m}" x2="{x:.1}" y2="{}" stroke="#ddd"/><text x="{x:.1}" y="{}" text-anchor="middle">1e{d}</text>"##,
                h - m,
                h - m + 16.0
            );
        }
        for d in y0 as i32..=y1 as i32 {
            let y = sy(10f64.powi(d));
            let _ = writeln!(
                s,
                r##"<line x1="{m}" y1="{y:.1}" x2="{}" y2="{y:.1}" stroke="#ddd"/><text x="{}" y="{:.1}" text-anchor="end">1e{d}</text>"##,
                w - m,
                m - 4.0,
                y + 4.0
            );
        }
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            w / 2.0,
            h - 14.0,
            escape(&self.x_label)
        );
        let _ = writeln!(
            s,
            r#"<text x="14" y="{}" transform="rotate(-90 14 {})" text-anchor="middle">{}</text>"#,
            h / 2.0,
            h / 2.0,
            escape(&self.y_label)
        );
        for series in &self.series {
            let c = escape(&series.colour);
            let points: Vec<&Point> = series.points.iter().filter(drawn).collect();
            if series.joined && !points.is_empty() {
                let path: Vec<String> = points
                    .iter()
                    .map(|p| format!("{:.1},{:.1}", sx(p.x), sy(p.y)))
                    .collect();
                let _ = writeln!(
                    s,
                    r#"<polyline points="{}" fill="none" stroke="{c}" stroke-width="1.5"/>"#,
                    path.join(" ")
                );
            }
            for p in points {
                let (x, y) = (sx(p.x), sy(p.y));
                let (tag, shape) = match p.marker {
                    Marker::Circle => (
                        "circle",
                        format!(r#"cx="{x:.1}" cy="{y:.1}" r="3" fill="{c}""#),
                    ),
                    Marker::Square => (
                        "rect",
                        format!(
                            r#"x="{:.1}" y="{:.1}" width="6" height="6" fill="none" stroke="{c}""#,
                            x - 3.0,
                            y - 3.0
                        ),
                    ),
                };
                let _ = if p.tooltip.is_empty() {
                    write!(s, "<{tag} {shape}/>")
                } else {
                    write!(
                        s,
                        "<{tag} {shape}><title>{}</title></{tag}>",
                        escape(&p.tooltip)
                    )
                };
                if !p.label.is_empty() {
                    let _ = write!(
                        s,
                        r#"<text x="{:.1}" y="{:.1}" font-size="9">{}</text>"#,
                        x + 6.0,
                        y - 4.0,
                        escape(&p.label)
                    );
                }
                s.push('\n');
            }
        }
        // The legend, right-aligned in the plot's top corner.
        let legend = self.series.iter().filter(|s| !s.name.is_empty());
        let mut line = 0.0;
        for series in legend {
            line += 1.0;
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}" text-anchor="end" fill="{}">{}</text>"#,
                w - m - 8.0,
                m + 14.0 * line,
                escape(&series.colour),
                escape(&series.name)
            );
        }
        if !self.note.is_empty() {
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}" text-anchor="end">{}</text>"#,
                w - m - 8.0,
                m + 14.0 * (line + 1.0),
                escape(&self.note)
            );
        }
        s.push_str("</svg>\n");
        s
    }
}

/// The whole decades (as base-10 exponents) that hold `values` (all
/// positive and finite): one decade either side of a single decade, and
/// `(0, 1)` when there are none.
fn decades(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .map(f64::log10)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        (0.0, 1.0)
    } else if hi.ceil() > lo.floor() {
        (lo.floor(), hi.ceil())
    } else {
        (lo.floor() - 1.0, lo.floor() + 1.0)
    }
}

/// `text` with the characters that XML gives a meaning escaped.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[track_caller]
    fn check_decades(values: &[f64], expected: (f64, f64)) {
        assert_eq!(decades(values.iter().copied()), expected);
    }

    #[test]
    fn axes_span_whole_decades() {
        check_decades(&[], (0.0, 1.0));
        check_decades(&[0.02, 300.0], (-2.0, 3.0));
        check_decades(&[5.0], (0.0, 1.0));
        check_decades(&[10.0], (0.0, 2.0));
        check_decades(&[10.0, 100.0], (1.0, 2.0));
    }

    #[test]
    fn bad_points_are_left_out_and_text_is_escaped() {
        let plot = LogLogPlot {
            title: "a < b & c".into(),
            series: vec![Series {
                name: "s".into(),
                colour: series_colour(0).into(),
                joined: true,
                points: vec![
                    Point::at(1.0, 0.1),
                    Point::at(f64::NAN, 1.0),
                    Point::at(0.0, 1.0),
                    Point::at(1.0, f64::INFINITY),
                    Point {
                        marker: Marker::Square,
                        tooltip: "\"q\"".into(),
                        ..Point::at(10.0, 0.01)
                    },
                ],
            }],
            ..LogLogPlot::default()
        };
        let svg = plot.to_svg();
        assert_eq!(svg.matches("<circle").count(), 1);
        assert_eq!(
            svg.matches("<title>&quot;q&quot;</title></rect>").count(),
            1
        );
        assert_eq!(svg.matches("<polyline").count(), 1);
        assert!(svg.contains("a &lt; b &amp; c"));
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>\n"));
    }
}
