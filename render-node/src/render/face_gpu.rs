//! The face role on the GPU: per-eye views through a CRT face with phantom
//! depth, shadow types 2 and 3 and occluding occlusion shadows, and the [`Renderer`] of a face node
//! (both eyes of one observer, side by side). CPU reference:
//! [`super::face::face_image_cpu`].

use std::sync::Arc;

use glam::DVec3;
use showcase_proto::{CrtFace, FrameState, ObjectKind, Showcase};

use super::RenderSetupError;
use super::frame::{DEFAULT_IPD, FrameScene};
use super::passes::bounding_sphere;
use super::passes::{FrameKey, Pass, PassList};
use super::projector_gpu::{ObjectRange, light_inputs, shadow_far, world_vertices_by_object};
use crate::gpu::face_view::{FaceFrameUniform, FaceInputs, FaceViewPass};
use crate::gpu::irradiance_map::EyeGpu;
use crate::gpu::shadow_views::fitted_views;
use crate::gpu::shadow_views::{ShadowDraw, ShadowMaps, ShadowViewsPass, WorldVertex};
use crate::gpu::{GpuContext, OffscreenTarget};
use crate::mirror_view::FaceView;
use crate::node::renderer::{OutputImage, RenderError, RenderOutput, Renderer, hash_pixels};
use wgpu::util::DeviceExt;

/// Near and far clip distances of face views (metres along the screen normal).
pub const FACE_NEAR: f64 = 0.01;
/// See [`FACE_NEAR`].
pub const FACE_FAR: f64 = 20.0;

/// The compiled face pipeline.
#[derive(Debug)]
pub struct FacePipeline {
    shadow: ShadowViewsPass,
    face: FaceViewPass,
    shadow_res: u32,
}

impl FacePipeline {
    /// Compile the passes; shadow maps get `shadow_res` texels per side.
    pub fn new(device: &wgpu::Device, shadow_res: u32) -> Self {
        Self {
            shadow: ShadowViewsPass::new(device),
            face: FaceViewPass::new(device),
            shadow_res: shadow_res.max(1),
        }
    }

