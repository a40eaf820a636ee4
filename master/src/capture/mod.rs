//! Reflectance capture (paper sections 3.2 to 3.5) with any projector and
//! camera behind the `Projector`/`Camera` traits, the `capture` job over
//! the simulated showcase, reflectance-map files, `sim render`, and the
//! reflectance bench.
//!
//! # Radiance maps
//! A frame's codes are decoded with the camera's calibrated response:
//! `signal = (code / max_code)^gamma`, `L = signal / (gain * exposure)`,
//! `I_rad = pi * L`. K frames are averaged (the DLP fix); their exposure
//! starts are spread evenly over the colour-wheel phase
//! (`t_k = k * (4 + 1/K) * wheel period`), whose offset the capture does
//! not know.

pub mod bench;
pub mod files;
pub mod pipeline;
pub mod scenes;

pub use bench::{Record, bench_reflectance, write_report};
pub use files::{read_reflectance_map, write_reflectance_map};
pub use pipeline::{
    CaptureConfig, CaptureOutcome, EtaMode, Method, adjust_camera_gain, calibrate_projector,
    capture_radiance, capture_reflectance,
};

use anyhow::Context;
use glam::DVec3;
use serde::Serialize;
use showcase_proto::{PinholeDevice, Showcase};
use showcase_render::sim::{SimConfig, SimShowcase, render_view, write_pfm};
use std::path::Path;

/// Load a scene for the sim: an `.obj` file directly (as real objects),
/// anything else through the scene-file loader.
pub fn load_any_scene(path: &Path) -> anyhow::Result<Showcase> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
    {
        scenes::load_obj_showcase(path)
    } else {
        Ok(crate::scene_file::load_scene(path)?)
    }
}

/// `showcase-master sim render`: render `scene` lit by its own emitters
/// from a pinhole at `eye` looking at `target` (`up` roughly up,
/// horizontal field of view `fov_deg`) as linear radiance into the PFM
/// file `out`, with 256 paths per pixel and seed 1.
#[allow(clippy::too_many_arguments)]
pub fn sim_render_command(
    scene: &Path,
    eye: DVec3,
    target: DVec3,
    up: DVec3,
    fov_deg: f64,
    width: u32,
    height: u32,
    out: &Path,
) -> anyhow::Result<()> {
    anyhow::ensure!(
        eye.is_finite() && target.is_finite() && up.is_finite() && (target - eye).length() > 0.0,
        "eye {eye} and target {target} must be finite and distinct"
    );
    anyhow::ensure!(
        fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 180.0,
        "fov {fov_deg} degrees is not in (0, 180)"
    );
    anyhow::ensure!(
        (target - eye)
            .normalize()
            .cross(up.normalize_or_zero())
            .length()
            > 1e-9,
        "up {up} is parallel to the view direction"
    );
    let showcase = load_any_scene(scene)?;
    let device = PinholeDevice::look_at(eye, target, up, fov_deg, width, height);
    let image = render_view(&showcase, &device, 256, 1)?;
    write_pfm(out, &image)?;
    Ok(())
}

/// What `run_capture` did.
#[derive(Clone, Debug, Serialize)]
pub struct CaptureSummary {
    /// Scene name.
    pub scene: String,
    /// Method used.
    pub method: String,
    /// Frames averaged per radiance map.
    pub frames: u32,
    /// Estimated projector intensity (W/sr).
    pub eta: f64,
    /// Estimated black level (W/sr).
    pub black_level: f64,
    /// Fraction of object pixels with a valid reflectance.
    pub coverage: f64,
    /// Relative RMSE against the sim's true albedo over valid pixels.
    pub rel_rmse: f64,
    /// Files written (relative to the output folder).
    pub files: Vec<String>,
}

/// `showcase-master capture --scene FILE --sim --out DIR`: capture the
/// reflectance of `scene`'s real objects in the simulated showcase (16
/// frames, eta estimated on the reference target, interreflection
/// corrected), write the map `reflectance.{pfm,weight.pfm,json}` and
/// `summary.json` into `out`. A scene without devices gets the default rig
/// in front of its bounds.
pub fn run_capture(scene: &Showcase, out: &Path) -> anyhow::Result<CaptureSummary> {
    let mut scene = scene.clone();
    if scene.cameras.is_empty() || scene.projectors.is_empty() {
        let geometry = showcase_render::light::SceneGeometry::build(
            &scene,
            &showcase_render::light::ObjectFilter::Real,
        )?;
        let b = geometry.bounds();
        anyhow::ensure!(!b.is_empty(), "the scene has no real geometry");
        let centre = b.center();
        let size = (b.max - b.min).max_element();
        scene.cameras.clear();
        scene.projectors.clear();
        scenes::add_rig(
            &mut scene,
            centre + DVec3::new(0.0, 0.1 * size, -1.6 * size),
            centre + DVec3::new(0.15 * size, 0.2 * size, -1.5 * size),
            centre,
            (96, 96),
            true,
        );
    }
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let config = CaptureConfig::default();
    let sim_config = SimConfig {
        samples_per_pixel: 256,
        ..SimConfig::default()
    };
    let probe = SimShowcase::new(&scene, sim_config.clone())?;
    adjust_camera_gain(&mut scene, &probe)?;
    let sim = SimShowcase::new(&scene, sim_config)?;
    let outcome = capture_reflectance(&scene, &sim, &config)?;
    let (truth, objects) = sim.ground_truth(0)?;
    let rel_rmse = showcase_render::light::metrics::relative_rmse(
        &outcome.reflectance,
        &truth,
        Some(&outcome.valid),
    )
    .unwrap_or(f64::NAN);
    let visible = objects.data.iter().filter(|o| o.is_some()).count().max(1);
    let coverage = outcome.valid.data.iter().filter(|v| **v).count() as f64 / visible as f64;
    let mut files = write_reflectance_map(out, "reflectance", &outcome.map)?;
    let summary = CaptureSummary {
        scene: scene.name.clone(),
        method: config.method.name().into(),
        frames: config.frames,
        eta: outcome.eta,
        black_level: outcome.black_level,
        coverage,
        rel_rmse: if rel_rmse.is_finite() { rel_rmse } else { -1.0 },
        files: {
            files.push("summary.json".into());
            files
        },
    };
    std::fs::write(
        out.join("summary.json"),
        serde_json::to_string_pretty(&summary)?,
    )?;
    Ok(summary)
}
