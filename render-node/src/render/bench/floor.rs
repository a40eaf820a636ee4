//! The measured floor of the projector and face roles on an adapter
//! (`showcase-master bench render --floor`): what the bench scene's passes
//! cost with everything but one kind of work taken out. The irradiance
//! pass with a constant fragment (rasterisation and vertex work), a
//! full-screen triangle with a constant fragment (the fill of the
//! targets), the same plus exactly the texel fetches the real fragment
//! shader makes per pixel for the bench scene, and the six light shadow
//! views of the moving light (all objects, occluders only, clears only).
//! No real pass can be cheaper than the floor of the work it must do.

use std::time::Instant;

use serde::Serialize;
use showcase_proto::Showcase;

use super::{BenchOptions, bench_frame, bench_projector};
use crate::gpu::irradiance_map::floor::{FloorBindings, FloorError, FloorKind, FloorPass};
use crate::gpu::shadow_views::occluders::cube_occluder_ranges;
use crate::gpu::shadow_views::{LayerDraw, SHADOW_NEAR, ShadowDraw, ShadowMaps, ShadowViewsPass};
use crate::gpu::target::{ColourReadback, read_colours};
use crate::gpu::upload::UploadBuffer;
use crate::gpu::{GpuContext, OffscreenTarget, wait_idle};
use crate::render::RenderError;
use crate::render::gpu_frame::{SceneBuffers, VertexSet, light_inputs, shadow_far, stable_far};
use showcase_light::metrics::percentile;
use showcase_light::render::frame::FrameScene;

/// Why the floor could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum FloorBenchError {
    /// The bench scene could not be set up or drawn.
    #[error(transparent)]
    Setup(#[from] RenderError),
    /// A GPU operation failed.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    /// A stripped pass could not be recorded.
    #[error(transparent)]
    Pass(#[from] FloorError),
}

/// One floor measurement.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FloorRecord {
    /// `projector` or `face` (stereo: both eyes, each `width x height`).
    pub role: String,
    /// Output width.
    pub width: u32,
    /// Output height.
    pub height: u32,
    /// What was kept: `irradiance_trivial_fragment` (the projector's
    /// geometry, vertex shader, depth test and two targets, a constant
    /// fragment), `full_screen_trivial` (a full-screen triangle, constant
    /// fragment), `full_screen_fetches` (plus `fetches_per_pixel` texel
    /// fetches), `light_shadow_views_all_objects`,
    /// `light_shadow_views_occluders` (the objects that can occlude) and
    /// `light_shadow_views_clear_only` (six layers cleared, nothing drawn),
    /// `readback_copy_only` (both targets copied to mappable buffers),
    /// `readback_one_target` and `readback_two_targets` (copied, mapped
    /// and converted to pixels, as the pipeline's `read` does).
    pub floor: String,
    /// Texel fetches per pixel (`full_screen_fetches`), else 0.
    pub fetches_per_pixel: u32,
    /// Colour targets written per output (RGBA32F).
    pub targets: u32,
    /// Median wall time of the step, submitted and waited for alone.
    pub median_ms: f64,
    /// 99th percentile.
    pub p99_ms: f64,
    /// The adapter.
    pub adapter: String,
    /// Shadow map texels per side.
    pub shadow_res: u32,
}

/// Texel fetches the projector's irradiance-map shader makes per lit
/// surface pixel of `frame` (irradiance_map.wgsl with
/// shadow_lookup.part.wgsl): one shadow-map texel per light sample (its
/// cube face), one per eye (its fitted view or cube face), and the blend
/// weight when the scene has projectors that may overlap.
pub fn projector_fetches(frame: &FrameScene) -> u32 {
    let blend = u32::from(frame.showcase.projectors.len() > 1);
    blend + frame.samples.len() as u32 + frame.eyes.len() as u32
}

/// Texel fetches of the face view's phantom pixel of one eye (face_view.wgsl
/// `fs_phantom`): one per other eye's view and, inside an occlusion
/// shadow, one per light sample. The lit virtual pixel reads one per
/// light sample; a reflective one four cube-map texels.
pub fn face_fetches(frame: &FrameScene) -> u32 {
    frame.eyes.len().saturating_sub(1) as u32 + frame.samples.len() as u32
}

