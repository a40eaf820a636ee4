//! `showcase-master demo`: the whole pipeline on the simulated showcase,
//! phase by phase (scene, calibration, reflectance, radiosity, the
//! interactive cluster, rendering), with `report.json` and `index.html`.
//! A phase that fails stops the demo with its error and no report.

mod views;

use crate::cli::DemoArgs;
use anyhow::{Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The built-in demo cabinet, shipped with the sources.
pub fn default_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/showcase.toml")
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
pub fn run(args: &DemoArgs) -> Result<()> {
    let scene_path = args.scene.clone().unwrap_or_else(default_scene);
    let mut report = Report::default();

    let t = Instant::now();
    let pb = progress("scene", None);
    let mut scene = crate::scene_file::load_scene(&scene_path)?;
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
    let calibration = calibration_stage(&mut scene)?;
    pb.finish_and_clear();
    report.ran("calibration", t, calibration.detail);
    report.figures.extend(calibration.figures);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let t = Instant::now();
    let pb = progress("reflectance", None);
    let reflectance = reflectance_stage(&scene, &args.out)?;
    pb.finish_and_clear();
    report.ran("reflectance", t, reflectance.detail);
    report.figures.extend(reflectance.figures);
    let t = Instant::now();
    let pb = progress("radiosity", None);
    let radiosity = radiosity_stage(&args.out)?;
    pb.finish_and_clear();
    report.ran("radiosity", t, radiosity.detail);
    report.figures.extend(radiosity.figures);
    let t = Instant::now();
    let pb = progress("interactive", None);
    pb.set_message(format!("{} frames at {INTERACTIVE_HZ} Hz", args.frames));
    let interactive = interactive_stage(&scene, args)?;
    pb.finish_and_clear();
    report.ran("interactive", t, interactive.detail);
    report.figures.extend(interactive.figures);
    let t = Instant::now();
    let rendering = rendering_stage(&truth, &scene, args, &mut report.gallery)?;
    report.ran("rendering", t, rendering.detail);
    report.figures.extend(rendering.figures);

    report.complete =
        report.phases.len() == PHASES.len() && report.phases.iter().all(|p| p.status == "ran");
    write_report(&args.out, &report)?;
    let skipped = report
        .phases
        .iter()
        .filter(|p| p.status == "skipped")
        .count();
    eprintln!(
        "[demo] wrote {}/report.json and index.html; {} of {} phases ran, {skipped} skipped (see above)",
        args.out.display(),
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
    let cornell = crate::radiosity_job::load_obj_scene(&cornell)?;
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
/// in the scene in place of the true ones for everything that follows.
fn calibration_stage(scene: &mut showcase_proto::Showcase) -> Result<StageOutcome> {
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

/// Frames of the walk the rendering stage draws: a quarter, half and
/// three quarters of the way.
fn rendered_frames(frames: u64) -> Vec<u64> {
    let mut v: Vec<u64> = [1, 2, 3].iter().map(|q| q * frames / 4).collect();
    v.dedup();
    v
}

/// Every output of the cabinet rendered by the node renderers at a few
/// frames of the walk (calibrated devices, demo resolution), and what each
/// observer sees of them through the simulated cabinet (true devices)
/// next to its target, with CIEDE2000 heat maps.
fn rendering_stage(
    truth: &showcase_proto::Showcase,
    calibrated: &showcase_proto::Showcase,
    args: &DemoArgs,
    gallery: &mut Vec<GalleryRow>,
) -> Result<StageOutcome> {
    use crate::cluster::commands::walk_tracking;
    use crate::cluster::{Show, Tracking};
    use showcase_proto::config::TrackingSource;

    let frames = rendered_frames(args.frames);
    let truth = views::at_demo_resolution(truth)?;
    let calibrated = std::sync::Arc::new(views::at_demo_resolution(calibrated)?);
    // The frame states the cluster sent: the same scripted walk, replayed.
    let tracker =
        crate::tracking::Tracker::new(&walk_tracking(&truth, TrackingSource::Scripted), &truth)?;
    let mut show = Show::new(Tracking::Scripted(tracker), INTERACTIVE_HZ as f64);
    let last = frames.last().copied().unwrap_or(0);
    let mut states = Vec::new();
    for f in 0..=last {
        let (state, _) = show.frame_state(f, 0.0, &truth, 1);
        if frames.contains(&f) {
            states.push(state);
        }
    }
    let backend = views::Backend::open();
    let mut renderers = views::NodeRenderers::new(&backend, calibrated.clone())?;
    eprintln!(
        "[demo] rendering: {} frames x {} outputs with {}...",
        states.len(),
        calibrated.projectors.len() + calibrated.faces.len(),
        backend.describe()
    );
    let observers = truth.observers.len();
    let mut all_de = Vec::new();
    let mut per_observer: Vec<Seen> = vec![Seen::default(); observers];
    let mut render_s = Vec::new();
    let pb = progress("rendering", Some(states.len() as u64));
    for state in &states {
        pb.set_message(format!("frame {}", state.frame));
        let dir_name = format!("frames/frame-{:04}", state.frame);
        let dir = args.out.join(&dir_name);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let t = Instant::now();
        let outputs = renderers.render(state)?;
        render_s.push(t.elapsed().as_secs_f64());
        let mut nodes = Vec::new();
        for (p, img) in calibrated.projectors.iter().zip(&outputs.projectors) {
            let file = format!("{dir_name}/{}.png", p.name);
            views::write_values(&args.out.join(&file), img)?;
            nodes.push((format!("{} (pixel values)", p.name), file));
        }
        let mut rows = Vec::new();
        for (o, seen) in per_observer.iter_mut().enumerate() {
            let r = views::observe(&truth, state, &outputs, o)?;
            let name = &truth.observers[o].name;
            let mut images = Vec::new();
            for (what, img) in [
                ("target", &r.view.target),
                ("composite", &r.view.composite),
                ("through-mirror", &r.view.reflected),
            ] {
                let file = format!("{dir_name}/{name}-{what}.png");
                views::write_radiance(&args.out.join(&file), img, r.exposure)?;
                images.push((format!("{name}: {what}"), file));
            }
            let file = format!("{dir_name}/{name}-delta-e.png");
            views::write_heat_map(
                &args.out.join(&file),
                r.view.target.width,
                r.view.target.height,
                &r.delta_e,
            )?;
            let median = views::quantile(&r.delta_e, 0.5).unwrap_or(f64::NAN);
            images.push((
                format!("{name}: CIEDE2000 (median {median:.2}; black 0, red >= 10)"),
                file,
            ));
            rows.push(GalleryRow {
                title: format!("frame {}: {name} (rel RMSE {:.3})", state.frame, r.rel_rmse),
                images,
            });
            all_de.extend(r.delta_e.iter().copied().filter(|d| d.is_finite()));
            seen.add(&r);
        }
        for (f, _, [left, right]) in &outputs.faces {
            let face = calibrated
                .faces
                .get(*f)
                .map_or("face".to_string(), |f| f.name.clone());
            for (eye, img) in [("left", left), ("right", right)] {
                let file = format!("{dir_name}/{face}-{eye}.png");
                views::write_radiance(&args.out.join(&file), img, 1.0)?;
                nodes.push((format!("{face}: {eye} eye"), file));
            }
        }
        gallery.push(GalleryRow {
            title: format!("frame {}: node outputs", state.frame),
            images: nodes,
        });
        gallery.extend(rows);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mut figures = serde_json::Map::new();
    let median = views::quantile(&all_de, 0.5);
    let p95 = views::quantile(&all_de, 0.95);
    figures.insert("delta_e2000_median".into(), serde_json::json!(median));
    figures.insert("delta_e2000_p95".into(), serde_json::json!(p95));
    let worst = per_observer.iter().map(|p| p.rel).fold(0.0f64, f64::max);
    figures.insert(
        "interactive_consistency_rel_rmse".into(),
        serde_json::json!(worst),
    );
    figures.insert(
        "observers".into(),
        serde_json::json!(
            per_observer
                .iter()
                .enumerate()
                .map(|(o, seen)| serde_json::json!({
                    "observer": truth.observers[o].name,
                    "delta_e2000_median": views::quantile(&seen.delta_e, 0.5),
                    "delta_e2000_p95": views::quantile(&seen.delta_e, 0.95),
                    "consistency_rel_rmse": seen.rel,
                    "consistency_rel_rmse_real": seen.rel_real,
                    "consistency_rel_rmse_virtual": seen.rel_virtual,
                    "consistency_rel_rmse_reflective": seen.rel_reflective,
                    "consistency_rel_rmse_per_object": seen.per_object,
                    "projector_reach_fraction": seen.reach,
                    "consistency_rel_rmse_real_comparable": seen.rel_real_comparable,
                    "consistency_rel_rmse_real_comparable_per_object": seen.per_object_comparable,
                    "comparable_real_fraction": seen.comparable_fraction,
                }))
                .collect::<Vec<_>>()
        ),
    );
    // Not the headline: the real-surface figure over the pixels the method
    // can get right by design (see `views::ObserverResult`), for the
    // real-surface error budget.
    let comparable = per_observer
        .iter()
        .filter_map(|p| p.rel_real_comparable)
        .reduce(f64::max);
    figures.insert(
        "interactive_consistency_rel_rmse_real_comparable".into(),
        serde_json::json!(comparable),
    );
    figures.insert("renderer".into(), serde_json::json!(backend.describe()));
    render_s.sort_by(f64::total_cmp);
    Ok(StageOutcome {
        detail: format!(
            "frames {frames:?}: {} projectors and {} faces rendered with {} (median {:.2} s per frame for all outputs); observers' views against targets: CIEDE2000 median {:.2}, p95 {:.2}, worst rel RMSE {worst:.3} (off edges, where a projector reaches), real surfaces where the method can be right {:.4}; images in {}/frames",
            calibrated.projectors.len(),
            calibrated.faces.len(),
            backend.describe(),
            render_s
                .get(render_s.len() / 2)
                .copied()
                .unwrap_or(f64::NAN),
            median.unwrap_or(f64::NAN),
            p95.unwrap_or(f64::NAN),
            comparable.unwrap_or(f64::NAN),
            args.out.display()
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
fn interactive_stage(scene: &showcase_proto::Showcase, args: &DemoArgs) -> Result<StageOutcome> {
    use crate::cluster::commands::{
        bench_record, output_nodes, state_hash_renderers, walk_tracking,
    };
    use crate::cluster::{LoopbackPlan, Show, Tracking, run_loopback};
    use showcase_proto::config::TrackingSource;

    const HZ: f32 = INTERACTIVE_HZ;
    let tracker =
        crate::tracking::Tracker::new(&walk_tracking(scene, TrackingSource::Scripted), scene)?;
    let mut show = Show::new(Tracking::Scripted(tracker), HZ as f64);
    let session = args.out.join("session.jsonl");
    let f = std::fs::File::create(&session)
        .with_context(|| format!("cannot create {}", session.display()))?;
    show.record_to(
        Box::new(std::io::BufWriter::new(f)),
        "showcase-master demo: the built-in walk",
    )?;
    let metrics_path = args.out.join("metrics.jsonl");
    let metrics = std::fs::File::create(&metrics_path)
        .with_context(|| format!("cannot create {}", metrics_path.display()))?;
    let nodes = output_nodes(scene);
    let node_count = nodes.len();
    eprintln!(
        "[demo] interactive: {} frames at {HZ} Hz, master + {node_count} nodes over QUIC on loopback...",
        args.frames
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
        frames: args.frames,
        core: showcase_proto::session::MasterConfig {
            target_hz: HZ,
            ..crate::cluster::cluster_core_defaults()
        },
        renderers: state_hash_renderers(),
        restart: None,
        metrics: Some(Box::new(std::io::BufWriter::new(metrics))),
        write_frames: None,
    }))?;
    let seconds = started.elapsed().as_secs_f64();
    let rec = bench_record(node_count, HZ, args.frames, &result);
    let presented: Vec<usize> = result.logs.iter().map(|(_, l)| l.presented.len()).collect();
    if presented.iter().any(|&n| n as u64 != args.frames) {
        anyhow::bail!(
            "interactive stage: nodes presented {presented:?} frames, expected {} each",
            args.frames
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
            args.frames,
            rec.swap_skew_ms_p99.unwrap_or(f64::NAN),
            rec.tracking_to_swap_ms_p99.unwrap_or(f64::NAN),
            rec.dropped_frames,
            session.display()
        ),
        figures,
    })
}

fn write_report(out: &Path, report: &Report) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let json = serde_json::to_string_pretty(report)?;
    let path = out.join("report.json");
    std::fs::write(&path, json).with_context(|| format!("cannot write {}", path.display()))?;
    let mut rows = String::new();
    for p in &report.phases {
        rows.push_str(&format!(
            "<tr class=\"{}\"><td>{}</td><td>{}</td><td>{:.2}</td><td>{}</td></tr>\n",
            p.status,
            html_escape(&p.name),
            p.status,
            p.seconds,
            html_escape(&p.detail)
        ));
    }
    let mut gallery = String::new();
    if !report.gallery.is_empty() {
        gallery.push_str("<h2>Images</h2>\n");
    }
    for row in &report.gallery {
        gallery.push_str(&format!(
            "<h3>{}</h3><div class=\"row\">\n",
            html_escape(&row.title)
        ));
        for (caption, file) in &row.images {
            gallery.push_str(&format!(
                "<figure><img src=\"{0}\" alt=\"{1}\"><figcaption>{1}</figcaption></figure>\n",
                html_escape(file),
                html_escape(caption)
            ));
        }
        gallery.push_str("</div>\n");
    }
    let html = format!(
        "<!doctype html><meta charset=\"utf-8\"><title>Showcase demo</title>\n\
         <style>body{{font-family:sans-serif;margin:2em}}td,th{{padding:4px 10px;border-bottom:1px solid #ddd}}\
         tr.skipped{{color:#a00}}.row{{display:flex;flex-wrap:wrap;gap:8px}}figure{{margin:0}}\
         figcaption{{font-size:small;max-width:320px}}img{{image-rendering:pixelated;max-width:400px}}</style>\n<h1>Showcase demo</h1>\n<p>Complete: <b>{}</b></p>\n\
         <table><tr><th>phase</th><th>status</th><th>seconds</th><th>detail</th></tr>\n{rows}</table>\n\
         <h2>Figures</h2><pre>{}</pre>\n{gallery}",
        report.complete,
        html_escape(&serde_json::to_string_pretty(&report.figures).unwrap_or_default())
    );
    let path = out.join("index.html");
    std::fs::write(&path, html).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// What one observer saw over the rendered frames: every CIEDE2000 value
/// and the worst of each figure.
#[derive(Clone, Debug)]
struct Seen {
    delta_e: Vec<f64>,
    rel: f64,
    rel_real: Option<f64>,
    rel_virtual: Option<f64>,
    rel_reflective: Option<f64>,
    per_object: std::collections::BTreeMap<String, f64>,
    reach: f64,
    rel_real_comparable: Option<f64>,
    per_object_comparable: std::collections::BTreeMap<String, f64>,
    comparable_fraction: f64,
}

impl Default for Seen {
    fn default() -> Self {
        Self {
            delta_e: Vec::new(),
            rel: 0.0,
            rel_real: None,
            rel_virtual: None,
            rel_reflective: None,
            per_object: std::collections::BTreeMap::new(),
            reach: 1.0,
            rel_real_comparable: None,
            per_object_comparable: std::collections::BTreeMap::new(),
            comparable_fraction: 1.0,
        }
    }
}

impl Seen {
    fn add(&mut self, r: &views::ObserverResult) {
        let worst = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
        self.delta_e
            .extend(r.delta_e.iter().copied().filter(|d| d.is_finite()));
        self.rel = self.rel.max(r.rel_rmse);
        self.rel_real = worst(self.rel_real, r.rel_rmse_real);
        self.rel_virtual = worst(self.rel_virtual, r.rel_rmse_virtual);
        self.rel_reflective = worst(self.rel_reflective, r.rel_rmse_reflective);
        for (name, e) in &r.rel_rmse_per_object {
            let w = self.per_object.entry(name.clone()).or_insert(0.0);
            *w = w.max(*e);
        }
        self.reach = self.reach.min(r.reachable_fraction);
        self.rel_real_comparable = worst(self.rel_real_comparable, r.rel_rmse_real_comparable);
        for (name, e) in &r.rel_rmse_real_comparable_per_object {
            let w = self
                .per_object_comparable
                .entry(name.clone())
                .or_insert(0.0);
            *w = w.max(*e);
        }
        self.comparable_fraction = self.comparable_fraction.min(r.comparable_real_fraction);
    }
}
