//! `showcase-master bench reflectance`: reflectance against the sim's true
//! albedo for the plate and the Cornell box, every method, 1 to 64 frames,
//! eta known or estimated, and a report plotting error against time.
//!
//! `seconds` is the capture's cost: the measured compute time of the
//! capture pipeline (with the sim's light transport for each projector
//! image computed beforehand, as the real scene would supply it for free)
//! plus the acquisition time of its frames at the rig's frame interval
//! (`(4 + 1/K)` wheel turns per frame, see `capture`), including the
//! reference target's frames when eta is estimated.

use super::pipeline::{
    CaptureConfig, EtaMode, Method, ProjectorLevels, adjust_camera_gain, calibrate_reference,
    capture_map,
};
use super::scenes;
use crate::plot::{Plot, Point, Series, series_colour};
use glam::Vec3;
use serde::Serialize;
use showcase_light::hardware::ProjectorDevice;
use showcase_light::reflectance::CorrectionParams;
use showcase_light::sim::{SimConfig, SimShowcase};
use showcase_light::{Image, metrics::relative_rmse};
use showcase_proto::Showcase;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One bench result (the keys are fixed: reports and tests read them).
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct Record {
    /// `plate` or `cornell`.
    pub scene: String,
    /// `naive`, `piecewise` or `corrected`.
    pub method: String,
    /// Frames averaged per radiance map.
    pub frames: u32,
    /// `known` or `estimated`.
    pub eta: String,
    /// Relative RMSE of reflectance against the true albedo, valid pixels.
    pub rel_rmse: f64,
    /// The same over valid pixels whose true indirect light exceeds 10% of
    /// the direct light (0 when there are none).
    pub rel_rmse_interreflection: f64,
    /// Fraction of visible object pixels with a valid reflectance.
    pub coverage: f64,
    /// `|eta_est - eta| / eta`.
    pub eta_rel_error: f64,
    /// `|black_est - black| / eta` (black-level error as a fraction of eta).
    pub black_level_error: f64,
    /// Capture cost in seconds (module docs).
    pub seconds: f64,
}

/// What to run.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// The Cornell box OBJ.
    pub cornell: PathBuf,
    /// Camera image side in pixels.
    pub size: u32,
    /// Paths per pixel of the sim's light transport.
    pub samples_per_pixel: u32,
    /// Frame counts.
    pub frames: Vec<u32>,
    /// Scenes by name (`plate`, `cornell`).
    pub scenes: Vec<String>,
    /// Camera noise on (the bench's default setting).
    pub noise: bool,
    /// Methods to run.
    pub methods: Vec<Method>,
    /// Gather rays per pixel of the interreflection correction.
    pub gather_samples: u32,
    /// Piecewise capture's tile grid (see `CaptureConfig::piece_tiles`).
    pub piece_tiles: u32,
    /// Piecewise capture's mask growth in projector pixels.
    pub piece_dilate_px: u32,
    /// Told each configuration as it is measured (one step each of
    /// [`BenchOptions::configurations`]); hidden by default.
    pub progress: indicatif::ProgressBar,
}

impl BenchOptions {
    /// Configurations measured: per scene, frame count, method and eta
    /// mode (given and estimated).
    pub fn configurations(&self) -> u64 {
        (self.scenes.len() * self.frames.len() * self.methods.len() * 2) as u64
    }
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            cornell: crate::scene_file::shared_data("cornell-box.obj"),
            size: 64,
            samples_per_pixel: 512,
            frames: vec![1, 2, 4, 8, 16, 32, 64],
            scenes: vec!["plate".into(), "cornell".into()],
            noise: true,
            methods: vec![Method::Naive, Method::Piecewise, Method::Corrected],
            gather_samples: 1024,
            progress: indicatif::ProgressBar::hidden(),
            piece_tiles: CaptureConfig::default().piece_tiles,
            piece_dilate_px: 1,
        }
    }
}

