//! The demo's `report.json` (the raw numbers) and `index.html`, a page
//! people can read: the phases (a skipped one with its reason), the figures
//! as a table with units, targets and pass or miss marks, plots, the
//! radiosity solution and the result maps as pictures, and the gallery with
//! a colour bar beside each CIEDE2000 heat map. What the page draws goes
//! into `page/` beside it.

mod figures;
mod images;
mod plots;

use super::views::{HEAT_MAP_SUFFIX, HEAT_STOPS, HEAT_UNCOVERED, heat_stop_rgb};
use super::{GalleryRow, Report};
use crate::plot::escape as html_escape;
use anyhow::{Context, Result};
use serde::Serialize;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::Path;

/// Folder of the page's own files, under the output folder.
const PAGE_DIR: &str = "page";

/// Histories the page plots, kept in `report.json` beside the figures.
#[derive(Debug, Default, Serialize)]
pub struct Histories {
    /// Each calibrated device's reprojection residuals.
    pub calibration: Vec<DeviceResiduals>,
}

/// One calibrated device's fit to its fiducial marks.
#[derive(Debug, Clone, Serialize)]
pub struct DeviceResiduals {
    /// Device name.
    pub device: String,
    /// RMS reprojection error (px).
    pub rms_px: f64,
    /// Every mark's reprojection residual (px), ascending.
    pub residuals_px: Vec<f64>,
}

impl DeviceResiduals {
    /// The residuals of calibration `cal` of device `name`.
    pub(super) fn new(name: &str, cal: &crate::calibrate::Calibration) -> Self {
        let mut residuals_px = cal.residuals_px.clone();
        residuals_px.sort_by(f64::total_cmp);
        Self {
            device: name.into(),
            rms_px: cal.rms_px,
            residuals_px,
        }
    }
}

pub(super) fn write_report(out: &Path, report: &Report) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let json = serde_json::to_string_pretty(report)?;
    let path = out.join("report.json");
    std::fs::write(&path, json).with_context(|| format!("cannot write {}", path.display()))?;
    let page = out.join(PAGE_DIR);
    std::fs::create_dir_all(&page).with_context(|| format!("cannot create {}", page.display()))?;

    let mut html = String::new();
    let _ = write!(
        html,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>Showcase demo</title>\n\
         <style>{STYLE}</style></head><body>\n<h1>Showcase demo</h1>\n<p>Complete: <b>{}</b>. \
         Raw numbers: <a href=\"report.json\">report.json</a>.</p>\n",
        report.complete
    );
    let phases: Vec<Value> = report
        .phases
        .iter()
        .map(|p| serde_json::to_value(p).unwrap_or(Value::Null))
        .collect();
    html.push_str(&phases_table(&phases));
    html.push_str(&figures_table(&report.figures));
    html.push_str(&plots_section(out, &page, report)?);
    html.push_str(&pictures_section(out, &page));
    html.push_str(&gallery_section(&report.gallery));
    html.push_str("</body></html>\n");
    let path = out.join("index.html");
    std::fs::write(&path, html).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

const STYLE: &str = "body{font-family:sans-serif;margin:2em;max-width:1400px}\
td,th{padding:4px 10px;border-bottom:1px solid #ddd;text-align:left;vertical-align:top}\
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}\
tr.skipped{color:#a00}tr.detail td{border-bottom:1px solid #ddd}.pass{color:#080;font-weight:bold}.miss{color:#c00;font-weight:bold}\
table.sub td{border:none;padding:0 6px;font-size:small}code{font-size:small;color:#555}\
.row{display:flex;flex-wrap:wrap;gap:8px}figure{margin:0}\
figcaption{font-size:small;max-width:400px}img{image-rendering:pixelated;max-width:400px}\
img.plot{image-rendering:auto;max-width:720px}figure.plot figcaption{max-width:720px}\
td.figure{min-width:16em;max-width:28em}.pass,.miss{white-space:nowrap}.colour-bar{display:block}\
.meaning{font-size:small;color:#444}.error{color:#c00}";