    /// Draw the views of `eyes` through `face` (the light shadow views
    /// and the `other_eyes`' views once, shared) and submit; one target
    /// per eye.
    pub fn draw(
        &self,
        ctx: &GpuContext,
        frame: &FrameScene,
        face: &CrtFace,
        eyes: &[DVec3],
        other_eyes: &[DVec3],
        passes: &PassList,
    ) -> Result<Vec<OffscreenTarget>, RenderSetupError> {
        let device = &ctx.device;
        let (all, ranges) = world_vertices_by_object(&frame.showcase, None)?;
        let far = shadow_far(frame, &all, eyes.first().copied().unwrap_or(DVec3::ZERO));
        let shadows = passes.runs(Pass::LightShadowViews);
        let (mut views, lights) = light_inputs(frame, shadows, 1e-3, far, self.shadow_res);
        let light_layers = 0..views.len() as u32;
        let occluding = passes.runs(Pass::EyeShadowViews);
        let virtual_points = all_ranges_points(frame, &all, &ranges);
        let virtual_sphere = bounding_sphere(virtual_points.into_iter());
        let mut others = Vec::with_capacity(other_eyes.len());
        for e in other_eyes {
            let first = views.len() as u32;
            if let (true, Some((c, r))) = (occluding, virtual_sphere) {
                views.extend(fitted_views(
                    e.as_vec3(),
                    c.as_vec3(),
                    (r * 1.001 + 1e-6) as f32,
                    1e-3,
                    far,
                    self.shadow_res,
                ));
            }
            others.push(EyeGpu {
                position: e.as_vec3().extend(0.0).to_array(),
                views: [first, views.len() as u32 - first, 0, 0],
            });
        }
        let eye_layers = light_layers.end..views.len() as u32;
        let maps = ShadowMaps::new(device, self.shadow_res, views.len() as u32)?;
        let views_buffer = self.shadow.upload_views(device, &views);
        let placeholder = [WorldVertex {
            position: [0.0; 3],
            normal: [0.0; 3],
        }];
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("face vertices"),
            contents: bytemuck::cast_slice(if all.is_empty() {
                &placeholder[..]
            } else {
                &all
            }),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let mut phantoms = Vec::new();
        let mut virtuals = Vec::new();
        let mut virtual_vertices = Vec::new();
        for (oi, r) in ranges {
            let o = &frame.showcase.objects[oi];
            let albedo = o.material.albedo.extend(0.0).to_array();
            match o.kind {
                ObjectKind::Real => phantoms.push((r, albedo)),
                ObjectKind::Virtual => {
                    virtual_vertices.extend_from_slice(&all[r.start as usize..r.end as usize]);
                    virtuals.push((r, albedo));
                }
            }
        }
        let mut encoder = device.create_command_encoder(&Default::default());
        let virtual_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("face virtual vertices"),
            contents: bytemuck::cast_slice(if virtual_vertices.is_empty() {
                &placeholder[..]
            } else {
                &virtual_vertices
            }),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let mut draws = Vec::new();
        if shadows {
            draws.push(ShadowDraw {
                vertices: &vertices,
                vertex_count: all.len() as u32,
                layers: light_layers,
            });
        }
        if occluding {
            draws.push(ShadowDraw {
                vertices: &virtual_buffer,
                vertex_count: virtual_vertices.len() as u32,
                layers: eye_layers,
            });
        }
        self.shadow
            .encode(device, &mut encoder, &maps, &views_buffer, &draws);
        let mut targets = Vec::with_capacity(eyes.len());
        for &eye in eyes {
            let view =
                FaceView::new(face, eye, FACE_NEAR, FACE_FAR).ok_or(RenderSetupError::NonFinite)?;
            let target = OffscreenTarget::new(device, face.width, face.height)?;
            let inputs = FaceInputs {
                frame: FaceFrameUniform {
                    clip_from_world: view.clip_from_world.as_mat4().to_cols_array_2d(),
                    eye: eye.as_vec3().extend(0.0).to_array(),
                    ambient: frame.ambient().as_vec3().extend(0.0).to_array(),
                    counts: [
                        lights.len() as u32,
                        others.len() as u32,
                        self.shadow_res,
                        u32::from(shadows) | (u32::from(occluding) << 1),
                    ],
                },
                lights: &lights,
                views: &views_buffer,
                maps: &maps,
                vertices: &vertices,
                phantoms: &phantoms,
                other_eyes: &others,
                virtuals: &virtuals,
            };
            self.face.encode(device, &mut encoder, &target, &inputs);
            targets.push(target);
        }
        ctx.queue.submit([encoder.finish()]);
        Ok(targets)
    }

    /// Read drawn targets back: linear RGBA per eye, alpha 1 where a
    /// virtual object is drawn; non-finite values become 0.
    pub fn read(
        &self,
        ctx: &GpuContext,
        targets: &[OffscreenTarget],
    ) -> Result<Vec<Vec<[f32; 4]>>, RenderSetupError> {
        let device = &ctx.device;
        targets
            .iter()
            .map(|t| {
                Ok(t.read_rgba_f32(device, &ctx.queue)?
                    .into_iter()
                    .map(|p| p.map(|c| if c.is_finite() { c } else { 0.0 }))
                    .collect())
            })
            .collect()
    }

    /// [`Self::draw`] then [`Self::read`].
    pub fn render(
        &self,
        ctx: &GpuContext,
        frame: &FrameScene,
        face: &CrtFace,
        eyes: &[DVec3],
        other_eyes: &[DVec3],
        passes: &PassList,
    ) -> Result<Vec<Vec<[f32; 4]>>, RenderSetupError> {
        let targets = self.draw(ctx, frame, face, eyes, other_eyes, passes)?;
        self.read(ctx, &targets)
    }
}

