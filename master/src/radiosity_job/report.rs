//! The human-readable radiosity benchmark report: `records.json`, two
//! hand-written SVG plots (error against time, time against patch count)
//! and a Markdown summary.

use super::bench::BenchRecord;
use anyhow::Context;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A scatter plot on log-log axes as SVG. Points that are not positive
/// and finite are left out.
pub fn scatter_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[(f64, f64, String)],
) -> String {
    let (w, h, m) = (640.0, 420.0, 60.0);
    let valid: Vec<&(f64, f64, String)> = points
        .iter()
        .filter(|(x, y, _)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .collect();
    let range = |f: &dyn Fn(&(f64, f64, String)) -> f64| {
        let lo = valid
            .iter()
            .map(|p| f(p).log10())
            .fold(f64::INFINITY, f64::min);
        let hi = valid
            .iter()
            .map(|p| f(p).log10())
            .fold(f64::NEG_INFINITY, f64::max);
        if lo.is_finite() && hi > lo {
            (lo.floor(), hi.ceil())
        } else if lo.is_finite() {
            (lo.floor() - 1.0, lo.floor() + 1.0)
        } else {
            (0.0, 1.0)
        }
    };
    let (x0, x1) = range(&|p| p.0);
    let (y0, y1) = range(&|p| p.1);
    let sx = |x: f64| m + (x.log10() - x0) / (x1 - x0) * (w - 2.0 * m);
    let sy = |y: f64| h - m - (y.log10() - y0) / (y1 - y0) * (h - 2.0 * m);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="20" text-anchor="middle" font-size="14">{title}</text>"#,
        w / 2.0
    );
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
            r##"<line x1="{x}" y1="{m}" x2="{x}" y2="{}" stroke="#ddd"/><text x="{x}" y="{}" text-anchor="middle">1e{d}</text>"##,
            h - m,
            h - m + 16.0
        );
    }
    for d in y0 as i32..=y1 as i32 {
        let y = sy(10f64.powi(d));
        let _ = writeln!(
            s,
            r##"<line x1="{m}" y1="{y}" x2="{}" y2="{y}" stroke="#ddd"/><text x="{}" y="{}" text-anchor="end">1e{d}</text>"##,
            w - m,
            m - 4.0,
            y + 4.0
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{x_label}</text>"#,
        w / 2.0,
        h - 12.0
    );
    let _ = writeln!(
        s,
        r#"<text x="14" y="{}" transform="rotate(-90 14 {})" text-anchor="middle">{y_label}</text>"#,
        h / 2.0,
        h / 2.0
    );
    for (x, y, label) in valid {
        let _ = writeln!(
            s,
            r##"<circle cx="{:.1}" cy="{:.1}" r="4" fill="#c33"/><text x="{:.1}" y="{:.1}" font-size="9">{label}</text>"##,
            sx(*x),
            sy(*y),
            sx(*x) + 6.0,
            sy(*y) - 4.0
        );
    }
    s.push_str("</svg>\n");
    s
}

fn num(r: &BenchRecord, key: &str) -> f64 {
    r.get(key).and_then(|v| v.as_f64()).unwrap_or(f64::NAN)
}

/// Write `records.json`, `error_vs_time.svg`, `time_vs_patches.svg` and
/// `report.md` into `out`; returns the report's path. `machine` names the
/// machine the figures were measured on.
pub fn write_report(records: &[BenchRecord], out: &Path, machine: &str) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    std::fs::write(
        out.join("records.json"),
        serde_json::to_string_pretty(records)?,
    )?;
    let sweep: Vec<&BenchRecord> = records
        .iter()
        .filter(|r| {
            matches!(
                r.get("kind").and_then(|k| k.as_str()),
                Some("sweep" | "scaling" | "gathered")
            )
        })
        .collect();
    let label = |r: &BenchRecord| {
        format!(
            "{}{} p{} h{} t{}",
            r.get("method").and_then(|m| m.as_str()).unwrap_or(""),
            if r.get("gather").is_some_and(|g| !g.is_null()) {
                "+gather"
            } else {
                ""
            },
            num(r, "patches"),
            num(r, "hemicube"),
            num(r, "threshold")
        )
    };
    let error_vs_time: Vec<(f64, f64, String)> = sweep
        .iter()
        .map(|r| (num(r, "seconds"), num(r, "rel_error"), label(r)))
        .collect();
    let time_vs_patches: Vec<(f64, f64, String)> = sweep
        .iter()
        .map(|r| {
            (
                num(r, "patches"),
                num(r, "seconds"),
                format!("{} el", num(r, "elements")),
            )
        })
        .collect();
    std::fs::write(
        out.join("error_vs_time.svg"),
        scatter_svg(
            "Cornell box: error against time",
            "seconds",
            "rel_error",
            &error_vs_time,
        ),
    )?;
    std::fs::write(
        out.join("time_vs_patches.svg"),
        scatter_svg(
            "Cornell box: time against patches",
            "patches",
            "seconds",
            &time_vs_patches,
        ),
    )?;
    let mut md = format!(
        "# Radiosity benchmark\n\nMachine: {machine}. Release build.\n\n\
         ![error against time](error_vs_time.svg)\n\n![time against patches](time_vs_patches.svg)\n\n\
         | kind | method | patches | elements | hemicube | threshold | seconds | rel_error | analytic_direct_error |\n\
         |---|---|---|---|---|---|---|---|---|\n"
    );
    for r in records {
        let s = |k: &str| r.get(k).map_or(String::new(), |v| v.to_string());
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            s("kind"),
            s("method"),
            s("patches"),
            s("elements"),
            s("hemicube"),
            s("threshold"),
            s("seconds"),
            s("rel_error"),
            s("analytic_direct_error")
        );
    }
    md.push_str(
        "\nOther records (incremental, incremental_object, augmented) in full:\n\n```json\n",
    );
    for r in records.iter().filter(|r| {
        matches!(
            r.get("kind").and_then(|k| k.as_str()),
            Some("incremental" | "incremental_object" | "augmented")
        )
    }) {
        let _ = writeln!(md, "{r}");
    }
    md.push_str("```\n");
    let path = out.join("report.md");
    std::fs::write(&path, md)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scatter_drops_bad_points_and_draws_the_rest() {
        let svg = scatter_svg(
            "t",
            "x",
            "y",
            &[
                (1.0, 0.1, "a".into()),
                (10.0, 0.01, "b".into()),
                (f64::NAN, 1.0, "nan".into()),
                (0.0, 1.0, "zero".into()),
            ],
        );
        assert_eq!(svg.matches("<circle").count(), 2);
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
    }
}
