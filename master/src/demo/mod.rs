//! `showcase-master demo`: the whole pipeline on the simulated showcase,
//! phase by phase (scene, calibration, reflectance, radiosity, the
//! interactive cluster, rendering), with `report.json` and `index.html`.
//! A phase that fails stops the demo with its error and no report.

mod page;
mod rendering;
mod views;

use anyhow::{Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The built-in demo cabinet, shipped with the sources.
pub fn default_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/showcase.toml")
}

/// What the demo runs on and where it writes (`showcase-master demo`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DemoOptions {
    /// Output folder.
    pub out: PathBuf,
    /// Frames of the interactive stage.
    pub frames: u64,
    /// Scene file (`None`: [`default_scene`], the built-in demo cabinet).
    pub scene: Option<PathBuf>,
}

/// How one phase of the demo went.
#[derive(Debug, Clone, Serialize)]
pub struct Phase {
    /// Phase name.
    pub name: String,
    /// `ran` (a phase that fails stops the demo).
    pub status: &'static str,
    /// Wall-clock seconds spent.
    pub seconds: f64,
    /// What it did.
    pub detail: String,
}

/// The demo's `report.json`.
#[derive(Debug, Default, Serialize)]
pub struct Report {
    /// True when every phase ran.
    pub complete: bool,
    /// Every phase in order.
    pub phases: Vec<Phase>,
    /// Headline figures, by name.
    pub figures: serde_json::Map<String, serde_json::Value>,
    /// Images written, in rows, for `index.html`.
    pub gallery: Vec<GalleryRow>,
    /// What the page plots beside the figures.
    pub histories: page::Histories,
}

/// A row of images in `index.html`.
#[derive(Debug, Clone, Serialize)]
pub struct GalleryRow {
    /// What the row shows.
    pub title: String,
    /// `(caption, path relative to the output folder)`.
    pub images: Vec<(String, String)>,
}

/// Phases of the demo, in order.
const PHASES: [&str; 6] = [
    "scene",
    "calibration",
    "reflectance",
    "radiosity",
    "interactive",
    "rendering",
];

/// A spinner (or, with `len`, a bar) for the phase about to run, on a
/// terminal only; the `[demo]` lines carry the same news in logs.
fn progress(name: &str, len: Option<u64>) -> indicatif::ProgressBar {
    let i = PHASES.iter().position(|p| *p == name).map_or(0, |i| i + 1);
    eprintln!("[demo] phase {i}/{}: {name}...", PHASES.len());
    let pb = match len {
        Some(n) => indicatif::ProgressBar::new(n).with_style(
            indicatif::ProgressStyle::with_template(
                "  {prefix} [{bar:30}] {pos}/{len} {msg} ({elapsed})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
        ),
        None => indicatif::ProgressBar::new_spinner().with_style(
            indicatif::ProgressStyle::with_template("  {spinner} {prefix} {msg} ({elapsed})")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        ),
    };
    pb.set_prefix(format!("{i}/{} {name}", PHASES.len()));
    pb.enable_steady_tick(std::time::Duration::from_millis(120));
    pb
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
}

/// Run the demo.
pub fn run(opts: &DemoOptions) -> Result<()> {
    let scene_path = opts.scene.clone().unwrap_or_else(default_scene);
    let mut report = Report::default();

    let t = Instant::now();
    let pb = progress("scene", None);
    let mut scene = crate::scene_file::load_any(&scene_path)?;
    pb.finish_and_clear();
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

    let truth = scene.clone();
    let t = Instant::now();
    let pb = progress("calibration", None);
    let calibration = calibration_stage(&mut scene, &mut report.histories)?;
    pb.finish_and_clear();
    report.ran("calibration", t, calibration.detail);
    report.figures.extend(calibration.figures);
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("cannot create {}", opts.out.display()))?;
    let t = Instant::now();
    let pb = progress("reflectance", None);
    let reflectance = reflectance_stage(&scene, &opts.out)?;
    pb.finish_and_clear();
    report.ran("reflectance", t, reflectance.detail);
    report.figures.extend(reflectance.figures);
    let t = Instant::now();
    let pb = progress("radiosity", None);
    let radiosity = radiosity_stage(&opts.out)?;
    pb.finish_and_clear();
    report.ran("radiosity", t, radiosity.detail);
    report.figures.extend(radiosity.figures);
    let t = Instant::now();
    let pb = progress("interactive", None);
    pb.set_message(format!("{} frames at {INTERACTIVE_HZ} Hz", opts.frames));
    let interactive = interactive_stage(&scene, opts)?;
    pb.finish_and_clear();
    report.ran("interactive", t, interactive.detail);
    report.figures.extend(interactive.figures);
    let t = Instant::now();
    let rendering = rendering::rendering_stage(&truth, &scene, opts, &mut report.gallery)?;
    report.ran("rendering", t, rendering.detail);
    report.figures.extend(rendering.figures);

    report.complete =
        report.phases.len() == PHASES.len() && report.phases.iter().all(|p| p.status == "ran");
    page::write_report(&opts.out, &report)?;
    let skipped = report
        .phases
        .iter()
        .filter(|p| p.status == "skipped")
        .count();
    eprintln!(
        "[demo] wrote {}/report.json and index.html; {} of {} phases ran, {skipped} skipped (see above)",
        opts.out.display(),
        report.phases.len() - skipped,
        report.phases.len()
    );
    Ok(())
}

