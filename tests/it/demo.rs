//! The main job end to end, short: `demo` with few frames must run every
//! built stage, write `report.json` and `index.html`, give a reason for
//! every skipped stage, and report finite headline figures.

use showcase_master::cli::{Cli, run};

#[test]
fn short_demo_writes_an_honest_report() {
    use clap::Parser;
    let out = std::env::temp_dir().join(format!("showcase-demo-{}", std::process::id()));
    let cli = Cli::try_parse_from([
        "showcase-master",
        "demo",
        "--frames",
        "30",
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap();
    run(cli).expect("the demo runs");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    let session = std::fs::read_to_string(out.join("session.jsonl")).unwrap();
    // Every image the report shows was written.
    let gallery = report["gallery"].as_array().unwrap();
    let images: Vec<&str> = gallery
        .iter()
        .flat_map(|row| row["images"].as_array().unwrap())
        .map(|pair| pair[1].as_str().unwrap())
        .collect();
    for file in &images {
        let bytes = std::fs::read(out.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(&bytes[1..4], b"PNG", "{file}");
        assert!(html.contains(file), "index.html does not show {file}");
    }
    crate::report_page::check_report_page(&out, &report);
    std::fs::remove_dir_all(&out).unwrap();
    // Three frames: two projectors' values, two faces' two eyes, per
    // observer its target, composite, mirror part and heat map, and the
    // camera's target and measurement.
    assert_eq!(images.len(), 3 * (2 + 2 * 2 + 2 * 4 + 2), "{images:?}");

    let phases = report["phases"].as_array().unwrap();
    let names: Vec<&str> = phases.iter().map(|p| p["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "scene",
            "calibration",
            "reflectance",
            "radiosity",
            "interactive",
            "rendering"
        ]
    );
    for p in phases {
        assert_eq!(p["status"], "ran", "{p}");
    }
    assert_eq!(report["complete"], serde_json::json!(true));
    let figures = &report["figures"];
    for key in [
        "calibration_rms_px",
        "calibration_center_error_m",
        "frame_rate_hz",
        "swap_skew_ms_p99",
        "tracking_to_swap_ms_p99",
        "delta_e2000_median",
        "delta_e2000_p95",
        "interactive_consistency_rel_rmse",
        "interactive_compared_fraction",
        "observer_consistency_rel_rmse",
        "reflectance_rel_rmse",
        "reflectance_coverage",
        "reflectance_eta_rel_error",
        "radiosity_consistency_rel_rmse",
        "radiosity_paper_consistency_rel_rmse",
    ] {
        let v = figures[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key} missing: {figures}"));
        assert!(v.is_finite() && v >= 0.0, "{key} = {v}");
    }
    // Calibration from 0.5 px marks: residuals of that order.
    assert!(figures["calibration_rms_px"].as_f64().unwrap() < 1.0);
    // Eta estimated within 1%, and the reflectance within 0.02 (the demo's camera is smaller than the bench's; 0.0174 measured
    // with the stratified gather, 0.0277 before it).
    assert!(figures["reflectance_eta_rel_error"].as_f64().unwrap() <= 0.01);
    let reflectance = figures["reflectance_rel_rmse"].as_f64().unwrap();
    assert!(reflectance <= 0.02, "reflectance rel RMSE {reflectance}");
    // Augmented radiosity through the simulated projectors, within 0.03.
    let radiosity = figures["radiosity_consistency_rel_rmse"].as_f64().unwrap();
    assert!(radiosity <= 0.03, "radiosity consistency {radiosity}");
    assert_eq!(figures["dropped_frames"], 0);
    // Swap skew and tracking-to-swap are timings: `bench cluster` holds
    // them to their targets, a test on a loaded machine must not.
    // The projector-role consistency check on the demo's outputs: both projectors'
    // values through the true projectors (direct light) onto the real
    // objects, seen by the cabinet's camera, within 1% of the
    // target over the pixels that check compares (0.0071 over 72% of the
    // real pixels measured on this short demo, 0.0048-0.0067 over 71% on
    // the default one), and those
    // exclusions (edges, every eye's occlusion shadow) leave most real
    // pixels compared.
    let interactive = figures["interactive_consistency_rel_rmse"]
        .as_f64()
        .unwrap();
    assert!(interactive <= 0.01, "interactive consistency {interactive}");
    let compared = figures["interactive_compared_fraction"].as_f64().unwrap();
    assert!(
        compared >= 0.6,
        "{compared} of the camera's real pixels compared"
    );
    let per_object = figures["interactive_consistency_rel_rmse_per_object"]
        .as_object()
        .unwrap();
    for name in ["plate", "room/floor", "room/back", "bunny"] {
        let e = per_object[name].as_f64().unwrap();
        assert!(e.is_finite() && e >= 0.0, "{name}: {e}");
    }
    // Each observer's view against its target (the same check seen from
    // the eyes, through both projectors and the mirror).
    let observers = figures["observers"].as_array().unwrap();
    assert_eq!(observers.len(), 2);
    // The real surfaces where the method can be right by design (off
    // projector pixels straddling an edge, off reach edges, outside other
    // eyes' occlusion shadows the face cannot fill) meet the same 1%,
    // and those exclusions leave most real pixels compared (0.0056 and
    // 0.0092 over 87% and 90% measured).
    let comparable = figures["observer_consistency_rel_rmse_real_comparable"]
        .as_f64()
        .unwrap();
    assert!(
        comparable <= 0.01,
        "comparable real-surface consistency {comparable}"
    );
    for o in observers {
        let kept = o["comparable_real_fraction"].as_f64().unwrap();
        assert!(
            kept >= 0.8,
            "{}: {kept} of the real pixels compared",
            o["observer"]
        );
        let c = o["consistency_rel_rmse_real_comparable"].as_f64().unwrap();
        assert!(c.is_finite() && c <= 0.01, "{}: {c}", o["observer"]);
    }
    for phase in &names {
        assert!(html.contains(phase), "index.html lacks {phase}");
    }
    // The walk was recorded: a header plus one datagram per frame.
    assert_eq!(session.lines().count(), 31);
}
