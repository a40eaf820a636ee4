//! The projector role on the GPU: the pass list's shadow views and the
//! irradiance map for one projector, and the [`Renderer`] a projector node
//! runs (with whole-frame reuse). CPU reference:
//! [`super::projector::irradiance_map_cpu`].

use std::sync::Arc;
use std::time::Instant;

use glam::{DVec3, Vec3};
use showcase_proto::{FrameState, ObjectKind, Projector, Showcase};

use super::RenderSetupError;
use super::frame::{FrameScene, Lobe};
use super::passes::{FrameKey, Pass, PassList, bounding_sphere};
use super::projector::COS_FLOOR;
use crate::gpu::irradiance_map::{
    EyeGpu, FrameUniform, IrradianceInputs, IrradianceMapPass, LightSampleGpu, state,
};
use crate::gpu::shadow_views::{
    ShadowDraw, ShadowMaps, ShadowView, ShadowViewsPass, WorldVertex, cube_views, fitted_views,
};
use crate::gpu::{GpuContext, OffscreenTarget, wait_idle};
use crate::light::world_matrix;
use crate::node::renderer::{OutputImage, RenderError, RenderOutput, Renderer, hash_pixels};
use wgpu::util::DeviceExt;

/// Default size of each shadow distance map (texels per side).
pub const DEFAULT_SHADOW_RES: u32 = 1024;

/// World-space vertices (three per triangle, flat normals) of the objects
/// of `kind` (`None`: all); degenerate triangles are left out.
pub fn world_vertices(
    showcase: &Showcase,
    kind: Option<ObjectKind>,
) -> Result<Vec<WorldVertex>, RenderSetupError> {
    Ok(world_vertices_by_object(showcase, kind)?.0)
}

/// An object index and its vertex range in a vertex buffer.
pub type ObjectRange = (usize, std::ops::Range<u32>);

/// [`world_vertices`] with the vertex range of each object drawn, as
/// `(object index, range)` in object order.
pub fn world_vertices_by_object(
    showcase: &Showcase,
    kind: Option<ObjectKind>,
) -> Result<(Vec<WorldVertex>, Vec<ObjectRange>), RenderSetupError> {
    let mut out = Vec::new();
    let mut ranges = Vec::new();
    for (oi, o) in showcase.objects.iter().enumerate() {
        if kind.is_some_and(|k| k != o.kind) {
            continue;
        }
        let start = out.len() as u32;
        let name = || o.name.clone();
        let mesh =
            showcase
                .mesh(&o.mesh)
                .ok_or_else(|| crate::light::GeometryError::MissingMesh {
                    object: oi,
                    name: name(),
                })?;
        let m = world_matrix(&o.transform).ok_or_else(|| {
            crate::light::GeometryError::BadTransform {
                object: oi,
                name: name(),
            }
        })?;
        for (ti, tri) in mesh.triangles.iter().enumerate() {
            let mut v = [DVec3::ZERO; 3];
            for (k, &i) in tri.iter().enumerate() {
                let p = mesh.positions.get(i as usize).ok_or_else(|| {
                    crate::light::GeometryError::IndexOutOfRange {
                        object: oi,
                        name: name(),
                        triangle: ti,
                        index: i,
                    }
                })?;
                v[k] = m.transform_point3(p.as_dvec3());
            }
            let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
            if n == DVec3::ZERO || !n.is_finite() {
                continue;
            }
            let normal = n.as_vec3().to_array();
            out.extend(v.iter().map(|p| WorldVertex {
                position: p.as_vec3().to_array(),
                normal,
            }));
        }
        ranges.push((oi, start..out.len() as u32));
    }
    Ok((out, ranges))
}

