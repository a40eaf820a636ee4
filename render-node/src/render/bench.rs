//! The renderer benchmark (`showcase-master bench render --json`): the
//! bench scene (Cornell walls as the real room, a real bunny, a virtual
//! reflective sphere and a virtual bunny, a moving virtual point light,
//! two observers) in its variants, timed per frame and per pass, with the
//! GPU-versus-CPU and end-to-end consistency errors of each variant.

pub mod floor;

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use glam::{DVec3, Quat, Vec3};
use serde::Serialize;
use showcase_proto::{
    CrtFace, FrameState, Light, LightSource, Material, Mesh, Object, ObjectKind, Observer,
    PinholeDevice, Plane, Pose, Projector, ProjectorResponse, Rect3, Showcase, Transform,
};

use super::RenderError;
use super::compare::{compare_maps, gpu_map_with_reference_state};
use super::face_gpu::{FacePipeline, other_eyes};
use super::gpu_frame::DEFAULT_SHADOW_RES;
use super::passes::{FrameKey, PassList};
use super::projector_gpu::ProjectorPipeline;
use crate::gpu::{GpuContext, wait_idle};
use showcase_light::Image;
use showcase_light::metrics::{percentile, relative_rmse};
use showcase_light::render::IndirectField;
use showcase_light::render::consistency::direct_light_consistency;
use showcase_light::render::face::{eyes_to_fill, face_image_cpu};
use showcase_light::render::frame::FrameScene;
use showcase_light::render::projector::{Occluders, ProjectorOptions, irradiance_map_cpu};

/// One benchmark result (one role, size and scene variant).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Record {
    /// `projector` or `face` (stereo: both eyes of observer 0, each `width x height`).
    pub role: String,
    /// Output width.
    pub width: u32,
    /// Output height.
    pub height: u32,
    /// `full`, `no_virtual_objects`, `single_observer`, `no_reflective` or `static`.
    pub scene_variant: String,
    /// Passes the pass list ran in the timed frames (after the first).
    pub passes_run: Vec<String>,
    /// Median frame time (pass list, shadow views, irradiance map or face
    /// views, GPU idle; no readback), frames submitted whole.
    pub median_ms: f64,
    /// 99th percentile frame time.
    pub p99_ms: f64,
    /// The adapter.
    pub adapter: String,
    /// End-to-end direct-light consistency of the GPU output (relative RMSE).
    pub consistency_rel_rmse_direct: Option<f64>,
    /// GPU against CPU reference, `L` relative RMSE over surface pixels.
    pub gpu_cpu_rel_rmse: Option<f64>,
    /// The same away from silhouette and shadow edges.
    pub gpu_cpu_rel_rmse_off_edges: Option<f64>,
    /// Outlier pixels (> 1 % off) that are not on an edge.
    pub outliers_off_edges: Option<usize>,
    /// Clipped fraction of the first frame.
    pub clipped_fraction: f64,
    /// Median wall time of each step of a drawn frame, each submitted and
    /// waited for separately (a second run of as many frames): `setup`
    /// (CPU work, uploads), the passes, and `readback` (copy to mappable
    /// buffers, map, convert). Empty when every frame was reused.
    pub pass_ms: BTreeMap<String, f64>,
    /// Median of the per-frame sums of `pass_ms`'s steps: a drawn frame
    /// read back, as a node renders it (0 when every frame was reused).
    pub median_with_readback_ms: f64,
    /// Median shadow map layers drawn per drawn frame (a layer whose
    /// light or eye and geometry did not change is kept).
    pub shadow_layers_drawn: f64,
    /// Shadow map texels per side.
    pub shadow_res: u32,
}

/// Per-step times of drawn frames, for [`Record::pass_ms`].
#[derive(Debug, Default)]
struct StepTimes {
    steps: BTreeMap<String, Vec<f64>>,
    totals: Vec<f64>,
    layers: Vec<f64>,
}

