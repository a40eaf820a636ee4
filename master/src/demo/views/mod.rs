//! The demo's rendering stage: the render nodes' outputs at a few frames
//! of the walk, and what each observer sees of them.
//!
//! The outputs come from the renderers the nodes run (the wgpu projector
//! and face renderers; their CPU references when no GPU adapter opens),
//! fed the *calibrated* devices. What the observer sees is then simulated
//! with the *true* devices and the true reflectance
//! ([`showcase_light::observer_view`]): calibration error, projector
//! resolution and device compensation all show up in the comparison with
//! the target (all lighting virtual).

use crate::radiosity_job::live::{Following, LiveScene};
use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use showcase_light::DeviceRays;
use showcase_light::observer_view::complete::{
    CompleteImage, CompleteOptions, CompleteView, complete_view_with_target,
};
use showcase_light::observer_view::{
    MirrorImage, ObserverView, ProjectedLight, crt_drive, observer_view, projector_edge_pixels,
};
use showcase_light::render::cube_map::{DEFAULT_CUBE_RES, cube_maps_cpu};
use showcase_light::render::face::{eyes_to_fill, face_image_cpu_with};
use showcase_light::render::projector::{PixelState, edge_mask};
use showcase_light::render::{
    FrameScene, IndirectField, Occluders, ProjectorOptions, irradiance_map_cpu,
};
use showcase_light::{Image, RgbImage, metrics};
use showcase_proto::{CrtPhotometry, FrameState, PinholeDevice, ProjectorResponse, Showcase};
use showcase_render::gpu::GpuContext;
use showcase_render::node::Renderer;
use showcase_render::render::face_gpu::FaceRenderer;
use showcase_render::render::projector_gpu::ProjectorRenderer;
use std::sync::Arc;

mod camera;
mod images;

pub(super) use camera::{CameraConsistency, camera_consistency};
pub(super) use images::{
    HEAT_MAP_SUFFIX, HEAT_STOPS, HEAT_UNCOVERED, heat_stop_rgb, write_heat_map, write_radiance,
    write_values,
};

/// The live scene of global mode: the nodes' scene `calibrated` (taken to
/// the demo's resolution) meshed at the walk's first state, as the demo's
/// cluster makes it before frame 0; and that state.
pub(super) fn live_scene(calibrated: &Showcase) -> Result<(LiveScene, FrameScene)> {
    let nodes = at_demo_resolution(calibrated)?;
    let first = FrameScene::resolve(
        &nodes,
        &crate::cluster::illumination::initial_state(&nodes, 1),
    )?;
    let scene = LiveScene::new(&first.showcase, &[], &Default::default())
        .context("global mode's solution of the nodes' scene")?;
    Ok((scene, first))
}

/// Global mode's field at each frame the demo judges, as the cluster's
/// solver makes it: one solution of the live scene, updated from the
/// walk's first state to each judged frame in turn (frames in order).
pub(super) struct GlobalFields<'s>(Following<'s>);

impl<'s> GlobalFields<'s> {
    /// The solution at `first`, the state `scene` was made at.
    pub(super) fn start(scene: &'s LiveScene, first: &FrameScene) -> Result<Self> {
        Ok(Self(Following::start(scene, &first.showcase)?))
    }

    /// The field at `frame` (the nodes' scene resolved at a later state).
    pub(super) fn at(&mut self, frame: &FrameScene) -> Result<IndirectField> {
        self.0
            .update(&frame.showcase)?
            .map_err(|e| anyhow::anyhow!("global mode's solution cannot follow the walk: {e}"))?;
        let values = self.0.field(&frame.showcase, &frame.eyes)?;
        Ok(IndirectField::new(
            Arc::new(self.0.mesh()?.clone()),
            &values,
        )?)
    }
}

/// Demo rendering resolutions: a quarter of the pixels of the cabinet's
/// projectors, a CRT face of 320x256 per eye, 320x240 eye views.
pub(super) const PROJECTOR_SCALE: f64 = 0.5;
/// Face size per eye at the demo resolution.
pub(super) const FACE_SIZE: (u32, u32) = (320, 256);
/// The simulated eye camera.
pub(super) const EYE_SIZE: (u32, u32) = (320, 240);
/// Horizontal field of view of the eye camera (degrees).
pub(super) const EYE_FOV_DEG: f64 = 30.0;
/// Shadow map size per view at the demo resolution.
pub(super) const SHADOW_RES: u32 = 512;

