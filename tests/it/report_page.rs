//! The demo's `index.html` on the demo's real output, opened in headless
//! Chromium (`browser.rs`): it renders with no errors, every image loads,
//! the figures table has a row with a unit for every figure of
//! `report.json`, the plots are there, and every heat map has its colour
//! bar. Called by the demo test with its output folder, so the demo runs
//! once.

use crate::browser::Browser;
use serde_json::Value;
use std::path::Path;
use std::time::Duration;

/// The plots the page must show, under `page/`.
const PLOTS: [&str; 4] = [
    "page/swap_skew.svg",
    "page/tracking_to_swap.svg",
    "page/radiosity_convergence.svg",
    "page/calibration_residuals.svg",
];

/// Check the page the demo wrote into `out`, whose `report.json` is
/// `report`.
pub(crate) fn check_report_page(out: &Path, report: &Value) {
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    let figures = report["figures"].as_object().unwrap();
    // Without a browser too: one row per figure, the plots written.
    assert_eq!(
        html.matches("data-figure=").count(),
        figures.len(),
        "the figures table should have one row per figure"
    );
    assert!(
        !html.contains("<tr class=\"unknown\""),
        "a figure the page does not describe: add it to demo/page/figures.rs"
    );
    for plot in PLOTS {
        let svg = std::fs::read_to_string(out.join(plot)).unwrap_or_else(|e| panic!("{plot}: {e}"));
        assert!(
            svg.starts_with("<svg") && svg.contains("<polyline"),
            "{plot}"
        );
    }

    let Some(mut b) = Browser::launch() else {
        return;
    };
    b.open(&format!("file://{}", out.join("index.html").display()));
    b.wait_for(
        "Array.from(document.images).every(i => i.complete)",
        Duration::from_secs(30),
    );
    let errors = b.errors();
    assert!(errors.is_empty(), "the page reported errors: {errors:?}");
    let broken = b.eval(
        "Array.from(document.images).filter(i => !(i.naturalWidth > 0)).map(i => i.getAttribute('src'))",
    );
    assert_eq!(broken, serde_json::json!([]), "images that did not load");

    // The figures table: a row per figure of report.json, each with a
    // unit, and none the page does not know.
    let rows = b.eval(
        "Array.from(document.querySelectorAll('#figures tr[data-figure]'))\
         .map(r => [r.dataset.figure, r.querySelector('td.unit').textContent, r.className])",
    );
    let rows = rows.as_array().unwrap();
    let mut names: Vec<&str> = rows.iter().map(|r| r[0].as_str().unwrap()).collect();
    names.sort_unstable();
    let mut expected: Vec<&str> = figures.keys().map(String::as_str).collect();
    expected.sort_unstable();
    assert_eq!(names, expected);
    for r in rows {
        let unit = r[1].as_str().unwrap();
        assert!(!unit.is_empty() && unit != "?", "{r}: no unit");
        assert_ne!(r[2], "unknown", "{r}: a figure the page does not describe");
    }
    // Targets are marked: at least the ones the demo test holds.
    let marked = b.eval("document.querySelectorAll('#figures .pass, #figures .miss').length");
    assert!(marked.as_u64().unwrap() >= 5, "{marked} figures marked");

    // The plots, shown and drawn.
    let plots = b.eval(
        "Array.from(document.querySelectorAll('img.plot')).filter(i => i.naturalWidth > 0).map(i => i.getAttribute('src'))",
    );
    for plot in PLOTS {
        assert!(
            plots.as_array().unwrap().iter().any(|p| p == plot),
            "{plot} not shown: {plots}"
        );
    }
    // The radiosity solution and the reflectance maps as pictures.
    let pictures = b.eval(
        "Array.from(document.images).map(i => i.getAttribute('src')).filter(s => s.startsWith('page/') && s.endsWith('.png'))",
    );
    let pictures: Vec<&str> = pictures
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_str().unwrap())
        .collect();
    assert!(
        pictures.iter().any(|p| p.ends_with("-solution.png")),
        "{pictures:?}"
    );
    assert!(
        pictures.iter().any(|p| p.starts_with("page/reflectance-")),
        "{pictures:?}"
    );
    assert_eq!(b.eval("document.querySelectorAll('.error').length"), 0);
    // A colour bar beside every heat map.
    let heat_maps = b.eval(
        "Array.from(document.images).filter(i => i.getAttribute('src').endsWith('-delta-e.png')).length",
    );
    let bars = b.eval("document.querySelectorAll('svg.colour-bar').length");
    assert!(heat_maps.as_u64().unwrap() > 0);
    assert_eq!(bars, heat_maps);
}