impl StepTimes {
    fn add(&mut self, times: &[(&'static str, f64)], readback_ms: f64, layers: u32) {
        for (step, ms) in times {
            self.steps.entry((*step).to_string()).or_default().push(*ms);
        }
        self.steps
            .entry("readback".into())
            .or_default()
            .push(readback_ms);
        self.totals
            .push(times.iter().map(|(_, ms)| ms).sum::<f64>() + readback_ms);
        self.layers.push(f64::from(layers));
    }

    /// (pass_ms, median_with_readback_ms, shadow_layers_drawn)
    fn medians(self) -> (BTreeMap<String, f64>, f64, f64) {
        let median = |v: Vec<f64>| percentile(&v, 50.0).unwrap_or(0.0);
        (
            self.steps
                .into_iter()
                .map(|(k, v)| (k, median(v)))
                .collect(),
            median(self.totals),
            median(self.layers),
        )
    }
}

/// The projector and face variant drawn in global mode
/// ([`BenchOptions::indirect`]).
pub const GLOBAL_VARIANT: &str = "global";

/// The benchmark scenes' variants.
pub const VARIANTS: [&str; 5] = [
    "full",
    "no_virtual_objects",
    "single_observer",
    "no_reflective",
    "static",
];

/// A UV sphere of `radius` around the origin with outward winding.
pub fn uv_sphere(radius: f32, segments: u32, rings: u32) -> Mesh {
    let (segments, rings) = (segments.max(3), rings.max(2));
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            positions.push(n * radius);
            normals.push(n);
        }
    }
    let row = segments + 1;
    let mut triangles = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let (a, b) = (r * row + s, (r + 1) * row + s);
            if r != 0 {
                triangles.push([a, a + 1, b]);
            }
            if r + 1 != rings {
                triangles.push([a + 1, b + 1, b]);
            }
        }
    }
    Mesh {
        positions,
        normals,
        triangles,
        ..Mesh::default()
    }
}

/// The benchmark projector at `width x height`: in front of the open side
/// of the Cornell box, looking in.
pub fn bench_projector(width: u32, height: u32) -> Projector {
    let mut device = PinholeDevice::look_at(
        DVec3::new(0.30, 0.36, -0.75),
        DVec3::new(0.278, 0.22, 0.3),
        DVec3::Y,
        42.0,
        width,
        height,
    );
    device.near = 0.05;
    device.far = 5.0;
    Projector {
        name: "projector-0".into(),
        device,
        response: ProjectorResponse {
            gamma: 2.2,
            eta: 2.0,
            black_level: 0.004,
            ..ProjectorResponse::default()
        },
    }
}

/// The benchmark camera for the consistency check (beside the projector).
pub fn bench_camera(width: u32, height: u32) -> PinholeDevice {
    PinholeDevice::look_at(
        DVec3::new(0.42, 0.30, -0.70),
        DVec3::new(0.27, 0.2, 0.3),
        DVec3::Y,
        45.0,
        width,
        height,
    )
}

