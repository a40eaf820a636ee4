//! `showcase-master demo`: the whole pipeline on the simulated showcase,
//! phase by phase (scene, calibration, reflectance, radiosity, the
//! interactive cluster, rendering), with `report.json` and `index.html`.
//! A phase that fails stops the demo with its error and no report.

pub mod gi;
mod page;
pub mod photometric;
mod rendering;
mod views;

use anyhow::{Context, Result};
use serde::Serialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The built-in demo cabinet (`builtin:showcase`, compiled into the
/// binary from `deploy/scenes/showcase.toml`).
pub fn default_scene() -> PathBuf {
    PathBuf::from("builtin:showcase")
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
    /// Paths per irradiance-cache point of the physically complete views
    /// ([`TRUTH_PATHS`] by default).
    pub truth_paths: u32,
}

/// Paths per irradiance-cache point of the demo's physically complete
/// views ([`showcase_light::observer_view::complete`]).
pub const TRUTH_PATHS: u32 = 1024;

/// How one phase of the demo went.
#[derive(Debug, Clone, Serialize)]
pub struct Phase {
    /// Phase name.
    pub name: String,
    /// `ran`, or `skipped` when the scene cannot support it (a phase that
    /// fails stops the demo).
    pub status: &'static str,
    /// Wall-clock seconds spent.
    pub seconds: f64,
    /// What it did, or why it was skipped.
    pub detail: String,
    /// Why it was skipped (what the scene lacks); absent when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
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
pub const PHASES: [&str; 8] = [
    "scene",
    "calibration",
    "reflectance",
    "radiosity",
    "radiosity_figure3",
    "interactive",
    "photometric",
    "rendering",
];

/// The radiosity settings of the demo: 0.02 m^2 patches, 1e-2 unshot
/// energy.
fn demo_radiosity_options() -> crate::radiosity_job::RadiosityOptions {
    crate::radiosity_job::RadiosityOptions {
        max_patch_area: Some(0.02),
        hemicube: None,
        threshold: Some(1e-2),
        ..Default::default()
    }
}

/// A spinner (or, with `len`, a bar) for the phase about to run, on a
/// terminal only; the `[demo]` lines carry the same news in logs.
fn progress(name: &str, len: Option<u64>) -> indicatif::ProgressBar {
    progress_counting(name, len, None)
}

/// [`progress`] whose spinner shows a count of `unit` (`12 shots`).
fn progress_counting(name: &str, len: Option<u64>, unit: Option<&str>) -> indicatif::ProgressBar {
    let i = PHASES.iter().position(|p| *p == name).map_or(0, |i| i + 1);
    eprintln!("[demo] phase {i}/{}: {name}...", PHASES.len());
    let prefix = format!("{i}/{} {name}", PHASES.len());
    match len {
        Some(n) => crate::progress::bar(prefix, n),
        None => crate::progress::spinner(prefix, unit),
    }
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
            reason: None,
        });
    }

    fn skipped(&mut self, name: &str, reason: String) {
        let i = PHASES.iter().position(|p| *p == name).map_or(0, |i| i + 1);
        eprintln!(
            "[demo] phase {i}/{}: {name}: skipped: {reason}",
            PHASES.len()
        );
        self.phases.push(Phase {
            name: name.into(),
            status: "skipped",
            seconds: 0.0,
            // It did nothing; `reason` says why (the page shows it once).
            detail: String::new(),
            reason: Some(reason),
        });
    }
}

