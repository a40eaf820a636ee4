//! The projector role on the GPU: the irradiance map of one projector,
//! drawn after the frame layer's shadow stage, and the renderer a
//! projector node runs (with whole-frame reuse). CPU reference:
//! [`showcase_light::render::projector::irradiance_map_cpu`].

use showcase_proto::Projector;

use super::RenderError;
use super::gpu_frame::{
    FrameInputs, LightOccluders, PassTimes, SceneBuffers, ShadowStage, TimedEncoder, VertexSet,
};
use super::passes::{Pass, PassList};
use crate::gpu::field::FieldBuffers;
use crate::gpu::frame_arrays::{ARRAY_USAGE, ArraySpace};
use crate::gpu::irradiance_map::{
    self, FrameUniform, IrradianceBindGroup, IrradianceBindings, IrradianceMapPass, state,
};
use crate::gpu::shadow_lookup::EyeGpu;
use crate::gpu::shadow_views::SHADOW_NEAR;
use crate::gpu::target::{ColourReadback, read_colours, visit_colours};
use crate::gpu::upload::UploadBuffer;
use crate::gpu::{GpuContext, OffscreenTarget};
use showcase_light::finite::finite_or_zero;
use showcase_light::render::frame::FrameScene;
use showcase_light::render::projector::COS_FLOOR;

mod blend_texture;
mod renderer;

use blend_texture::{BlendTexture, blend_key};
pub use renderer::{FrameReport, ProjectorRenderer};

/// The compiled projector pipeline and the GPU state it keeps across
/// frames (create once per device and projector): the scene's vertices
/// and the shadow stage (see [`super::gpu_frame`]), the irradiance pass's
/// uploads and bind group, the blend weights, targets and readback
/// buffers.
#[derive(Debug)]
pub struct ProjectorPipeline {
    scene: SceneBuffers,
    shadow: ShadowStage,
    irradiance: IrradianceMapPass,
    frame_uniform: UploadBuffer,
    eyes: UploadBuffer,
    /// The global-illumination field (`FrameScene::indirect`) as the pass
    /// reads it.
    field: FieldBuffers,
    /// The irradiance bind group and the buffer generations and array
    /// space it names.
    irradiance_bind: Option<(([u64; 4], ArraySpace), IrradianceBindGroup)>,
    targets: Option<ProjectorTargets>,
    /// The blend weights in use and what they were computed from.
    blend: Option<BlendTexture>,
    /// What the light samples' cube faces draw (the projector culls;
    /// [`LightOccluders`] says why).
    light_occluders: LightOccluders,
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

impl ProjectorPipeline {
    /// Compile the passes; shadow maps get `shadow_res` texels per side.
    pub fn new(device: &wgpu::Device, shadow_res: u32) -> Self {
        // Bindable as the irradiance shader's uniform array (whole
        // capacity) or as storage (long frames).
        let eye_bytes = irradiance_map::capacity("eyes") * size_of::<EyeGpu>();
        Self {
            scene: SceneBuffers::new(device),
            shadow: ShadowStage::new(device, shadow_res, irradiance_map::capacity),
            irradiance: IrradianceMapPass::new(device),
            frame_uniform: UploadBuffer::new(
                device,
                "irradiance frame",
                wgpu::BufferUsages::UNIFORM,
            ),
            eyes: UploadBuffer::with_min_size(device, "eyes", ARRAY_USAGE, eye_bytes as u64),
            field: FieldBuffers::new(device),
            irradiance_bind: None,
            targets: None,
            blend: None,
            light_occluders: LightOccluders::ShadowingReal,
        }
    }

    /// Whether the light samples' cube faces hold only the objects that
    /// can shadow a real surface and reach into the face (the default),
    /// or every object (for comparisons); see [`LightOccluders`].
    pub fn set_light_occluder_culling(&mut self, on: bool) {
        self.light_occluders = if on {
            LightOccluders::ShadowingReal
        } else {
            LightOccluders::Every
        };
    }

    /// Shadow map layers the last [`Self::draw`] drew (the others held
    /// the same view and geometry already).
    pub fn last_layers_drawn(&self) -> u32 {
        self.shadow.last_layers_drawn()
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
        let mut steps = TimedEncoder::new(ctx, timed);
        self.scene
            .update(&ctx.device, &ctx.queue, &frame.showcase)?;
        self.field.update(
            &ctx.device,
            &ctx.queue,
            frame.indirect.as_ref(),
            self.scene.real(),
            self.scene.real_triangles(),
            self.scene.generation(),
        );
        // Every tracked eye's occlusion shadows are darkened.
        let eyes = frame.eyes.iter().copied();
        let centre = projector.device.center();
        let res = self.shadow.res();
        let inputs = FrameInputs::new(frame, &self.scene, centre, eyes, passes, res);
        if self.shadow.prepare(&ctx.device, &ctx.queue, &inputs)? {
            self.irradiance_bind = None;
        }
        self.prepare_irradiance(ctx, frame, projector, &inputs)?;
        steps.step("setup")?;
        let occluders = self.light_occluders;
        self.shadow
            .encode(&mut steps, &self.scene, frame, &inputs, occluders)?;
        self.encode_irradiance(steps.encoder())?;
        steps.step(Pass::IrradianceMap.name())?;
        Ok(steps.submit())
    }