/// The light samples as the shaders read them and, with `shadows`, the
/// six cube views of each (in sample order, from layer 0).
pub fn light_inputs(
    frame: &FrameScene,
    shadows: bool,
    near: f32,
    far: f32,
    shadow_res: u32,
) -> (Vec<ShadowView>, Vec<LightSampleGpu>) {
    let mut views: Vec<ShadowView> = Vec::new();
    let mut lights = Vec::with_capacity(frame.samples.len());
    for s in &frame.samples {
        let first = views.len() as u32;
        if shadows {
            views.extend(cube_views(s.position.as_vec3(), near, far, shadow_res));
        }
        let (axis, kind, cone) = match s.lobe {
            Lobe::Isotropic => (DVec3::ZERO, 0.0, [0.0, 0.0]),
            Lobe::Spot {
                axis,
                cos_inner,
                cos_outer,
            } => (axis, 1.0, [cos_inner as f32, cos_outer as f32]),
            Lobe::Cosine { normal } => (normal, 2.0, [0.0, 0.0]),
        };
        let a = axis.as_vec3();
        lights.push(LightSampleGpu {
            position: s.position.as_vec3().extend(0.0).to_array(),
            intensity: s.intensity.as_vec3().extend(0.0).to_array(),
            axis: [a.x, a.y, a.z, kind],
            cone: [cone[0], cone[1], 0.0, 0.0],
            views: [first, views.len() as u32 - first, 0, 0],
        });
    }
    (views, lights)
}

/// Far plane for shadow views: every light, eye and surface point lies
/// within it from every origin (`from` is any reference point).
pub fn shadow_far(frame: &FrameScene, points: &[WorldVertex], from: DVec3) -> f32 {
    let mut far_base = 0.0f64;
    for p in points
        .iter()
        .map(|w| Vec3::from_array(w.position).as_dvec3())
        .chain(frame.eyes.iter().copied())
        .chain(frame.samples.iter().map(|s| s.position))
    {
        far_base = far_base.max((p - from).length());
    }
    // Every origin is within 2 far_base of every point.
    (4.0 * far_base + 1.0) as f32
}

/// The compiled projector pipeline; create once per device.
#[derive(Debug)]
pub struct ProjectorPipeline {
    shadow: ShadowViewsPass,
    irradiance: IrradianceMapPass,
    shadow_res: u32,
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

/// The targets a frame was drawn into, before readback.
#[derive(Debug)]
pub struct ProjectorTargets {
    irradiance: OffscreenTarget,
    value: OffscreenTarget,
}

/// Wall time of each pass group (submitted and waited for separately).
pub type PassTimes = Vec<(Pass, f64)>;

fn vertex_buffer(device: &wgpu::Device, vertices: &[WorldVertex]) -> wgpu::Buffer {
    let placeholder = [WorldVertex {
        position: [0.0; 3],
        normal: [0.0; 3],
    }];
    let data = if vertices.is_empty() {
        &placeholder[..]
    } else {
        vertices
    };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("world vertices"),
        contents: bytemuck::cast_slice(data),
        usage: wgpu::BufferUsages::VERTEX,
    })
}

impl ProjectorPipeline {
    /// Compile the passes; shadow maps get `shadow_res` texels per side.
    pub fn new(device: &wgpu::Device, shadow_res: u32) -> Self {
        Self {
            shadow: ShadowViewsPass::new(device),
            irradiance: IrradianceMapPass::new(device),
            shadow_res: shadow_res.max(1),
        }
    }