/// Why the demo cannot run phase `name` on `scene` (what the scene
/// lacks), or `None` when it can. The `radiosity` phase is decided by
/// its mesh (`radiosity_stage`).
pub fn unsupported(scene: &showcase_proto::Showcase, name: &str) -> Option<String> {
    let real = scene
        .objects
        .iter()
        .any(|o| o.kind == showcase_proto::ObjectKind::Real);
    let outputs = scene.faces.len() + scene.projectors.len();
    let why = match name {
        "calibration" if scene.projectors.is_empty() && scene.cameras.is_empty() => {
            "the scene has no projector or camera to calibrate"
        }
        "reflectance" if scene.projectors.is_empty() => {
            "the scene has no projector to light its real objects"
        }
        "reflectance" if scene.cameras.is_empty() => {
            "the scene has no camera to capture its real objects"
        }
        "reflectance" if !real => "the scene has no real object to capture",
        "interactive" if outputs == 0 => {
            "the scene has no CRT face or projector, so no render node to run"
        }
        "photometric"
            if !(0..scene.faces.len()).any(|f| views::face_observer(scene, f).is_some()) =>
        {
            "the scene has no CRT face serving an observer to calibrate"
        }
        "photometric" if scene.cameras.is_empty() => {
            "the scene has no camera to put in an observer's place"
        }
        "photometric" if scene.projectors.is_empty() || !real => {
            "the scene has no projector-lit real surface to give the camera a known radiance"
        }
        "rendering" if outputs == 0 => "the scene has no CRT face or projector output to render",
        "rendering" if scene.observers.is_empty() => {
            "the scene has no observer whose view to render and compare"
        }
        _ => return None,
    };
    Some(why.to_string())
}

/// Run the demo: every phase on the scene (the built-in cabinet by
/// default), skipping those the scene cannot support, each with its
/// reason; `complete` only when every phase ran.
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
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("cannot create {}", opts.out.display()))?;

    let truth = scene.clone();
    // The physically complete world, shared by the phases that judge in
    // it: the photometric phase's frame is one the rendering stage draws.
    let transport =
        views::Transport::complete(showcase_light::observer_view::complete::CompleteOptions {
            paths_per_point: opts.truth_paths,
            seed: rendering::COMPLETE_SEED,
        });
    // The nodes know their devices' geometry from calibration, but not
    // their photometry: they start from a nominal profile until the
    // photometric phase measures it.
    for f in &mut scene.faces {
        f.photometry = showcase_proto::CrtPhotometry::nominal(photometric::NOMINAL_GAMMA);
    }
    for p in &mut scene.projectors {
        p.response.photometry = None;
    }
    if let Some(reason) = unsupported(&scene, "calibration") {
        report.skipped("calibration", reason);
    } else {
        let t = Instant::now();
        let n = (scene.projectors.len() + scene.cameras.len()) as u64;
        let pb = progress("calibration", Some(n));
        let calibration = calibration_stage(&mut scene, &pb, &mut report.histories)?;
        pb.finish_and_clear();
        report.ran("calibration", t, calibration.detail);
        report.figures.extend(calibration.figures);
    }
    if let Some(reason) = unsupported(&scene, "reflectance") {
        report.skipped("reflectance", reason);
    } else {
        let t = Instant::now();
        let pb = progress("reflectance", None);
        let reflectance = reflectance_stage(&scene, &opts.out, &pb)?;
        pb.finish_and_clear();
        report.ran("reflectance", t, reflectance.detail);
        report.figures.extend(reflectance.figures);
    }
    match radiosity_elements(&scene) {
        Err(reason) => report.skipped("radiosity", reason),
        Ok(elements) => {
            let t = Instant::now();
            let pb = progress_counting("radiosity", None, Some("gathers"));
            let outcome = radiosity_stage(&scene, elements, &opts.out, &pb)?;
            pb.finish_and_clear();
            report.ran("radiosity", t, outcome.detail);
            report.figures.extend(outcome.figures);
        }
    }
    let t = Instant::now();
    let pb = progress_counting("radiosity_figure3", None, Some("shots"));
    let figure3 = figure3_stage(&opts.out, &pb)?;
    pb.finish_and_clear();
    report.ran("radiosity_figure3", t, figure3.detail);
    report.figures.extend(figure3.figures);
    if let Some(reason) = unsupported(&scene, "interactive") {
        report.skipped("interactive", reason);
    } else {
        let t = Instant::now();
        let pb = progress("interactive", None);
        pb.set_message(format!("{} frames at {INTERACTIVE_HZ} Hz", opts.frames));
        let interactive = interactive_stage(&scene, opts)?;
        pb.finish_and_clear();
        report.ran("interactive", t, interactive.detail);
        report.figures.extend(interactive.figures);
    }
    // Global mode's solution, as the demo's cluster keeps it: made once
    // for the nodes' scene and followed to each frame the phases judge.
    let judged_globally = ["photometric", "rendering"]
        .iter()
        .any(|p| unsupported(&scene, p).is_none());
    let live = judged_globally
        .then(|| views::live_scene(&scene))
        .transpose()?;
    let mut fields = live
        .as_ref()
        .map(|(live, first)| views::GlobalFields::start(live, first))
        .transpose()?;
    if let Some(reason) = unsupported(&scene, "photometric") {
        report.skipped("photometric", reason);
    } else {
        let t = Instant::now();
        let pb = progress("photometric", None);
        pb.set_message("each face through its mirror, from its observer's place");
        let fields = fields.as_mut().context("no global solution")?;
        let outcome = photometric_stage(&truth, &mut scene, &transport, fields)?;
        pb.finish_and_clear();
        report.ran("photometric", t, outcome.detail);
        report.figures.extend(outcome.figures);
    }
    if let Some(reason) = unsupported(&scene, "rendering") {
        report.skipped("rendering", reason);
    } else {
        let t = Instant::now();
        let fields = fields.as_mut().context("no global solution")?;
        let rendering = rendering::rendering_stage(
            &truth,
            &scene,
            opts,
            &transport,
            &mut report.gallery,
            fields,
        )?;
        report.ran("rendering", t, rendering.detail);
        report.figures.extend(rendering.figures);
    }

    report.complete =
        report.phases.len() == PHASES.len() && report.phases.iter().all(|p| p.status == "ran");
    page::write_report(&opts.out, &report)?;
    let skipped: Vec<String> = report
        .phases
        .iter()
        .filter_map(|p| Some(format!("{} ({})", p.name, p.reason.as_ref()?)))
        .collect();
    eprintln!(
        "[demo] wrote {}/report.json and index.html; {} of {} phases ran{}",
        opts.out.display(),
        report.phases.len() - skipped.len(),
        report.phases.len(),
        if skipped.is_empty() {
            "; complete".to_string()
        } else {
            format!(
                ", so the run is not complete; skipped: {}",
                skipped.join("; ")
            )
        }
    );
    Ok(())
}