/// `scene` with its projectors and cameras scaled by `PROJECTOR_SCALE` (the
/// same view, fewer pixels) and its faces at `FACE_SIZE`.
pub(super) fn at_demo_resolution(scene: &Showcase) -> Result<Showcase> {
    let mut s = scene.clone();
    let devices = s
        .projectors
        .iter_mut()
        .map(|p| &mut p.device)
        .chain(s.cameras.iter_mut().map(|c| &mut c.device));
    for d in devices {
        let w = ((d.width as f64 * PROJECTOR_SCALE).round() as u32).max(1);
        let h = ((d.height as f64 * PROJECTOR_SCALE).round() as u32).max(1);
        *d = crate::capture::resize_device(d, w, h)?;
    }
    for f in &mut s.faces {
        (f.width, f.height) = FACE_SIZE;
    }
    Ok(s)
}

pub(super) use showcase_render::node::observer_in_front as face_observer;

/// What renders the outputs.
pub(super) enum Backend {
    /// The nodes' wgpu renderers.
    Gpu(Box<GpuContext>),
    /// The CPU references, because no adapter opened (the reason).
    Cpu(String),
}

impl Backend {
    pub(super) fn open() -> Self {
        match GpuContext::new_headless() {
            Ok(ctx) => Self::Gpu(Box::new(ctx)),
            Err(e) => Self::Cpu(e.to_string()),
        }
    }

    pub(super) fn describe(&self) -> String {
        match self {
            Self::Gpu(ctx) => format!("wgpu on {}", ctx.describe()),
            Self::Cpu(why) => format!("CPU reference renderers (no GPU adapter: {why})"),
        }
    }
}

/// The render nodes' outputs for one frame.
pub(super) struct Outputs {
    /// Per projector: pixel values in `0..=1`.
    pub projectors: Vec<RgbImage>,
    /// Per projector: its edge mask (silhouette, shadow and
    /// occlusion-shadow edges of the CPU reference map of the same frame,
    /// one pixel wide on each side), where one pixel cannot be right on
    /// both sides.
    pub projector_edges: Vec<Image<bool>>,
    /// Per face serving an observer: `(face index, observer, [left eye,
    /// right eye])` radiance (the face index, not the position in this
    /// list, names the face: a face serving no observer has no entry).
    pub faces: Vec<(usize, usize, [RgbImage; 2])>,
    /// Per projector: the clipped fraction of its CPU reference map of the
    /// same frame.
    pub reference_clipped: Vec<f64>,
    /// Per face (by index): the photometric profile its node encodes the
    /// radiance with at the device boundary (`crt_drive`).
    pub profiles: Vec<CrtPhotometry>,
    /// Per projector (by index): the response its node encodes its values
    /// with at the device boundary ([`ProjectorResponse::encode`]); values
    /// go as they are where it has none.
    pub projector_profiles: Vec<ProjectorResponse>,
}

impl Outputs {
    /// Per projector, the device values its node sends for its values.
    fn device_values(&self) -> Vec<RgbImage> {
        self.projectors
            .iter()
            .enumerate()
            .map(|(i, img)| match self.projector_profiles.get(i) {
                Some(r) if r.photometry.is_some() => img.map(|v| r.encode(*v)),
                _ => img.clone(),
            })
            .collect()
    }
}

fn split_rgba(width: u32, height: u32, rgba: &[[f32; 4]], x0: u32, w: u32) -> RgbImage {
    Image::from_fn(w, height, |x, y| {
        let p = rgba[(y * width + x0 + x) as usize];
        Vec3::new(p[0], p[1], p[2])
    })
}