/// The phases (as `report.json` has them), each with its status, time and
/// detail; a phase that gives a reason (a skipped one) shows it. Read
/// through JSON so a phase's optional fields show when present.
fn phases_table(phases: &[Value]) -> String {
    let mut rows = String::new();
    for v in phases {
        let text = |key: &str| html_escape(v[key].as_str().unwrap_or(""));
        let reason = v["reason"]
            .as_str()
            .map_or(String::new(), |r| format!("<b>{}</b> ", html_escape(r)));
        let _ = writeln!(
            rows,
            "<tr class=\"{0}\"><td>{1}</td><td>{0}</td><td class=\"num\">{2:.2}</td><td>{reason}{3}</td></tr>",
            text("status"),
            text("name"),
            v["seconds"].as_f64().unwrap_or(f64::NAN),
            text("detail")
        );
    }
    format!(
        "<h2>Phases</h2>\n<table id=\"phases\"><tr><th>phase</th><th>status</th><th>seconds</th><th>detail</th></tr>\n{rows}</table>\n"
    )
}

/// The figures, one row each in the page's order: label and name, value,
/// unit, target, pass or miss; the label with the figure's name and
/// meaning. Unknown figures show raw.
fn figures_table(figures_map: &serde_json::Map<String, Value>) -> String {
    let mut names: Vec<&String> = figures_map.keys().collect();
    names.sort_by_key(|n| (figures::order(n), n.as_str()));
    let mut rows = String::new();
    for name in names {
        let value = &figures_map[name];
        let Some(f) = figures::figure(name) else {
            let _ = writeln!(
                rows,
                "<tr class=\"unknown\" data-figure=\"{0}\"><td class=\"figure\"><code>{0}</code>\
                 <div class=\"meaning\">not described</div></td><td class=\"num\">{1}</td>\
                 <td class=\"unit\">?</td><td>—</td><td></td></tr>",
                html_escape(name),
                html_escape(&value.to_string())
            );
            continue;
        };
        let mark = match (f.target, value.as_f64()) {
            (Some(t), Some(v)) => match t.met_by(v) {
                Some(true) => "<span class=\"pass\">✓ pass</span>",
                Some(false) => "<span class=\"miss\">✗ miss</span>",
                None => "",
            },
            _ => "",
        };
        // Records (per object, per observer) take a row of their own
        // below, so the table keeps to the page's width.
        let nested = match value {
            Value::Object(_) => true,
            Value::Array(items) => items.iter().any(Value::is_object),
            _ => false,
        };
        let shown = value_html(value);
        let _ = writeln!(
            rows,
            "<tr data-figure=\"{}\"><td class=\"figure\">{} <code>{}</code><div class=\"meaning\">{}</div></td>\
             <td class=\"{}\">{}</td><td class=\"unit\">{}</td><td class=\"num\">{}</td><td>{mark}</td></tr>",
            html_escape(name),
            html_escape(f.label),
            html_escape(name),
            html_escape(f.meaning),
            // Words wrap; numbers keep to one line.
            if value.is_string() { "text" } else { "num" },
            if nested { "below" } else { &shown },
            html_escape(f.unit),
            html_escape(&figures::target_text(f)),
        );
        if nested {
            let _ = writeln!(
                rows,
                "<tr class=\"detail\"><td></td><td colspan=\"4\">{shown}</td></tr>"
            );
        }
    }
    format!(
        "<h2>Figures</h2>\n<table id=\"figures\"><tr><th>figure</th><th>value</th><th>unit</th>\
         <th>target</th><th></th></tr>\n{rows}</table>\n"
    )
}