/// The bench scene from the Cornell walls (`(name, mesh, albedo)`, in
/// metres) and the bunny mesh (about 10 units tall, as shipped).
pub fn bench_scene(walls: Vec<(String, Mesh, Vec3)>, bunny: Mesh) -> Showcase {
    let mut s = Showcase {
        name: "render bench".into(),
        ambient: Vec3::splat(0.01),
        ..Showcase::default()
    };
    for (name, mesh, albedo) in walls {
        let id = s.add_mesh(mesh);
        s.objects.push(Object {
            name,
            mesh: id,
            material: Material::diffuse(albedo),
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
    }
    let bunny_id = s.add_mesh(bunny);
    s.objects.push(Object {
        name: "bunny".into(),
        mesh: bunny_id,
        material: Material::diffuse(Vec3::new(0.7, 0.6, 0.5)),
        kind: ObjectKind::Real,
        transform: Transform {
            translation: Vec3::new(0.38, 0.0, 0.33),
            rotation: Quat::from_rotation_y(0.4),
            scale: Vec3::splat(0.02),
        },
    });
    s.objects.push(Object {
        name: "virtual bunny".into(),
        mesh: bunny_id,
        material: Material::diffuse(Vec3::new(0.6, 0.6, 0.7)),
        kind: ObjectKind::Virtual,
        transform: Transform {
            translation: Vec3::new(0.15, 0.0, 0.18),
            rotation: Quat::from_rotation_y(-0.8),
            scale: Vec3::splat(0.014),
        },
    });
    let sphere = s.add_mesh(uv_sphere(0.06, 32, 16));
    let mut mirror = Material::diffuse(Vec3::splat(0.9));
    mirror.reflective = true;
    s.objects.push(Object {
        name: "virtual sphere".into(),
        mesh: sphere,
        material: mirror,
        kind: ObjectKind::Virtual,
        transform: Transform {
            translation: Vec3::new(0.22, 0.30, 0.32),
            ..Transform::IDENTITY
        },
    });
    s.lights = vec![bench_light(0.0)];
    for (i, x) in [0.20f32, 0.40].into_iter().enumerate() {
        s.observers.push(Observer {
            name: format!("observer-{i}"),
            head: Pose {
                position: Vec3::new(x, 0.32, -0.55),
                orientation: Quat::from_rotation_y(std::f32::consts::PI),
            },
            ipd: Observer::DEFAULT_IPD,
        });
    }
    s.projectors.push(bench_projector(640, 480));
    s
}

/// The benchmark CRT face at `width x height`: its reflection in the beam
/// splitter is the open front of the Cornell box (the plane `z = 0`), so
/// observers in front of the box look through it into the room.
pub fn bench_face(width: u32, height: u32) -> CrtFace {
    let mirror = Plane::from_point_normal(Vec3::new(0.28, 0.3, -0.25), Vec3::new(0.0, 1.0, 1.0));
    let seen = Rect3 {
        origin: Vec3::new(0.0, 0.48, 0.0),
        right: Vec3::new(0.556, 0.0, 0.0),
        down: Vec3::new(0.0, -0.417, 0.0),
    };
    let n = mirror.normal;
    let vector = |v: Vec3| v - 2.0 * n.dot(v) * n;
    CrtFace {
        name: "face-0".into(),
        screen: Rect3 {
            origin: mirror.reflect_point(seen.origin),
            right: vector(seen.right),
            down: vector(seen.down),
        },
        mirror,
        width,
        height,
        photometry: showcase_proto::CrtPhotometry::nominal(2.2),
    }
}

/// The moving virtual point light at show time `t` (a circle under the
/// ceiling, one turn in about 6 s).
pub fn bench_light(t: f64) -> LightSource {
    let a = t as f32;
    LightSource {
        name: "moving".into(),
        light: Light::Point {
            position: Vec3::new(0.278 + 0.12 * a.cos(), 0.46, 0.28 + 0.12 * a.sin()),
            intensity: Vec3::new(0.05, 0.045, 0.04),
        },
    }
}

/// Frame `n` of a variant of the bench scene (`static` does not move).
pub fn bench_frame(scene: &Showcase, variant: &str, n: u64) -> FrameState {
    let t = if variant == "static" {
        0.0
    } else {
        n as f64 / 60.0
    };
    FrameState {
        frame: n,
        time_s: t,
        scene_version: 1,
        heads: scene.observers.iter().map(|o| o.head).collect(),
        lights: vec![bench_light(t)],
        object_transforms: Vec::new(),
        tracking_time_ns: None,
        illumination_version: None,
    }
}

/// The bench scene adjusted for `variant`.
pub fn variant_scene(scene: &Showcase, variant: &str) -> Showcase {
    let mut s = scene.clone();
    match variant {
        "no_virtual_objects" => s.objects.retain(|o| o.kind == ObjectKind::Real),
        "single_observer" => s.observers.truncate(1),
        "no_reflective" => s
            .objects
            .iter_mut()
            .for_each(|o| o.material.reflective = false),
        _ => {}
    }
    s
}

/// What to run.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Output sizes.
    pub sizes: Vec<(u32, u32)>,
    /// Timed frames per variant (after one warm-up frame).
    pub frames: usize,
    /// Compute the CPU reference and consistency (slow at large sizes).
    pub accuracy: bool,
    /// Shadow map size.
    pub shadow_res: u32,
    /// The projectors' global-illumination correction on the `full`
    /// scene: with it, the projector role also runs the variant `global`
    /// (the `full` scene drawn with this field), to set global mode's
    /// cost beside direct mode's.
    pub indirect: Option<Arc<IndirectField>>,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            sizes: vec![(640, 480), (1024, 768), (1920, 1080)],
            frames: 30,
            accuracy: true,
            shadow_res: DEFAULT_SHADOW_RES,
            indirect: None,
        }
    }
}