/// The renderers of every output of a scene, as the nodes run them.
pub(super) struct NodeRenderers {
    scene: Arc<Showcase>,
    /// Per projector, the response its node encodes with (the renderers'
    /// scene has none: [`Outputs::device_values`] applies it).
    projector_profiles: Vec<ProjectorResponse>,
    kind: RenderersKind,
    /// The projectors' global-illumination correction, if any.
    indirect: Option<Arc<IndirectField>>,
    /// The projectors' CPU reference settings.
    projector_options: ProjectorOptions,
}

enum RenderersKind {
    Gpu {
        projectors: Vec<ProjectorRenderer>,
        faces: Vec<(usize, usize, FaceRenderer)>,
    },
    Cpu,
}

impl NodeRenderers {
    /// One renderer per projector and per face of `scene` (calibrated
    /// devices); each face serves the observer in front of its mirror.
    pub(super) fn new(backend: &Backend, scene: Arc<Showcase>) -> Result<Self> {
        const VERSION: u64 = 1;
        // The renderers draw the model's values; each projector's profile
        // is applied where its values leave for the device
        // ([`Outputs::device_values`]), so a state can swap it.
        let projector_profiles = scene
            .projectors
            .iter()
            .map(|p| p.response.clone())
            .collect();
        let scene = if scene
            .projectors
            .iter()
            .any(|p| p.response.photometry.is_some())
        {
            let mut s = (*scene).clone();
            for p in &mut s.projectors {
                p.response.photometry = None;
            }
            Arc::new(s)
        } else {
            scene
        };
        let kind = match backend {
            Backend::Gpu(ctx) => {
                let mut projectors = Vec::new();
                for i in 0..scene.projectors.len() {
                    let mut r = ProjectorRenderer::new((**ctx).clone(), i, SHADOW_RES);
                    r.set_scene(VERSION, scene.clone())?;
                    projectors.push(r);
                }
                let mut faces = Vec::new();
                for f in 0..scene.faces.len() {
                    let Some(observer) = face_observer(&scene, f) else {
                        continue;
                    };
                    let mut r = FaceRenderer::new((**ctx).clone(), f, observer, SHADOW_RES);
                    r.set_scene(VERSION, scene.clone())?;
                    faces.push((f, observer, r));
                }
                RenderersKind::Gpu { projectors, faces }
            }
            Backend::Cpu(_) => RenderersKind::Cpu,
        };
        Ok(Self {
            scene,
            projector_profiles,
            kind,
            indirect: None,
            projector_options: ProjectorOptions::default(),
        })
    }

    /// Draw the projectors without occlusion shadows (the CPU references
    /// only: the GPU renderers always draw them).
    pub(super) fn without_occlusion_shadows(&mut self) -> Result<()> {
        anyhow::ensure!(
            matches!(self.kind, RenderersKind::Cpu),
            "the GPU projector renderer always draws occlusion shadows"
        );
        self.projector_options.occlusion = false;
        Ok(())
    }

    /// Draw the projectors and the faces in global mode with `field`.
    pub(super) fn set_indirect(&mut self, field: Arc<IndirectField>) {
        if let RenderersKind::Gpu { projectors, faces } = &mut self.kind {
            for r in projectors {
                r.set_indirect(Some(field.clone()));
            }
            for (_, _, r) in faces {
                r.set_indirect(Some(field.clone()));
            }
        }
        self.indirect = Some(field);
    }