/// A figure's value: numbers to three significant digits, lists joined,
/// objects as a small table of their fields.
fn value_html(v: &Value) -> String {
    match v {
        Value::Null => "n/a".into(),
        Value::Bool(b) => b.to_string(),
        Value::Number(n) => n
            .as_f64()
            .map_or_else(|| n.to_string(), figures::format_number),
        Value::String(s) => html_escape(s),
        Value::Array(items) if items.iter().all(|i| !i.is_object()) => {
            items.iter().map(value_html).collect::<Vec<_>>().join(", ")
        }
        // A list of records (one per observer): a column each, a row per
        // field.
        Value::Array(items) => {
            let mut keys: Vec<&String> = Vec::new();
            for k in items
                .iter()
                .filter_map(Value::as_object)
                .flat_map(|o| o.keys())
            {
                if !keys.contains(&k) {
                    keys.push(k);
                }
            }
            let mut t = String::from("<table class=\"sub\">");
            for k in keys {
                let _ = write!(t, "<tr><td>{}</td>", html_escape(k));
                for item in items {
                    let _ = write!(
                        t,
                        "<td class=\"num\">{}</td>",
                        value_html(item.get(k.as_str()).unwrap_or(&Value::Null))
                    );
                }
                t.push_str("</tr>");
            }
            t.push_str("</table>");
            t
        }
        Value::Object(fields) => {
            let mut t = String::from("<table class=\"sub\">");
            for (k, f) in fields {
                let _ = write!(
                    t,
                    "<tr><td>{}</td><td class=\"num\">{}</td></tr>",
                    html_escape(k),
                    value_html(f)
                );
            }
            t.push_str("</table>");
            t
        }
    }
}

/// The plots, written as SVG files under `page` and shown as images.
fn plots_section(out: &Path, page: &Path, report: &Report) -> Result<String> {
    let mut all = Vec::new();
    let metrics = out.join("metrics.jsonl");
    if metrics.is_file() {
        all.extend(plots::frame_plots(&plots::read_frame_metrics(&metrics)?));
    }
    let solves: Vec<(String, Vec<(f64, f64)>)> = subfolders(out)
        .into_iter()
        .filter_map(|(name, dir)| Some((name, plots::read_convergence(&dir.join("summary.json"))?)))
        .collect();
    all.extend(plots::convergence_plot(&solves));
    all.extend(plots::calibration_plot(&report.histories.calibration));
    if all.is_empty() {
        return Ok(String::new());
    }
    let mut html = String::from("<h2>Plots</h2>\n<div class=\"row\">\n");
    for p in all {
        let path = page.join(p.file);
        std::fs::write(&path, &p.svg)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let _ = writeln!(
            html,
            "<figure class=\"plot\"><img class=\"plot\" src=\"{PAGE_DIR}/{}\" alt=\"{1}\"><figcaption>{1}</figcaption></figure>",
            p.file,
            html_escape(&p.caption)
        );
    }
    html.push_str("</div>\n");
    Ok(html)
}

/// The output folder's subfolders, sorted by name (the page's own left
/// out).
fn subfolders(out: &Path) -> Vec<(String, std::path::PathBuf)> {
    let mut dirs: Vec<(String, std::path::PathBuf)> = std::fs::read_dir(out)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().is_dir())
        .filter_map(|e| Some((e.file_name().into_string().ok()?, e.path())))
        .filter(|(n, _)| n != PAGE_DIR)
        .collect();
    dirs.sort();
    dirs
}

/// The result files a browser cannot show, as PNGs: each radiosity
/// solution (`*/solution.ply`) drawn, and each colour PFM map
/// (reflectance, irradiance; not the grey weight, depth and object maps).
/// A file that cannot be drawn is named with its error.
fn pictures_section(out: &Path, page: &Path) -> String {
    let mut rows = Vec::new();
    for (name, dir) in subfolders(out) {
        let mut images = Vec::new();
        let mut errors = Vec::new();
        let ply = dir.join("solution.ply");
        if ply.is_file() {
            let file = format!("{name}-solution.png");
            match images::write_solution_png(&ply, &page.join(&file)) {
                Ok(()) => images.push((
                    format!("{name}/solution.ply: B0, exposed to its brightest percent"),
                    format!("{PAGE_DIR}/{file}"),
                )),
                Err(e) => errors.push(format!("{}: {e:#}", ply.display())),
            }
        }
        let mut maps: Vec<std::path::PathBuf> = std::fs::read_dir(&dir)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                let n = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
                n.ends_with(".pfm")
                    && ![".weight.pfm", ".depth.pfm", ".object.pfm"]
                        .iter()
                        .any(|s| n.ends_with(s))
            })
            .collect();
        maps.sort();
        for pfm in maps {
            let stem = pfm.file_stem().and_then(|s| s.to_str()).unwrap_or("map");
            let file = format!("{name}-{stem}.png");
            match images::write_pfm_png(&pfm, &page.join(&file)) {
                Ok(()) => images.push((
                    format!("{name}/{stem}.pfm (linear 0 to 1, sRGB-encoded)"),
                    format!("{PAGE_DIR}/{file}"),
                )),
                Err(e) => errors.push(format!("{}: {e:#}", pfm.display())),
            }
        }
        if !images.is_empty() || !errors.is_empty() {
            rows.push((name, images, errors));
        }
    }
    if rows.is_empty() {
        return String::new();
    }
    let mut html = String::from("<h2>Results</h2>\n");
    for (name, images, errors) in rows {
        let _ = writeln!(html, "<h3>{}</h3><div class=\"row\">", html_escape(&name));
        for (caption, file) in images {
            html.push_str(&figure_html(&caption, &file, ""));
        }
        html.push_str("</div>\n");
        for e in errors {
            let _ = writeln!(
                html,
                "<p class=\"error\">cannot draw {}</p>",
                html_escape(&e)
            );
        }
    }
    html
}

