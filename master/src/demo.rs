//! `showcase-master demo`: the whole pipeline on the simulated showcase.
//! Stages that are not built yet are reported as skipped, in the console
//! and in `report.json`, never passed off as done.

use crate::cli::DemoArgs;
use anyhow::{Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The built-in demo cabinet, shipped with the sources.
pub fn default_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/showcase.toml")
}

/// How one phase of the demo went.
#[derive(Debug, Clone, Serialize)]
pub struct Phase {
    /// Phase name.
    pub name: String,
    /// `ran` or `skipped`.
    pub status: &'static str,
    /// Wall-clock seconds spent.
    pub seconds: f64,
    /// What it did or why it was skipped.
    pub detail: String,
}

/// The demo's `report.json`.
#[derive(Debug, Default, Serialize)]
pub struct Report {
    /// True only when no phase was skipped.
    pub complete: bool,
    /// Every phase in order.
    pub phases: Vec<Phase>,
    /// Headline figures, by name.
    pub figures: serde_json::Map<String, serde_json::Value>,
}

impl Report {
    fn ran(&mut self, name: &str, started: Instant, detail: String) {
        let seconds = started.elapsed().as_secs_f64();
        eprintln!("[demo] {name}: done in {seconds:.2} s ({detail})");
        self.phases.push(Phase {
            name: name.into(),
            status: "ran",
            seconds,
            detail,
        });
    }

    fn skipped(&mut self, name: &str, why: &str) {
        eprintln!("[demo] {name}: SKIPPED: {why}");
        self.phases.push(Phase {
            name: name.into(),
            status: "skipped",
            seconds: 0.0,
            detail: why.into(),
        });
    }
}

/// Run the demo.
pub fn run(args: &DemoArgs) -> Result<()> {
    let scene_path = args.scene.clone().unwrap_or_else(default_scene);
    let mut report = Report::default();

    let t = Instant::now();
    let scene = crate::scene_file::load_scene(&scene_path)?;
    report.ran(
        "scene",
        t,
        format!(
            "{}: {} objects, {} lights, {} projectors, {} cameras, {} faces, {} observers",
            scene_path.display(),
            scene.objects.len(),
            scene.lights.len(),
            scene.projectors.len(),
            scene.cameras.len(),
            scene.faces.len(),
            scene.observers.len()
        ),
    );

    report.skipped(
        "calibration",
        "device calibration is not built yet (issue #4)",
    );
    report.skipped(
        "reflectance",
        "reflectance capture is not built yet (issue #3)",
    );
    report.skipped(
        "radiosity",
        "augmented radiosity is not built yet (issue #5)",
    );
    report.skipped(
        "interactive",
        &format!(
            "{} frames of the loopback cluster: the cluster runtime (issue #7) and the real-time renderer (issue #6) are not built yet",
            args.frames
        ),
    );

    report.complete = report.phases.iter().all(|p| p.status == "ran");
    write_report(&args.out, &report)?;
    let skipped = report
        .phases
        .iter()
        .filter(|p| p.status == "skipped")
        .count();
    eprintln!(
        "[demo] wrote {}/report.json and index.html; {} of {} phases ran, {skipped} skipped (see above)",
        args.out.display(),
        report.phases.len() - skipped,
        report.phases.len()
    );
    Ok(())
}

fn write_report(out: &Path, report: &Report) -> Result<()> {
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
    let html = format!(
        "<!doctype html><meta charset=\"utf-8\"><title>Showcase demo</title>\n\
         <style>body{{font-family:sans-serif;margin:2em}}td,th{{padding:4px 10px;border-bottom:1px solid #ddd}}\
         tr.skipped{{color:#a00}}</style>\n<h1>Showcase demo</h1>\n<p>Complete: <b>{}</b></p>\n\
         <table><tr><th>phase</th><th>status</th><th>seconds</th><th>detail</th></tr>\n{rows}</table>\n",
        report.complete
    );
    let path = out.join("index.html");
    std::fs::write(&path, html).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
