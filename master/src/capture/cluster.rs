//! Capture through the cluster: the unchanged pipeline
//! ([`super::pipeline`]) on a [`RemoteProjector`] and a [`RemoteCamera`],
//! which send patterns and capture requests to a projector node and a
//! camera node through the running master ([`CaptureLink`]); the job
//! ([`run_cluster_capture`]) fits eta on the reference target, captures by
//! each method asked, writes each map as soon as it is done (a later
//! failure keeps them), and publishes the maps to the cluster (a scene
//! version bump; later joiners get them in their snapshot).
//! [`loopback_capture`](crate::cluster::capture_loopback::loopback_capture) runs it all on one machine: the master and sim
//! nodes as tasks talking QUIC over loopback.

use super::pipeline::{
    CaptureConfig, EtaMode, Method, ProjectorLevels, adjust_camera_gain, calibrate_projector,
    capture_map,
};
use super::{files::write_reflectance_map, scenes};
use crate::cluster::capture_link::CaptureLink;
use anyhow::Context;
use glam::Vec3;
use serde::Serialize;
use showcase_light::hardware::{CameraDevice, CameraFrame, ProjectorDevice, pattern_of};
use showcase_light::reflectance::ReflectanceMap;
use showcase_light::sim::{SimConfig, SimShowcase};
use showcase_light::{Image, RgbImage};
use showcase_proto::capture::{CaptureFrames, CapturedMap, Pattern};
use showcase_proto::{CameraResponse, PinholeDevice, Role, Showcase};
use showcase_render::camera::Levels;
use std::path::Path;
use std::time::{Duration, Instant};

/// Why a remote device failed: the words say what to change.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct RemoteError(String);

impl From<anyhow::Error> for RemoteError {
    fn from(e: anyhow::Error) -> Self {
        RemoteError(format!("{e:#}"))
    }
}

/// A projector node seen from the master.
pub struct RemoteProjector {
    link: CaptureLink,
    node: String,
    device: PinholeDevice,
    period_s: f64,
    /// Patterns shown.
    pub shown: u64,
}

impl RemoteProjector {
    /// Projector node `node`, driving the scene's `projector`.
    pub fn new(link: CaptureLink, node: &str, projector: &showcase_proto::Projector) -> Self {
        let r = &projector.response;
        Self {
            link,
            node: node.into(),
            device: projector.device.clone(),
            period_s: if r.wheel_segments.is_empty() {
                0.0
            } else {
                r.wheel_period_s as f64
            },
            shown: 0,
        }
    }
}

impl ProjectorDevice for RemoteProjector {
    type Error = RemoteError;
    fn device(&self) -> &PinholeDevice {
        &self.device
    }
    fn show(&mut self, image: &RgbImage) -> Result<(), RemoteError> {
        let p = pattern_of(image).ok_or_else(|| {
            RemoteError(format!(
                "projector node {:?}: the image is neither one level nor a mask of one level; send it as a pattern",
                self.node
            ))
        })?;
        self.show_pattern(&p)
    }
    fn show_pattern(&mut self, pattern: &Pattern) -> Result<(), RemoteError> {
        self.link.show(&self.node, pattern.clone())?;
        self.shown += 1;
        Ok(())
    }
    fn wheel_period_s(&self) -> f64 {
        self.period_s
    }
}

/// A camera node seen from the master: exposure and gain fixed by the
/// master's calibration, sent with every request.
pub struct RemoteCamera {
    link: CaptureLink,
    node: String,
    device: PinholeDevice,
    response: CameraResponse,
    check_exposure: bool,
    /// Frames received.
    pub frames: u64,
    /// Bytes of codes received.
    pub bytes: u64,
}

impl RemoteCamera {
    /// Camera node `node`, driving the scene's `camera`.
    pub fn new(link: CaptureLink, node: &str, camera: &showcase_proto::Camera) -> Self {
        Self {
            link,
            node: node.into(),
            device: camera.device.clone(),
            response: camera.response.clone(),
            check_exposure: true,
            frames: 0,
            bytes: 0,
        }
    }

    /// Without [`check_exposure`] on each frame: for a job that judges its
    /// frames itself (structured light's black reference is dark by
    /// design, and its automatic exposure must see a clipped white to
    /// shorten it).
    pub fn without_exposure_check(mut self) -> Self {
        self.check_exposure = false;
        self
    }
}

/// The share of pixels a frame may have at full scale before the capture
/// is called saturated.
pub const MAX_SATURATED: f64 = 0.01;
/// The brightest code, as a share of full scale, below which a frame is
/// called dark.
pub const MIN_PEAK: f64 = 0.01;

