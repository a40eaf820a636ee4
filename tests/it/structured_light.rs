//! Integration tests: projector calibration by structured light in the
//! simulated showcase (the demo cabinet with its camera at 240x180, one
//! path per pixel, to keep the light transport cheap): the decode against
//! the sim's truth, the validity mask, the calibration against the true
//! projector, the job's files, and the errors a technician gets.

use glam::{DMat3, DVec3};
use showcase_light::sim::{SimConfig, SimShowcase};
use showcase_light::{DeviceRays, ObjectFilter, SceneGeometry};
use showcase_master::calibrate::structured_light::bench::{surface_points, true_rms};
use showcase_master::calibrate::structured_light::{
    CorrespondenceSettings, StructuredLightError, StructuredLightJob, StructuredLightOptions,
    calibrate_structured_light, capture_and_decode, correspondences, run_structured_light,
};
use showcase_proto::Showcase;
use std::path::Path;

/// Paths per camera pixel of the sim's light transport (full white).
const SAMPLES: u32 = 4;

/// The camera's size in these tests.
const CAMERA: (u32, u32) = (240, 180);

/// The demo cabinet with its camera scaled down to [`CAMERA`].
fn small_showcase() -> Showcase {
    let mut scene = showcase_master::scene_file::load_any(Path::new("builtin:showcase")).unwrap();
    let c = &mut scene.cameras[0].device;
    let s = CAMERA.0 as f64 / c.width as f64;
    c.k = DMat3::from_diagonal(DVec3::new(s, s, 1.0)) * c.k;
    (c.width, c.height) = CAMERA;
    scene
}

fn sim(scene: &Showcase) -> SimShowcase {
    SimShowcase::new(
        scene,
        SimConfig {
            samples_per_pixel: SAMPLES,
            ..SimConfig::default()
        },
    )
    .unwrap()
}