    /// Render every output for `state` (its scene version is taken as the
    /// renderers').
    pub(super) fn render(&mut self, state: &FrameState) -> Result<Outputs> {
        let state = FrameState {
            scene_version: 1,
            ..state.clone()
        };
        let scene = &self.scene;
        let mut out = Outputs {
            projectors: Vec::new(),
            projector_edges: Vec::new(),
            faces: Vec::new(),
            reference_clipped: Vec::new(),
            profiles: scene.faces.iter().map(|f| f.photometry).collect(),
            projector_profiles: self.projector_profiles.clone(),
        };
        let mut frame = FrameScene::resolve(scene, &state)?;
        if let Some(field) = &self.indirect {
            frame = frame.with_indirect(field.clone());
        }
        let occluders = Occluders::new(&frame)?;
        let mut maps = Vec::new();
        for p in &scene.projectors {
            let map = irradiance_map_cpu(&frame, &occluders, p, self.projector_options)?;
            out.projector_edges
                .push(projector_edges(scene, &occluders, p, &map.state)?);
            out.reference_clipped.push(map.clipped_fraction);
            maps.push(map);
        }
        match &mut self.kind {
            RenderersKind::Gpu { projectors, faces } => {
                for r in projectors {
                    let o = r.render(&state, scene)?;
                    let img = o.image.context("the projector renderer kept no image")?;
                    out.projectors
                        .push(split_rgba(img.width, img.height, &img.rgba, 0, img.width));
                }
                for (f, observer, r) in faces {
                    let o = r.render(&state, scene)?;
                    let img = o.image.context("the face renderer kept no image")?;
                    let w = img.width / 2;
                    out.faces.push((
                        *f,
                        *observer,
                        [
                            split_rgba(img.width, img.height, &img.rgba, 0, w),
                            split_rgba(img.width, img.height, &img.rgba, w, w),
                        ],
                    ));
                }
            }
            RenderersKind::Cpu => {
                out.projectors = maps.into_iter().map(|m| m.value).collect();
                // The maps depend on the lights and the real room, not
                // on the eye: one set serves every face and eye.
                let cube_maps = cube_maps_cpu(&frame, &occluders, DEFAULT_CUBE_RES)?;
                for (f, face) in scene.faces.iter().enumerate() {
                    let Some(observer) = face_observer(scene, f) else {
                        continue;
                    };
                    let eyes = eyes_of(scene, &state, observer);
                    let others: Vec<DVec3> = (0..state.heads.len())
                        .filter(|&o| o != observer)
                        .flat_map(|o| eyes_of(scene, &state, o))
                        .collect();
                    let draw = |k: usize| {
                        let filled = eyes_to_fill(&eyes, k, &others);
                        face_image_cpu_with(&frame, &occluders, face, eyes[k], &filled, &cube_maps)
                    };
                    let (l, r) = (draw(0)?, draw(1)?);
                    out.faces.push((f, observer, [l.radiance, r.radiance]));
                }
            }
        }
        Ok(out)
    }
}

/// The edge mask of `projector`'s map (its per-pixel `state`): silhouette,
/// shadow and occlusion-shadow edges, and blend seams (a change of which
/// projectors see the pixel centre's surface, where this projector's
/// share jumps), one pixel wide on each side.
fn projector_edges(
    scene: &Showcase,
    occluders: &Occluders,
    projector: &showcase_proto::Projector,
    state: &Image<PixelState>,
) -> Result<Image<bool>> {
    let rays = DeviceRays::new(&projector.device)?;
    let all: Vec<DeviceRays> = scene
        .projectors
        .iter()
        .map(|p| DeviceRays::new(&p.device))
        .collect::<Result<_, _>>()?;
    let mut keyed = state.clone();
    keyed.data.par_iter_mut().enumerate().for_each(|(i, s)| {
        let (x, y) = (i as u32 % state.width, i as u32 / state.width);
        let Some(ray) = rays.pixel_ray(x, y) else {
            return;
        };
        let Some(hit) = occluders.real_only.closest_hit(&ray, 0.0, f64::INFINITY) else {
            return;
        };
        let facing = hit.facing_normal(ray.direction);
        // Which projectors see the point, in bits the light samples leave
        // free (at most 64 samples, a handful of projectors).
        let seen = all
            .iter()
            .enumerate()
            .filter(|(_, a)| a.sees(&occluders.real_only, hit.point, facing))
            .fold(0u64, |b, (j, _)| b | 1u64.rotate_right(1 + j as u32));
        s.lit ^= seen;
    });
    Ok(edge_mask(&keyed, 1, false))
}

fn eyes_of(scene: &Showcase, state: &FrameState, observer: usize) -> [DVec3; 2] {
    let ipd = scene
        .observers
        .get(observer)
        .map_or(showcase_proto::Observer::DEFAULT_IPD, |o| o.ipd);
    let head = state.heads.get(observer).copied().unwrap_or_default();
    showcase_proto::Observer::eyes(&head, ipd).map(|e| e.as_dvec3())
}

