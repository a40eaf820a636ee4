//! `showcase-master calibrate --structured-light --config CLUSTER.toml`:
//! every projector of the cluster calibrated by structured light, seen by
//! the cluster's camera, on the simulated showcase of the config's scene
//! (no real projector or camera driver is part of this build; the job
//! itself only sees the device traits). Each projector gets the file
//! `calibrate --points` writes, `<out>/<projector>.json`, and the folder a
//! `summary.json`.

use super::bench::{surface_points, true_rms};
use super::{StructuredLightOptions, StructuredLightOutcome, calibrate_structured_light};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use showcase_light::sim::{SimConfig, SimShowcase};
use showcase_light::{ObjectFilter, SceneGeometry};
use showcase_proto::config::ClusterConfig;
use showcase_proto::message::Role;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug)]
pub struct StructuredLightJob {
    /// The cluster configuration: its scene, its camera node and its
    /// projector nodes.
    pub config: PathBuf,
    /// Another scene than the config's.
    pub scene: Option<PathBuf>,
    /// Output folder.
    pub out: PathBuf,
    /// The method's settings.
    pub options: StructuredLightOptions,
    /// Paths per camera pixel of the simulated showcase's light transport
    /// for a full-white projector image.
    pub sim_samples: u32,
}

/// One projector's result.
#[derive(Clone, Debug, Serialize)]
pub struct ProjectorSummary {
    /// The projector.
    pub device: String,
    /// The calibration file written.
    pub file: PathBuf,
    /// The file its node reads, where the config names one.
    pub node_reads: Option<PathBuf>,
    /// How it went.
    pub outcome: StructuredLightOutcome,
    /// Simulated showcase only: RMS pixel distance between the fitted and
    /// the true projector's projections of held-out points where its light
    /// lands on the scene.
    pub sim_true_heldout_px: f64,
    /// Simulated showcase only: the same at the held-out correspondences'
    /// points, inside the camera's view (no extrapolation).
    pub sim_true_heldout_in_view_px: f64,
    /// Seconds for this projector.
    pub seconds: f64,
}

/// The job's `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct StructuredLightSummary {
    /// The scene.
    pub scene: String,
    /// The camera used.
    pub camera: String,
    /// One entry per projector.
    pub projectors: Vec<ProjectorSummary>,
    /// Seconds in all.
    pub seconds: f64,
}

/// Run `job`; `progress(projector, done, total, what)` follows each
/// projector's patterns.
pub fn run_structured_light(
    job: &StructuredLightJob,
    progress: &dyn Fn(&str, usize, usize, &str),
) -> Result<StructuredLightSummary> {
    let start = Instant::now();
    let text = std::fs::read_to_string(&job.config)
        .with_context(|| format!("cannot read cluster config {}", job.config.display()))?;
    let label = job.config.display().to_string();
    let cfg = ClusterConfig::parse(&text, &label)?;
    let base = job.config.parent().unwrap_or(Path::new("."));
    let scene_path = match &job.scene {
        Some(s) => s.clone(),
        None => crate::scene_file::resolve(base, &cfg.master.scene),
    };
    let scene = crate::scene_file::load_any(&scene_path)?;
    let camera_name = match cfg.nodes.iter().find(|n| n.role == Role::Camera) {
        Some(n) => n.output.clone(),
        None => match scene.cameras.first() {
            Some(c) => c.name.clone(),
            None => bail!(
                "{}: the scene has no camera; structured light needs a calibrated camera that sees what the projectors light",
                scene_path.display()
            ),
        },
    };
    let camera_index = scene
        .cameras
        .iter()
        .position(|c| c.name == camera_name)
        .with_context(|| {
            format!(
                "{label}: the camera node drives {camera_name:?}, which {} does not have",
                scene_path.display()
            )
        })?;
    let mut projectors: Vec<(String, Option<PathBuf>)> = cfg
        .nodes
        .iter()
        .filter(|n| n.role == Role::Projector)
        .map(|n| {
            let reads = n
                .calibration
                .as_deref()
                .filter(|c| *c != "scene")
                .map(|c| base.join(c));
            (n.output.clone(), reads)
        })
        .collect();
    if projectors.is_empty() {
        projectors = scene
            .projectors
            .iter()
            .map(|p| (p.name.clone(), None))
            .collect();
    }
    if projectors.is_empty() {
        bail!(
            "{}: the scene has no projector to calibrate",
            scene_path.display()
        );
    }
    let sim = SimShowcase::new(
        &scene,
        SimConfig {
            samples_per_pixel: job.sim_samples.max(1),
            ..SimConfig::default()
        },
    )?;
    let geometry = SceneGeometry::build(&scene, &ObjectFilter::Real)?;
    std::fs::create_dir_all(&job.out)
        .with_context(|| format!("cannot create {}", job.out.display()))?;
    let mut camera = sim.camera(camera_index)?;
    let mut summaries = Vec::new();
    for (name, node_reads) in projectors {
        let t = Instant::now();
        let index = scene
            .projectors
            .iter()
            .position(|p| p.name == name)
            .with_context(|| {
                format!(
                    "{label}: a projector node drives {name:?}, which {} does not have",
                    scene_path.display()
                )
            })?;
        let mut projector = sim.projector(index)?;
        let outcome = calibrate_structured_light(
            &name,
            &mut projector,
            &mut camera,
            &geometry,
            &job.options,
            &|done, total, what| progress(&name, done, total, what),
        )?;
        let file = job.out.join(format!("{name}.json"));
        let json = serde_json::to_string_pretty(&outcome.calibration)
            .context("serialising the calibration")?;
        std::fs::write(&file, json + "\n")
            .with_context(|| format!("writing {}", file.display()))?;
        let truth = &scene.projectors[index].device;
        let points = surface_points(truth, &geometry, 2000, 1);
        summaries.push(ProjectorSummary {
            device: name,
            file,
            node_reads,
            sim_true_heldout_px: true_rms(&outcome.calibration, truth, &points),
            sim_true_heldout_in_view_px: true_rms(
                &outcome.calibration,
                truth,
                &outcome
                    .heldout
                    .iter()
                    .map(|c| glam::DVec3::from_array(c.world))
                    .collect::<Vec<_>>(),
            ),
            outcome,
            seconds: t.elapsed().as_secs_f64(),
        });
    }
    let summary = StructuredLightSummary {
        scene: scene.name.clone(),
        camera: camera_name,
        projectors: summaries,
        seconds: start.elapsed().as_secs_f64(),
    };
    let path = job.out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(summary)
}
