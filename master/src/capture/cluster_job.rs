//! `capture --config CLUSTER.toml`: the master of the configured cluster
//! runs the capture through its projector and camera nodes
//! ([`super::cluster::run_cluster_capture`]); and `bench capture-cluster`:
//! the loopback cluster's capture against the in-process one, same scene,
//! seeds and sizes, by method (maps' error and wall time).

use super::cluster::{ClusterCaptureOptions, ClusterCaptureSummary, run_cluster_capture};
use super::pipeline::{CaptureConfig, EtaMode, Method};
use super::{CaptureOptions, resize_device, run_capture_with, with_capture_rig};
use crate::cluster::capture_link::CaptureLink;
use crate::cluster::capture_loopback::{CaptureLoopback, loopback_capture};
use crate::cluster::{Server, ServerSettings, Show, Tracking};
use anyhow::{Context, Result, bail};
use serde::Serialize;
use showcase_light::reflectance::CorrectionParams;
use showcase_light::sim::SimConfig;
use showcase_proto::config::ClusterConfig;
use showcase_proto::{Role, Showcase};
use showcase_render::net::ClusterIdentity;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use tokio_util::sync::CancellationToken;

/// Settings of `capture --config`.
#[derive(Clone, Debug)]
pub struct ConfigCaptureOptions {
    /// The cluster configuration.
    pub config: PathBuf,
    /// Output folder.
    pub out: PathBuf,
    /// The job's settings.
    pub capture: ClusterCaptureOptions,
}

/// The `[[node]]` of `role` whose output is `output`.
fn node_for<'a>(cfg: &'a ClusterConfig, role: Role, output: &str) -> Result<&'a str> {
    cfg.nodes
        .iter()
        .find(|n| n.role == role && n.output == output)
        .map(|n| n.name.as_str())
        .with_context(|| {
            format!(
                "the cluster config has no [[node]] with role = \"{role}\" and output = \"{output}\": add one for the capture"
            )
        })
}

/// Run `capture --config`: bind the master, wait for the scene's
/// projector 0 and camera 0 nodes, capture, publish the maps to the
/// connected nodes, stop. `stage` is told each step.
pub fn run_config_capture(
    opts: &ConfigCaptureOptions,
    stage: std::sync::Arc<dyn Fn(&str) + Send + Sync>,
) -> Result<ClusterCaptureSummary> {
    let text = std::fs::read_to_string(&opts.config)
        .with_context(|| format!("cannot read cluster config {}", opts.config.display()))?;
    let label = opts.config.display().to_string();
    let cfg = ClusterConfig::parse(&text, &label)?;
    let base = opts.config.parent().unwrap_or(Path::new("."));
    let scene = crate::scene_file::load_any(&crate::scene_file::resolve(base, &cfg.master.scene))?;
    let (Some(projector), Some(camera)) = (scene.projectors.first(), scene.cameras.first()) else {
        bail!(
            "the scene {} has no projector or no camera: a capture needs both",
            cfg.master.scene.display()
        );
    };
    let pnode = node_for(&cfg, Role::Projector, &projector.name)?.to_string();
    let cnode = node_for(&cfg, Role::Camera, &camera.name)?.to_string();
    with_config_master(&cfg, base, scene.clone(), &|s| stage(s), |link| {
        run_cluster_capture(
            &scene,
            link,
            &pnode,
            &cnode,
            &opts.out,
            &opts.capture,
            &|s| stage(s),
        )
    })
}

/// Bind the master of `cfg` (whose folder is `base`) serving `scene`,
/// its frame clock held, run `job` on its capture link on this thread,
/// then let the nodes get what the job published and stop the master:
/// the start-up every job through the configured cluster's nodes shares
/// (`capture --config`, `calibrate --structured-light --config`). `stage`
/// is told where the master listens.
pub fn with_config_master<T>(
    cfg: &ClusterConfig,
    base: &Path,
    scene: Showcase,
    stage: &dyn Fn(&str),
    job: impl FnOnce(&CaptureLink) -> Result<T>,
) -> Result<T> {
    let listen = showcase_render::net::resolve(&cfg.master.listen, "master.listen")?;
    let identity = ClusterIdentity::load(&base.join(&cfg.master.certs), crate::certs::MASTER_FILE)?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let (link, commands) = CaptureLink::new(Duration::from_secs(600));
    let (master, stop) = {
        let _inside = runtime.enter();
        let server = Server::bind(ServerSettings::capture(
            listen,
            identity,
            crate::cluster::Roster::from_config(cfg),
            // The frame clock is held while the nodes capture.
            cfg.nodes.len(),
        ))?
        .capture_from(commands);
        stage(&format!("master listening on {}", server.local_addr()));
        let stop = CancellationToken::new();
        let show = Show::new(Tracking::None, cfg.master.target_hz as f64);
        (runtime.spawn(server.run(scene, show, stop.clone())), stop)
    };
    // The master's tasks run on the runtime's workers while the job
    // blocks this thread on its requests.
    let result = job(&link);
    runtime.block_on(async {
        // Let the nodes get a published snapshot before the Bye.
        tokio::time::sleep(Duration::from_millis(200)).await;
        stop.cancel();
        let _ = tokio::time::timeout(Duration::from_secs(10), master).await;
    });
    result
}