/// The left eye's camera of `observer` at `state`, looking where the head
/// looks.
pub(super) fn eye_camera(
    scene: &Showcase,
    state: &FrameState,
    observer: usize,
) -> showcase_proto::PinholeDevice {
    let head = state.heads.get(observer).copied().unwrap_or_default();
    let eye = eyes_of(scene, state, observer)[0];
    let forward = (head.orientation * glam::Vec3::NEG_Z).as_dvec3();
    let up = (head.orientation * glam::Vec3::Y).as_dvec3();
    let mut cam = showcase_proto::PinholeDevice::look_at(
        eye,
        eye + forward,
        up,
        EYE_FOV_DEG,
        EYE_SIZE.0,
        EYE_SIZE.1,
    );
    cam.near = 0.05;
    cam.far = 10.0;
    cam
}

/// One observer's view at one frame, with its figures.
pub(super) struct ObserverResult {
    pub view: ObserverView,
    /// Exposure that maps the target's 99th-percentile channel to 0.9.
    pub exposure: f64,
    /// CIEDE2000 per covered pixel, at `exposure` (row-major, NaN elsewhere).
    pub delta_e: Vec<f64>,
    /// [`Self::delta_e`] had the mirror shown exactly what the real view
    /// lacks of the target (`max(target - real, 0)` per channel: a CRT
    /// adds light only), anywhere: the floor of any face image under these
    /// projector maps. What is left is real light no CRT can take away
    /// (the real surfaces' own interreflection seen through a virtual
    /// object darker than it) and real surfaces brighter than the target.
    pub delta_e_ideal_crt: Vec<f64>,
    /// Relative RMSE of composite against target over covered pixels off
    /// the edges whose real surface some projector reaches.
    pub rel_rmse: f64,
    /// [`Self::rel_rmse`] over the pixels that show a real surface (the
    /// projectors' share; `None` when none is compared).
    pub rel_rmse_real: Option<f64>,
    /// Over the pixels that show a diffuse virtual object (the CRT image).
    pub rel_rmse_virtual: Option<f64>,
    /// Over the pixels that show a reflective virtual object (the CRT
    /// image's cube-map reflection against the exactly traced one).
    pub rel_rmse_reflective: Option<f64>,
    /// [`Self::rel_rmse`] per object the pixels show (name, value).
    pub rel_rmse_per_object: Vec<(String, f64)>,
    /// Covered pixels whose real surface some projector reaches, over
    /// covered pixels.
    pub reachable_fraction: f64,
    /// [`Self::rel_rmse_real`] over the real-surface pixels the method can
    /// get right by design: also off the surfaces a projector lights from
    /// a pixel on one of its edges (the render crate's projector-role
    /// consistency check leaves these out too), off the pixels next to a
    /// change of reachability, and outside other eyes' occlusion shadows
    /// that the mirror image cannot fill (`None` when none is compared).
    pub rel_rmse_real_comparable: Option<f64>,
    /// [`Self::rel_rmse_real_comparable`] per real object (name, value).
    pub rel_rmse_real_comparable_per_object: Vec<(String, f64)>,
    /// Pixels of [`Self::rel_rmse_real_comparable`] over those of
    /// [`Self::rel_rmse_real`].
    pub comparable_real_fraction: f64,
    /// With complete light transport, the noise over [`Self::rel_rmse`]'s
    /// pixels ([`noise`]).
    pub noise: Option<TruthNoise>,
}

