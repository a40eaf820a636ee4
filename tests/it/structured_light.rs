//! Integration tests: projector calibration by structured light in the
//! simulated showcase (the demo cabinet with its camera at 240x180, one
//! path per pixel, to keep the light transport cheap): the decode against
//! the sim's truth, the validity mask, the calibration against the true
//! projector, the job's files, the errors a technician gets, and the job
//! through a loopback cluster of sim nodes against the in-process one.

use glam::{DMat3, DVec3};
use showcase_light::sim::{SimConfig, SimShowcase};
use showcase_light::{DeviceRays, ObjectFilter, SceneGeometry};
use showcase_master::calibrate::structured_light::bench::{surface_points, true_rms};
use showcase_master::calibrate::structured_light::{
    CorrespondenceSettings, StructuredLightError, StructuredLightJob, StructuredLightOptions,
    StructuredLightOutcome, Targets, calibrate_structured_light, calibrate_targets,
    capture_and_decode, correspondences, run_structured_light,
};
use showcase_master::cluster::capture_loopback::{
    StructuredLightLoopback, loopback_structured_light,
};
use showcase_proto::Showcase;
use std::path::Path;
use std::time::Duration;

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

/// Calibrate projector `index` of `scene` in its sim, seen by camera 0,
/// with the default options; the real surfaces' geometry it used.
fn calibrate_in_sim(
    scene: &Showcase,
    index: usize,
) -> (
    Result<StructuredLightOutcome, StructuredLightError>,
    SceneGeometry,
) {
    let sim = sim(scene);
    let geometry = SceneGeometry::build(scene, &ObjectFilter::Real).unwrap();
    let outcome = calibrate_structured_light(
        &format!("projector-{index}"),
        &mut sim.projector(index).unwrap(),
        &mut sim.camera(0).unwrap(),
        &geometry,
        &StructuredLightOptions::default(),
        &|_, _, _| {},
    );
    (outcome, geometry)
}

#[test]
fn structured_light_calibrates_a_showcase_projector_within_0_3_px_of_the_truth() {
    let scene = small_showcase();
    let (outcome, geometry) = calibrate_in_sim(&scene, 1);
    let outcome = outcome.unwrap();
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
    let err = calibrate_in_sim(&scene, 0).0.unwrap_err();
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

fn loopback_plan(scene: Showcase, out: &Path) -> StructuredLightLoopback {
    StructuredLightLoopback {
        scene,
        sim: SimConfig {
            samples_per_pixel: SAMPLES,
            ..SimConfig::default()
        },
        options: StructuredLightOptions::default(),
        out: out.to_path_buf(),
        wait: Duration::from_secs(10),
        request_timeout: Duration::from_secs(120),
        absent: None,
    }
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// Through a loopback cluster (the master, a sim node per projector and
/// one for the camera, QUIC over 127.0.0.1, the light on the room's bus)
/// the job gives the in-process calibration exactly, not merely within a
/// tolerance: the sims have the same seeds, each projector node
/// rasterises its Gray-code pattern with the same code as the in-process
/// projector, the camera node's sim takes the same captures in the same
/// order (the auto-exposure included) and the frames' integer codes travel
/// unchanged, so the decode, the correspondences and the solves see the
/// same numbers. Each fit is within 0.3 px of the true projector.
#[test]
fn structured_light_through_a_loopback_cluster_equals_the_in_process_run() {
    let scene = small_showcase();
    let dir = std::env::temp_dir().join(format!("sl-cluster-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    let targets = Targets::of_scene(&scene).unwrap();
    let sim = sim(&scene);
    let local = calibrate_targets(
        &targets,
        &dir.join("in-process"),
        &StructuredLightOptions::default(),
        &mut sim.camera(0).unwrap(),
        &mut |t| Ok(sim.projector(t.index)?),
        true,
        std::time::Instant::now(),
        &|_, _, _, _| {},
    )
    .unwrap();
    let out = dir.join("cluster");
    let r = runtime()
        .block_on(loopback_structured_light(loopback_plan(scene, &out)))
        .unwrap();
    let cluster = r.summary.unwrap();
    assert_eq!(cluster.camera, "camera-0");
    assert_eq!(cluster.projectors.len(), 2);
    let mut patterns = 0;
    for (c, l) in cluster.projectors.iter().zip(&local.projectors) {
        assert_eq!(c.device, l.device);
        let (co, lo) = (&c.outcome, &l.outcome);
        eprintln!(
            "{}: through the cluster {} fit points, held-out {:.4} px against the truth; in process {} and {:.4} px",
            c.device, co.fit_points, c.sim_true_heldout_px, lo.fit_points, l.sim_true_heldout_px
        );
        assert_eq!(
            (co.exposure_s, co.frames, co.valid_pixels, co.fit_points),
            (lo.exposure_s, lo.frames, lo.valid_pixels, lo.fit_points),
            "{}",
            c.device
        );
        assert_eq!(co.calibration, lo.calibration, "{}", c.device);
        assert!(
            c.sim_true_heldout_px <= 0.3,
            "{}: held-out {} px against the truth",
            c.device,
            c.sim_true_heldout_px
        );
        assert_eq!(c.file, out.join(format!("{}.json", c.device)));
        assert_eq!(
            std::fs::read(&c.file).unwrap(),
            std::fs::read(&l.file).unwrap()
        );
        // Each pattern and the dark one left at the end went to the node.
        patterns += co.patterns as u64 + 1;
    }
    assert!(
        r.patterns_shown >= patterns,
        "{} patterns shown, {patterns} at least",
        r.patterns_shown
    );
    assert!(out.join("summary.json").is_file());
    std::fs::remove_dir_all(&dir).ok();
}

/// A projector node that is not connected stops the job before any
/// pattern, naming it and saying to start it.
#[test]
fn structured_light_with_a_missing_projector_node_says_which_to_start() {
    let dir = std::env::temp_dir().join(format!("sl-missing-{}", std::process::id()));
    let mut plan = loopback_plan(small_showcase(), &dir);
    plan.absent = Some("projector-1".into());
    plan.wait = Duration::from_millis(500);
    let r = runtime().block_on(loopback_structured_light(plan)).unwrap();
    let e = r.summary.unwrap_err();
    for part in [
        "projector node \"projector-1\" is not connected",
        "start it (showcase-node --config CLUSTER.toml --name projector-1)",
    ] {
        assert!(e.contains(part), "{part:?} missing from: {e}");
    }
    assert_eq!(r.patterns_shown, 0);
    std::fs::remove_dir_all(&dir).ok();
}