/// Capture the reflectance of the cabinet's real objects in the simulated
/// showcase with the calibrated devices (16 frames, eta and black level
/// estimated, interreflection corrected) at a demo resolution
/// (`CaptureOptions::demo`: a 160x120 camera); `pb` names the stage.
fn reflectance_stage(
    scene: &showcase_proto::Showcase,
    out: &Path,
    pb: &indicatif::ProgressBar,
) -> Result<StageOutcome> {
    let dir = out.join("reflectance");
    let opts = crate::capture::CaptureOptions::demo();
    let s = crate::capture::run_capture_staged(scene, &dir, &opts, &|_, stage| {
        pb.set_message(stage.to_string())
    })?;
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

/// The elements of `scene` at the demo's radiosity settings, or why the
/// `radiosity` phase cannot solve it (nothing to solve). Above
/// [`crate::radiosity_job::AUTO_HIERARCHICAL_ELEMENTS`] the hierarchical
/// solver takes it.
fn radiosity_elements(scene: &showcase_proto::Showcase) -> Result<usize, String> {
    let opts = demo_radiosity_options();
    let (_, elements) = crate::radiosity_job::mesh_size(scene, &opts)
        .map_err(|e| format!("nothing to solve: {e:#}"))?;
    Ok(elements)
}

/// Augmented radiosity on the demo's scene (with its calibrated devices):
/// B0..B3 and the projectors' irradiance maps at the demo's settings, in
/// `<out>/radiosity`; `pb` counts the shots.
fn radiosity_stage(
    scene: &showcase_proto::Showcase,
    elements: usize,
    out: &Path,
    pb: &indicatif::ProgressBar,
) -> Result<StageOutcome> {
    let mut opts = demo_radiosity_options();
    opts.progress = crate::progress::radiosity_shots(pb, "[demo] radiosity");
    opts.hierarchy_progress = crate::progress::radiosity_gathers(pb, "[demo] radiosity", None);
    let dir = out.join("radiosity");
    let s = crate::radiosity_job::run_radiosity_scene(
        scene,
        &scene.name,
        &dir,
        &opts,
        crate::radiosity_job::FormFactorDevice::Cpu,
    )?;
    let mut figures = serde_json::Map::new();
    figures.insert("radiosity_links".into(), serde_json::json!(s.links));
    figures.insert("radiosity_elements".into(), serde_json::json!(s.elements));
    figures.insert("radiosity_shots".into(), serde_json::json!(s.shots));
    figures.insert(
        "radiosity_unshot_fraction".into(),
        serde_json::json!(s.unshot_fraction),
    );
    figures.insert(
        "radiosity_clipped_fractions".into(),
        serde_json::json!(s.clipped_fractions),
    );
    figures.insert(
        "radiosity_b3_b0_deviation_rgb".into(),
        serde_json::json!(s.b3_b0_deviation_rgb),
    );
    Ok(StageOutcome {
        detail: format!(
            "scene {}, {} solver: {} patches, {} elements ({}), {} links, {} {}; {}; solution and maps in {}",
            scene.name,
            s.solver,
            s.patches,
            s.elements,
            if s.solver == "hierarchical" {
                format!("small triangles kept whole; {elements} with every patch split")
            } else {
                format!("{elements} before refinement")
            },
            s.links,
            s.shots,
            if s.solver == "hierarchical" {
                "gathers"
            } else {
                "shots"
            },
            match s.b3_b0_deviation_rgb {
                Some(d) => format!(
                    "augmented: B3-B0 deviation per channel {:.3}/{:.3}/{:.3}, projector clipped fractions {}",
                    d[0],
                    d[1],
                    d[2],
                    s.clipped_fractions
                        .iter()
                        .map(|c| format!("{c:.3}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                None => "not augmented (no real object lit by a projector)".to_string(),
            },
            dir.display(),
        ),
        figures,
    })
}

/// The solver's reference check, whatever the demo's scene: the paper's
/// figure-3 configuration (built-in `builtin:figure3`: Cornell walls
/// real, blocks and ceiling light virtual), augmented radiosity B0..B3
/// and the projectors' irradiance maps at the demo's settings, in
/// `<out>/radiosity-figure3`; `pb` counts the shots.
fn figure3_stage(out: &Path, pb: &indicatif::ProgressBar) -> Result<StageOutcome> {
    let scene = Path::new("builtin:figure3");
    let mut opts = demo_radiosity_options();
    opts.progress = crate::progress::radiosity_shots(pb, "[demo] radiosity_figure3");
    let dir = out.join("radiosity-figure3");
    let s = crate::radiosity_job::run_radiosity(scene, &dir, &opts)?;
    let mut figures = serde_json::Map::new();
    figures.insert(
        "radiosity_figure3_clipped_fractions".into(),
        serde_json::json!(s.clipped_fractions),
    );
    figures.insert(
        "radiosity_figure3_b3_b0_deviation_rgb".into(),
        serde_json::json!(s.b3_b0_deviation_rgb),
    );
    // End to end through the sim (path tracing, independent of the
    // solver): the projectors' maps on the real walls against B0, with B2
    // from the real room's interreflection gathered at the vertices (the
    // headline) and with the paper's converged B1.
    pb.set_message("the maps through the simulated projectors (path tracing)".to_string());
    let cornell = crate::scene_file::shared_data("cornell-box.obj");
    let cornell = crate::scene_file::load_any(&cornell)?;
    let record = crate::radiosity_job::bench::augmented_record_with(&cornell, false)?;
    let gathered = record["consistency_rel_rmse"].as_f64();
    let paper = record["paper_consistency_rel_rmse"].as_f64();
    figures.insert(
        "radiosity_figure3_consistency_rel_rmse".into(),
        serde_json::json!(gathered),
    );
    figures.insert(
        "radiosity_figure3_paper_consistency_rel_rmse".into(),
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
/// `pb` counts the devices, and each device's residuals go to `histories`
/// for the page's plot.
fn calibration_stage(
    scene: &mut showcase_proto::Showcase,
    pb: &indicatif::ProgressBar,
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
        pb.set_message(name.clone());
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
        pb.inc(1);
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

/// Calibrate each face photometrically in the simulated showcase `truth`
/// and give the nodes' scene `scene` the profiles; the figures judge the
/// recovered parameters against the truth, and the observers at frame 60
/// of the walk (global mode) uncalibrated, calibrated, with the true
/// devices, and without the photometric chain.
fn photometric_stage(
    truth: &showcase_proto::Showcase,
    scene: &mut showcase_proto::Showcase,
    transport: &views::Transport,
    fields: &mut views::GlobalFields<'_>,
) -> Result<StageOutcome> {
    let (judged, record) =
        photometric::photometric_record(truth, scene, PHOTOMETRIC_FRAME, transport, fields)?;
    let faces = &judged.faces;
    for j in faces {
        if let Some(f) = scene.faces.get_mut(j.face) {
            f.photometry = j.calibration.profile;
        }
    }
    for j in &judged.projectors {
        if let Some(p) = scene.projectors.get_mut(j.projector) {
            p.response.photometry = Some(j.calibration.profile);
        }
    }
    let worst =
        |f: &dyn Fn(&photometric::JudgedFace) -> f64| faces.iter().map(f).fold(0.0, f64::max);
    let max3 = |a: [f64; 3]| a.into_iter().fold(0.0, f64::max);
    let mut figures = serde_json::Map::new();
    let mut put = |k: &str, v: serde_json::Value| {
        figures.insert(k.into(), v);
    };
    put(
        "photometric_camera_response_error",
        json!(worst(&|j| max3(j.camera_response_error))),
    );
    put(
        "photometric_crt_curve_error",
        json!(worst(&|j| max3(j.crt_curve_error))),
    );
    put(
        "photometric_balance_error",
        json!(worst(&|j| max3(j.balance_error))),
    );
    put(
        "photometric_held_out_error",
        json!(worst(&|j| j.calibration.held_out_error)),
    );
    put(
        "photometric_held_out_error_uncalibrated",
        json!(worst(&|j| j.calibration.held_out_error_before)),
    );
    let worst_projector = |f: &dyn Fn(&photometric::JudgedProjector) -> f64| {
        judged.projectors.iter().map(f).fold(0.0, f64::max)
    };
    let abs3 = |a: [f64; 3]| a.into_iter().map(f64::abs).fold(0.0, f64::max);
    put(
        "photometric_projector_curve_error",
        json!(worst_projector(&|j| max3(j.curve_error))),
    );
    put(
        "photometric_projector_curve_error_uncalibrated",
        json!(worst_projector(&|j| max3(j.curve_error_before))),
    );
    put(
        "photometric_projector_gamma_error",
        json!(worst_projector(&|j| abs3(j.gamma_error))),
    );
    put(
        "photometric_projector_black_error",
        json!(worst_projector(&|j| abs3(j.black_error))),
    );
    put("photometric_calibration_s", record["calibration_s"].clone());
    for (state, suffix) in [
        ("calibrated", ""),
        ("uncalibrated", "_uncalibrated"),
        ("true", "_true"),
        ("ideal_photometry", "_ideal_photometry"),
    ] {
        let s = &record["states"][state];
        for (what, key) in [
            ("seam_delta_e_median", "photometric_seam_delta_e_median"),
            ("seam_delta_e_p95", "photometric_seam_delta_e_p95"),
            (
                "observer_delta_e_median",
                "photometric_observer_delta_e_median",
            ),
            ("observer_delta_e_p95", "photometric_observer_delta_e_p95"),
        ] {
            put(&format!("{key}{suffix}"), s[what].clone());
        }
    }
    let s = &record["states"];
    let detail = format!(
        "{} faces and {} projectors in {:.1} s; seams median {:.2} calibrated, {:.2} uncalibrated, {:.2} with the true devices",
        faces.len(),
        judged.projectors.len(),
        record["calibration_s"].as_f64().unwrap_or(f64::NAN),
        s["calibrated"]["seam_delta_e_median"]
            .as_f64()
            .unwrap_or(f64::NAN),
        s["uncalibrated"]["seam_delta_e_median"]
            .as_f64()
            .unwrap_or(f64::NAN),
        s["true"]["seam_delta_e_median"]
            .as_f64()
            .unwrap_or(f64::NAN),
    );
    Ok(StageOutcome { detail, figures })
}

/// The frame of the walk the photometric phase judges.
const PHOTOMETRIC_FRAME: u64 = 60;

/// Frame rate of the interactive stage.
const INTERACTIVE_HZ: f32 = 60.0;

/// The loopback cluster: master plus one node per face and projector,
/// frame-locked over QUIC, driven by the built-in walk (recorded to
/// `session.jsonl` for `replay`), in global-illumination mode: the master
/// solves before frame 0 and again as the walk moves the light and the
/// heads. The same walk in direct mode runs after it, for the figures of
/// both modes side by side (`*_direct_mode`).
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
    let mut global_scene = scene.clone();
    global_scene.illumination = showcase_proto::IlluminationMode::Global;
    let result = runtime.block_on(run_loopback(LoopbackPlan {
        scene: global_scene,
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
        keep_presented: false,
        illumination_lag: None,
        illumination_patch_area: None,
        maps: Vec::new(),
    }))?;
    let seconds = started.elapsed().as_secs_f64();
    let rec = bench_record(node_count, HZ, opts.frames, &result);
    let presented: Vec<u64> = result.logs.iter().map(|(_, l)| l.presented_count).collect();
    if presented.iter().any(|&n| n != opts.frames) {
        anyhow::bail!(
            "interactive stage: nodes presented {presented:?} frames, expected {} each",
            opts.frames
        );
    }
    let mut figures = serde_json::Map::new();
    tracing::debug!(seconds, "interactive stage wall time");
    let fps = crate::cluster::metrics::swap_rate_hz(&result.run.frames);
    if let Some(fps) = fps {
        figures.insert("frame_rate_hz".into(), serde_json::json!(fps));
    }
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
    let updates = crate::cluster::illumination::UpdateSummary::of(&result.run.illumination_updates);
    figures.insert(
        "illumination_updates".into(),
        serde_json::json!(updates.updates),
    );
    figures.insert(
        "illumination_update_ms_p50".into(),
        serde_json::json!(updates.latency_ms_p50),
    );
    figures.insert(
        "illumination_update_ms_p99".into(),
        serde_json::json!(updates.latency_ms_p99),
    );
    figures.insert(
        "illumination_frames_stale_max".into(),
        serde_json::json!(updates.frames_stale_max),
    );
    if !result.run.illumination_failures.is_empty() {
        anyhow::bail!(
            "interactive stage: global-illumination solves failed: {:?}",
            result.run.illumination_failures
        );
    }
    eprintln!("[demo] interactive: the same walk in direct mode, for comparison...");
    let direct = gi::live_figures(
        scene,
        showcase_proto::IlluminationMode::Direct,
        gi::WalkMove::All,
        opts.frames,
        None,
    )?;
    figures.insert(
        "swap_skew_ms_p99_direct_mode".into(),
        serde_json::json!(direct.swap_skew_ms_p99),
    );
    figures.insert(
        "tracking_to_swap_ms_p99_direct_mode".into(),
        serde_json::json!(direct.tracking_to_swap_ms_p99),
    );
    Ok(StageOutcome {
        detail: format!(
            "{} frames on {node_count} nodes in global mode, {:.1} frames/s, swap skew p99 {:.3} ms (direct mode {:.3}), tracking-to-swap p99 {:.3} ms (direct mode {:.3}), {} ticks dropped; {}; session in {}",
            opts.frames,
            fps.unwrap_or(f64::NAN),
            rec.swap_skew_ms_p99.unwrap_or(f64::NAN),
            direct.swap_skew_ms_p99.unwrap_or(f64::NAN),
            rec.tracking_to_swap_ms_p99.unwrap_or(f64::NAN),
            direct.tracking_to_swap_ms_p99.unwrap_or(f64::NAN),
            rec.dropped_frames,
            updates.line(),
            session.display()
        ),
        figures,
    })
}