/// Run the bench (module docs).
pub fn bench_reflectance(options: &BenchOptions) -> anyhow::Result<Vec<Record>> {
    let mut records = Vec::new();
    for name in &options.scenes {
        let size = (options.size, options.size);
        let mut scene = match name.as_str() {
            "plate" => scenes::plate_scene(size, options.noise),
            "cornell" => scenes::cornell_scene(&options.cornell, size, options.noise)?,
            other => anyhow::bail!("unknown bench scene {other:?} (plate, cornell)"),
        };
        let config = SimConfig {
            samples_per_pixel: options.samples_per_pixel,
            ..SimConfig::default()
        };
        let probe = SimShowcase::new(&scene, config.clone())?;
        adjust_camera_gain(&mut scene, &probe)?;
        let sim = SimShowcase::new(&scene, config)?;
        records.extend(bench_scene(name, &scene, &sim, options)?);
    }
    Ok(records)
}

fn bench_scene(
    name: &str,
    scene: &Showcase,
    sim: &SimShowcase,
    options: &BenchOptions,
) -> anyhow::Result<Vec<Record>> {
    let truth = GroundTruth::new(sim)?;
    let true_levels = ProjectorLevels::of(&scene.projectors[0].response);
    let period = sim.projector(0)?.wheel_period_s();
    let methods = options.methods.clone();
    let correction = CorrectionParams {
        gather_samples: options.gather_samples,
        ..CorrectionParams::default()
    };
    // Warm the sim's transport cache for every projector image.
    for &method in &methods {
        let config = CaptureConfig {
            frames: 1,
            method,
            eta: EtaMode::FromScene,
            piece_tiles: options.piece_tiles,
            piece_dilate_px: options.piece_dilate_px,
            ..CaptureConfig::default()
        };
        capture_map(
            scene,
            &mut sim.projector(0)?,
            &mut sim.camera(0)?,
            config.resolve_eta(scene)?,
            &config,
        )?;
    }
    let mut records = Vec::new();
    for &frames in &options.frames {
        let frame_s = if period > 0.0 {
            (4.0 + 1.0 / frames as f64) * period
        } else {
            1.0 / 30.0
        };
        // The projector fit is shared by the methods; timed once per K.
        let t = Instant::now();
        let fit = calibrate_reference(scene, frames, 4)?;
        let fit_seconds = t.elapsed().as_secs_f64() + 2.0 * frames as f64 * frame_s;
        for &method in &methods {
            for estimated in [false, true] {
                let config = CaptureConfig {
                    frames,
                    method,
                    eta: if estimated {
                        EtaMode::Estimated
                    } else {
                        EtaMode::FromScene
                    },
                    correction,
                    piece_tiles: options.piece_tiles,
                    piece_dilate_px: options.piece_dilate_px,
                    ..CaptureConfig::default()
                };
                options.progress.inc(1);
                options.progress.set_message(format!(
                    "{name}, {frames} frames, {}, eta {}",
                    method.name(),
                    if estimated { "estimated" } else { "given" }
                ));
                // The fit made above for this K, not one per method.
                let levels = config.eta.resolve(scene, || Ok(fit))?;
                let t = Instant::now();
                let mut projector = sim.projector(0)?;
                let outcome =
                    capture_map(scene, &mut projector, &mut sim.camera(0)?, levels, &config)?;
                let maps = if method == Method::Piecewise {
                    outcome.pieces
                } else {
                    1
                };
                let mut seconds =
                    t.elapsed().as_secs_f64() + (maps * frames as usize) as f64 * frame_s;
                if estimated {
                    seconds += fit_seconds;
                }
                let rel = relative_rmse(&outcome.reflectance, &truth.albedo, Some(&outcome.valid))
                    .unwrap_or(f64::NAN);
                let ir_mask = Image {
                    width: outcome.valid.width,
                    height: outcome.valid.height,
                    data: outcome
                        .valid
                        .data
                        .iter()
                        .zip(&truth.interreflection.data)
                        .map(|(a, b)| *a && *b)
                        .collect(),
                };
                let rel_ir = if ir_mask.data.iter().any(|v| *v) {
                    relative_rmse(&outcome.reflectance, &truth.albedo, Some(&ir_mask))
                        .unwrap_or(f64::NAN)
                } else {
                    0.0
                };
                let valid = outcome.valid.data.iter().filter(|v| **v).count();
                records.push(Record {
                    scene: name.into(),
                    method: method.name().into(),
                    frames,
                    eta: if estimated { "estimated" } else { "known" }.into(),
                    rel_rmse: rel,
                    rel_rmse_interreflection: rel_ir,
                    coverage: valid as f64 / truth.visible.max(1) as f64,
                    eta_rel_error: (levels.eta - true_levels.eta).abs() / true_levels.eta,
                    black_level_error: (levels.black_level - true_levels.black_level).abs()
                        / true_levels.eta,
                    seconds,
                });
            }
        }
    }
    Ok(records)
}