    /// Draw `projector`'s frame with the passes of `passes` (a pass not in
    /// the list is replaced by "everything visible"), submit, and return
    /// the targets. With `timed`, each pass group is submitted and waited
    /// for separately and its wall time returned.
    pub fn draw(
        &self,
        ctx: &GpuContext,
        frame: &FrameScene,
        projector: &Projector,
        passes: &PassList,
        timed: bool,
    ) -> Result<(ProjectorTargets, PassTimes), RenderSetupError> {
        let device = &ctx.device;
        let start = Instant::now();
        let all = world_vertices(&frame.showcase, None)?;
        let real = world_vertices(&frame.showcase, Some(ObjectKind::Real))?;
        let virt = world_vertices(&frame.showcase, Some(ObjectKind::Virtual))?;
        let points = |v: &[WorldVertex]| {
            v.iter()
                .map(|w| Vec3::from_array(w.position).as_dvec3())
                .collect::<Vec<_>>()
        };
        let centre = projector.device.center();
        let far = shadow_far(frame, &all, centre);
        let near = 1e-3f32;

        let shadows = passes.runs(Pass::LightShadowViews);
        let (mut views, lights) = light_inputs(frame, shadows, near, far, self.shadow_res);
        let light_layers = 0..views.len() as u32;
        let occlusion = passes.runs(Pass::EyeShadowViews);
        let virtual_sphere = bounding_sphere(points(&virt).into_iter());
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

        let maps = ShadowMaps::new(device, self.shadow_res, views.len() as u32)?;
        let views_buffer = self.shadow.upload_views(device, &views);
        let all_buffer = vertex_buffer(device, &all);
        let real_buffer = vertex_buffer(device, &real);
        let virt_buffer = vertex_buffer(device, &virt);
        let (w, h) = (projector.device.width, projector.device.height);
        let targets = ProjectorTargets {
            irradiance: OffscreenTarget::new(device, w, h)?,
            value: OffscreenTarget::new(device, w, h)?,
        };
        let mut times = Vec::new();
        let mut encoder = device.create_command_encoder(&Default::default());
        let mut flush = |encoder: &mut wgpu::CommandEncoder,
                         pass: Pass,
                         since: &mut Instant|
         -> Result<(), RenderSetupError> {
            if timed {
                let done =
                    std::mem::replace(encoder, device.create_command_encoder(&Default::default()));
                ctx.queue.submit([done.finish()]);
                wait_idle(device)?;
                times.push((pass, since.elapsed().as_secs_f64() * 1e3));
                *since = Instant::now();
            }
            Ok(())
        };
        let mut since = start;
        if shadows {
            self.shadow.encode(
                device,
                &mut encoder,
                &maps,
                &views_buffer,
                &[ShadowDraw {
                    vertices: &all_buffer,
                    vertex_count: all.len() as u32,
                    layers: light_layers,
                }],
            );
            flush(&mut encoder, Pass::LightShadowViews, &mut since)?;
        }
        if occlusion {
            self.shadow.encode(
                device,
                &mut encoder,
                &maps,
                &views_buffer,
                &[ShadowDraw {
                    vertices: &virt_buffer,
                    vertex_count: virt.len() as u32,
                    layers: eye_layers,
                }],
            );
            flush(&mut encoder, Pass::EyeShadowViews, &mut since)?;
        }
        let response = &projector.response;
        let inputs = IrradianceInputs {
            frame: FrameUniform {
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
                    u32::from(shadows) | (u32::from(occlusion) << 1),
                ],
            },
            lights: &lights,
            eyes: &eyes,
            views: &views_buffer,
            maps: &maps,
            vertices: &real_buffer,
            vertex_count: real.len() as u32,
        };
        self.irradiance.encode(
            device,
            &mut encoder,
            &targets.irradiance,
            &targets.value,
            &inputs,
        )?;
        flush(&mut encoder, Pass::IrradianceMap, &mut since)?;
        ctx.queue.submit([encoder.finish()]);
        Ok((targets, times))
    }

    /// Read a drawn frame back (waits for the GPU). Non-finite values
    /// become 0.
    pub fn read(
        &self,
        ctx: &GpuContext,
        targets: &ProjectorTargets,
    ) -> Result<GpuIrradianceMap, RenderSetupError> {
        let clean = |v: Vec<[f32; 4]>| -> Vec<[f32; 4]> {
            v.into_iter()
                .map(|p| p.map(|c| if c.is_finite() { c } else { 0.0 }))
                .collect()
        };
        let irradiance = clean(targets.irradiance.read_rgba_f32(&ctx.device, &ctx.queue)?);
        let value = clean(targets.value.read_rgba_f32(&ctx.device, &ctx.queue)?);
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
            clipped_fraction: if counted == 0 {
                0.0
            } else {
                clipped as f64 / counted as f64
            },
        })
    }

    /// [`Self::draw`] then [`Self::read`].
    pub fn render(
        &self,
        ctx: &GpuContext,
        frame: &FrameScene,
        projector: &Projector,
        passes: &PassList,
    ) -> Result<GpuIrradianceMap, RenderSetupError> {
        let (targets, _) = self.draw(ctx, frame, projector, passes, false)?;
        self.read(ctx, &targets)
    }
}