/// Capture the reflectance of the cabinet's real objects in the simulated
/// showcase with the calibrated devices (16 frames, eta and black level
/// estimated, interreflection corrected) at a demo resolution
/// (`CaptureOptions::demo`: a 160x120 camera).
fn reflectance_stage(scene: &showcase_proto::Showcase, out: &Path) -> Result<StageOutcome> {
    let dir = out.join("reflectance");
    let opts = crate::capture::CaptureOptions::demo();
    let s = crate::capture::run_capture_with(scene, &dir, &opts)?;
    let mut figures = serde_json::Map::new();
    figures.insert("reflectance_rel_rmse".into(), serde_json::json!(s.rel_rmse));
    figures.insert("reflectance_coverage".into(), serde_json::json!(s.coverage));
    figures.insert(
        "reflectance_eta_rel_error".into(),
        serde_json::json!(s.eta_rel_error),
    );
    Ok(StageOutcome {
        detail: format!(
            "{} capture, {} frames, {}x{} camera, {} paths per pixel: eta {:.4} W/sr ({:.1e} off), black level {:.4} W/sr, rel RMSE {:.4} against the sim's albedo over {:.0}% of the visible object pixels; map in {}",
            s.method,
            s.frames,
            s.camera_size[0],
            s.camera_size[1],
            s.samples_per_pixel,
            s.eta,
            s.eta_rel_error,
            s.black_level,
            s.rel_rmse,
            100.0 * s.coverage,
            dir.display()
        ),
        figures,
    })
}