/// Simulate `observer`'s view of `outputs` in the true scene `truth` (at
/// the demo resolution) and compare it with the target.
pub(super) fn observe(
    truth: &Showcase,
    state: &FrameState,
    outputs: &Outputs,
    observer: usize,
    transport: Transport,
) -> Result<ObserverResult> {
    // The face node sends its CRT drive values (its own profile); the
    // true CRT behind the true splitter turns them into light.
    let drive = outputs
        .faces
        .iter()
        .find(|(_, o, _)| *o == observer)
        .and_then(|(f, _, [left, _])| Some((*f, crt_drive(outputs.profiles.get(*f)?, left))));
    let mirror = drive.as_ref().and_then(|(f, drive)| {
        Some(MirrorImage {
            face: truth.faces.get(*f)?,
            drive,
        })
    });
    let cam = eye_camera(truth, state, observer);
    let Simulated {
        view,
        projector_edges,
        complete,
    } = simulate(truth, state, outputs, &cam, mirror, transport)?;
    let exposure = exposure(&view).with_context(|| {
        format!(
            "observer {observer} sees no object at frame {}",
            state.frame
        )
    })?;
    let delta_e_of = |seen: &dyn Fn(usize) -> Vec3| -> Vec<f64> {
        (0..view.target.data.len())
            .map(|i| {
                if !view.covered.data[i] {
                    return f64::NAN;
                }
                let lab = |v: Vec3| metrics::linear_srgb_to_lab(v.as_dvec3() * exposure);
                metrics::delta_e_2000(lab(seen(i)), lab(view.target.data[i])).unwrap_or(f64::NAN)
            })
            .collect()
    };
    let delta_e = delta_e_of(&|i| view.composite.data[i]);
    let delta_e_ideal_crt = delta_e_of(&|i| {
        let (real, target) = (view.real.data[i], view.target.data[i]);
        real + (target - real).max(Vec3::ZERO)
    });
    let mask = Image {
        width: view.covered.width,
        height: view.covered.height,
        data: view
            .covered
            .data
            .iter()
            .zip(&view.edge.data)
            .zip(&view.reachable.data)
            .map(|((c, e), r)| *c && !e && *r)
            .collect(),
    };
    let covered = view.covered.data.iter().filter(|c| **c).count();
    let reachable = view
        .covered
        .data
        .iter()
        .zip(&view.reachable.data)
        .filter(|(c, r)| **c && **r)
        .count();
    let rel_rmse = metrics::relative_rmse(&view.composite, &view.target, Some(&mask))
        .with_context(|| format!("observer {observer} at frame {}", state.frame))?;
    // Pixels of `mask` that show a virtual object (`virtual_`) that is
    // reflective (`reflective`, ignored for real surfaces).
    let part = |virtual_: bool, reflective: bool| {
        let part = Image {
            width: mask.width,
            height: mask.height,
            data: (0..mask.data.len())
                .map(|i| {
                    let v = view.sees_virtual.data[i];
                    mask.data[i]
                        && v == virtual_
                        && (!v || view.sees_reflective.data[i] == reflective)
                })
                .collect(),
        };
        metrics::relative_rmse(&view.composite, &view.target, Some(&part)).ok()
    };
    let rel_rmse_per_object = per_object_rel_rmse(truth, &view, &mask, false);
    let rel_rmse_real = part(false, false);
    let rel_rmse_virtual = part(true, false);
    let rel_rmse_reflective = part(true, true);
    let real_mask = |comparable: bool| Image {
        width: mask.width,
        height: mask.height,
        data: (0..mask.data.len())
            .map(|i| {
                mask.data[i]
                    && !view.sees_virtual.data[i]
                    && (!comparable
                        || !(projector_edges.data[i]
                            || view.reach_edge.data[i]
                            || view.unfillable.data[i]))
            })
            .collect(),
    };
    let comparable = real_mask(true);
    let count = |m: &Image<bool>| m.data.iter().filter(|b| **b).count();
    let comparable_real_fraction =
        count(&comparable) as f64 / count(&real_mask(false)).max(1) as f64;
    let rel_rmse_real_comparable =
        metrics::relative_rmse(&view.composite, &view.target, Some(&comparable)).ok();
    let rel_rmse_real_comparable_per_object = per_object_rel_rmse(truth, &view, &comparable, true);
    let noise = noise(complete.as_ref(), &mask);
    Ok(ObserverResult {
        view,
        exposure,
        delta_e,
        delta_e_ideal_crt,
        rel_rmse,
        rel_rmse_real,
        rel_rmse_virtual,
        rel_rmse_reflective,
        rel_rmse_per_object,
        reachable_fraction: reachable as f64 / covered.max(1) as f64,
        rel_rmse_real_comparable,
        rel_rmse_real_comparable_per_object,
        comparable_real_fraction,
        noise,
    })
}