    /// Upload the eyes and the frame uniform, and bring the blend weights,
    /// the bind group and the targets up to date for this frame.
    fn prepare_irradiance(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameScene,
        projector: &Projector,
        inputs: &FrameInputs,
    ) -> Result<(), RenderError> {
        let (device, queue) = (&ctx.device, &ctx.queue);
        self.eyes.write(device, queue, &inputs.eyes);
        let key = blend_key(frame, projector);
        // Weights other than 1 exist only where projectors overlap
        // (BlendTexture::new); without them the shader skips the fetch.
        let blending = key.projector.is_some() && key.projectors.len() > 1;
        let uniform = frame_uniform(frame, projector, inputs, self.shadow.res(), blending);
        self.frame_uniform.write(device, queue, &[uniform]);
        if self.blend.as_ref().is_none_or(|b| b.key != key) {
            self.blend = Some(BlendTexture::new(ctx, frame, projector, key)?);
            self.irradiance_bind = None;
        }
        self.bind_irradiance(device, inputs)?;
        let (w, h) = (projector.device.width, projector.device.height);
        self.ensure_targets(device, w, h)
    }

    /// Make the irradiance bind group name this frame's buffers, maps,
    /// blend weights and array space.
    fn bind_irradiance(
        &mut self,
        device: &wgpu::Device,
        inputs: &FrameInputs,
    ) -> Result<(), RenderError> {
        let (lights, views) = (self.shadow.lights(), self.shadow.views());
        let space =
            IrradianceMapPass::space(inputs.lights.len(), inputs.eyes.len(), inputs.views.len());
        let generations = (
            [
                self.frame_uniform.generation(),
                lights.generation(),
                self.eyes.generation(),
                views.generation(),
            ],
            space,
        );
        if self
            .irradiance_bind
            .as_ref()
            .is_some_and(|(g, _)| *g == generations)
        {
            return Ok(());
        }
        let blend = self.blend.as_ref().ok_or(RenderError::NothingDrawn)?;
        let bind = self.irradiance.bind_group(
            device,
            &IrradianceBindings {
                frame: self.frame_uniform.buffer(),
                lights: lights.buffer(),
                eyes: self.eyes.buffer(),
                views: views.buffer(),
                maps: self.shadow.maps()?,
                blend: &blend.view,
                space,
            },
        );
        self.irradiance_bind = Some((generations, bind));
        Ok(())
    }

    /// Targets and readback buffers of `w x h` (kept while the size is).
    fn ensure_targets(&mut self, device: &wgpu::Device, w: u32, h: u32) -> Result<(), RenderError> {
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
        Ok(())
    }

    /// Record the irradiance map pass over the real objects.
    fn encode_irradiance(&self, encoder: &mut wgpu::CommandEncoder) -> Result<(), RenderError> {
        let (Some(targets), Some((_, bind))) = (&self.targets, &self.irradiance_bind) else {
            return Err(RenderError::NothingDrawn);
        };
        // Global mode draws the real set split into the field's pieces.
        let (vertices, vertex_count) = self
            .field
            .vertices()
            .unwrap_or_else(|| self.scene.buffer(VertexSet::Real));
        self.irradiance.encode(
            encoder,
            &targets.irradiance,
            &targets.value,
            bind,
            vertices,
            self.field.values(),
            vertex_count,
        )?;
        Ok(())
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
                        *v = finite_or_zero(*v);
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

/// The irradiance shader's frame uniform for `projector` in `frame`.
fn frame_uniform(
    frame: &FrameScene,
    projector: &Projector,
    inputs: &FrameInputs,
    shadow_res: u32,
    blending: bool,
) -> FrameUniform {
    let response = &projector.response;
    let flags = u32::from(inputs.shadows)
        | (u32::from(inputs.occlusion) << 1)
        | (u32::from(blending) << 2)
        | (u32::from(frame.indirect.is_some()) << 3);
    FrameUniform {
        clip_from_world: projector
            .device
            .clip_from_world()
            .as_mat4()
            .to_cols_array_2d(),
        projector: projector.device.center().as_vec3().extend(0.0).to_array(),
        ambient: frame.ambient().as_vec3().extend(0.0).to_array(),
        response: [
            response.gamma,
            response.eta,
            response.black_level,
            COS_FLOOR as f32,
        ],
        counts: [
            inputs.lights.len() as u32,
            inputs.eyes.len() as u32,
            shadow_res,
            flags,
        ],
        shadow: [SHADOW_NEAR, inputs.far, 0.0, 0.0],
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