/// The paper's figure-3 configuration (Cornell walls real, blocks and
/// ceiling light virtual): augmented radiosity B0..B3 and the projectors'
/// irradiance maps, at a demo resolution (1e-2 unshot energy, 0.02 m^2
/// patches).
fn radiosity_stage(out: &Path) -> Result<StageOutcome> {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/figure3.toml");
    let opts = crate::radiosity_job::RadiosityOptions {
        max_patch_area: Some(0.02),
        hemicube: None,
        threshold: Some(1e-2),
    };
    let dir = out.join("radiosity");
    let s = crate::radiosity_job::run_radiosity(&scene, &dir, &opts)?;
    let mut figures = serde_json::Map::new();
    figures.insert(
        "radiosity_clipped_fractions".into(),
        serde_json::json!(s.clipped_fractions),
    );
    figures.insert(
        "radiosity_b3_b0_deviation_rgb".into(),
        serde_json::json!(s.b3_b0_deviation_rgb),
    );
    // End to end through the sim (path tracing, independent of the
    // solver): the projectors' maps on the real walls against B0, with B2
    // from the real room's interreflection gathered at the vertices (the
    // headline) and with the paper's converged B1.
    let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/cornell-box.obj");
    let cornell = crate::scene_file::load_any(&cornell)?;
    let record = crate::radiosity_job::bench::augmented_record_with(&cornell, false)?;
    let gathered = record["consistency_rel_rmse"].as_f64();
    let paper = record["paper_consistency_rel_rmse"].as_f64();
    figures.insert(
        "radiosity_consistency_rel_rmse".into(),
        serde_json::json!(gathered),
    );
    figures.insert(
        "radiosity_paper_consistency_rel_rmse".into(),
        serde_json::json!(paper),
    );
    Ok(StageOutcome {
        detail: format!(
            "figure 3: {} patches, {} elements, {} shots to {:.3} unshot; B3-B0 deviation per channel {}; projector clipped fractions {}; solution and irradiance maps in {}; through the simulated projectors and the sim's interreflection, B against B0: rel RMSE {:.3} with B2 gathered at the vertices, {:.3} with the paper's B1",
            s.patches,
            s.elements,
            s.shots,
            s.unshot_fraction,
            s.b3_b0_deviation_rgb.map_or("n/a".to_string(), |d| format!(
                "{:.3}/{:.3}/{:.3}",
                d[0], d[1], d[2]
            )),
            s.clipped_fractions
                .iter()
                .map(|c| format!("{c:.3}"))
                .collect::<Vec<_>>()
                .join(", "),
            dir.display(),
            gathered.unwrap_or(f64::NAN),
            paper.unwrap_or(f64::NAN),
        ),
        figures,
    })
}

/// Calibrate every projector and camera from simulated fiducial marks
/// (0.5 px noise) on a rig in the cabinet, and put the calibrated devices
/// in the scene in place of the true ones for everything that follows;
/// each device's residuals go to `histories` for the page's plot.
fn calibration_stage(
    scene: &mut showcase_proto::Showcase,
    histories: &mut page::Histories,
) -> Result<StageOutcome> {
    use crate::calibrate::{CalibrateOptions, calibrate, fiducial_rig, simulate_fiducials};
    const NOISE_PX: f64 = 0.5;
    let rig = fiducial_rig(40, 7);
    let mut worst_rms = 0.0f64;
    let mut worst_centre = 0.0f64;
    let mut lines = Vec::new();
    let devices: Vec<(String, &mut showcase_proto::PinholeDevice)> = scene
        .projectors
        .iter_mut()
        .map(|p| (p.name.clone(), &mut p.device))
        .chain(
            scene
                .cameras
                .iter_mut()
                .map(|c| (c.name.clone(), &mut c.device)),
        )
        .collect();
    for (i, (name, device)) in devices.into_iter().enumerate() {
        let mut input = simulate_fiducials(device, &rig, NOISE_PX, 100 + i as u64);
        input.device = name.clone();
        let cal = calibrate(&input, &CalibrateOptions::default()).with_context(|| {
            format!(
                "calibrating {name} from {} simulated fiducials",
                input.points.len()
            )
        })?;
        let mut calibrated = cal.to_device();
        calibrated.near = device.near;
        calibrated.far = device.far;
        let centre_error = (calibrated.center() - device.center()).length();
        worst_rms = worst_rms.max(cal.rms_px);
        worst_centre = worst_centre.max(centre_error);
        lines.push(format!(
            "{name}: {} points, rms {:.3} px, centre off by {:.1} mm",
            input.points.len(),
            cal.rms_px,
            centre_error * 1e3
        ));
        histories
            .calibration
            .push(page::DeviceResiduals::new(&name, &cal));
        *device = calibrated;
    }
    let mut figures = serde_json::Map::new();
    figures.insert("calibration_rms_px".into(), serde_json::json!(worst_rms));
    figures.insert(
        "calibration_center_error_m".into(),
        serde_json::json!(worst_centre),
    );
    Ok(StageOutcome {
        detail: format!(
            "LM from simulated marks at {NOISE_PX} px noise: {}",
            lines.join("; ")
        ),
        figures,
    })
}