/// Which light transport the simulated cabinet follows.
#[derive(Clone, Debug)]
pub(in crate::demo) enum Transport {
    /// Direct light only, as paper section 5 assumes (the `_direct`
    /// figures).
    Direct,
    /// Every bounce, path-traced by the simulated showcase (the headline
    /// figures, [`showcase_light::observer_view::complete`]), the targets
    /// traced once per frame and view and kept in the [`Targets`] (the
    /// same whatever the projectors show).
    Complete(CompleteOptions, Arc<Targets>),
}

impl Transport {
    /// Every bounce with `options`, each target traced once.
    pub(in crate::demo) fn complete(options: CompleteOptions) -> Self {
        Self::Complete(options, Arc::default())
    }
}

/// The complete views' targets already traced, by frame and view (the
/// eye's device), to judge another set of node outputs of the same frame
/// without tracing its target again; and their real parts, by frame, view
/// and the projectors' images (a digest), to judge other face outputs
/// under the same projector images (the photometric states) without
/// tracing the real part again.
#[derive(Debug, Default)]
pub(in crate::demo) struct Targets {
    /// Targets by frame and view.
    targets: std::sync::Mutex<std::collections::HashMap<(u64, String), CompleteImage>>,
    /// Real parts by frame, view and projector digest.
    reals: std::sync::Mutex<std::collections::HashMap<(u64, String, u64), CompleteImage>>,
}

/// A digest of the projectors' images, bit for bit, and of the true
/// projectors' own light (the same values light a world of other
/// projectors differently).
fn projector_digest(truth: &Showcase, images: &[RgbImage]) -> u64 {
    let mut h = showcase_light::digest::Fnv64::default();
    for p in &truth.projectors {
        if let Some(c) = &p.response.photometry {
            for v in [c.gamma, c.peak, c.black_level] {
                for x in v.to_array() {
                    h.write(&x.to_bits().to_le_bytes());
                }
            }
        }
    }
    for img in images {
        h.write(&img.width.to_le_bytes());
        for v in &img.data {
            for c in v.to_array() {
                h.write(&c.to_bits().to_le_bytes());
            }
        }
    }
    h.finish()
}

/// One simulated view of the cabinet.
pub(in crate::demo) struct Simulated {
    /// The view; with [`Transport::Complete`] its real part, composite and
    /// target are the complete ones, its masks those of the direct view.
    pub view: ObserverView,
    /// Its pixels lit from a projector pixel on an edge of that
    /// projector's map.
    pub projector_edges: Image<bool>,
    /// The complete images (with their halves, for the noise), with
    /// [`Transport::Complete`].
    pub complete: Option<CompleteView>,
}

/// The noise of a complete view over some pixels, each relative to the
/// target's mean there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::demo) struct TruthNoise {
    /// Of the target alone.
    pub target: f64,
    /// Of `measured - target`, what the figures compare (common random
    /// numbers make it far less than either image's own).
    pub compared: f64,
}

/// The complete images' noise over `mask`; `None` without complete images
/// or for an empty mask.
pub(in crate::demo) fn noise(
    complete: Option<&CompleteView>,
    mask: &Image<bool>,
) -> Option<TruthNoise> {
    let c = complete?;
    Some(TruthNoise {
        target: c.target.noise_rel_rmse(Some(mask)).ok()?,
        compared: c.difference_noise_rel_rmse(Some(mask)).ok()?,
    })
}

/// How far the complete real part's direct light alone is from all of it
/// over `mask` (relative RMSE): the interreflection's share; `None`
/// without complete images or for an empty mask.
pub(in crate::demo) fn interreflection_share(
    complete: Option<&CompleteView>,
    mask: &Image<bool>,
) -> Option<f64> {
    metrics::relative_rmse(&complete?.real.direct, &complete?.real.radiance, Some(mask)).ok()
}

