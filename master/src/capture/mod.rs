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
pub mod cluster;
pub mod cluster_job;
pub mod files;
pub mod pipeline;
pub mod scenes;

pub use bench::{Record, bench_reflectance, write_report};
pub use files::{read_reflectance_map, read_reflectance_maps, write_reflectance_map};
pub use pipeline::{
    CaptureConfig, CaptureOutcome, EtaMode, Method, ProjectorLevels, adjust_camera_gain,
    calibrate_projector, calibrate_reference, capture_map, capture_radiance,
    capture_radiance_pattern, capture_reflectance,
};

use crate::pfm::write_pfm;
use anyhow::Context;
use glam::DVec3;
use serde::Serialize;
use showcase_light::finite::finite_or;
use showcase_light::hardware::ProjectorDevice;
use showcase_light::sim::{SimConfig, SimShowcase, render_view};
use showcase_proto::{PinholeDevice, Showcase};
use std::path::Path;
use std::time::Instant;

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
    let showcase = crate::scene_file::load_any(scene)?;
    let device = PinholeDevice::look_at(eye, target, up, fov_deg, width, height);
    let image = render_view(&showcase, &device, 256, 1)?;
    write_pfm(out, &image)?;
    Ok(())
}

/// What `run_capture_with` did.
#[derive(Clone, Debug, Serialize)]
pub struct CaptureSummary {
    /// Scene name.
    pub scene: String,
    /// Method used.
    pub method: String,
    /// Frames averaged per radiance map.
    pub frames: u32,
    /// Camera image `[width, height]` the capture used.
    pub camera_size: [u32; 2],
    /// Paths per pixel of the sim's light transport.
    pub samples_per_pixel: u32,
    /// Estimated projector intensity (W/sr).
    pub eta: f64,
    /// Estimated black level (W/sr).
    pub black_level: f64,
    /// `|eta - true eta| / true eta` (the sim knows the truth).
    pub eta_rel_error: f64,
    /// Fraction of object pixels with a valid reflectance.
    pub coverage: f64,
    /// Relative RMSE against the sim's true albedo over valid pixels.
    pub rel_rmse: f64,
    /// Wall-clock seconds of the whole job, by phase.
    pub seconds: CaptureSeconds,
    /// Files written (relative to the output folder).
    pub files: Vec<String>,
}

/// Wall-clock seconds of a capture job, by phase.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct CaptureSeconds {
    /// Building the sims and setting the camera gain.
    pub setup: f64,
    /// Fitting eta and the black level on the reference target (its sim's
    /// light transport included).
    pub calibration: f64,
    /// The sim's light transport for the capture's projector images (what
    /// the physical world does for free).
    pub light_transport: f64,
    /// Frames, extraction and the interreflection correction.
    pub capture: f64,
    /// Ground-truth comparison and writing the files.
    pub output: f64,
    /// Everything.
    pub total: f64,
}

/// Settings of a capture job ([`run_capture_with`]): the simulated
/// world's and camera's, and the capture's own.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureOptions {
    /// Camera image `(width, height)`: the scene's camera is resampled to
    /// it (same pose and field of view, intrinsics scaled); `None` keeps
    /// the scene's camera.
    pub camera_size: Option<(u32, u32)>,
    /// Paths per camera pixel of the sim's light transport (the world's
    /// accuracy, not the capture's).
    pub samples_per_pixel: u32,
    /// The capture: frames averaged per radiance map, extraction method,
    /// where eta comes from ([`EtaMode::FromScene`]: the sim's true
    /// values), the interreflection correction's gather rays, the
    /// reference target's paths per pixel, ... (frame, ray and sample
    /// counts below 1 are taken as 1).
    pub capture: CaptureConfig,
}