/// `Err` with what to change when `frame` is saturated or dark, measured
/// as every camera frame is ([`Levels`]; the peak is the brightest pixel).
pub fn check_exposure(frame: &CameraFrame, node: &str, gain: f64) -> Result<(), String> {
    let levels = Levels::of(frame, 0.0);
    if levels.saturated_fraction > MAX_SATURATED {
        return Err(format!(
            "camera node {node:?}: the capture is saturated ({:.1} % of pixels at full scale): lower the camera gain ({gain:.4}) or exposure in its calibration",
            100.0 * levels.saturated_fraction
        ));
    }
    let peak = f64::from(levels.peak) / f64::from(levels.top);
    if peak < MIN_PEAK {
        return Err(format!(
            "camera node {node:?}: the capture is dark (brightest pixel at {:.2} % of full scale): check that the projector node lights what the camera sees, or raise the gain ({gain:.4}) or exposure",
            100.0 * peak
        ));
    }
    Ok(())
}

impl CameraDevice for RemoteCamera {
    type Error = RemoteError;
    fn device(&self) -> &PinholeDevice {
        &self.device
    }
    fn response(&self) -> &CameraResponse {
        &self.response
    }
    fn capture(&mut self, _start_s: f64, exposure_s: f64) -> Result<CameraFrame, RemoteError> {
        // The node's camera starts when it is asked: one frame.
        self.capture_series(exposure_s, 0.0, 1)?
            .pop()
            .ok_or_else(|| RemoteError("no frame came back".into()))
    }
    fn capture_series(
        &mut self,
        exposure_s: f64,
        period_s: f64,
        count: u32,
    ) -> Result<Vec<CameraFrame>, RemoteError> {
        let request = CaptureFrames {
            id: 0,
            exposure_s,
            gain: self.response.gain as f64,
            period_s,
            count,
        };
        let size = (self.device.width, self.device.height);
        let frames = self.link.capture(&self.node, request, size)?;
        let mut out = Vec::with_capacity(frames.len());
        for f in frames {
            let frame = CameraFrame {
                codes: Image {
                    width: f.width,
                    height: f.height,
                    data: f.codes,
                },
                bits: f.bits,
            };
            if self.check_exposure {
                check_exposure(&frame, &self.node, request.gain).map_err(RemoteError)?;
            }
            self.frames += 1;
            self.bytes += frame.codes.data.len() as u64 * 6;
            out.push(frame);
        }
        Ok(out)
    }
}

/// A map as the scene snapshot carries it.
pub fn captured_map(name: &str, map: &ReflectanceMap) -> CapturedMap {
    CapturedMap {
        name: name.into(),
        camera: map.camera.clone(),
        reflectance: map.reflectance.data.iter().map(|v| v.to_array()).collect(),
        weight: map.weight.data.clone(),
        depth: map.depth.data.clone(),
        object: map
            .object
            .data
            .iter()
            .map(|o| o.unwrap_or(u32::MAX))
            .collect(),
        object_transforms: map
            .object_transforms
            .iter()
            .map(|m| m.to_cols_array())
            .collect(),
    }
}

/// Every map in the folder `dir` (what `capture --out DIR` wrote), as the
/// scene snapshot carries them, each checked as a node would check it.
pub fn captured_maps_in(dir: &Path) -> anyhow::Result<Vec<CapturedMap>> {
    use showcase_proto::Validate;
    super::files::read_reflectance_maps(dir)?
        .into_iter()
        .map(|(name, map)| {
            let m = captured_map(&name, &map);
            m.validate().with_context(|| {
                format!(
                    "{}: reflectance map {name:?} cannot be sent to the nodes",
                    dir.display()
                )
            })?;
            Ok(m)
        })
        .collect()
}

/// A map as the scene snapshot carries it, back as the light transport
/// uses it ([`captured_map`]'s inverse). The message was validated on
/// arrival (sizes, finite values); what is checked here again names the
/// map.
pub fn reflectance_map(map: &CapturedMap) -> anyhow::Result<ReflectanceMap> {
    let (w, h) = (map.camera.width, map.camera.height);
    let n = w as usize * h as usize;
    anyhow::ensure!(
        [
            map.reflectance.len(),
            map.weight.len(),
            map.depth.len(),
            map.object.len()
        ]
        .iter()
        .all(|len| *len == n),
        "reflectance map {:?}: its images do not all have the camera's {w}x{h} pixels",
        map.name
    );
    fn image<T>(width: u32, height: u32, data: Vec<T>) -> Image<T> {
        Image {
            width,
            height,
            data,
        }
    }
    Ok(ReflectanceMap {
        reflectance: image(
            w,
            h,
            map.reflectance.iter().map(|v| Vec3::from(*v)).collect(),
        ),
        weight: image(w, h, map.weight.clone()),
        depth: image(w, h, map.depth.clone()),
        object: image(
            w,
            h,
            map.object
                .iter()
                .map(|o| (*o != u32::MAX).then_some(*o))
                .collect(),
        ),
        camera: map.camera.clone(),
        object_transforms: map
            .object_transforms
            .iter()
            .map(glam::DMat4::from_cols_array)
            .collect(),
    })
}