/// Benchmark the projector and face roles on `scene` (from
/// [`bench_scene`]) for every size and variant. Frames whose
/// [`FrameKey`] did not change are reused (not drawn).
pub fn bench_render(
    ctx: &GpuContext,
    scene: &Showcase,
    options: &BenchOptions,
) -> Result<Vec<Record>, RenderError> {
    let mut pipeline = ProjectorPipeline::new(&ctx.device, options.shadow_res);
    let mut face_pipeline = FacePipeline::new(&ctx.device, options.shadow_res);
    let mut records = Vec::new();
    let global = options.indirect.as_ref().map(|_| GLOBAL_VARIANT);
    for &(width, height) in &options.sizes {
        for variant in VARIANTS.into_iter().chain(global) {
            let mut s = variant_scene(scene, variant);
            s.projectors = vec![bench_projector(width, height)];
            let projector = s.projectors[0].clone();
            let field = variant_field(variant, options);
            let resolve = |state: &FrameState| resolve_variant(&s, state, field);
            // Warm-up frame (pipeline caches, allocation), then timing.
            let first = resolve(&bench_frame(&s, variant, 0))?;
            let passes = PassList::for_projector(&first);
            let gpu = pipeline.render(ctx, &first, &projector, &passes)?;
            let mut last_key = Some(FrameKey::projector(
                0,
                &bench_frame(&s, variant, 0),
                &passes,
            ));
            let mut times = Vec::with_capacity(options.frames);
            let mut steps = StepTimes::default();
            let mut passes_run = Vec::new();
            let frames = options.frames as u64;
            for n in 1..=2 * frames {
                let state = bench_frame(&s, variant, n);
                let timed = n > frames;
                let start = Instant::now();
                let frame = resolve(&state)?;
                let passes = PassList::for_projector(&frame);
                let key = FrameKey::projector(0, &state, &passes);
                if last_key != Some(key) {
                    let pass_times = pipeline.draw(ctx, &frame, &projector, &passes, timed)?;
                    wait_idle(&ctx.device)?;
                    if timed {
                        // What a node reads back (ProjectorRenderer).
                        let read_start = Instant::now();
                        let _ = pipeline.read_output(ctx)?;
                        let readback = read_start.elapsed().as_secs_f64() * 1e3;
                        steps.add(&pass_times, readback, pipeline.last_layers_drawn());
                    }
                    passes_run = passes.passes.iter().map(|p| p.name().to_string()).collect();
                }
                last_key = Some(key);
                if !timed {
                    times.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
            times.sort_by(f64::total_cmp);
            let (pass_ms, median_with_readback_ms, shadow_layers_drawn) = steps.medians();
            let (mut consistency, mut gpu_cpu, mut off_edges, mut outliers) =
                (None, None, None, None);
            if options.accuracy {
                let occluders = Occluders::new(&first)?;
                let cpu = irradiance_map_cpu(
                    &first,
                    &occluders,
                    &projector,
                    ProjectorOptions::default(),
                )?;
                if let Ok(c) = compare_maps(&gpu, &cpu) {
                    gpu_cpu = Some(c.rel_rmse);
                    off_edges = Some(c.rel_rmse_off_edges);
                    outliers = Some(c.outliers_off_edges);
                }
                // The direct-light check judges direct maps only.
                if field.is_none() {
                    let map = gpu_map_with_reference_state(&gpu, &cpu);
                    let camera = bench_camera(width, height);
                    consistency =
                        direct_light_consistency(&first, &occluders, &projector, &map, &camera)
                            .ok()
                            .map(|r| r.rel_rmse);
                }
            }
            records.push(Record {
                role: "projector".into(),
                width,
                height,
                scene_variant: variant.into(),
                passes_run,
                median_ms: percentile(&times, 50.0).unwrap_or(0.0),
                p99_ms: percentile(&times, 99.0).unwrap_or(0.0),
                adapter: ctx.describe(),
                consistency_rel_rmse_direct: consistency,
                gpu_cpu_rel_rmse: gpu_cpu,
                gpu_cpu_rel_rmse_off_edges: off_edges,
                outliers_off_edges: outliers,
                clipped_fraction: gpu.clipped_fraction,
                pass_ms,
                median_with_readback_ms,
                shadow_layers_drawn,
                shadow_res: options.shadow_res,
            });
        }
        for variant in VARIANTS.into_iter().chain(global) {
            records.push(bench_face_variant(
                ctx,
                &mut face_pipeline,
                scene,
                variant,
                width,
                height,
                options,
            )?);
        }
    }
    Ok(records)
}

/// The global-illumination field `variant` is drawn with: the bench's
/// field for [`GLOBAL_VARIANT`], none for the others.
fn variant_field<'a>(
    variant: &str,
    options: &'a BenchOptions,
) -> Option<&'a std::sync::Arc<showcase_light::render::IndirectField>> {
    options
        .indirect
        .as_ref()
        .filter(|_| variant == GLOBAL_VARIANT)
}