/// The gallery rows, a colour bar beside each heat map.
fn gallery_section(gallery: &[GalleryRow]) -> String {
    let mut html = String::new();
    if !gallery.is_empty() {
        html.push_str("<h2>Images</h2>\n");
    }
    for (r, row) in gallery.iter().enumerate() {
        let _ = writeln!(
            html,
            "<h3>{}</h3><div class=\"row\">",
            html_escape(&row.title)
        );
        for (i, (caption, file)) in row.images.iter().enumerate() {
            let bar = if file.ends_with(HEAT_MAP_SUFFIX) {
                colour_bar(&format!("heat-{r}-{i}"))
            } else {
                String::new()
            };
            html.push_str(&figure_html(caption, file, &bar));
        }
        html.push_str("</div>\n");
    }
    html
}

/// An image with its caption, and `extra` (HTML) under them.
fn figure_html(caption: &str, file: &str, extra: &str) -> String {
    format!(
        "<figure><img src=\"{0}\" alt=\"{1}\"><figcaption>{1}</figcaption>{extra}</figure>\n",
        html_escape(file),
        html_escape(caption)
    )
}

/// An SVG colour bar of the heat maps' ΔE00 scale, from [`HEAT_STOPS`],
/// with a number at each stop and the uncovered colour.
fn colour_bar(id: &str) -> String {
    const W: f64 = 200.0;
    let max = HEAT_STOPS[HEAT_STOPS.len() - 1].0;
    let hex = |c: [u8; 3]| format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
    let mut stops = String::new();
    let mut labels = String::new();
    for (i, (d, c)) in HEAT_STOPS.iter().enumerate() {
        let _ = write!(
            stops,
            "<stop offset=\"{}\" stop-color=\"{}\"/>",
            d / max,
            hex(heat_stop_rgb(*c))
        );
        let last = i + 1 == HEAT_STOPS.len();
        let _ = write!(
            labels,
            "<text x=\"{:.1}\" y=\"44\" text-anchor=\"middle\">{}{}</text>",
            10.0 + W * d / max,
            if last { "≥ " } else { "" },
            d
        );
    }
    format!(
        "<svg class=\"colour-bar\" width=\"300\" height=\"50\" font-family=\"sans-serif\" font-size=\"11\" \
         role=\"img\" aria-label=\"CIEDE2000 colour scale\"><defs><linearGradient id=\"{id}\">{stops}</linearGradient></defs>\
         <text x=\"10\" y=\"12\">ΔE00</text><rect x=\"10\" y=\"16\" width=\"{W}\" height=\"14\" fill=\"url(#{id})\" stroke=\"black\"/>\
         {labels}<rect x=\"{:.0}\" y=\"16\" width=\"14\" height=\"14\" fill=\"{}\" stroke=\"black\"/>\
         <text x=\"{:.0}\" y=\"44\">none</text></svg>\n",
        W + 30.0,
        hex(HEAT_UNCOVERED),
        W + 26.0
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_show_units_marks_and_unknown_names_raw() {
        let mut m = serde_json::Map::new();
        m.insert("swap_skew_ms_p99".into(), serde_json::json!(0.123456));
        m.insert("dropped_frames".into(), serde_json::json!(2));
        m.insert("frame_rate_hz".into(), serde_json::json!(59.98765));
        m.insert("a_new_figure".into(), serde_json::json!([1.5, 2]));
        m.insert("renderer".into(), serde_json::json!("llvmpipe (LLVM 15)"));
        m.insert(
            "interactive_consistency_rel_rmse_per_object".into(),
            serde_json::json!({"plate": 0.001}),
        );
        let html = figures_table(&m);
        assert_eq!(html.matches("<tr data-figure=").count(), 5);
        assert!(
            html.contains("<td class=\"text\">llvmpipe (LLVM 15)</td><td class=\"unit\">text</td>")
        );
        // A record gets a row of its own under its figure's.
        assert!(html.contains("<td class=\"num\">below</td>"));
        assert!(html.contains("<tr class=\"detail\"><td></td><td colspan=\"4\"><table class=\"sub\"><tr><td>plate</td>"));
        assert!(html.contains(">0.123</td><td class=\"unit\">ms</td><td class=\"num\">≤ 1 ms</td><td><span class=\"pass\">"));
        assert!(html.contains(">2</td><td class=\"unit\">frames</td><td class=\"num\">= 0 frames</td><td><span class=\"miss\">"));
        assert!(
            html.contains(">60.0</td><td class=\"unit\">Hz</td><td class=\"num\">—</td><td></td>")
        );
        assert!(html.contains("<tr class=\"unknown\" data-figure=\"a_new_figure\">"));
        assert!(html.contains("[1.5,2]"));
        // The table's order: the skew before the dropped frames, unknown last.
        let at = |s: &str| html.find(s).unwrap();
        assert!(at("swap_skew_ms_p99") < at("dropped_frames"));
        assert!(at("dropped_frames") < at("a_new_figure"));
    }

    #[test]
    fn a_skipped_phase_shows_its_reason() {
        let phases = [
            serde_json::json!({"name": "scene", "status": "ran", "seconds": 0.5, "detail": "7 objects"}),
            serde_json::json!({"name": "radiosity", "status": "skipped", "seconds": 0.0,
                "detail": "", "reason": "the scene has no projector < 1"}),
        ];
        let html = phases_table(&phases);
        assert!(html.contains("<tr class=\"ran\"><td>scene</td><td>ran</td><td class=\"num\">0.50</td><td>7 objects</td></tr>"));
        assert!(html.contains("<tr class=\"skipped\"><td>radiosity</td><td>skipped</td><td class=\"num\">0.00</td><td><b>the scene has no projector &lt; 1</b> </td></tr>"));
    }

    #[test]
    fn a_list_of_records_is_a_table_with_a_column_each() {
        let v = serde_json::json!([
            {"observer": "a", "x": 0.5},
            {"observer": "b", "x": 0.25, "y": null}
        ]);
        let html = value_html(&v);
        assert!(html.contains(
            "<tr><td>observer</td><td class=\"num\">a</td><td class=\"num\">b</td></tr>"
        ));
        assert!(html.contains(
            "<tr><td>x</td><td class=\"num\">0.500</td><td class=\"num\">0.250</td></tr>"
        ));
        assert!(
            html.contains(
                "<tr><td>y</td><td class=\"num\">n/a</td><td class=\"num\">n/a</td></tr>"
            )
        );
        assert_eq!(value_html(&serde_json::json!([0.5, null])), "0.500, n/a");
    }

    #[test]
    fn the_colour_bar_names_every_stop() {
        let bar = colour_bar("x");
        assert_eq!(bar.matches("<stop ").count(), HEAT_STOPS.len());
        for label in [">0<", ">2.5<", ">5<", ">7.5<", ">≥ 10<"] {
            assert!(bar.contains(label), "{label}: {bar}");
        }
        assert!(bar.contains("stop-color=\"#ff0000\""));
    }
}