impl Default for CaptureOptions {
    /// The `capture` command's settings: the scene's camera, 256 paths per
    /// pixel, and [`CaptureConfig::default`]: 16 frames, eta estimated,
    /// interreflection corrected.
    fn default() -> Self {
        Self {
            camera_size: None,
            samples_per_pixel: 256,
            capture: CaptureConfig::default(),
        }
    }
}

impl CaptureOptions {
    /// The demo's preset: the whole cabinet captured (eta estimated,
    /// interreflection corrected, 16 frames) with a 160 x 120 camera, 256
    /// paths per pixel and the default 256 gather rays: seconds on a 2-core
    /// machine for `deploy/scenes/showcase.toml`, where the default camera
    /// (640 x 480) takes minutes. The gather's noise is most of the error
    /// at this size (rel RMSE 0.0207 with 128 rays, 0.0174 with 256).
    pub fn demo() -> Self {
        Self {
            camera_size: Some((160, 120)),
            samples_per_pixel: 256,
            ..Self::default()
        }
    }
}

/// `showcase-master capture --scene FILE --sim --out DIR`: capture the
/// reflectance of `scene`'s real objects in the simulated showcase with
/// [`CaptureOptions::default`]; see [`run_capture_with`].
pub fn run_capture(scene: &Showcase, out: &Path) -> anyhow::Result<CaptureSummary> {
    run_capture_with(scene, out, &CaptureOptions::default())
}

/// Capture the reflectance of `scene`'s real objects in the simulated
/// showcase (projector 0, camera 0) with `opts`, write the map
/// `reflectance.{pfm,weight.pfm,json}` and `summary.json` into `out`, and
/// return the summary. A scene without devices gets the default rig in
/// front of its bounds.
pub fn run_capture_with(
    scene: &Showcase,
    out: &Path,
    opts: &CaptureOptions,
) -> anyhow::Result<CaptureSummary> {
    run_capture_staged(scene, out, opts, &|_, _| {})
}

/// The stages of a capture job, in order, as [`run_capture_staged`]
/// announces them.
pub const CAPTURE_STAGES: [&str; 5] = [
    "setting up the sims and the camera gain",
    "fitting eta and the black level on the reference target",
    "light transport of the projector images",
    "capturing frames and extracting the reflectance",
    "comparing with the truth and writing the map",
];

/// [`run_capture_with`], calling `stage(i, name)` as stage `i` of
/// [`CAPTURE_STAGES`] begins (progress display).
pub fn run_capture_staged(
    scene: &Showcase,
    out: &Path,
    opts: &CaptureOptions,
    stage: &dyn Fn(usize, &str),
) -> anyhow::Result<CaptureSummary> {
    let begin = |i: usize| stage(i, CAPTURE_STAGES[i]);
    begin(0);
    let t0 = Instant::now();
    let mut seconds = CaptureSeconds::default();
    let mut scene = with_capture_rig(scene, opts.camera_size)?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut config = opts.capture.clone();
    config.frames = config.frames.max(1);
    config.correction.gather_samples = config.correction.gather_samples.max(1);
    config.reference_samples = config.reference_samples.max(1);
    let sim_config = SimConfig {
        samples_per_pixel: opts.samples_per_pixel.max(1),
        ..SimConfig::default()
    };
    let probe = SimShowcase::new(&scene, sim_config.clone())?;
    adjust_camera_gain(&mut scene, &probe)?;
    let sim = SimShowcase::new(&scene, sim_config)?;
    let true_levels = ProjectorLevels::of(&scene.projectors[0].response);
    let mut t = Instant::now();
    let lap = |t: &mut Instant| {
        let s = t.elapsed().as_secs_f64();
        *t = Instant::now();
        s
    };
    seconds.setup = t0.elapsed().as_secs_f64();
    begin(1);
    let levels = config.resolve_eta(&scene)?;
    seconds.calibration = lap(&mut t);
    begin(2);
    warm_transport(&scene, &sim, &config)?;
    seconds.light_transport = lap(&mut t);
    begin(3);
    let outcome = capture_map(
        &scene,
        &mut sim.projector(0)?,
        &mut sim.camera(0)?,
        levels,
        &config,
    )?;
    seconds.capture = lap(&mut t);
    begin(4);
    let (truth, objects) = sim.ground_truth(0)?;
    let rel_rmse =
        showcase_light::metrics::relative_rmse(&outcome.reflectance, &truth, Some(&outcome.valid))
            .unwrap_or(f64::NAN);
    let visible = objects.data.iter().filter(|o| o.is_some()).count().max(1);
    let coverage = outcome.valid.data.iter().filter(|v| **v).count() as f64 / visible as f64;
    let mut files = write_reflectance_map(out, "reflectance", &outcome.map)?;
    files.push("summary.json".into());
    let eta_rel_error = (levels.eta - true_levels.eta).abs() / true_levels.eta;
    let d = &scene.cameras[0].device;
    let mut summary = CaptureSummary {
        scene: scene.name.clone(),
        method: config.method.name().into(),
        frames: config.frames,
        camera_size: [d.width, d.height],
        samples_per_pixel: opts.samples_per_pixel.max(1),
        eta: outcome.eta,
        black_level: outcome.black_level,
        eta_rel_error: finite_or(eta_rel_error, -1.0),
        coverage,
        rel_rmse: finite_or(rel_rmse, -1.0),
        seconds,
        files,
    };
    summary.seconds.output = lap(&mut t);
    summary.seconds.total = t0.elapsed().as_secs_f64();
    std::fs::write(
        out.join("summary.json"),
        serde_json::to_string_pretty(&summary)?,
    )?;
    Ok(summary)
}

