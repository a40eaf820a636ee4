//! Scatter and line plots as SVG: the one writer behind the figures of the
//! bench reports (calibration, reflectance capture, radiosity, render) and
//! the demo's page, written by hand so that no plotting crate has to be
//! built.
//!
//! Each axis is logarithmic or linear ([`Scale`]). A log axis spans whole
//! decades, with a grid line and a `1eN` label at each; points that are not
//! positive and finite cannot sit on it and are left out, from the markers
//! and from the lines. A linear axis spans whole steps of 1, 2 or 5 times a
//! power of ten, about five of them, with a grid line and a label at each;
//! points that are not finite are left out.

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

/// How an axis maps values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Scale {
    /// Whole decades, for values over several orders of magnitude.
    #[default]
    Log,
    /// Evenly spaced "nice" steps.
    Linear,
}

impl Scale {
    /// Whether `v` can be drawn on this axis.
    fn holds(self, v: f64) -> bool {
        match self {
            Scale::Log => v > 0.0 && v.is_finite(),
            Scale::Linear => v.is_finite(),
        }
    }

    /// The axis that holds `values` (all drawable): its ends in axis units
    /// (exponents on a log axis) and its ticks as `(value, label)`.
    fn axis(self, values: impl Iterator<Item = f64>) -> Axis {
        match self {
            Scale::Log => {
                let (lo, hi) = decades(values);
                Axis {
                    scale: self,
                    lo,
                    hi,
                    ticks: (lo as i32..=hi as i32)
                        .map(|d| (10f64.powi(d), format!("1e{d}")))
                        .collect(),
                }
            }
            Scale::Linear => {
                let (lo, hi, step) = linear_steps(values);
                let n = ((hi - lo) / step).round() as i64;
                let decimals = (-step.log10().floor()).max(0.0) as usize;
                Axis {
                    scale: self,
                    lo,
                    hi,
                    ticks: (0..=n)
                        .map(|i| {
                            let v = lo + i as f64 * step;
                            // -0.0 prints as "-0".
                            let v = if v.abs() < step * 1e-9 { 0.0 } else { v };
                            (v, format!("{v:.decimals$}"))
                        })
                        .collect(),
                }
            }
        }
    }
}

/// One axis of a drawn plot.
struct Axis {
    scale: Scale,
    /// Its ends, in axis units (log10 of the value on a log axis).
    lo: f64,
    hi: f64,
    /// Grid lines: value and label.
    ticks: Vec<(f64, String)>,
}

impl Axis {
    /// Where `v` falls between the ends, 0 to 1.
    fn fraction(&self, v: f64) -> f64 {
        let u = match self.scale {
            Scale::Log => v.log10(),
            Scale::Linear => v,
        };
        (u - self.lo) / (self.hi - self.lo)
    }
}

/// One point of a [`Series`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Point {
    /// Horizontal value (must be finite, and positive on a log axis, to be
    /// drawn).
    pub x: f64,
    /// Vertical value (must be finite, and positive on a log axis, to be
    /// drawn).
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

/// A scatter or line plot.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Plot {
    /// Heading above the plot; empty for none.
    pub title: String,
    /// Horizontal axis label.
    pub x_label: String,
    /// Vertical axis label.
    pub y_label: String,
    /// Horizontal axis scale.
    pub x_scale: Scale,
    /// Vertical axis scale.
    pub y_scale: Scale,
    /// The data, drawn in order.
    pub series: Vec<Series>,
    /// A line of text under the legend (what the markers mean); empty for
    /// none.
    pub note: String,
}

