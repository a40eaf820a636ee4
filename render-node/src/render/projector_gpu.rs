//! The projector role on the GPU: the pass list's shadow views and the
//! irradiance map for one projector, and the renderer a projector node
//! runs (with whole-frame reuse). CPU reference:
//! [`showcase_light::render::projector::irradiance_map_cpu`].

use std::time::Instant;

use glam::Vec3;
use showcase_proto::{ObjectKind, Projector};

use super::RenderError;
use super::gpu_scene::{SceneBuffers, VertexSet, ensure_maps, stable_far};
use super::passes::{Pass, PassList, bounding_sphere};
use crate::gpu::frame_arrays::ARRAY_USAGE;
use crate::gpu::irradiance_map::{
    self, FrameUniform, IrradianceBindGroup, IrradianceBindings, IrradianceMapPass, state,
};
use crate::gpu::shadow_lookup::{EyeGpu, LightSampleGpu};
use crate::gpu::shadow_views::occluders::{cube_occluder_ranges, ranges_identity};
use crate::gpu::shadow_views::{
    LayerDraw, SHADOW_NEAR, ShadowDraw, ShadowMaps, ShadowView, ShadowViewsPass, fitted_views,
};
use crate::gpu::target::{ColourReadback, read_colours, visit_colours};
use crate::gpu::upload::UploadBuffer;
use crate::gpu::{GpuContext, OffscreenTarget, wait_idle};
use showcase_light::render::frame::FrameScene;
use showcase_light::render::projector::COS_FLOOR;

mod blend_texture;
mod inputs;
mod renderer;

use blend_texture::{BlendTexture, blend_key};
pub use inputs::{ObjectRange, light_inputs, shadow_far, world_vertices, world_vertices_by_object};
pub use renderer::{FrameReport, ProjectorRenderer};

/// Default size of each shadow distance map (texels per side).
pub const DEFAULT_SHADOW_RES: u32 = 1024;

/// The compiled projector pipeline and the GPU state it keeps across
/// frames (create once per device and projector): the scene's vertices
/// (uploaded when they change), the shadow maps (a layer whose light or
/// eye did not move is not drawn again), the per-frame uploads, bind
/// groups, targets and readback buffers.
#[derive(Debug)]
pub struct ProjectorPipeline {
    shadow: ShadowViewsPass,
    irradiance: IrradianceMapPass,
    shadow_res: u32,
    scene: SceneBuffers,
    frame_uniform: UploadBuffer,
    lights: UploadBuffer,
    eyes: UploadBuffer,
    views: UploadBuffer,
    maps: Option<ShadowMaps>,
    /// The shadow bind group and the views buffer generation it names.
    shadow_bind: Option<(u64, wgpu::BindGroup)>,
    /// The irradiance bind group and the buffer generations and array
    /// space it names.
    irradiance_bind: Option<(
        ([u64; 4], crate::gpu::frame_arrays::ArraySpace),
        IrradianceBindGroup,
    )>,
    targets: Option<ProjectorTargets>,
    /// The blend weights in use and what they were computed from.
    blend: Option<BlendTexture>,
    last_layers_drawn: u32,
    /// Draw only the objects that can occlude into each light cube face.
    cull_light_occluders: bool,
}

/// A projector frame read back from the GPU.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuIrradianceMap {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `L` (W/sr) in rgb and the state code (`gpu::irradiance_map::state`) in alpha.
    pub irradiance: Vec<[f32; 4]>,
    /// Device values in rgb, alpha 1: what the projector shows.
    pub value: Vec<[f32; 4]>,
    /// Clipped over unmasked surface pixels.
    pub clipped_fraction: f64,
}

/// What a projector node presents of a frame ([`ProjectorPipeline::read_output`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ProjectorOutput {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Device values in rgb, alpha 1: what the projector shows.
    pub value: Vec<[f32; 4]>,
    /// Clipped over unmasked surface pixels.
    pub clipped_fraction: f64,
}

/// The targets a frame is drawn into and their readback buffers.
#[derive(Debug)]
struct ProjectorTargets {
    irradiance: OffscreenTarget,
    value: OffscreenTarget,
    readback: [ColourReadback; 2],
}

