//! Capture through the cluster: a loopback cluster (the master and sim
//! nodes as tasks, real QUIC over 127.0.0.1) captures the figure-3 scene
//! as the in-process capture does, to within the sim's noise; a missing
//! projector node stops the job with what to change and keeps the maps
//! done; a late joiner gets the new maps in its snapshot. Small: figure 3
//! with a 40 x 30 camera and 128 x 96 projectors, every wait bounded.

use showcase_light::reflectance::CorrectionParams;
use showcase_light::sim::SimConfig;
use showcase_master::capture::cluster::ClusterCaptureOptions;
use showcase_master::capture::pipeline::{CaptureConfig, EtaMode, Method};
use showcase_master::capture::{CaptureOptions, resize_device, run_capture_with, with_capture_rig};
use showcase_master::cluster::capture_loopback::{CaptureLoopback, loopback_capture};
use showcase_proto::Showcase;
use std::path::PathBuf;
use std::time::Duration;

const SAMPLES: u32 = 8;

/// Figure 3, small: a 40 x 30 camera, 128 x 96 projectors.
fn figure3() -> Showcase {
    let scene = showcase_master::scene_file::load_any(std::path::Path::new("builtin:figure3"))
        .expect("the built-in figure-3 scene");
    let mut scene = with_capture_rig(&scene, Some((40, 30))).unwrap();
    for p in &mut scene.projectors {
        p.device = resize_device(&p.device, 128, 96).unwrap();
    }
    scene
}

fn config(method: Method, eta: EtaMode) -> CaptureConfig {
    CaptureConfig {
        frames: 4,
        method,
        eta,
        reference_samples: SAMPLES,
        correction: CorrectionParams {
            gather_samples: 16,
            ..CorrectionParams::default()
        },
        ..CaptureConfig::default()
    }
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("showcase-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&d).ok();
    d
}

fn plan(scene: Showcase, methods: Vec<Method>, eta: EtaMode, out: PathBuf) -> CaptureLoopback {
    let sim = SimConfig {
        samples_per_pixel: SAMPLES,
        ..SimConfig::default()
    };
    CaptureLoopback {
        scene,
        sim: sim.clone(),
        options: ClusterCaptureOptions {
            methods,
            capture: config(Method::Naive, eta),
            sim: Some(sim),
            wait: Duration::from_secs(10),
        },
        out,
        projector: true,
        projector_leaves_after: None,
        late_joiner: false,
        request_timeout: Duration::from_secs(120),
    }
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// The loopback cluster's corrected map, eta fitted through the nodes,
/// against the in-process capture with the same seeds and sizes: the same
/// rel RMSE against the true albedo to within 0.002, and the same eta.
/// A late joiner then gets the maps in its snapshot.
#[test]
fn cluster_capture_matches_the_in_process_capture() {
    let scene = figure3();
    let local_dir = dir("capture-local");
    let local = run_capture_with(
        &scene,
        &local_dir,
        &CaptureOptions {
            camera_size: None,
            samples_per_pixel: SAMPLES,
            capture: config(Method::Corrected, EtaMode::Estimated),
        },
    )
    .unwrap();
    let out = dir("capture-cluster");
    let mut p = plan(
        scene,
        vec![Method::Corrected],
        EtaMode::Estimated,
        out.clone(),
    );
    p.late_joiner = true;
    let r = runtime().block_on(loopback_capture(p)).unwrap();
    let summary = r.summary.unwrap();
    let cluster = &summary.methods[0];
    assert!(
        (cluster.rel_rmse - local.rel_rmse).abs() <= 0.002,
        "cluster rel RMSE {} against in-process {}",
        cluster.rel_rmse,
        local.rel_rmse
    );
    assert!(
        (summary.eta - local.eta).abs() <= 1e-3 * local.eta,
        "eta {} against {}",
        summary.eta,
        local.eta
    );
    assert!((cluster.coverage - local.coverage).abs() < 0.01);
    assert!(summary.frames > 0 && summary.patterns >= 3, "{summary:?}");
    assert!(out.join("reflectance-corrected.pfm").is_file());
    // The late joiner's first scene is its snapshot: it carries the map.
    let late = r.late_joiner.unwrap();
    let first = late.scenes.first().copied();
    assert_eq!(first, Some((summary.published_version, 1)), "{late:?}");
    std::fs::remove_dir_all(&local_dir).ok();
    std::fs::remove_dir_all(&out).ok();
}

/// No projector node: the job stops and says which node to start.
#[test]
fn a_missing_projector_node_stops_the_job_with_what_to_do() {
    let out = dir("capture-missing");
    let mut p = plan(
        figure3(),
        vec![Method::Naive],
        EtaMode::FromScene,
        out.clone(),
    );
    p.projector = false;
    p.options.wait = Duration::from_millis(500);
    let r = runtime().block_on(loopback_capture(p)).unwrap();
    let e = r.summary.unwrap_err();
    assert!(
        e.contains("projector node \"projector-0\" is not connected"),
        "{e}"
    );
    assert!(e.contains("start it"), "{e}");
    std::fs::remove_dir_all(&out).ok();
}

/// The projector node leaves after the naive capture's one pattern: the
/// piecewise capture stops with what to do, and the naive map is kept on
/// disk and in the summary.
#[test]
fn a_projector_node_leaving_keeps_the_maps_done() {
    let out = dir("capture-partial");
    let mut p = plan(
        figure3(),
        vec![Method::Naive, Method::Piecewise],
        EtaMode::FromScene,
        out.clone(),
    );
    p.projector_leaves_after = Some(1);
    let r = runtime().block_on(loopback_capture(p)).unwrap();
    let e = r.summary.unwrap_err();
    assert!(e.contains("projector-0"), "{e}");
    assert!(e.contains("1 map(s) kept"), "{e}");
    assert!(out.join("reflectance-naive.pfm").is_file());
    assert!(!out.join("reflectance-piecewise.pfm").exists());
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["methods"][0]["method"], "naive");
    assert_eq!(json["methods"].as_array().unwrap().len(), 1);
    assert!(json["error"].as_str().unwrap().contains("projector-0"));
    std::fs::remove_dir_all(&out).ok();
}

/// A saturated or a dark frame stops the job with what to change.
#[test]
fn saturated_and_dark_frames_say_what_to_change() {
    use showcase_light::Image;
    use showcase_light::hardware::CameraFrame;
    use showcase_master::capture::cluster::check_exposure;
    let frame = |v: u16| CameraFrame {
        codes: Image {
            width: 10,
            height: 10,
            data: (0..100)
                .map(|i| if i < 5 { [v; 3] } else { [800; 3] })
                .collect(),
        },
        bits: 12,
    };
    assert!(check_exposure(&frame(800), "camera-0", 1.0).is_ok());
    let e = check_exposure(&frame(4095), "camera-0", 1.0).unwrap_err();
    assert!(
        e.contains("saturated") && e.contains("lower the camera gain"),
        "{e}"
    );
    let mut dark = frame(0);
    dark.codes.data = vec![[10; 3]; 100];
    let e = check_exposure(&dark, "camera-0", 1.0).unwrap_err();
    assert!(e.contains("dark") && e.contains("raise the gain"), "{e}");
}