struct StageOutcome {
    detail: String,
    figures: serde_json::Map<String, serde_json::Value>,
}

/// Frame rate of the interactive stage.
const INTERACTIVE_HZ: f32 = 60.0;

/// The loopback cluster: master plus one node per face and projector,
/// frame-locked over QUIC, driven by the built-in walk (recorded to
/// `session.jsonl` for `replay`).
fn interactive_stage(scene: &showcase_proto::Showcase, opts: &DemoOptions) -> Result<StageOutcome> {
    use crate::cluster::commands::{
        bench_record, output_nodes, state_hash_renderers, walk_tracking,
    };
    use crate::cluster::{LoopbackPlan, Show, Tracking, run_loopback};
    use showcase_proto::config::TrackingSource;

    const HZ: f32 = INTERACTIVE_HZ;
    let tracking = walk_tracking(scene, TrackingSource::Scripted);
    let tracker = crate::tracking::Tracker::new(&tracking, scene)?;
    let mut show = Show::new(Tracking::Scripted(tracker), HZ as f64);
    let session = opts.out.join("session.jsonl");
    let f = std::fs::File::create(&session)
        .with_context(|| format!("cannot create {}", session.display()))?;
    show.record_to(
        Box::new(std::io::BufWriter::new(f)),
        "showcase-master demo: the built-in walk",
        Some(&tracking),
    )?;
    let metrics_path = opts.out.join("metrics.jsonl");
    let metrics = std::fs::File::create(&metrics_path)
        .with_context(|| format!("cannot create {}", metrics_path.display()))?;
    let nodes = output_nodes(scene);
    let node_count = nodes.len();
    eprintln!(
        "[demo] interactive: {} frames at {HZ} Hz, master + {node_count} nodes over QUIC on loopback...",
        opts.frames
    );
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let started = Instant::now();
    let result = runtime.block_on(run_loopback(LoopbackPlan {
        scene: scene.clone(),
        show,
        nodes,
        frames: opts.frames,
        core: showcase_proto::session::MasterConfig {
            target_hz: HZ,
            ..crate::cluster::cluster_core_defaults()
        },
        renderers: state_hash_renderers(),
        restart: None,
        metrics: Some(Box::new(std::io::BufWriter::new(metrics))),
        write_frames: None,
        keep_frames: true,
    }))?;
    let seconds = started.elapsed().as_secs_f64();
    let rec = bench_record(node_count, HZ, opts.frames, &result);
    let presented: Vec<usize> = result.logs.iter().map(|(_, l)| l.presented.len()).collect();
    if presented.iter().any(|&n| n as u64 != opts.frames) {
        anyhow::bail!(
            "interactive stage: nodes presented {presented:?} frames, expected {} each",
            opts.frames
        );
    }
    let mut figures = serde_json::Map::new();
    // Frames presented per second of running frame clock (set-up excluded).
    let running_s = result.run.finished_ns.saturating_sub(result.run.started_ns) as f64 / 1e9;
    let fps = result.run.frames.len() as f64 / running_s.max(1e-9);
    tracing::debug!(seconds, "interactive stage wall time");
    figures.insert("frame_rate_hz".into(), serde_json::json!(fps));
    figures.insert(
        "swap_skew_ms_p99".into(),
        serde_json::json!(rec.swap_skew_ms_p99),
    );
    figures.insert(
        "tracking_to_swap_ms_p99".into(),
        serde_json::json!(rec.tracking_to_swap_ms_p99),
    );
    figures.insert(
        "dropped_frames".into(),
        serde_json::json!(rec.dropped_frames),
    );
    Ok(StageOutcome {
        detail: format!(
            "{} frames on {node_count} nodes, {fps:.1} frames/s, swap skew p99 {:.3} ms, tracking-to-swap p99 {:.3} ms, {} ticks dropped; session in {}",
            opts.frames,
            rec.swap_skew_ms_p99.unwrap_or(f64::NAN),
            rec.tracking_to_swap_ms_p99.unwrap_or(f64::NAN),
            rec.dropped_frames,
            session.display()
        ),
        figures,
    })
}