/// One record of `bench capture-cluster`: one method captured in process
/// and through the loopback cluster, same scene, seeds and sizes.
#[derive(Clone, Debug, Serialize)]
pub struct ClusterCaptureRecord {
    /// Scene.
    pub scene: String,
    /// Method.
    pub method: String,
    /// Camera `[width, height]`.
    pub camera: [u32; 2],
    /// Projector `[width, height]`.
    pub projector: [u32; 2],
    /// Paths per pixel of the sim.
    pub samples_per_pixel: u32,
    /// Frames per radiance map.
    pub frames: u32,
    /// Rel RMSE against the true albedo, in process.
    pub rel_rmse_in_process: f64,
    /// Rel RMSE against the true albedo, through the cluster.
    pub rel_rmse_cluster: f64,
    /// `|cluster - in process|` (target: at most 0.002).
    pub rel_rmse_diff: f64,
    /// Eta, in process and through the cluster.
    pub eta: [f64; 2],
    /// Wall seconds of the in-process capture job (eta fit included).
    pub seconds_in_process: f64,
    /// Wall seconds of the cluster capture job (eta fit, patterns,
    /// frames over QUIC, publishing the maps).
    pub seconds_cluster: f64,
    /// `seconds_cluster / seconds_in_process` (target: at most 2).
    pub time_ratio: f64,
    /// Wall seconds of the whole loopback run: certificates, the master
    /// and the nodes started and stopped, the job.
    pub seconds_cluster_with_start: f64,
    /// Patterns sent to the projector node.
    pub patterns: u64,
    /// Frames that came back.
    pub frames_received: u64,
    /// Bytes of frame codes that came back.
    pub frame_bytes: u64,
}

/// Settings of `bench capture-cluster`.
#[derive(Clone, Debug)]
pub struct ClusterBenchOptions {
    /// The scene (default: the built-in figure 3).
    pub scene: PathBuf,
    /// Camera size.
    pub camera: (u32, u32),
    /// Projector size (`None`: the scene's).
    pub projector: Option<(u32, u32)>,
    /// Paths per camera pixel.
    pub samples_per_pixel: u32,
    /// Frames per radiance map.
    pub frames: u32,
    /// Methods.
    pub methods: Vec<Method>,
    /// Scratch folder for the maps.
    pub scratch: PathBuf,
}

impl Default for ClusterBenchOptions {
    fn default() -> Self {
        Self {
            scene: PathBuf::from("builtin:figure3"),
            camera: (128, 96),
            projector: Some((256, 192)),
            samples_per_pixel: 32,
            frames: 16,
            methods: vec![Method::Naive, Method::Piecewise, Method::Corrected],
            scratch: std::env::temp_dir().join(format!(
                "showcase-bench-capture-cluster-{}",
                std::process::id()
            )),
        }
    }
}