impl Plot {
    /// The plot as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let (w, h, m) = (WIDTH, HEIGHT, MARGIN);
        let drawn = |p: &&Point| self.x_scale.holds(p.x) && self.y_scale.holds(p.y);
        let all = || {
            self.series
                .iter()
                .flat_map(|s| s.points.iter().filter(drawn))
        };
        let x_axis = self.x_scale.axis(all().map(|p| p.x));
        let y_axis = self.y_scale.axis(all().map(|p| p.y));
        let sx = |x: f64| m + x_axis.fraction(x) * (w - 2.0 * m);
        let sy = |y: f64| h - m - y_axis.fraction(y) * (h - 2.0 * m);
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
        for (v, label) in &x_axis.ticks {
            let x = sx(*v);
            let _ = writeln!(
                s,
                r##"<line x1="{x:.1}" y1="{m}" x2="{x:.1}" y2="{}" stroke="#ddd"/><text x="{x:.1}" y="{}" text-anchor="middle">{label}</text>"##,
                h - m,
                h - m + 16.0
            );
        }
        for (v, label) in &y_axis.ticks {
            let y = sy(*v);
            let _ = writeln!(
                s,
                r##"<line x1="{m}" y1="{y:.1}" x2="{}" y2="{y:.1}" stroke="#ddd"/><text x="{}" y="{:.1}" text-anchor="end">{label}</text>"##,
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

/// A linear axis for `values` (all finite): its ends and its step, a 1, 2
/// or 5 times a power of ten that cuts the span into at most about five
/// steps, the ends whole steps; a single value gets a step either side and
/// no values `(0, 1, 0.2)`.
fn linear_steps(values: impl Iterator<Item = f64>) -> (f64, f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !lo.is_finite() {
        return (0.0, 1.0, 0.2);
    }
    let span = if hi > lo {
        hi - lo
    } else {
        lo.abs().max(1e-300)
    };
    let raw = span / 5.0;
    let decade = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|k| k * decade)
        .find(|s| *s >= raw * (1.0 - 1e-12))
        .unwrap_or(10.0 * decade);
    let (mut a, mut b) = ((lo / step).floor() * step, (hi / step).ceil() * step);
    if b <= a {
        a -= step;
        b += step;
    }
    (a, b, step)
}

/// `text` with the characters that XML and HTML give a meaning escaped:
/// the one escaper of the SVG plots and the report pages.
pub(crate) fn escape(text: &str) -> String {
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
        let plot = Plot {
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
            ..Plot::default()
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

    #[test]
    fn linear_axes_take_nice_whole_steps() {
        assert_eq!(linear_steps([].into_iter()), (0.0, 1.0, 0.2));
        assert_eq!(linear_steps([0.0, 10.0].into_iter()), (0.0, 10.0, 2.0));
        assert_eq!(linear_steps([0.13, 0.87].into_iter()), (0.0, 1.0, 0.2));
        assert_eq!(linear_steps([1.0, 240.0].into_iter()), (0.0, 250.0, 50.0));
        let (a, b, step) = linear_steps([-3.0, 2.0].into_iter());
        assert_eq!((a, b, step), (-3.0, 2.0, 1.0));
        // One value: a step either side of it.
        let (a, b, step) = linear_steps([4.0].into_iter());
        assert!(a < 4.0 && b > 4.0 && step > 0.0, "{a} {b} {step}");
    }

    #[test]
    fn a_linear_axis_draws_zero_and_negative_points_with_plain_labels() {
        let plot = Plot {
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
            series: vec![Series {
                colour: series_colour(1).into(),
                joined: true,
                points: vec![
                    Point::at(0.0, 0.0),
                    Point::at(1.0, -0.5),
                    Point::at(2.0, f64::NAN),
                    Point::at(3.0, 1.0),
                ],
                ..Series::default()
            }],
            ..Plot::default()
        };
        let svg = plot.to_svg();
        // The NaN point alone is left out; zero and negatives are drawn.
        assert_eq!(svg.matches("<circle").count(), 3);
        assert!(svg.contains(">-0.5</text>") && svg.contains(">0.0</text>"));
        assert!(!svg.contains(">1e") && !svg.contains("NaN") && !svg.contains(">-0.0<"));
        // On log axes the same points would lose all but one.
        let log = Plot {
            x_scale: Scale::Log,
            y_scale: Scale::Log,
            ..plot
        };
        assert_eq!(log.to_svg().matches("<circle").count(), 1);
    }
}
