//! `showcase-master calibrate --structured-light --config CLUSTER.toml`:
//! every projector of the cluster calibrated by structured light, seen by
//! the cluster's camera, either through the cluster's nodes (the master
//! of the config listens, its projector nodes show the patterns and its
//! camera node captures them: [`run_config_structured_light`], as
//! `capture --config` does) or on an in-process simulated showcase of the
//! config's scene (`--sim-in-process`: [`run_structured_light`]). Both run
//! the same loop on the device traits ([`calibrate_targets`]). Each
//! projector gets the file `calibrate --points` writes,
//! `<out>/<projector>.json`, and the folder a `summary.json`.

use super::bench::{surface_points, true_rms};
use super::{StructuredLightOptions, StructuredLightOutcome, calibrate_structured_light};
use crate::capture::cluster::{RemoteCamera, RemoteProjector};
use crate::cluster::capture_link::CaptureLink;
use anyhow::{Context, Result, bail};
use serde::Serialize;
use showcase_light::hardware::{CameraDevice, ProjectorDevice};
use showcase_light::sim::{SimConfig, SimShowcase};
use showcase_light::{ObjectFilter, SceneGeometry};
use showcase_proto::Showcase;
use showcase_proto::config::ClusterConfig;
use showcase_proto::message::Role;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

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
    /// Paths per camera pixel of the in-process simulated showcase's light
    /// transport for a full-white projector image (through the nodes, each
    /// camera node's sim has its own).
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
    /// Simulated showcase only (-1 through nodes not in sim mode): RMS
    /// pixel distance between the fitted and the true projector's
    /// projections of held-out points where its light lands on the scene.
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

/// One device of the job: the scene's device and the node driving it.
#[derive(Clone, Debug)]
pub struct Target {
    /// The scene's device (camera or projector name).
    pub device: String,
    /// Its index in the scene's cameras or projectors.
    pub index: usize,
    /// The cluster config's `[[node]]` whose output it is (`None`: the
    /// config has none; only the in-process run does without).
    pub node: Option<String>,
    /// The file its node reads, where the config names one.
    pub node_reads: Option<PathBuf>,
}

/// What a structured-light job calibrates and with which camera.
#[derive(Clone, Debug)]
pub struct Targets {
    /// The scene (the geometry the correspondences land on).
    pub scene: Showcase,
    /// The camera (trusted as calibrated).
    pub camera: Target,
    /// The projectors, in order.
    pub projectors: Vec<Target>,
}

