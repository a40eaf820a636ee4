//! The demo's `report.json` and `index.html`.

use super::Report;
use anyhow::{Context, Result};
use std::path::Path;

pub(super) fn write_report(out: &Path, report: &Report) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let json = serde_json::to_string_pretty(report)?;
    let path = out.join("report.json");
    std::fs::write(&path, json).with_context(|| format!("cannot write {}", path.display()))?;
    let mut rows = String::new();
    for p in &report.phases {
        rows.push_str(&format!(
            "<tr class=\"{}\"><td>{}</td><td>{}</td><td>{:.2}</td><td>{}</td></tr>\n",
            p.status,
            html_escape(&p.name),
            p.status,
            p.seconds,
            html_escape(&p.detail)
        ));
    }
    let mut gallery = String::new();
    if !report.gallery.is_empty() {
        gallery.push_str("<h2>Images</h2>\n");
    }
    for row in &report.gallery {
        gallery.push_str(&format!(
            "<h3>{}</h3><div class=\"row\">\n",
            html_escape(&row.title)
        ));
        for (caption, file) in &row.images {
            gallery.push_str(&format!(
                "<figure><img src=\"{0}\" alt=\"{1}\"><figcaption>{1}</figcaption></figure>\n",
                html_escape(file),
                html_escape(caption)
            ));
        }
        gallery.push_str("</div>\n");
    }
    let html = format!(
        "<!doctype html><meta charset=\"utf-8\"><title>Showcase demo</title>\n\
         <style>body{{font-family:sans-serif;margin:2em}}td,th{{padding:4px 10px;border-bottom:1px solid #ddd}}\
         tr.skipped{{color:#a00}}.row{{display:flex;flex-wrap:wrap;gap:8px}}figure{{margin:0}}\
         figcaption{{font-size:small;max-width:320px}}img{{image-rendering:pixelated;max-width:400px}}</style>\n<h1>Showcase demo</h1>\n<p>Complete: <b>{}</b></p>\n\
         <table><tr><th>phase</th><th>status</th><th>seconds</th><th>detail</th></tr>\n{rows}</table>\n\
         <h2>Figures</h2><pre>{}</pre>\n{gallery}",
        report.complete,
        html_escape(&serde_json::to_string_pretty(&report.figures).unwrap_or_default())
    );
    let path = out.join("index.html");
    std::fs::write(&path, html).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