/// `state` of the variant scene `s`, with `field` in global mode.
fn resolve_variant(
    s: &Showcase,
    state: &FrameState,
    field: Option<&std::sync::Arc<showcase_light::render::IndirectField>>,
) -> Result<FrameScene, RenderError> {
    let frame = FrameScene::resolve(s, state)?;
    Ok(match field {
        Some(f) => frame.with_indirect(f.clone()),
        None => frame,
    })
}

/// One face-role record: both eyes of observer 0 at `width x height` each.
fn bench_face_variant(
    ctx: &GpuContext,
    pipeline: &mut FacePipeline,
    scene: &Showcase,
    variant: &str,
    width: u32,
    height: u32,
    options: &BenchOptions,
) -> Result<Record, RenderError> {
    let s = variant_scene(scene, variant);
    let face = bench_face(width, height);
    let eyes_of = |state: &FrameState| {
        let head = state.heads.first().copied().unwrap_or_default();
        Observer::eyes(
            &head,
            s.observers.first().map_or(Observer::DEFAULT_IPD, |o| o.ipd),
        )
        .map(|e| e.as_dvec3())
    };
    let resolve = |state: &FrameState| resolve_variant(&s, state, variant_field(variant, options));
    let state0 = bench_frame(&s, variant, 0);
    let first = resolve(&state0)?;
    // Stereo: each eye also fills its other eye's occlusion shadows.
    let passes = PassList::for_face(&first, other_eyes(&first, 0).len() + 1);
    let eyes = eyes_of(&state0);
    let others0 = other_eyes(&first, 0);
    let images = pipeline.render(ctx, &first, &face, &eyes, &others0, &passes)?;
    let mut last_key = Some(FrameKey::face(0, 0, &state0));
    let mut times = Vec::with_capacity(options.frames);
    let mut steps = StepTimes::default();
    let mut passes_run = Vec::new();
    let frames = options.frames as u64;
    for n in 1..=2 * frames {
        let state = bench_frame(&s, variant, n);
        let timed = n > frames;
        let start = Instant::now();
        let frame = resolve(&state)?;
        let passes = PassList::for_face(&frame, other_eyes(&frame, 0).len() + 1);
        // Everything a face shows: lights, transforms, and the heads.
        let key = FrameKey::face(0, 0, &state);
        if last_key != Some(key) {
            let others = other_eyes(&frame, 0);
            let pass_times = pipeline.draw(
                ctx,
                &frame,
                &face,
                &eyes_of(&state),
                &others,
                &passes,
                timed,
            )?;
            wait_idle(&ctx.device)?;
            if timed {
                let read_start = Instant::now();
                let _ = pipeline.read(ctx)?;
                let readback = read_start.elapsed().as_secs_f64() * 1e3;
                steps.add(&pass_times, readback, pipeline.last_layers_drawn());
            }
            passes_run = passes.passes.iter().map(|p| p.name().to_string()).collect();
        }
        last_key = Some(key);
        if !timed {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    times.sort_by(f64::total_cmp);
    let (pass_ms, median_with_readback_ms, shadow_layers_drawn) = steps.medians();
    let mut gpu_cpu = None;
    if options.accuracy {
        let occluders = Occluders::new(&first)?;
        let filled = eyes_to_fill(&eyes, 0, &others0);
        let cpu = face_image_cpu(&first, &occluders, &face, eyes[0], &filled)?;
        let g = Image {
            width,
            height,
            data: images[0]
                .iter()
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect(),
        };
        let drawn = cpu.state.map(|st| !st.masked);
        gpu_cpu = relative_rmse(&g, &cpu.radiance, Some(&drawn)).ok();
    }
    Ok(Record {
        role: "face".into(),
        width,
        height,
        scene_variant: variant.into(),
        passes_run,
        median_ms: percentile(&times, 50.0).unwrap_or(0.0),
        p99_ms: percentile(&times, 99.0).unwrap_or(0.0),
        adapter: ctx.describe(),
        consistency_rel_rmse_direct: None,
        gpu_cpu_rel_rmse: gpu_cpu,
        gpu_cpu_rel_rmse_off_edges: None,
        outliers_off_edges: None,
        clipped_fraction: 0.0,
        pass_ms,
        median_with_readback_ms,
        shadow_layers_drawn,
        shadow_res: options.shadow_res,
    })
}
