//! `bench gi`, judged in the physically complete world: on the figure-3
//! scene the projectors' global-illumination correction against their
//! direct-light maps, and on the demo scene what the observers see of the
//! faces' virtual objects in both modes.

use showcase_master::demo::gi::{GiBenchOptions, bench_gi_scene};
use std::path::Path;

#[test]
fn global_mode_brings_figure3_at_least_three_times_closer_to_the_complete_target() {
    // The virtual blocks and ceiling light carry much of the real walls'
    // indirect light: direct maps 0.20, global maps 0.029 (noise 0.015)
    // measured at 1024 paths; here 256 paths (noise about twice that).
    let records = bench_gi_scene(
        Path::new("builtin:figure3"),
        &GiBenchOptions {
            frame: 10,
            truth_paths: 256,
            max_truth_paths: 256,
            without_occlusion: false,
            live_frames: 240,
            patch_area: None,
        },
    )
    .unwrap();
    // Direct and global mode, each with the live walk moving the light and
    // then the carried block.
    assert_eq!(records.len(), 4);
    let figure = |mode: &str| {
        let r = records.iter().find(|r| r["mode"] == mode).unwrap();
        for key in [
            "scene",
            "elements",
            "frame",
            "renderer",
            "observer_delta_e_median",
            "observer_delta_e_p95",
            "compared_noise_rel_rmse",
            "projector_clipped_fractions",
            "camera_consistency_rel_rmse_per_object",
        ] {
            assert!(r.get(key).is_some(), "{mode} lacks {key}: {r}");
        }
        assert_eq!(r["scene"], "figure3");
        (
            r["camera_consistency_rel_rmse"].as_f64().unwrap(),
            r["compared_noise_rel_rmse"].as_f64().unwrap(),
        )
    };
    // The live cluster: the walk moves the ceiling light, then the short
    // block, so global mode publishes updates for each; direct mode has
    // none. The offline figures are the same in both records of a mode.
    for moving in ["light", "object"] {
        let live = |mode: &str| {
            records
                .iter()
                .find(|r| r["mode"] == mode && r["move"] == moving)
                .unwrap_or_else(|| panic!("no {mode} record for the {moving} move"))
        };
        for key in [
            "update_ms_p50",
            "update_ms_p99",
            "frames_stale_max",
            "swap_skew_ms_p99",
            "tracking_to_swap_ms_p99",
        ] {
            assert!(live("global").get(key).is_some(), "global lacks {key}");
        }
        assert_eq!(live("direct")["updates"], 0);
        assert!(live("direct")["update_ms_p50"].is_null());
        assert!(
            live("global")["updates"].as_u64().unwrap() >= 1,
            "{}",
            live("global")
        );
        assert!(live("global")["frames_stale_max"].as_u64().unwrap() >= 1);
        for mode in ["direct", "global"] {
            assert_eq!(
                live(mode)["camera_consistency_rel_rmse"],
                figure(mode).0,
                "{mode}, {moving}"
            );
        }
    }
    let (direct, noise) = figure("direct");
    let (global, _) = figure("global");
    assert!(direct > 5.0 * noise, "direct {direct}, noise {noise}");
    assert!(
        global < direct / 3.0,
        "global {global} against direct {direct}"
    );
    // No observer in figure 3: no observer figures.
    assert!(
        records
            .iter()
            .all(|r| r["observer_delta_e_median"].is_null())
    );
}

#[test]
fn bench_gi_names_what_a_scene_lacks() {
    let err = bench_gi_scene(
        Path::new("builtin:cornell"),
        &GiBenchOptions {
            frame: 1,
            truth_paths: 8,
            max_truth_paths: 8,
            without_occlusion: false,
            live_frames: 0,
            patch_area: None,
        },
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("needs a projector and a camera"),
        "{err:#}"
    );
}

/// `bench gi` on the demo scene's observers: in global mode the faces
/// add the virtual objects' indirect light and take away the real light
/// seen through them, which brings what the observers see of the virtual
/// objects much closer to the complete target (CIEDE2000 median over the
/// virtual pixels 5.4 direct against 2.3 global, measured with the
/// demo's paths on lavapipe); the whole view's p95 improves too (8.3
/// against 6.2), and stays above the ideal-CRT floor (1.2).
#[test]
fn global_mode_faces_bring_the_virtual_objects_closer_to_the_complete_target() {
    let records = bench_gi_scene(
        Path::new("builtin:showcase"),
        &GiBenchOptions {
            frame: 60,
            truth_paths: 128,
            max_truth_paths: 128,
            without_occlusion: false,
            live_frames: 0,
            patch_area: None,
        },
    )
    .unwrap();
    let figure = |mode: &str, key: &str| {
        let r = records.iter().find(|r| r["mode"] == mode).unwrap();
        r[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{mode} lacks {key}: {r}"))
    };
    let key = "observer_delta_e_median_virtual";
    let (direct, global) = (figure("direct", key), figure("global", key));
    eprintln!("{key}: direct {direct}, global {global}");
    assert!(
        global < 0.6 * direct,
        "{key}: global {global} against direct {direct}"
    );
    let key = "observer_delta_e_p95";
    let (direct, global) = (figure("direct", key), figure("global", key));
    let floor = figure("global", "observer_delta_e_p95_ideal_crt");
    eprintln!("{key}: direct {direct}, global {global}, ideal CRT {floor}");
    assert!(
        global < direct,
        "{key}: global {global} against direct {direct}"
    );
    assert!(
        floor < global,
        "{key}: ideal CRT {floor} against global {global}"
    );
}

/// The demo scene's solution at 0.0004 m^2 patches (18,159 elements)
/// against the default 0.01 (11,988): on every object the largest `add`
/// stays within twice the default's (at most 1.6 times measured). A
/// source nearly in a flat cluster's plane once made the kernel's linear
/// variation unbounded, and one red-wall element got 3,192 W/m^2 against
/// 0.50 by default.
#[test]
fn finer_patches_leave_no_runaway_element() {
    use showcase_master::radiosity_job::{RadiosityOptions, indirect_values};
    let scene = showcase_master::scene_file::load_any(Path::new("builtin:showcase")).unwrap();
    let state = showcase_master::tracking::initial_frame(&scene, 60, 1.0, 1);
    let frame = showcase_light::render::FrameScene::resolve(&scene, &state).unwrap();
    let largest = |area: Option<f64>| {
        let options = RadiosityOptions {
            max_patch_area: area,
            ..Default::default()
        };
        let (mesh, values) = indirect_values(&frame.showcase, &[], &frame.eyes, &options).unwrap();
        let mut per = std::collections::BTreeMap::<String, f64>::new();
        for (e, v) in mesh.elements.iter().zip(&values) {
            let name = frame.showcase.objects[e.object as usize].name.clone();
            let m = per.entry(name).or_default();
            *m = m.max(v.add.abs().max_element());
        }
        (mesh.elements.len(), per)
    };
    let (coarse_n, coarse) = largest(None);
    let (fine_n, fine) = largest(Some(0.0004));
    assert!(fine_n > coarse_n, "{fine_n} against {coarse_n} elements");
    for (name, f) in &fine {
        let c = coarse[name];
        eprintln!("{name}: largest add {f:.3} against {c:.3} W/m^2");
        assert!(*f <= 2.0 * c, "{name}: largest add {f} against {c}");
    }
}