/// Wall time of `frames` submissions of what `record` encodes (after one
/// warm-up), each waited for; (median, p99) in ms.
fn time_steps(
    ctx: &GpuContext,
    frames: usize,
    mut record: impl FnMut(&mut wgpu::CommandEncoder) -> Result<(), FloorBenchError>,
) -> Result<(f64, f64), FloorBenchError> {
    let mut times = Vec::with_capacity(frames);
    for i in 0..=frames {
        let start = Instant::now();
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        record(&mut encoder)?;
        ctx.queue.submit([encoder.finish()]);
        wait_idle(&ctx.device)?;
        if i > 0 {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    times.sort_by(f64::total_cmp);
    Ok((
        percentile(&times, 50.0).unwrap_or(0.0),
        percentile(&times, 99.0).unwrap_or(0.0),
    ))
}

/// Measure the floor of both roles on the bench `scene` (from
/// [`super::bench_scene`]) at every size of `options`, `options.frames`
/// timed submissions per record.
pub fn bench_floor(
    ctx: &GpuContext,
    scene: &Showcase,
    options: &BenchOptions,
) -> Result<Vec<FloorRecord>, FloorBenchError> {
    let (device, queue) = (&ctx.device, &ctx.queue);
    let frames = options.frames.max(1);
    let res = options.shadow_res.max(1);
    let mut records = Vec::new();
    let mut scene_buffers = SceneBuffers::new(device);
    let shadow = ShadowViewsPass::new(device);
    for &(width, height) in &options.sizes {
        let mut s = scene.clone();
        s.projectors = vec![bench_projector(width, height)];
        let projector = s.projectors[0].clone();
        let frame =
            FrameScene::resolve(&s, &bench_frame(&s, "full", 1)).map_err(RenderError::from)?;
        scene_buffers.update(device, queue, &frame.showcase)?;
        let far = stable_far(shadow_far(
            &frame,
            scene_buffers.all(),
            projector.device.center(),
        ));
        let (views, _) = light_inputs(&frame, true, SHADOW_NEAR, far, res);
        let layers = views.len() as u32 + frame.eyes.len() as u32;
        let mut maps = ShadowMaps::new(device, res, layers)?;
        let mut views_buffer =
            UploadBuffer::new(device, "floor views", wgpu::BufferUsages::STORAGE);
        views_buffer.write(device, queue, &views);
        let shadow_bind = shadow.bind_group(device, views_buffer.buffer());
        let record = |floor: &str, role: &str, fetches, targets, (median_ms, p99_ms)| FloorRecord {
            role: role.into(),
            width,
            height,
            floor: floor.into(),
            fetches_per_pixel: fetches,
            targets,
            median_ms,
            p99_ms,
            adapter: ctx.describe(),
            shadow_res: res,
        };
        let light_layers = 0..views.len() as u32;
        let (all_vertices, _) = scene_buffers.buffer(VertexSet::All);
        let objects = scene_buffers.object_vertices(&frame.showcase);
        let everything = 0..scene_buffers.all().len() as u32;
        let mut occluder_ranges = Vec::new();
        for (i, sample) in frame.samples.iter().enumerate() {
            let cube = &views[6 * i..6 * i + 6];
            occluder_ranges.extend(cube_occluder_ranges(
                scene_buffers.all(),
                &objects,
                sample.position,
                cube,
            ));
        }
        for name in [
            "light_shadow_views_all_objects",
            "light_shadow_views_occluders",
            "light_shadow_views_clear_only",
        ] {
            let draws: Vec<LayerDraw<'_>> = light_layers
                .clone()
                .map(|layer| LayerDraw {
                    vertices: all_vertices,
                    layer,
                    ranges: match name {
                        "light_shadow_views_all_objects" => std::slice::from_ref(&everything),
                        "light_shadow_views_occluders" => &occluder_ranges[layer as usize],
                        _ => &[],
                    },
                    geometry: 0,
                })
                .collect();
            let times = time_steps(ctx, frames, |encoder| {
                maps.invalidate();
                shadow.encode_layers(encoder, &mut maps, &shadow_bind, &views, &draws);
                Ok(())
            })?;
            records.push(record(name, "projector", 0, 0, times));
        }
        // Leave the maps holding the light's views for the fetch floors.
        maps.invalidate();
        let mut encoder = device.create_command_encoder(&Default::default());
        let (vertices, vertex_count) = scene_buffers.buffer(VertexSet::All);
        shadow.encode(
            &mut encoder,
            &mut maps,
            &shadow_bind,
            &views,
            &[ShadowDraw {
                vertices,
                vertex_count,
                layers: light_layers.clone(),
                geometry: 0,
            }],
        );
        queue.submit([encoder.finish()]);

        let mut frame_uniform =
            UploadBuffer::new(device, "floor frame", wgpu::BufferUsages::UNIFORM);
        frame_uniform.write(
            device,
            queue,
            &[projector
                .device
                .clip_from_world()
                .as_mat4()
                .to_cols_array_2d()],
        );
        let blend = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("floor blend"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let blend_view = blend.create_view(&Default::default());
        let bindings = FloorBindings {
            frame: frame_uniform.buffer(),
            maps: maps.array_view(),
            blend: &blend_view,
        };
        let targets = [
            OffscreenTarget::new(device, width, height)?,
            OffscreenTarget::new(device, width, height)?,
        ];
        let (real, real_count) = scene_buffers.buffer(VertexSet::Real);
        let projector_fetches = projector_fetches(&frame);
        let face_fetches = face_fetches(&frame);
        for (role, name, kind, outputs, fetches) in [
            (
                "projector",
                "irradiance_trivial_fragment",
                FloorKind::Geometry,
                1,
                0,
            ),
            (
                "projector",
                "full_screen_trivial",
                FloorKind::FullScreen,
                1,
                0,
            ),
            (
                "projector",
                "full_screen_fetches",
                FloorKind::Fetches(projector_fetches),
                1,
                projector_fetches,
            ),
            ("face", "full_screen_trivial", FloorKind::FullScreen, 2, 0),
            (
                "face",
                "full_screen_fetches",
                FloorKind::Fetches(face_fetches),
                2,
                face_fetches,
            ),
        ] {
            // The projector writes two targets (L and device values); a
            // face view one per eye, and stereo draws two views.
            let target_count = if role == "projector" { 2 } else { 1 };
            let pass = FloorPass::new(device, kind, target_count);
            let bind = pass.bind_group(device, &bindings);
            let outs: Vec<&OffscreenTarget> = targets.iter().take(target_count as usize).collect();
            let times = time_steps(ctx, frames, |encoder| {
                for _ in 0..outputs {
                    pass.encode(encoder, &outs, &bind, real, real_count)?;
                }
                Ok(())
            })?;
            records.push(record(name, role, fetches, target_count, times));
        }
        // Reading the projector's targets back: the copies alone, then
        // copies, map and conversion of one target and of both.
        let readback = [
            ColourReadback::new(device, width, height),
            ColourReadback::new(device, width, height),
        ];
        let times = time_steps(ctx, frames, |encoder| {
            for (r, t) in readback.iter().zip(&targets) {
                r.encode_copy(encoder, t);
            }
            Ok(())
        })?;
        records.push(record("readback_copy_only", "projector", 0, 2, times));
        for count in [1, 2] {
            let mut times = Vec::with_capacity(frames);
            for i in 0..=frames {
                let start = Instant::now();
                let mut encoder = device.create_command_encoder(&Default::default());
                for (r, t) in readback.iter().zip(&targets).take(count) {
                    r.encode_copy(&mut encoder, t);
                }
                queue.submit([encoder.finish()]);
                let refs: Vec<&ColourReadback> = readback.iter().take(count).collect();
                let pixels = read_colours(device, &refs)?;
                if i > 0 {
                    times.push(start.elapsed().as_secs_f64() * 1e3);
                }
                drop(pixels);
            }
            times.sort_by(f64::total_cmp);
            let name = if count == 1 {
                "readback_one_target"
            } else {
                "readback_two_targets"
            };
            records.push(record(
                name,
                "projector",
                0,
                count as u32,
                (
                    percentile(&times, 50.0).unwrap_or(0.0),
                    percentile(&times, 99.0).unwrap_or(0.0),
                ),
            ));
        }
    }
    Ok(records)
}