/// Settings of a capture through the cluster.
#[derive(Clone, Debug)]
pub struct ClusterCaptureOptions {
    /// Methods, in order; each map is written as soon as it is done.
    pub methods: Vec<Method>,
    /// Frames, eta source, extraction, correction (`method` is ignored).
    pub capture: CaptureConfig,
    /// Sim mode: the master sets the camera gain from the sim as the
    /// in-process capture does, and judges each map against the sim's
    /// true albedo with this sim config's world.
    pub sim: Option<SimConfig>,
    /// Longest wait for the nodes to join.
    pub wait: Duration,
}

/// One method's result.
#[derive(Clone, Debug, Serialize)]
pub struct MethodResult {
    /// The method.
    pub method: String,
    /// Files written.
    pub files: Vec<String>,
    /// Relative RMSE against the true albedo (sim mode), else -1.
    pub rel_rmse: f64,
    /// Fraction of object pixels with a valid reflectance (sim mode).
    pub coverage: f64,
    /// Radiance maps captured.
    pub pieces: usize,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// What a capture through the cluster did (`summary.json`).
#[derive(Clone, Debug, Serialize)]
pub struct ClusterCaptureSummary {
    /// Scene name.
    pub scene: String,
    /// The projector and camera nodes.
    pub nodes: [String; 2],
    /// Eta and black level used.
    pub eta: f64,
    /// Black level (W/sr).
    pub black_level: f64,
    /// `|eta - true| / true` (sim mode), else -1.
    pub eta_rel_error: f64,
    /// Seconds of the eta fit through the nodes.
    pub eta_seconds: f64,
    /// Methods done, in order.
    pub methods: Vec<MethodResult>,
    /// The scene version that carries the maps (0: not published).
    pub published_version: u64,
    /// Frames and bytes that came back over QUIC.
    pub frames: u64,
    /// Bytes of codes.
    pub frame_bytes: u64,
    /// Patterns shown.
    pub patterns: u64,
    /// Why the job stopped early, if it did (the maps done are kept).
    pub error: Option<String>,
    /// Wall-clock seconds of the whole job.
    pub seconds: f64,
}

/// Capture the reflectance of `scene`'s real objects through projector
/// node `projector_node` (the scene's projector 0) and camera node
/// `camera_node` (camera 0), writing `reflectance-<method>.*` and
/// `summary.json` into `out` and publishing the maps on `link`'s cluster.
/// On failure the maps done are kept, `summary.json` says what stopped the
/// job, and the error says what to change.
pub fn run_cluster_capture(
    scene: &Showcase,
    link: &CaptureLink,
    projector_node: &str,
    camera_node: &str,
    out: &Path,
    opts: &ClusterCaptureOptions,
    stage: &dyn Fn(&str),
) -> anyhow::Result<ClusterCaptureSummary> {
    let t0 = Instant::now();
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut summary = ClusterCaptureSummary {
        scene: scene.name.clone(),
        nodes: [projector_node.into(), camera_node.into()],
        eta: 0.0,
        black_level: 0.0,
        eta_rel_error: -1.0,
        eta_seconds: 0.0,
        methods: Vec::new(),
        published_version: 0,
        frames: 0,
        frame_bytes: 0,
        patterns: 0,
        error: None,
        seconds: 0.0,
    };
    let mut maps = Vec::new();
    let result = capture_steps(
        scene,
        link,
        [projector_node, camera_node],
        out,
        opts,
        stage,
        &mut summary,
        &mut maps,
    );
    if !maps.is_empty() {
        stage("publishing the maps to the cluster");
        match link.publish_maps(maps) {
            Ok(v) => summary.published_version = v,
            Err(e) if result.is_ok() => summary.error = Some(format!("{e:#}")),
            Err(_) => {}
        }
    }
    if let Err(e) = &result {
        summary.error = Some(format!("{e:#}"));
    }
    summary.seconds = t0.elapsed().as_secs_f64();
    std::fs::write(
        out.join("summary.json"),
        serde_json::to_string_pretty(&summary)?,
    )?;
    match (result, &summary.error) {
        (Err(e), _) => Err(e.context(format!(
            "capture through the cluster stopped; {} map(s) kept in {}",
            summary.methods.len(),
            out.display()
        ))),
        (Ok(()), Some(e)) => anyhow::bail!("{e}"),
        (Ok(()), None) => Ok(summary),
    }
}

#[allow(clippy::too_many_arguments)]
fn capture_steps(
    scene: &Showcase,
    link: &CaptureLink,
    [pnode, cnode]: [&str; 2],
    out: &Path,
    opts: &ClusterCaptureOptions,
    stage: &dyn Fn(&str),
    summary: &mut ClusterCaptureSummary,
    maps: &mut Vec<CapturedMap>,
) -> anyhow::Result<()> {
    let mut scene = scene.clone();
    anyhow::ensure!(
        !scene.projectors.is_empty() && !scene.cameras.is_empty(),
        "the scene has no projector or no camera: a capture needs both"
    );
    stage("waiting for the projector and camera nodes");
    link.wait_for(
        &[
            (pnode.into(), Role::Projector),
            (cnode.into(), Role::Camera),
        ],
        opts.wait,
    )?;
    let truth = match &opts.sim {
        Some(cfg) => {
            let probe = SimShowcase::new(&scene, cfg.clone())?;
            adjust_camera_gain(&mut scene, &probe)?;
            Some(probe.ground_truth(0)?)
        }
        None => None,
    };
    let mut projector = RemoteProjector::new(link.clone(), pnode, &scene.projectors[0]);
    let mut camera = RemoteCamera::new(link.clone(), cnode, &scene.cameras[0]);
    let config = &opts.capture;
    let t = Instant::now();
    let levels = match config.eta {
        EtaMode::Estimated => {
            stage("fitting eta and the black level on the reference target");
            let reference = scenes::reference_scene(&scene)?;
            link.set_scene(reference.clone())?;
            let fit = calibrate_projector(
                &reference,
                &mut projector,
                &mut camera,
                Vec3::splat(scenes::REFERENCE_ALBEDO),
                scene.projectors[0].response.gamma as f64,
                config.frames,
            );
            // The product back in the showcase, whatever the fit did.
            link.set_scene(scene.clone())?;
            let fit = fit?;
            ProjectorLevels {
                eta: fit.eta,
                black_level: fit.black_level,
            }
        }
        mode => mode.resolve(&scene, || anyhow::bail!("not estimated"))?,
    };
    summary.eta_seconds = t.elapsed().as_secs_f64();
    summary.eta = levels.eta;
    summary.black_level = levels.black_level;
    if opts.sim.is_some() {
        let truth = ProjectorLevels::of(&scene.projectors[0].response);
        summary.eta_rel_error = (levels.eta - truth.eta).abs() / truth.eta;
    }
    let total = opts.methods.len();
    for (i, method) in opts.methods.iter().enumerate() {
        stage(&format!(
            "capturing by the {} method ({}/{total})",
            method.name(),
            i + 1
        ));
        let t = Instant::now();
        let mut c = config.clone();
        c.method = *method;
        let outcome = capture_map(&scene, &mut projector, &mut camera, levels, &c);
        summary.frames = camera.frames;
        summary.frame_bytes = camera.bytes;
        summary.patterns = projector.shown;
        let outcome = outcome?;
        let name = format!("reflectance-{}", method.name());
        let files = write_reflectance_map(out, &name, &outcome.map)?;
        let (rel_rmse, coverage) = match &truth {
            Some((albedo, objects)) => {
                let r = showcase_light::metrics::relative_rmse(
                    &outcome.reflectance,
                    albedo,
                    Some(&outcome.valid),
                )
                .unwrap_or(f64::NAN);
                let visible = objects.data.iter().filter(|o| o.is_some()).count().max(1);
                let valid = outcome.valid.data.iter().filter(|v| **v).count();
                (r, valid as f64 / visible as f64)
            }
            None => (-1.0, -1.0),
        };
        summary.methods.push(MethodResult {
            method: method.name().into(),
            files,
            rel_rmse: showcase_light::finite::finite_or(rel_rmse, -1.0),
            coverage,
            pieces: outcome.pieces,
            seconds: t.elapsed().as_secs_f64(),
        });
        maps.push(captured_map(&name, &outcome.map));
        // Partial results on disk as each method ends.
        std::fs::write(
            out.join("summary.json"),
            serde_json::to_string_pretty(&summary)?,
        )?;
    }
    Ok(())
}