/// `scene` ready for a capture: a scene without a camera or projector gets
/// the default rig in front of its bounds (a 96 x 96 camera), and camera 0
/// is resampled to `camera_size` when given ([`resize_device`]).
pub fn with_capture_rig(
    scene: &Showcase,
    camera_size: Option<(u32, u32)>,
) -> anyhow::Result<Showcase> {
    let mut scene = scene.clone();
    if scene.cameras.is_empty() || scene.projectors.is_empty() {
        let geometry =
            showcase_light::SceneGeometry::build(&scene, &showcase_light::ObjectFilter::Real)?;
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
    if let Some((w, h)) = camera_size {
        let camera = &mut scene.cameras[0];
        camera.device = resize_device(&camera.device, w, h)?;
    }
    Ok(scene)
}

/// The same device seen at `width x height` pixels: pose, field of view
/// and distortion kept, intrinsics scaled.
pub fn resize_device(
    device: &PinholeDevice,
    width: u32,
    height: u32,
) -> anyhow::Result<PinholeDevice> {
    anyhow::ensure!(
        width > 0 && height > 0 && device.width > 0 && device.height > 0,
        "cannot resize a {}x{} camera to {width}x{height}",
        device.width,
        device.height
    );
    let sx = width as f64 / device.width as f64;
    let sy = height as f64 / device.height as f64;
    let mut d = device.clone();
    d.k = glam::DMat3::from_diagonal(DVec3::new(sx, sy, 1.0)) * device.k;
    d.width = width;
    d.height = height;
    Ok(d)
}

/// Run the sim's light transport for the projector images a capture by
/// `config.method` will show (so the capture's own time is measured
/// apart): the white image for the naive and corrected methods; piecewise
/// capture computes its pieces as it goes.
fn warm_transport(
    scene: &Showcase,
    sim: &SimShowcase,
    config: &CaptureConfig,
) -> anyhow::Result<()> {
    if config.method == Method::Piecewise {
        return Ok(());
    }
    let mut projector = sim.projector(0)?;
    let d = &scene.projectors[0].device;
    projector.show(&showcase_light::Image::new(
        d.width,
        d.height,
        glam::Vec3::ONE,
    ))?;
    for p in 0..scene.projectors.len() {
        sim.transport(0, p)?;
    }
    Ok(())
}