/// Run `bench capture-cluster` (eta estimated on the reference target,
/// in process and through the nodes); `progress(k, what)` before record k.
pub fn bench_capture_cluster(
    opts: &ClusterBenchOptions,
    progress: &dyn Fn(usize, &str),
) -> Result<Vec<ClusterCaptureRecord>> {
    let scene = crate::scene_file::load_any(&opts.scene)?;
    let mut scene = with_capture_rig(&scene, Some(opts.camera))?;
    if let Some((w, h)) = opts.projector {
        for p in &mut scene.projectors {
            p.device = resize_device(&p.device, w, h)?;
        }
    }
    let sim = SimConfig {
        samples_per_pixel: opts.samples_per_pixel,
        ..SimConfig::default()
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let mut records = Vec::new();
    for (k, method) in opts.methods.iter().enumerate() {
        progress(k, method.name());
        let config = CaptureConfig {
            frames: opts.frames,
            method: *method,
            eta: EtaMode::Estimated,
            // The nodes' sim traces the reference target as the scene.
            reference_samples: opts.samples_per_pixel,
            correction: CorrectionParams::default(),
            ..CaptureConfig::default()
        };
        let local_dir = opts.scratch.join(format!("{}-in-process", method.name()));
        let local = run_capture_with(
            &scene,
            &local_dir,
            &CaptureOptions {
                camera_size: None,
                samples_per_pixel: opts.samples_per_pixel,
                capture: config.clone(),
            },
        )?;
        let t = Instant::now();
        let r = runtime.block_on(loopback_capture(CaptureLoopback {
            scene: scene.clone(),
            sim: sim.clone(),
            options: ClusterCaptureOptions {
                methods: vec![*method],
                capture: config,
                sim: Some(sim.clone()),
                wait: Duration::from_secs(30),
            },
            out: opts.scratch.join(format!("{}-cluster", method.name())),
            projector: true,
            projector_leaves_after: None,
            late_joiner: false,
            request_timeout: Duration::from_secs(600),
        }))?;
        let with_start = t.elapsed().as_secs_f64();
        let s = r.summary.map_err(|e| anyhow::anyhow!(e))?;
        let m = s.methods.first().context("no method captured")?;
        let p = &scene.projectors[0].device;
        records.push(ClusterCaptureRecord {
            scene: scene.name.clone(),
            method: method.name().into(),
            camera: [opts.camera.0, opts.camera.1],
            projector: [p.width, p.height],
            samples_per_pixel: opts.samples_per_pixel,
            frames: opts.frames,
            rel_rmse_in_process: local.rel_rmse,
            rel_rmse_cluster: m.rel_rmse,
            rel_rmse_diff: (m.rel_rmse - local.rel_rmse).abs(),
            eta: [local.eta, s.eta],
            seconds_in_process: local.seconds.total,
            seconds_cluster: s.seconds,
            time_ratio: s.seconds / local.seconds.total,
            seconds_cluster_with_start: with_start,
            patterns: s.patterns,
            frames_received: s.frames,
            frame_bytes: s.frame_bytes,
        });
    }
    std::fs::remove_dir_all(&opts.scratch).ok();
    Ok(records)
}

/// The structured-light record of `bench capture-cluster`: every
/// projector of the demo cabinet calibrated by Gray codes in process and
/// through the loopback cluster's sim nodes, same seeds and sizes.
#[derive(Clone, Debug, Serialize)]
pub struct StructuredLightClusterRecord {
    /// Scene.
    pub scene: String,
    /// The job (`structured-light`).
    pub method: String,
    /// Camera `[width, height]`.
    pub camera: [u32; 2],
    /// Projectors calibrated.
    pub projectors: usize,
    /// Paths per pixel of the sim.
    pub samples_per_pixel: u32,
    /// Patterns the projector nodes showed.
    pub patterns: u64,
    /// Every calibration through the cluster equals the in-process one.
    pub identical: bool,
    /// The worst projector's held-out RMS against the true projector
    /// through the cluster (px).
    pub true_heldout_px: f64,
    /// Wall seconds of the in-process job.
    pub seconds_in_process: f64,
    /// Wall seconds of the job through the cluster (patterns and frames
    /// over QUIC).
    pub seconds_cluster: f64,
    /// `seconds_cluster / seconds_in_process`.
    pub time_ratio: f64,
    /// Wall seconds of the whole loopback run: certificates, the master
    /// and the nodes started and stopped, the job.
    pub seconds_cluster_with_start: f64,
}

/// Run the structured-light record of `bench capture-cluster` on the demo
/// cabinet with its camera at `camera` and `samples` paths per pixel.
pub fn bench_structured_light_cluster(
    camera: (u32, u32),
    samples: u32,
    scratch: &Path,
) -> Result<StructuredLightClusterRecord> {
    use crate::calibrate::structured_light::{StructuredLightOptions, Targets, calibrate_targets};
    use crate::cluster::capture_loopback::{StructuredLightLoopback, loopback_structured_light};
    let mut scene = crate::scene_file::load_any(&crate::demo::default_scene())?;
    let c = scene
        .cameras
        .first_mut()
        .context("the demo scene has no camera")?;
    c.device = resize_device(&c.device, camera.0, camera.1)?;
    let sim = SimConfig {
        samples_per_pixel: samples,
        ..SimConfig::default()
    };
    let targets = Targets::of_scene(&scene)?;
    let options = StructuredLightOptions::default();
    let t = Instant::now();
    let world = showcase_light::sim::SimShowcase::new(&scene, sim.clone())?;
    let local = calibrate_targets(
        &targets,
        &scratch.join("sl-in-process"),
        &options,
        &mut world.camera(0)?,
        &mut |t| Ok(world.projector(t.index)?),
        true,
        t,
        &|_, _, _, _| {},
    )?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let t = Instant::now();
    let r = runtime.block_on(loopback_structured_light(StructuredLightLoopback {
        scene: scene.clone(),
        sim,
        options,
        out: scratch.join("sl-cluster"),
        wait: Duration::from_secs(30),
        request_timeout: Duration::from_secs(600),
        absent: None,
    }))?;
    let with_start = t.elapsed().as_secs_f64();
    let s = r.summary.map_err(|e| anyhow::anyhow!(e))?;
    let identical = s.projectors.len() == local.projectors.len()
        && s.projectors
            .iter()
            .zip(&local.projectors)
            .all(|(a, b)| a.outcome.calibration == b.outcome.calibration);
    std::fs::remove_dir_all(scratch).ok();
    Ok(StructuredLightClusterRecord {
        scene: scene.name.clone(),
        method: "structured-light".into(),
        camera: [camera.0, camera.1],
        projectors: s.projectors.len(),
        samples_per_pixel: samples,
        patterns: r.patterns_shown,
        identical,
        true_heldout_px: s
            .projectors
            .iter()
            .map(|p| p.sim_true_heldout_px)
            .fold(0.0, f64::max),
        seconds_in_process: local.seconds,
        seconds_cluster: s.seconds,
        time_ratio: s.seconds / local.seconds,
        seconds_cluster_with_start: with_start,
    })
}