impl Targets {
    /// The camera node and projector nodes of the cluster config at
    /// `config` (without a camera node the scene's first camera; without
    /// projector nodes every projector of the scene), on its scene or
    /// `scene`; with the parsed config.
    pub fn of_config(config: &Path, scene: Option<&Path>) -> Result<(Targets, ClusterConfig)> {
        let text = std::fs::read_to_string(config)
            .with_context(|| format!("cannot read cluster config {}", config.display()))?;
        let label = config.display().to_string();
        let cfg = ClusterConfig::parse(&text, &label)?;
        let base = config.parent().unwrap_or(Path::new("."));
        let scene_path = match scene {
            Some(s) => s.to_path_buf(),
            None => crate::scene_file::resolve(base, &cfg.master.scene),
        };
        let scene = crate::scene_file::load_any(&scene_path)?;
        let camera_node = cfg.nodes.iter().find(|n| n.role == Role::Camera);
        let camera_name = match camera_node {
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
        let camera = Target {
            device: camera_name,
            index: camera_index,
            node: camera_node.map(|n| n.name.clone()),
            node_reads: None,
        };
        let mut projectors: Vec<(String, Option<String>, Option<PathBuf>)> = cfg
            .nodes
            .iter()
            .filter(|n| n.role == Role::Projector)
            .map(|n| {
                let reads = n
                    .calibration
                    .as_deref()
                    .filter(|c| *c != "scene")
                    .map(|c| base.join(c));
                (n.output.clone(), Some(n.name.clone()), reads)
            })
            .collect();
        if projectors.is_empty() {
            projectors = scene
                .projectors
                .iter()
                .map(|p| (p.name.clone(), None, None))
                .collect();
        }
        if projectors.is_empty() {
            bail!(
                "{}: the scene has no projector to calibrate",
                scene_path.display()
            );
        }
        let projectors = projectors
            .into_iter()
            .map(|(name, node, node_reads)| {
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
                Ok(Target {
                    device: name,
                    index,
                    node,
                    node_reads,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok((
            Targets {
                scene,
                camera,
                projectors,
            },
            cfg,
        ))
    }

    /// Every projector of `scene` seen by its first camera, each device
    /// driven by a node of its own name (a loopback cluster's).
    pub fn of_scene(scene: &Showcase) -> Result<Targets> {
        let camera = scene
            .cameras
            .first()
            .context("the scene has no camera; structured light needs one")?;
        anyhow::ensure!(
            !scene.projectors.is_empty(),
            "the scene has no projector to calibrate"
        );
        let target = |device: &str, index| Target {
            device: device.into(),
            index,
            node: Some(device.into()),
            node_reads: None,
        };
        Ok(Targets {
            scene: scene.clone(),
            camera: target(&camera.name, 0),
            projectors: scene
                .projectors
                .iter()
                .enumerate()
                .map(|(i, p)| target(&p.name, i))
                .collect(),
        })
    }
}

/// Run `job` on an in-process simulated showcase of its scene (the
/// `--sim-in-process` path); `progress(projector, done, total, what)`
/// follows each projector's patterns.
pub fn run_structured_light(
    job: &StructuredLightJob,
    progress: &dyn Fn(&str, usize, usize, &str),
) -> Result<StructuredLightSummary> {
    let start = Instant::now();
    let (targets, _) = Targets::of_config(&job.config, job.scene.as_deref())?;
    let sim = SimShowcase::new(
        &targets.scene,
        SimConfig {
            samples_per_pixel: job.sim_samples.max(1),
            ..SimConfig::default()
        },
    )?;
    let mut camera = sim.camera(targets.camera.index)?;
    calibrate_targets(
        &targets,
        &job.out,
        &job.options,
        &mut camera,
        &mut |t| Ok(sim.projector(t.index)?),
        true,
        start,
        progress,
    )
}

/// How a structured-light job runs through the cluster's nodes.
#[derive(Clone, Copy, Debug)]
pub struct ThroughNodes {
    /// Longest wait for the camera and projector nodes to join.
    pub wait: Duration,
    /// The nodes run in sim mode (`showcase-node --sim-light`): judge each
    /// fit against the scene's projector, as the in-process run does.
    pub sim: bool,
}

/// Run `job` through the nodes of its cluster config: listen as the
/// config's master, wait for its camera node and projector nodes, show
/// each projector's patterns on its node and capture them on the camera
/// node. `stage` is told each step, `progress` each pattern.
pub fn run_config_structured_light(
    job: &StructuredLightJob,
    nodes: &ThroughNodes,
    stage: &dyn Fn(&str),
    progress: &dyn Fn(&str, usize, usize, &str),
) -> Result<StructuredLightSummary> {
    let (targets, cfg) = Targets::of_config(&job.config, job.scene.as_deref())?;
    let base = job.config.parent().unwrap_or(Path::new("."));
    crate::capture::cluster_job::with_config_master(
        &cfg,
        base,
        targets.scene.clone(),
        stage,
        |link| {
            run_structured_light_on_nodes(
                link,
                &targets,
                &job.out,
                &job.options,
                nodes,
                stage,
                progress,
            )
        },
    )
}

/// Calibrate `targets`' projectors through the running master's `link`:
/// the patterns shown by each projector's node, captured by the camera's
/// node (the loopback cluster's tests and bench call it directly).
pub fn run_structured_light_on_nodes(
    link: &CaptureLink,
    targets: &Targets,
    out: &Path,
    options: &StructuredLightOptions,
    nodes: &ThroughNodes,
    stage: &dyn Fn(&str),
    progress: &dyn Fn(&str, usize, usize, &str),
) -> Result<StructuredLightSummary> {
    let start = Instant::now();
    let node = |t: &Target, role: Role| {
        t.node.clone().with_context(|| {
            format!(
                "the cluster config has no [[node]] with role = \"{role}\" and output = \"{}\": add one for the calibration",
                t.device
            )
        })
    };
    let camera_node = node(&targets.camera, Role::Camera)?;
    let mut needed = vec![(camera_node.clone(), Role::Camera)];
    for p in &targets.projectors {
        needed.push((node(p, Role::Projector)?, Role::Projector));
    }
    stage("waiting for the camera and projector nodes");
    link.wait_for(&needed, nodes.wait)?;
    let scene = &targets.scene;
    let mut camera = RemoteCamera::new(
        link.clone(),
        &camera_node,
        &scene.cameras[targets.camera.index],
    )
    .without_exposure_check();
    calibrate_targets(
        targets,
        out,
        options,
        &mut camera,
        &mut |t| {
            let node = node(t, Role::Projector)?;
            Ok(RemoteProjector::new(
                link.clone(),
                &node,
                &scene.projectors[t.index],
            ))
        },
        nodes.sim,
        start,
        progress,
    )
}

/// The job's loop on any devices: each target projector (from
/// `projector`) calibrated with `camera`, its file and `summary.json`
/// written to `out`; `judge`: the scene's projectors are the truth (a
/// simulated showcase), else the `sim_true_*` figures are -1.
#[allow(clippy::too_many_arguments)]
pub fn calibrate_targets<C: CameraDevice, P: ProjectorDevice>(
    targets: &Targets,
    out: &Path,
    options: &StructuredLightOptions,
    camera: &mut C,
    projector: &mut dyn FnMut(&Target) -> Result<P>,
    judge: bool,
    start: Instant,
    progress: &dyn Fn(&str, usize, usize, &str),
) -> Result<StructuredLightSummary> {
    let scene = &targets.scene;
    let geometry = SceneGeometry::build(scene, &ObjectFilter::Real)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut summaries = Vec::new();
    for target in &targets.projectors {
        let t = Instant::now();
        let name = &target.device;
        let mut device = projector(target)?;
        let outcome = calibrate_structured_light(
            name,
            &mut device,
            camera,
            &geometry,
            options,
            &|done, total, what| progress(name, done, total, what),
        )?;
        let file = out.join(format!("{name}.json"));
        let json = serde_json::to_string_pretty(&outcome.calibration)
            .context("serialising the calibration")?;
        std::fs::write(&file, json + "\n")
            .with_context(|| format!("writing {}", file.display()))?;
        let (heldout, in_view) = if judge {
            let truth = &scene.projectors[target.index].device;
            let points = surface_points(truth, &geometry, 2000, 1);
            let in_view: Vec<_> = outcome
                .heldout
                .iter()
                .map(|c| glam::DVec3::from_array(c.world))
                .collect();
            (
                true_rms(&outcome.calibration, truth, &points),
                true_rms(&outcome.calibration, truth, &in_view),
            )
        } else {
            (-1.0, -1.0)
        };
        summaries.push(ProjectorSummary {
            device: name.clone(),
            file,
            node_reads: target.node_reads.clone(),
            sim_true_heldout_px: heldout,
            sim_true_heldout_in_view_px: in_view,
            outcome,
            seconds: t.elapsed().as_secs_f64(),
        });
    }
    let summary = StructuredLightSummary {
        scene: scene.name.clone(),
        camera: targets.camera.device.clone(),
        projectors: summaries,
        seconds: start.elapsed().as_secs_f64(),
    };
    let path = out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(summary)
}