/// The sim's answers a bench compares against.
struct GroundTruth {
    albedo: showcase_light::RgbImage,
    /// Pixels whose indirect light exceeds 10% of the direct light under
    /// the white projector.
    interreflection: Image<bool>,
    /// Visible object pixels.
    visible: usize,
}

impl GroundTruth {
    fn new(sim: &SimShowcase) -> anyhow::Result<Self> {
        let (albedo, objects) = sim.ground_truth(0)?;
        let mut projector = sim.projector(0)?;
        let d = projector.device().clone();
        projector.show(&Image::new(d.width, d.height, Vec3::ONE))?;
        let t = sim.transport(0, 0)?;
        let interreflection = Image {
            width: albedo.width,
            height: albedo.height,
            data: t
                .direct
                .data
                .iter()
                .zip(&t.indirect.data)
                .map(|(d, i)| i.element_sum() > 0.1 * d.element_sum())
                .collect(),
        };
        Ok(Self {
            albedo,
            interreflection,
            visible: objects.data.iter().filter(|o| o.is_some()).count(),
        })
    }
}

/// Write `records.json`, `report.md` (a table) and `report.svg` (error
/// against time, log-log, one line per scene, method and eta mode) into
/// `dir`.
pub fn write_report(records: &[Record], dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(
        dir.join("records.json"),
        serde_json::to_string_pretty(records)?,
    )?;
    let mut md = String::from(
        "# Reflectance bench\n\n| scene | method | eta | frames | rel_rmse | rel_rmse_interreflection | coverage | eta_rel_error | black_level_error | seconds |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in records {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.4} | {:.4} | {:.3} | {:.4} | {:.4} | {:.3} |",
            r.scene,
            r.method,
            r.eta,
            r.frames,
            r.rel_rmse,
            r.rel_rmse_interreflection,
            r.coverage,
            r.eta_rel_error,
            r.black_level_error,
            r.seconds
        );
    }
    std::fs::write(dir.join("report.md"), md)?;
    std::fs::write(dir.join("report.svg"), svg_plot(records))?;
    Ok(())
}

/// A log-log SVG plot of `rel_rmse` against `seconds`, one line per scene,
/// method and eta mode.
pub fn svg_plot(records: &[Record]) -> String {
    let mut series: Vec<Series> = Vec::new();
    for r in records {
        let name = format!("{} {} eta {}", r.scene, r.method, r.eta);
        let point = Point {
            tooltip: format!("{name}, {} frames", r.frames),
            ..Point::at(r.seconds, r.rel_rmse)
        };
        match series.iter_mut().find(|s| s.name == name) {
            Some(s) => s.points.push(point),
            None => series.push(Series {
                name,
                colour: series_colour(series.len()).into(),
                joined: true,
                points: vec![point],
            }),
        }
    }
    Plot {
        title: "Reflectance error against capture time".into(),
        x_label: "seconds".into(),
        y_label: "rel_rmse".into(),
        series,
        note: String::new(),
        ..Plot::default()
    }
    .to_svg()
}