/// The eyes of every observer but `observer` (two per head, in order).
pub fn other_eyes(frame: &FrameScene, observer: usize) -> Vec<DVec3> {
    frame
        .eyes
        .iter()
        .enumerate()
        .filter(|(i, _)| i / 2 != observer)
        .map(|(_, e)| *e)
        .collect()
}

/// World points of the virtual objects' vertices.
fn all_ranges_points(
    frame: &FrameScene,
    all: &[WorldVertex],
    ranges: &[ObjectRange],
) -> Vec<DVec3> {
    ranges
        .iter()
        .filter(|(oi, _)| frame.showcase.objects[*oi].kind == ObjectKind::Virtual)
        .flat_map(|(_, r)| all[r.start as usize..r.end as usize].iter())
        .map(|v| glam::Vec3::from_array(v.position).as_dvec3())
        .collect()
}

/// The [`Renderer`] of a face node: both eyes of one observer through one
/// face, left eye in the left half of the output image.
#[derive(Debug)]
pub struct FaceRenderer {
    ctx: GpuContext,
    pipeline: FacePipeline,
    face: usize,
    observer: usize,
    scene_version: Option<u64>,
    last_passes: Vec<Pass>,
    last: Option<(FrameKey, RenderOutput)>,
    presented: Vec<u64>,
}

impl FaceRenderer {
    /// A renderer for `Showcase::faces[face]` seen by head `observer`.
    pub fn new(ctx: GpuContext, face: usize, observer: usize, shadow_res: u32) -> Self {
        let pipeline = FacePipeline::new(&ctx.device, shadow_res);
        Self {
            ctx,
            pipeline,
            face,
            observer,
            scene_version: None,
            last_passes: Vec::new(),
            last: None,
            presented: Vec::new(),
        }
    }

    /// Passes the last frame ran (empty when it reused the frame before).
    pub fn last_passes(&self) -> &[Pass] {
        &self.last_passes
    }

    fn render_frame(
        &mut self,
        frame: &FrameState,
        scene: &Showcase,
    ) -> Result<RenderOutput, RenderError> {
        let face = scene
            .faces
            .get(self.face)
            .ok_or_else(|| RenderError(format!("the scene has no face {}", self.face)))?;
        let head = frame.heads.get(self.observer).ok_or_else(|| {
            RenderError(format!(
                "frame {} has no head {}",
                frame.frame, self.observer
            ))
        })?;
        let ipd = scene
            .observers
            .get(self.observer)
            .map_or(DEFAULT_IPD, |o| o.ipd);
        let eyes = showcase_proto::Observer::eyes(head, ipd).map(|e| e.as_dvec3());
        let key = FrameKey::face(self.face, self.observer, frame);
        if let Some((last_key, output)) = &self.last
            && *last_key == key
        {
            self.last_passes.clear();
            return Ok(output.clone());
        }
        let resolved = FrameScene::resolve(scene, frame).map_err(|e| RenderError(e.to_string()))?;
        let other_eyes = other_eyes(&resolved, self.observer);
        let passes = PassList::for_face(&resolved, other_eyes.len());
        let images = self
            .pipeline
            .render(&self.ctx, &resolved, face, &eyes, &other_eyes, &passes)
            .map_err(|e| RenderError(e.to_string()))?;
        let (w, h) = (face.width as usize, face.height as usize);
        let mut rgba = Vec::with_capacity(2 * w * h);
        for y in 0..h {
            for image in &images {
                rgba.extend_from_slice(&image[y * w..(y + 1) * w]);
            }
        }
        self.last_passes = passes.passes;
        let output = RenderOutput {
            hash: hash_pixels(&rgba),
            image: Some(OutputImage {
                width: 2 * face.width,
                height: face.height,
                rgba,
            }),
        };
        self.last = Some((key, output.clone()));
        Ok(output)
    }
}

impl Renderer for FaceRenderer {
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
                "face {}: frame {} is for scene version {} but the renderer has {:?}",
                self.face, frame.frame, frame.scene_version, self.scene_version
            )));
        }
        self.render_frame(frame, scene)
    }

    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        self.presented.push(frame);
        Ok(())
    }
}