/// What `eye` sees of `outputs` in the true scene `truth` at `state`
/// through the simulated cabinet (`mirror`: the face image reflected to
/// it, if any), with light following `transport`.
pub(in crate::demo) fn simulate(
    truth: &Showcase,
    state: &FrameState,
    outputs: &Outputs,
    eye: &PinholeDevice,
    mirror: Option<MirrorImage<'_>>,
    transport: Transport,
) -> Result<Simulated> {
    let frame = FrameScene::resolve(truth, state)?;
    let occluders = Occluders::new(&frame)?;
    // The projector nodes send device values (their own profiles); the
    // true projectors turn them into light.
    let shown = outputs.device_values();
    let projected: Vec<ProjectedLight<'_>> = truth
        .projectors
        .iter()
        .zip(&shown)
        .map(|(projector, value)| ProjectedLight { projector, value })
        .collect();
    let mut view = observer_view(&frame, &occluders, eye, &projected, mirror)?;
    let edges: Vec<(&showcase_proto::Projector, &Image<bool>)> = truth
        .projectors
        .iter()
        .zip(&outputs.projector_edges)
        .collect();
    let projector_edges = projector_edge_pixels(&occluders, eye, &edges)?;
    let complete = match transport {
        Transport::Direct => None,
        Transport::Complete(options, targets) => {
            let key = (state.frame, format!("{eye:?}"));
            let real_key = (key.0, key.1.clone(), projector_digest(truth, &shown));
            let known = targets
                .targets
                .lock()
                .ok()
                .and_then(|t| t.get(&key).cloned());
            let known_real = targets
                .reals
                .lock()
                .ok()
                .and_then(|t| t.get(&real_key).cloned());
            let c = match (known, known_real) {
                (Some(target), Some(real)) => CompleteView { real, target },
                (known, _) => {
                    let traced = known.is_none();
                    let c = complete_view_with_target(&frame, eye, &projected, options, known)?;
                    if traced && let Ok(mut t) = targets.targets.lock() {
                        t.insert(key, c.target.clone());
                    }
                    if let Ok(mut t) = targets.reals.lock() {
                        t.insert(real_key, c.real.clone());
                    }
                    c
                }
            };
            // Seen through the same glass as the direct view's.
            let t = view.glass.transmission;
            for i in 0..view.covered.data.len() {
                let real = t * c.real.radiance.data[i];
                view.real.data[i] = real;
                view.composite.data[i] = real + view.reflected.data[i];
                view.target.data[i] = if view.covered.data[i] {
                    t * c.target.radiance.data[i]
                } else {
                    Vec3::ZERO
                };
            }
            Some(c)
        }
    };
    Ok(Simulated {
        view,
        projector_edges,
        complete,
    })
}

/// The exposure that maps the 99th percentile of `view`'s target (its
/// largest channel, over covered pixels) to 0.9; `None` when no pixel is
/// covered.
fn exposure(view: &ObserverView) -> Option<f64> {
    let peaks: Vec<f64> = view
        .target
        .data
        .iter()
        .zip(&view.covered.data)
        .filter(|(_, c)| **c)
        .map(|(t, _)| f64::from(t.max_element()))
        .collect();
    let p99 = metrics::percentile(&peaks, 99.0)?;
    Some(if p99 > 0.0 { 0.9 / p99 } else { 1.0 })
}

/// Relative RMSE of `view`'s composite against its target per object of
/// `truth` (by name; only real objects when `real_only`), over the pixels
/// of `mask` whose first surface is that object; objects with no such
/// pixel are left out.
fn per_object_rel_rmse(
    truth: &Showcase,
    view: &ObserverView,
    mask: &Image<bool>,
    real_only: bool,
) -> Vec<(String, f64)> {
    truth
        .objects
        .iter()
        .enumerate()
        .filter(|(_, o)| !real_only || o.kind == showcase_proto::ObjectKind::Real)
        .filter_map(|(i, o)| {
            let part = Image {
                width: mask.width,
                height: mask.height,
                data: mask
                    .data
                    .iter()
                    .zip(&view.first_object.data)
                    .map(|(m, f)| *m && *f == Some(i as u32))
                    .collect(),
            };
            metrics::relative_rmse(&view.composite, &view.target, Some(&part))
                .ok()
                .map(|e| (o.name.clone(), e))
        })
        .collect()
}
