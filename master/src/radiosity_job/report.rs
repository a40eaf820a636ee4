//! The human-readable radiosity benchmark report: `records.json`, two
//! SVG plots (error against time, time against patch count) and a
//! Markdown summary.

use super::bench::BenchRecord;
use crate::plot::{Plot, Point, Series};
use anyhow::Context;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A scatter plot on log-log axes as SVG, each point labelled. Points that
/// are not positive and finite are left out.
pub fn scatter_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[(f64, f64, String)],
) -> String {
    Plot {
        title: title.into(),
        x_label: x_label.into(),
        y_label: y_label.into(),
        series: vec![Series {
            name: String::new(),
            colour: "#c33".into(),
            joined: false,
            points: points
                .iter()
                .map(|(x, y, label)| Point {
                    label: label.clone(),
                    ..Point::at(*x, *y)
                })
                .collect(),
        }],
        note: String::new(),
        ..Plot::default()
    }
    .to_svg()
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
        "\nOther records (probes, incremental, incremental_object, augmented) in full:\n\n```json\n",
    );
    for r in records.iter().filter(|r| {
        matches!(
            r.get("kind").and_then(|k| k.as_str()),
            Some("probes" | "incremental" | "incremental_object" | "augmented")
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