/// What the last [`ProjectorRenderer::render`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReport {
    /// Passes run (empty when the last frame was reused).
    pub passes_run: Vec<Pass>,
    /// True when the previous output was reused unchanged.
    pub reused: bool,
    /// Clipped fraction of the output.
    pub clipped_fraction: f64,
}

/// The [`Renderer`] of a projector node.
#[derive(Debug)]
pub struct ProjectorRenderer {
    ctx: GpuContext,
    pipeline: ProjectorPipeline,
    projector: usize,
    scene_version: Option<u64>,
    /// Run every pass regardless of the pass list (for comparisons).
    pub force_all_passes: bool,
    last: Option<(FrameKey, RenderOutput, f64)>,
    report: FrameReport,
    presented: Vec<u64>,
}

impl ProjectorRenderer {
    /// A renderer for `Showcase::projectors[projector]` on `ctx`.
    pub fn new(ctx: GpuContext, projector: usize, shadow_res: u32) -> Self {
        let pipeline = ProjectorPipeline::new(&ctx.device, shadow_res);
        Self {
            ctx,
            pipeline,
            projector,
            scene_version: None,
            force_all_passes: false,
            last: None,
            report: FrameReport::default(),
            presented: Vec::new(),
        }
    }

    /// What the last render did.
    pub fn report(&self) -> &FrameReport {
        &self.report
    }

    /// Frames presented so far.
    pub fn presented(&self) -> &[u64] {
        &self.presented
    }

    /// The GPU context.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    fn render_frame(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderSetupError> {
        let projector =
            scene
                .projectors
                .get(self.projector)
                .ok_or(RenderSetupError::NoProjector {
                    index: self.projector,
                })?;
        let resolved = FrameScene::resolve(scene, frame)?;
        let passes = if self.force_all_passes {
            PassList::full()
        } else {
            PassList::for_projector(&resolved)
        };
        let key = FrameKey::projector(self.projector, frame, &passes);
        if let Some((last_key, output, clipped)) = &self.last
            && *last_key == key
            && !self.force_all_passes
        {
            self.report = FrameReport {
                passes_run: Vec::new(),
                reused: true,
                clipped_fraction: *clipped,
            };
            return Ok(output.clone());
        }
        let map = self
            .pipeline
            .render(&self.ctx, &resolved, projector, &passes)?;
        let output = RenderOutput {
            hash: hash_pixels(&map.value),
            image: Some(OutputImage {
                width: map.width,
                height: map.height,
                rgba: map.value,
            }),
        };
        self.report = FrameReport {
            passes_run: passes.passes.clone(),
            reused: false,
            clipped_fraction: map.clipped_fraction,
        };
        self.last = Some((key, output.clone(), map.clipped_fraction));
        Ok(output)
    }
}

impl Renderer for ProjectorRenderer {
    fn set_scene(&mut self, version: u64, _scene: Arc<Showcase>) -> Result<(), RenderError> {
        self.scene_version = Some(version);
        self.last = None;
        Ok(())
    }

    fn render(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        if self.scene_version != Some(frame.scene_version) {
            return Err(RenderError(format!(
                "projector {}: frame {} is for scene version {} but the renderer has {:?}",
                self.projector, frame.frame, frame.scene_version, self.scene_version
            )));
        }
        self.render_frame(frame, scene).map_err(|e| {
            RenderError(format!(
                "projector {}: frame {}: {e}",
                self.projector, frame.frame
            ))
        })
    }

    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        self.presented.push(frame);
        Ok(())
    }
}