#[test]
fn decode_under_camera_noise_finds_the_true_projector_pixels_and_masks_the_unlit() {
    let scene = small_showcase();
    let sim = sim(&scene);
    let captured = capture_and_decode(
        "projector-0",
        &mut sim.projector(0).unwrap(),
        &mut sim.camera(0).unwrap(),
        &StructuredLightOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    let geometry = SceneGeometry::build(&scene, &ObjectFilter::Real).unwrap();
    let camera = DeviceRays::new(&scene.cameras[0].device).unwrap();
    let projector = DeviceRays::new(&scene.projectors[0].device).unwrap();
    let (w, h) = CAMERA;
    let (mut lit, mut unlit, mut valid, mut exact, mut near, mut unlit_valid) = (0, 0, 0, 0, 0, 0);
    for y in 0..h {
        for x in 0..w {
            let decoded = captured.decoded.pixels[(y * w + x) as usize];
            let ray = camera.pixel_ray(x, y).unwrap();
            let truth = geometry
                .closest_hit(&ray, 0.0, f64::INFINITY)
                .filter(|hit| {
                    projector.sees(&geometry, hit.point, hit.facing_normal(ray.direction))
                })
                .and_then(|hit| projector.pixel_of(hit.point));
            match (truth, decoded) {
                (None, d) => {
                    unlit += 1;
                    unlit_valid += usize::from(d.is_some());
                }
                (Some(t), d) => {
                    lit += 1;
                    if let Some(d) = d {
                        valid += 1;
                        exact += usize::from(t == d);
                        near += usize::from(t.0.abs_diff(d.0) <= 1 && t.1.abs_diff(d.1) <= 1);
                    }
                }
            }
        }
    }
    eprintln!(
        "lit {lit}, unlit {unlit}, valid {valid}, exact {exact}, within 1 px {near}, unlit but valid {unlit_valid}; exposure {} s",
        captured.exposure_s
    );
    assert!(lit > 10_000 && unlit > 1_000, "lit {lit}, unlit {unlit}");
    assert!(
        valid as f64 > 0.8 * lit as f64,
        "{valid} of {lit} lit pixels valid"
    );
    assert!(
        exact as f64 >= 0.99 * valid as f64,
        "{exact} of {valid} exact"
    );
    assert!(
        near as f64 >= 0.999 * valid as f64,
        "{near} of {valid} within 1 px"
    );
    assert!(
        unlit_valid as f64 <= 0.005 * unlit as f64,
        "{unlit_valid} of {unlit} pixels the projector cannot light decoded as valid"
    );
    // What stays after the geometric and neighbour tests lies where the
    // true projector sends the pixel it decoded.
    let corr = correspondences(
        &captured.decoded,
        &camera,
        &geometry,
        &CorrespondenceSettings::default(),
    );
    let all: Vec<_> = corr.fit.iter().chain(&corr.heldout).collect();
    let off: Vec<f64> = all
        .iter()
        .map(|c| {
            let p = projector.project(DVec3::from_array(c.world)).unwrap();
            (p - glam::DVec2::from_array(c.pixel)).abs().max_element()
        })
        .collect();
    let far = off.iter().filter(|d| **d > 1.0).count();
    eprintln!(
        "{} correspondences from {} accepted pixels, {far} more than 1 px from the truth, dropped {:?}",
        all.len(),
        corr.accepted,
        corr.dropped
    );
    assert!(all.len() > 10_000, "{} correspondences", all.len());
    assert!(
        far as f64 <= 1e-3 * all.len() as f64,
        "{far} of {} off by more than 1 px",
        all.len()
    );
}

#[test]
fn structured_light_calibrates_a_showcase_projector_within_0_3_px_of_the_truth() {
    let scene = small_showcase();
    let sim = sim(&scene);
    let geometry = SceneGeometry::build(&scene, &ObjectFilter::Real).unwrap();
    let outcome = calibrate_structured_light(
        "projector-1",
        &mut sim.projector(1).unwrap(),
        &mut sim.camera(0).unwrap(),
        &geometry,
        &StructuredLightOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    let truth = &scene.projectors[1].device;
    let points = surface_points(truth, &geometry, 2000, 1);
    assert!(points.len() > 1000, "{} held-out points", points.len());
    let heldout = true_rms(&outcome.calibration, truth, &points);
    let cal = &outcome.calibration;
    eprintln!(
        "{} fit points, fit rms {:.3} px, held-out {:.3} px (decoded), {heldout:.3} px against the true projector",
        outcome.fit_points, cal.rms_px, outcome.heldout_rms_px
    );
    assert!(heldout <= 0.3, "held-out {heldout} px against the truth");
    assert!(outcome.fit_points > 5_000 && outcome.heldout_points > 500);
    assert!(cal.rms_px < 0.6 && outcome.heldout_rms_px < 0.6);
    let centre = (cal.to_device().center() - truth.center()).length();
    assert!(centre < 0.003, "centre {centre} m off");
}

#[test]
fn a_dark_capture_says_to_raise_the_exposure_or_the_level() {
    let scene = small_showcase();
    let sim = sim(&scene);
    let options = StructuredLightOptions {
        exposure_s: Some(0.008333),
        level: 0.02,
        ..StructuredLightOptions::default()
    };
    let err = capture_and_decode(
        "projector-0",
        &mut sim.projector(0).unwrap(),
        &mut sim.camera(0).unwrap(),
        &options,
        &|_, _, _| {},
    )
    .unwrap_err();
    assert!(matches!(err, StructuredLightError::Dark { .. }), "{err:?}");
    let msg = err.to_string();
    for part in [
        "projector-0",
        "too dark",
        "raise the camera exposure",
        "--exposure",
        "--level",
    ] {
        assert!(msg.contains(part), "{part:?} missing from: {msg}");
    }
}

#[test]
fn a_saturated_capture_says_to_lower_the_exposure_or_the_level() {
    let scene = small_showcase();
    let sim = sim(&scene);
    let options = StructuredLightOptions {
        exposure_s: Some(0.2),
        ..StructuredLightOptions::default()
    };
    let err = capture_and_decode(
        "projector-0",
        &mut sim.projector(0).unwrap(),
        &mut sim.camera(0).unwrap(),
        &options,
        &|_, _, _| {},
    )
    .unwrap_err();
    assert!(
        matches!(err, StructuredLightError::Saturated { frame: "white", .. }),
        "{err:?}"
    );
    let msg = err.to_string();
    for part in [
        "saturated",
        "% of the projector-lit pixels clip",
        "lower the camera exposure",
        "--level",
    ] {
        assert!(msg.contains(part), "{part:?} missing from: {msg}");
    }
}

#[test]
fn too_few_valid_pixels_say_how_many_and_what_to_check() {
    // A camera so noisy that hardly a bit reads clearly.
    let mut scene = small_showcase();
    scene.cameras[0].response.read_noise = 0.3;
    let sim = sim(&scene);
    let geometry = SceneGeometry::build(&scene, &ObjectFilter::Real).unwrap();
    let err = calibrate_structured_light(
        "projector-0",
        &mut sim.projector(0).unwrap(),
        &mut sim.camera(0).unwrap(),
        &geometry,
        &StructuredLightOptions::default(),
        &|_, _, _| {},
    )
    .unwrap_err();
    let StructuredLightError::TooFewValid { valid, needed, .. } = err else {
        panic!("{err:?}");
    };
    assert!(valid < needed);
    let msg = err.to_string();
    let counted = format!("only {valid} camera pixels decoded");
    for part in [
        counted.as_str(),
        "at least 2000",
        "check that the camera sees what the projector lights",
        "--frames",
    ] {
        assert!(msg.contains(part), "{part:?} missing from: {msg}");
    }
}

#[test]
fn the_job_writes_a_calibration_file_per_projector_that_the_cluster_reads() {
    let dir = std::env::temp_dir().join(format!("sl-job-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // The demo cabinet's file with its meshes found from here and a
    // smaller camera.
    let scenes = concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/scenes");
    let text = std::fs::read_to_string(Path::new(scenes).join("showcase.toml"))
        .unwrap()
        .replace("../../../shared/", &format!("{scenes}/../../../shared/"))
        .replace(
            "width = 640\nheight = 480",
            &format!("width = {}\nheight = {}", CAMERA.0, CAMERA.1),
        );
    std::fs::write(dir.join("scene.toml"), text).unwrap();
    let config = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../deploy/cluster.toml"
    ))
    .unwrap()
    .replace("scenes/showcase.toml", "scene.toml");
    std::fs::write(dir.join("cluster.toml"), config).unwrap();
    let out = dir.join("out");
    let job = StructuredLightJob {
        config: dir.join("cluster.toml"),
        scene: None,
        out: out.clone(),
        options: StructuredLightOptions::default(),
        sim_samples: SAMPLES,
    };
    let summary = run_structured_light(&job, &|_, _, _, _| {}).unwrap();
    assert_eq!(summary.camera, "camera-0");
    assert_eq!(summary.projectors.len(), 2);
    for p in &summary.projectors {
        assert_eq!(p.file, out.join(format!("{}.json", p.device)));
        let device = showcase_master::scene_file::read_calibration(
            &p.file,
            "cluster.toml",
            &p.device,
            Some((800, 600)),
        )
        .unwrap();
        assert_eq!((device.width, device.height), (800, 600));
        assert!(
            p.sim_true_heldout_px <= 0.3,
            "{}: {}",
            p.device,
            p.sim_true_heldout_px
        );
        assert_eq!(
            p.node_reads.as_deref(),
            Some(Path::new(&format!("/etc/showcase/calib/{}.json", p.device)))
        );
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["projectors"].as_array().unwrap().len(), 2);
    std::fs::remove_dir_all(&dir).ok();
}