/// Wall time of each step of a frame in milliseconds (each submitted and
/// waited for separately): `setup` (CPU work and uploads), then the passes
/// by [`Pass::name`].
pub type PassTimes = Vec<(&'static str, f64)>;

impl ProjectorPipeline {
    /// Compile the passes; shadow maps get `shadow_res` texels per side.
    pub fn new(device: &wgpu::Device, shadow_res: u32) -> Self {
        // Bindable as the irradiance shader's uniform arrays (whole
        // capacity) or as storage (the shadow views pass, long frames).
        let array = |label, bytes: usize| {
            UploadBuffer::with_min_size(device, label, ARRAY_USAGE, bytes as u64)
        };
        let cap = irradiance_map::capacity;
        Self {
            shadow: ShadowViewsPass::new(device),
            irradiance: IrradianceMapPass::new(device),
            shadow_res: shadow_res.max(1),
            scene: SceneBuffers::new(device),
            frame_uniform: UploadBuffer::new(
                device,
                "irradiance frame",
                wgpu::BufferUsages::UNIFORM,
            ),
            lights: array("light samples", cap("lights") * size_of::<LightSampleGpu>()),
            eyes: array("eyes", cap("eyes") * size_of::<EyeGpu>()),
            views: array("shadow views", cap("views") * size_of::<ShadowView>()),
            maps: None,
            shadow_bind: None,
            irradiance_bind: None,
            targets: None,
            blend: None,
            last_layers_drawn: 0,
            cull_light_occluders: true,
        }
    }

    /// Whether the light samples' cube faces hold only the objects that
    /// can shadow a real surface and reach into the face (the default),
    /// or every object (as before; for comparisons).
    pub fn set_light_occluder_culling(&mut self, on: bool) {
        self.cull_light_occluders = on;
    }

    /// Shadow map layers the last [`Self::draw`] drew (the others held
    /// the same view and geometry already).
    pub fn last_layers_drawn(&self) -> u32 {
        self.last_layers_drawn
    }

    /// Draw `projector`'s frame with the passes of `passes` (a pass not in
    /// the list is replaced by "everything visible") and submit. With
    /// `timed`, each step is submitted and waited for separately and its
    /// wall time returned.
    pub fn draw(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameScene,
        projector: &Projector,
        passes: &PassList,
        timed: bool,
    ) -> Result<PassTimes, RenderError> {
        let (device, queue) = (&ctx.device, &ctx.queue);
        let start = Instant::now();
        self.scene.update(device, queue, &frame.showcase)?;
        let centre = projector.device.center();
        let far = stable_far(shadow_far(frame, self.scene.all(), centre));
        let near = SHADOW_NEAR;

        let shadows = passes.runs(Pass::LightShadowViews);
        let (mut views, lights) = light_inputs(frame, shadows, near, far, self.shadow_res);
        let light_layers = 0..views.len() as u32;
        let occlusion = passes.runs(Pass::EyeShadowViews);
        let virtual_sphere = if occlusion {
            let (all, ranges) = (self.scene.all(), self.scene.ranges());
            bounding_sphere(
                ranges
                    .iter()
                    .filter(|(oi, _)| frame.showcase.objects[*oi].kind == ObjectKind::Virtual)
                    .flat_map(|(_, r)| all[r.start as usize..r.end as usize].iter())
                    .map(|w| Vec3::from_array(w.position).as_dvec3()),
            )
        } else {
            None
        };
        let mut eyes = Vec::with_capacity(frame.eyes.len());
        for e in &frame.eyes {
            let first = views.len() as u32;
            if let (true, Some((c, r))) = (occlusion, virtual_sphere) {
                views.extend(fitted_views(
                    e.as_vec3(),
                    c.as_vec3(),
                    (r * 1.001 + 1e-6) as f32,
                    near,
                    far,
                    self.shadow_res,
                ));
            }
            eyes.push(EyeGpu {
                position: e.as_vec3().extend(0.0).to_array(),
                views: [first, views.len() as u32 - first, 0, 0],
            });
        }
        let eye_layers = light_layers.end..views.len() as u32;

        let maps_changed =
            ensure_maps(&mut self.maps, device, self.shadow_res, views.len() as u32)?;
        self.views.write(device, queue, &views);
        self.lights.write(device, queue, &lights);
        self.eyes.write(device, queue, &eyes);
        let response = &projector.response;
        let key = blend_key(frame, projector);
        // Weights other than 1 exist only where projectors overlap
        // (BlendTexture::new); without them the shader skips the fetch.
        let blending = key.projector.is_some() && key.projectors.len() > 1;
        let uniform = FrameUniform {
            clip_from_world: projector
                .device
                .clip_from_world()
                .as_mat4()
                .to_cols_array_2d(),
            projector: centre.as_vec3().extend(0.0).to_array(),
            ambient: frame.ambient().as_vec3().extend(0.0).to_array(),
            response: [
                response.gamma,
                response.eta,
                response.black_level,
                COS_FLOOR as f32,
            ],
            counts: [
                lights.len() as u32,
                eyes.len() as u32,
                self.shadow_res,
                u32::from(shadows) | (u32::from(occlusion) << 1) | (u32::from(blending) << 2),
            ],
            shadow: [near, far, 0.0, 0.0],
        };
        self.frame_uniform.write(device, queue, &[uniform]);
        if maps_changed {
            self.irradiance_bind = None;
        }
        let (w, h) = (projector.device.width, projector.device.height);
        if self.blend.as_ref().is_none_or(|b| b.key != key) {
            self.blend = Some(BlendTexture::new(ctx, frame, projector, key)?);
            self.irradiance_bind = None;
        }
        let Some(blend) = self.blend.as_ref() else {
            return Err(RenderError::NothingDrawn);
        };
        let Some(maps) = self.maps.as_mut() else {
            return Err(RenderError::NothingDrawn);
        };
        let views_generation = self.views.generation();
        if self
            .shadow_bind
            .as_ref()
            .is_none_or(|(g, _)| *g != views_generation)
        {
            self.shadow_bind = Some((
                views_generation,
                self.shadow.bind_group(device, self.views.buffer()),
            ));
        }
        let space = IrradianceMapPass::space(lights.len(), eyes.len(), views.len());
        let generations = (
            [
                self.frame_uniform.generation(),
                self.lights.generation(),
                self.eyes.generation(),
                views_generation,
            ],
            space,
        );
        if self
            .irradiance_bind
            .as_ref()
            .is_none_or(|(g, _)| *g != generations)
        {
            let bind = self.irradiance.bind_group(
                device,
                &IrradianceBindings {
                    frame: self.frame_uniform.buffer(),
                    lights: self.lights.buffer(),
                    eyes: self.eyes.buffer(),
                    views: self.views.buffer(),
                    maps,
                    blend: &blend.view,
                    space,
                },
            );
            self.irradiance_bind = Some((generations, bind));
        }
        if self
            .targets
            .as_ref()
            .is_none_or(|t| (t.value.width(), t.value.height()) != (w, h))
        {
            self.targets = Some(ProjectorTargets {
                irradiance: OffscreenTarget::new(device, w, h)?,
                value: OffscreenTarget::new(device, w, h)?,
                readback: [
                    ColourReadback::new(device, w, h),
                    ColourReadback::new(device, w, h),
                ],
            });
        }
        let (Some(targets), Some((_, shadow_bind)), Some((_, irradiance_bind))) =
            (&self.targets, &self.shadow_bind, &self.irradiance_bind)
        else {
            return Err(RenderError::NothingDrawn);
        };

        let mut times = Vec::new();
        let mut encoder = device.create_command_encoder(&Default::default());
        let mut since = start;
        let mut flush = |encoder: &mut wgpu::CommandEncoder,
                         step: &'static str|
         -> Result<(), RenderError> {
            if timed {
                let done =
                    std::mem::replace(encoder, device.create_command_encoder(&Default::default()));
                queue.submit([done.finish()]);
                wait_idle(device)?;
                times.push((step, since.elapsed().as_secs_f64() * 1e3));
                since = Instant::now();
            }
            Ok(())
        };
        flush(&mut encoder, "setup")?;
        let mut layers_drawn = 0;
        if shadows {
            // Each light sample's cube faces hold only the objects that
            // can shadow a real surface and reach into the face
            // (shadow_views::occluders); the others read as lit anyway.
            let (vertices, _) = self.scene.buffer(VertexSet::All);
            let objects = self.scene.object_vertices(&frame.showcase);
            let geometry = self.scene.geometry(VertexSet::All);
            let mut per_layer = Vec::with_capacity(light_layers.len());
            let everything = 0..self.scene.all().len() as u32;
            for (s, l) in frame.samples.iter().zip(&lights) {
                let first = l.views[0] as usize;
                let cube = &views[first..first + l.views[1] as usize];
                let ranges = if self.cull_light_occluders {
                    cube_occluder_ranges(self.scene.all(), &objects, s.position, cube)
                } else {
                    vec![vec![everything.clone()]; cube.len()]
                };
                for (k, ranges) in ranges.into_iter().enumerate() {
                    per_layer.push(((first + k) as u32, ranges));
                }
            }
            let draws: Vec<LayerDraw<'_>> = per_layer
                .iter()
                .map(|(layer, ranges)| LayerDraw {
                    vertices,
                    layer: *layer,
                    ranges,
                    geometry: ranges_identity(geometry, ranges),
                })
                .collect();
            layers_drawn +=
                self.shadow
                    .encode_layers(&mut encoder, maps, shadow_bind, &views, &draws);
            flush(&mut encoder, Pass::LightShadowViews.name())?;
        }
        if occlusion {
            let (vertices, vertex_count) = self.scene.buffer(VertexSet::Virtual);
            layers_drawn += self.shadow.encode(
                &mut encoder,
                maps,
                shadow_bind,
                &views,
                &[ShadowDraw {
                    vertices,
                    vertex_count,
                    layers: eye_layers,
                    geometry: self.scene.geometry(VertexSet::Virtual),
                }],
            );
            flush(&mut encoder, Pass::EyeShadowViews.name())?;
        }
        let (vertices, vertex_count) = self.scene.buffer(VertexSet::Real);
        self.irradiance.encode(
            &mut encoder,
            &targets.irradiance,
            &targets.value,
            irradiance_bind,
            vertices,
            vertex_count,
        )?;
        flush(&mut encoder, Pass::IrradianceMap.name())?;
        queue.submit([encoder.finish()]);
        self.last_layers_drawn = layers_drawn;
        Ok(times)
    }

    /// Copy both targets of the last drawn frame to their readback
    /// buffers and submit the copies.
    fn submit_readback(&self, ctx: &GpuContext) -> Result<&ProjectorTargets, RenderError> {
        let targets = self.targets.as_ref().ok_or(RenderError::NothingDrawn)?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        targets.readback[0].encode_copy(&mut encoder, &targets.irradiance);
        targets.readback[1].encode_copy(&mut encoder, &targets.value);
        ctx.queue.submit([encoder.finish()]);
        Ok(targets)
    }

    /// Read the last drawn frame back (waits for the GPU). Non-finite
    /// values become 0.
    pub fn read(&self, ctx: &GpuContext) -> Result<GpuIrradianceMap, RenderError> {
        let targets = self.submit_readback(ctx)?;
        let mut read = read_colours(&ctx.device, &[&targets.readback[0], &targets.readback[1]])?;
        let value = read.pop().unwrap_or_default();
        let irradiance = read.pop().unwrap_or_default();
        let counted = irradiance
            .iter()
            .filter(|p| p[3] == state::UNCLIPPED || p[3] == state::CLIPPED)
            .count();
        let clipped = irradiance.iter().filter(|p| p[3] == state::CLIPPED).count();
        Ok(GpuIrradianceMap {
            width: targets.irradiance.width(),
            height: targets.irradiance.height(),
            irradiance,
            value,
            clipped_fraction: clipped_fraction(clipped, counted),
        })
    }

    /// What a node presents of the last drawn frame (waits for the GPU):
    /// the device values and the clipped fraction, equal to
    /// [`Self::read`]'s. The `L` target is copied back too, but only its
    /// state codes are looked at, in place, so no image of it is built.
    pub fn read_output(&self, ctx: &GpuContext) -> Result<ProjectorOutput, RenderError> {
        let targets = self.submit_readback(ctx)?;
        let (w, h) = (targets.value.width(), targets.value.height());
        let mut value: Vec<[f32; 4]> = Vec::with_capacity(w as usize * h as usize);
        let (mut counted, mut clipped) = (0usize, 0usize);
        visit_colours(
            &ctx.device,
            &[&targets.readback[0], &targets.readback[1]],
            |i, row| {
                if i == 0 {
                    for p in row {
                        counted += usize::from(p[3] == state::UNCLIPPED || p[3] == state::CLIPPED);
                        clipped += usize::from(p[3] == state::CLIPPED);
                    }
                } else {
                    let from = value.len();
                    value.extend_from_slice(row);
                    for v in value[from..].iter_mut().flatten() {
                        if !v.is_finite() {
                            *v = 0.0;
                        }
                    }
                }
            },
        )?;
        Ok(ProjectorOutput {
            width: w,
            height: h,
            value,
            clipped_fraction: clipped_fraction(clipped, counted),
        })
    }

    /// [`Self::draw`] then [`Self::read`].
    pub fn render(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameScene,
        projector: &Projector,
        passes: &PassList,
    ) -> Result<GpuIrradianceMap, RenderError> {
        self.draw(ctx, frame, projector, passes, false)?;
        self.read(ctx)
    }
}

/// Clipped over counted (unclipped and clipped) pixels; 0 with none.
fn clipped_fraction(clipped: usize, counted: usize) -> f64 {
    if counted == 0 {
        0.0
    } else {
        clipped as f64 / counted as f64
    }
}
