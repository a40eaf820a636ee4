//! `bench_render` records: every variant at a small size has the
//! record's fixed keys, the reduced variants run fewer passes, and `static` reuses its
//! frame. With `SHOWCASE_RENDER_BENCH=WxH[,WxH...]` it runs those sizes
//! and prints the JSON array (the measurement command of the report;
//! timings are printed, never asserted).

use anyhow::{Result, ensure};
use showcase_render::render::bench::{BenchOptions, bench_render};

use super::gpu_or_skip;
use super::scenes::bench;

#[test]
fn bench_records_cover_every_variant_with_the_issues_keys() -> Result<()> {
    let Some(ctx) = gpu_or_skip("bench_records_cover_every_variant_with_the_issues_keys")? else {
        return Ok(());
    };
    let sizes: Vec<(u32, u32)> = match std::env::var("SHOWCASE_RENDER_BENCH") {
        Ok(list) => list
            .split(',')
            .filter_map(|s| s.split_once('x'))
            .filter_map(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)))
            .collect(),
        Err(_) => vec![(96, 72)],
    };
    let full = std::env::var_os("SHOWCASE_RENDER_BENCH").is_some();
    let options = BenchOptions {
        sizes: sizes.clone(),
        frames: if full { 30 } else { 3 },
        accuracy: true,
        ..BenchOptions::default()
    };
    let records = bench_render(&ctx, &bench()?, &options)?;
    let json = serde_json::to_value(&records)?;
    if full {
        println!("{}", serde_json::to_string_pretty(&json)?);
    }
    ensure!(records.len() == 10 * sizes.len());
    for r in json.as_array().unwrap() {
        for key in [
            "role",
            "width",
            "height",
            "scene_variant",
            "passes_run",
            "median_ms",
            "p99_ms",
            "adapter",
            "consistency_rel_rmse_direct",
            "gpu_cpu_rel_rmse",
        ] {
            ensure!(r.get(key).is_some(), "record lacks {key}: {r}");
        }
    }
    let by = |v: &str| {
        records
            .iter()
            .find(|r| r.role == "projector" && r.scene_variant == v)
            .unwrap()
    };
    let face = |v: &str| {
        records
            .iter()
            .find(|r| r.role == "face" && r.scene_variant == v)
            .unwrap()
    };
    ensure!(
        face("full").passes_run
            == [
                "light_shadow_views",
                "eye_shadow_views",
                "cube_maps",
                "face_view"
            ],
        "{:?}",
        face("full").passes_run
    );
    // One observer in stereo: each eye still fills the other eye's
    // occlusion shadows, so the eye views run (the projector's single
    // observer variant is what saves work).
    ensure!(
        face("single_observer").passes_run
            == [
                "light_shadow_views",
                "eye_shadow_views",
                "cube_maps",
                "face_view"
            ],
        "{:?}",
        face("single_observer").passes_run
    );
    // The sphere is reflective only in the full scene.
    ensure!(
        face("no_reflective").passes_run == ["light_shadow_views", "eye_shadow_views", "face_view"],
        "{:?}",
        face("no_reflective").passes_run
    );
    ensure!(face("no_virtual_objects").passes_run == ["face_view"]);
    ensure!(face("static").passes_run.is_empty());
    ensure!(face("full").gpu_cpu_rel_rmse.is_some());
    ensure!(
        by("full").passes_run.len() == 3,
        "{:?}",
        by("full").passes_run
    );
    ensure!(by("no_virtual_objects").passes_run.len() == 2);
    ensure!(
        by("static").passes_run.is_empty(),
        "static redrew: {:?}",
        by("static").passes_run
    );
    ensure!(
        by("full").gpu_cpu_rel_rmse.is_some() && by("full").consistency_rel_rmse_direct.is_some()
    );
    Ok(())
}
