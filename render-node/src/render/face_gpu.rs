//! The face role on the GPU: per-eye views through a CRT face with phantom
//! depth, shadow types 2 and 3, occluding occlusion shadows and cube-map
//! reflections (kept across frames while the lights and the geometry stay
//! put), and the [`Renderer`] of a face node
//! (both eyes of one observer, side by side). CPU reference:
//! [`showcase_light::render::face::face_image_cpu`].

use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;
use showcase_proto::{CrtFace, FrameState, ObjectKind, Showcase};

use super::RenderSetupError;
use super::gpu_scene::{SceneBuffers, VertexSet, ensure_maps, stable_far};
use super::passes::bounding_sphere;
use super::passes::{FrameKey, Pass, PassList};
use super::projector_gpu::{ObjectRange, PassTimes, light_inputs, shadow_far};
use super::renderer::{OutputImage, RenderError, RenderOutput, Renderer, check_scene_version};
use crate::gpu::cube_map::{CubeDraws, CubeMapFrames};
use crate::gpu::face_view::NO_OWN_EYE;
use crate::gpu::face_view::{
    self, FaceBindGroup, FaceBindings, FaceDraws, FaceFrameUniform, FaceViewPass,
};
use crate::gpu::frame_arrays::{ARRAY_USAGE, ArraySpace};
use crate::gpu::shadow_lookup::{EyeGpu, LightSampleGpu};
use crate::gpu::shadow_views::{SHADOW_NEAR, fitted_views};
use crate::gpu::shadow_views::{ShadowDraw, ShadowMaps, ShadowViewsPass, WorldVertex};
use crate::gpu::target::{ColourReadback, read_colours};
use crate::gpu::upload::UploadBuffer;
use crate::gpu::{GpuContext, OffscreenTarget, wait_idle};
use showcase_light::digest::{Fnv64, hash_pixels};
use showcase_light::mirror_view::FaceView;
use showcase_light::render::cube_map::{DEFAULT_CUBE_RES, reflective_centres};
use showcase_light::render::frame::FrameScene;

/// Near and far clip distances of face views (metres along the screen normal).
pub const FACE_NEAR: f64 = 0.01;
/// See [`FACE_NEAR`].
pub const FACE_FAR: f64 = 20.0;

/// The compiled face pipeline and the GPU state it keeps across frames
/// (create once per device and face): the scene's vertices (uploaded when
/// they change), the shadow maps (a layer whose light or eye did not move
/// is not drawn again), the cube maps (drawn again only when what they
/// show changed), per-frame uploads, bind groups, one target and
/// readback buffer per eye.
#[derive(Debug)]
pub struct FacePipeline {
    shadow: ShadowViewsPass,
    face: FaceViewPass,
    shadow_res: u32,
    scene: SceneBuffers,
    lights: UploadBuffer,
    views: UploadBuffer,
    albedos: UploadBuffer,
    other_eyes: UploadBuffer,
    maps: Option<ShadowMaps>,
    shadow_bind: Option<(u64, wgpu::BindGroup)>,
    cubes: CubeMapFrames,
    eyes: Vec<EyeResources>,
    /// How many of `eyes` the last frame drew.
    drawn: usize,
    last_layers_drawn: u32,
    /// Cube maps the last frame used.
    cube_count: usize,
}

/// One eye's uniform, bind group, target and readback buffer.
#[derive(Debug)]
struct EyeResources {
    frame: UploadBuffer,
    /// The bind group and the buffer (and cube map) generations and the
    /// array space it names.
    bind: Option<(([u64; 6], ArraySpace), FaceBindGroup)>,
    target: OffscreenTarget,
    readback: ColourReadback,
}

impl FacePipeline {
    /// Compile the passes; shadow maps get `shadow_res` texels per side,
    /// cube maps [`DEFAULT_CUBE_RES`].
    pub fn new(device: &wgpu::Device, shadow_res: u32) -> Self {
        Self::with_cube_res(device, shadow_res, DEFAULT_CUBE_RES)
    }

    /// [`Self::new`] with cube maps of `cube_res` texels per side.
    pub fn with_cube_res(device: &wgpu::Device, shadow_res: u32, cube_res: u32) -> Self {
        // Bindable as the face shader's uniform arrays (whole capacity)
        // or as storage (the shadow views pass, long frames).
        let array = |label, name, element: usize| {
            let bytes = face_view::capacity(name) * element;
            UploadBuffer::with_min_size(device, label, ARRAY_USAGE, bytes as u64)
        };
        Self {
            shadow: ShadowViewsPass::new(device),
            face: FaceViewPass::new(device),
            shadow_res: shadow_res.max(1),
            scene: SceneBuffers::new(device),
            lights: array("face lights", "lights", size_of::<LightSampleGpu>()),
            views: array(
                "face shadow views",
                "views",
                size_of::<crate::gpu::shadow_views::ShadowView>(),
            ),
            albedos: array("face albedos", "albedos", size_of::<[f32; 4]>()),
            other_eyes: array("face other eyes", "eyes", size_of::<EyeGpu>()),
            maps: None,
            shadow_bind: None,
            cubes: CubeMapFrames::new(device, cube_res),
            eyes: Vec::new(),
            drawn: 0,
            last_layers_drawn: 0,
            cube_count: 0,
        }
    }

    /// Shadow map layers the last [`Self::draw`] drew (the others held
    /// the same view and geometry already).
    pub fn last_layers_drawn(&self) -> u32 {
        self.last_layers_drawn
    }

    /// Cube map layers the last [`Self::draw`] drew (0 when it kept them).
    pub fn last_cube_layers_drawn(&self) -> u32 {
        self.cubes.last_layers_drawn()
    }

    /// Read the cube maps back (after a draw that ran
    /// [`Pass::CubeMaps`]): per map, its six faces of `res * res` texels
    /// (linear RGB radiance, distance from the centre; `showcase_light::render::cube_map`
    /// order), maps in object order.
    pub fn read_cube_maps(&self, ctx: &GpuContext) -> Result<Vec<Vec<Vec<[f32; 4]>>>, RenderError> {
        let Some(maps) = self.cubes.maps() else {
            return Err(RenderError::NothingDrawn);
        };
        let mut layers = maps.read(&ctx.device, &ctx.queue)?.into_iter();
        Ok((0..self.cube_count)
            .map(|_| layers.by_ref().take(6).collect())
            .collect())
    }

    /// Draw the views of `eyes` through `face` (the light shadow views
    /// and the `other_eyes`' views once, shared) and submit; one target
    /// per eye. With `timed`, each step is submitted and waited for
    /// separately and its wall time returned.
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameScene,
        face: &CrtFace,
        eyes: &[DVec3],
        other_eyes: &[DVec3],
        passes: &PassList,
        timed: bool,
    ) -> Result<PassTimes, RenderError> {
        let (device, queue) = (&ctx.device, &ctx.queue);
        let start = Instant::now();
        self.scene.update(device, queue, &frame.showcase)?;
        let far = stable_far(shadow_far(
            frame,
            self.scene.all(),
            eyes.first().copied().unwrap_or(DVec3::ZERO),
        ));
        let shadows = passes.runs(Pass::LightShadowViews);
        let (mut views, lights) = light_inputs(frame, shadows, SHADOW_NEAR, far, self.shadow_res);
        let light_layers = 0..views.len() as u32;
        let occluding = passes.runs(Pass::EyeShadowViews);
        let virtual_sphere = if occluding {
            bounding_sphere(virtual_points(frame, self.scene.all(), self.scene.ranges()))
        } else {
            None
        };
        // Every tracked eye but the drawn one casts occlusion shadows this
        // view fills: the other observers' eyes, then this observer's own
        // eyes (each eye's uniform names its own entry, which it skips).
        let mut others = Vec::with_capacity(other_eyes.len() + eyes.len());
        for e in other_eyes.iter().chain(eyes) {
            let first = views.len() as u32;
            if let (true, Some((c, r))) = (occluding, virtual_sphere) {
                views.extend(fitted_views(
                    e.as_vec3(),
                    c.as_vec3(),
                    (r * 1.001 + 1e-6) as f32,
                    SHADOW_NEAR,
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
        let cubes = passes.runs(Pass::CubeMaps);
        let centres = if cubes {
            reflective_centres(frame)
        } else {
            Vec::new()
        };
        let mut phantoms = Vec::new();
        let mut virtuals = Vec::new();
        let mut mirrors = Vec::new();
        let mut albedo = Vec::new();
        let mut phantom_albedo = Vec::new();
        for (oi, r) in self.scene.ranges() {
            let o = &frame.showcase.objects[*oi];
            // w: 1 + the object's cube map, 0 for none (face_view.wgsl).
            let map = centres.iter().position(|(c, _)| c == oi);
            let a = o
                .material
                .albedo
                .extend(map.map_or(0.0, |k| k as f32 + 1.0));
            let a = a.to_array();
            match o.kind {
                ObjectKind::Real => {
                    phantoms.push(r.clone());
                    phantom_albedo.push(a);
                }
                ObjectKind::Virtual => {
                    virtuals.push(r.clone());
                    mirrors.push(map.is_some());
                    albedo.push(a);
                }
            }
        }
        // Instances: virtual objects first, then phantoms; after them
        // the cube maps' centres (the distance-corrected lookup's origin).
        albedo.extend(phantom_albedo);
        let first_centre = albedo.len() as u32;
        albedo.extend(
            centres
                .iter()
                .map(|(_, c)| c.as_vec3().extend(0.0).to_array()),
        );

        let maps_changed =
            ensure_maps(&mut self.maps, device, self.shadow_res, views.len() as u32)?;
        if maps_changed {
            self.eyes.iter_mut().for_each(|e| e.bind = None);
        }
        self.views.write(device, queue, &views);
        self.lights.write(device, queue, &lights);
        self.albedos.write(device, queue, &albedo);
        self.other_eyes.write(device, queue, &others);
        let space = face_view::space(lights.len(), views.len(), albedo.len(), others.len());
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
        let (cube_res, shadow_res) = (self.cubes.res(), self.shadow_res);
        let base =
            |clip_from_world, eye: DVec3, others: u32, own: u32, flags: u32| FaceFrameUniform {
                clip_from_world,
                eye: eye.as_vec3().extend(0.0).to_array(),
                ambient: frame.ambient().as_vec3().extend(0.0).to_array(),
                counts: [lights.len() as u32, others, shadow_res, flags],
                shadow: [SHADOW_NEAR, far, 0.0, 0.0],
                cube: [cube_res, centres.len() as u32, first_centre, 0],
                own: [own, 0, 0, 0],
            };
        // The maps show the lights, every object's geometry (phantoms,
        // and virtual objects as shadow casters), the phantoms' albedos
        // and the light views.
        let mut content = Fnv64::default();
        content.write(&self.scene.geometry(VertexSet::All).to_le_bytes());
        content.write(bytemuck::cast_slice(&albedo));
        content.write(bytemuck::cast_slice(&lights));
        content.write(bytemuck::cast_slice(
            &views[light_layers.start as usize..light_layers.end as usize],
        ));
        let cube_centres: Vec<glam::Vec3> = centres.iter().map(|(_, c)| c.as_vec3()).collect();
        self.cubes.reserve(device, centres.len())?;
        let draw_cubes = cubes
            && self.cubes.prepare(
                device,
                queue,
                &cube_centres,
                &base(
                    [[0.0; 4]; 4],
                    DVec3::ZERO,
                    0,
                    NO_OWN_EYE,
                    u32::from(shadows),
                ),
                FACE_FAR as f32,
                content.finish(),
            )?;
        self.cube_count = centres.len();
        let cube_generation = self.cubes.generation();
        let Some(cube_maps) = self.cubes.maps() else {
            return Err(RenderError::NothingDrawn);
        };
        let Some(maps) = self.maps.as_mut() else {
            return Err(RenderError::NothingDrawn);
        };
        // Per-eye uniforms, bind groups and targets.
        if self.eyes.len() < eyes.len()
            || self
                .eyes
                .iter()
                .any(|e| (e.target.width(), e.target.height()) != (face.width, face.height))
        {
            self.eyes = (0..eyes.len())
                .map(|_| {
                    Ok(EyeResources {
                        frame: UploadBuffer::new(device, "face frame", wgpu::BufferUsages::UNIFORM),
                        bind: None,
                        target: OffscreenTarget::new(device, face.width, face.height)?,
                        readback: ColourReadback::new(device, face.width, face.height),
                    })
                })
                .collect::<Result<_, RenderError>>()?;
        }
        for (k, (&eye, res)) in eyes.iter().zip(self.eyes.iter_mut()).enumerate() {
            let view =
                FaceView::new(face, eye, FACE_NEAR, FACE_FAR).ok_or(RenderSetupError::NonFinite)?;
            let uniform = base(
                view.clip_from_world.as_mat4().to_cols_array_2d(),
                eye,
                others.len() as u32,
                (other_eyes.len() + k) as u32,
                u32::from(shadows) | (u32::from(occluding) << 1),
            );
            res.frame.write(device, queue, &[uniform]);
            let generations = (
                [
                    res.frame.generation(),
                    self.lights.generation(),
                    views_generation,
                    self.albedos.generation(),
                    self.other_eyes.generation(),
                    cube_generation,
                ],
                space,
            );
            if res.bind.as_ref().is_none_or(|(g, _)| *g != generations) {
                let bind = self.face.bind_group(
                    device,
                    &FaceBindings {
                        frame: res.frame.buffer(),
                        lights: self.lights.buffer(),
                        views: self.views.buffer(),
                        maps,
                        albedos: self.albedos.buffer(),
                        other_eyes: self.other_eyes.buffer(),
                        cube_maps: Some(cube_maps.array_view()),
                        space,
                    },
                );
                res.bind = Some((generations, bind));
            }
        }
        let Some((_, shadow_bind)) = &self.shadow_bind else {
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
            let (vertices, vertex_count) = self.scene.buffer(VertexSet::All);
            layers_drawn += self.shadow.encode(
                &mut encoder,
                maps,
                shadow_bind,
                &views,
                &[ShadowDraw {
                    vertices,
                    vertex_count,
                    layers: light_layers,
                    geometry: self.scene.geometry(VertexSet::All),
                }],
            );
            flush(&mut encoder, Pass::LightShadowViews.name())?;
        }
        if occluding {
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
        let (vertices, _) = self.scene.buffer(VertexSet::All);
        if draw_cubes {
            let bindings = FaceBindings {
                // Replaced by each layer's own uniform.
                frame: self.lights.buffer(),
                lights: self.lights.buffer(),
                views: self.views.buffer(),
                maps,
                albedos: self.albedos.buffer(),
                other_eyes: self.other_eyes.buffer(),
                cube_maps: None,
                space,
            };
            let draws = CubeDraws {
                vertices,
                phantoms: &phantoms,
                first_instance: virtuals.len() as u32,
            };
            self.cubes
                .encode(device, &mut encoder, centres.len(), &bindings, &draws);
            flush(&mut encoder, Pass::CubeMaps.name())?;
        } else {
            self.cubes.kept();
        }
        // Without virtual objects the phantoms have nothing to hide and no
        // occlusion shadow to fill (the eyes' views are empty), so they
        // would draw the clear colour: skip them (the image is the same).
        let nothing_virtual = virtuals.iter().all(|r| r.is_empty());
        let draws = FaceDraws {
            vertices,
            phantoms: if nothing_virtual { &[] } else { &phantoms },
            virtuals: &virtuals,
            mirrors: &mirrors,
        };
        for res in self.eyes.iter().take(eyes.len()) {
            if let Some((_, bind)) = &res.bind {
                self.face.encode(&mut encoder, &res.target, bind, &draws);
            }
        }
        flush(&mut encoder, Pass::FaceView.name())?;
        queue.submit([encoder.finish()]);
        self.drawn = eyes.len();
        self.last_layers_drawn = layers_drawn;
        Ok(times)
    }

    /// Read the last frame's targets back: linear RGBA per eye, alpha 1
    /// where a virtual object is drawn; non-finite values become 0.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<Vec<[f32; 4]>>, RenderError> {
        let drawn = &self.eyes[..self.drawn.min(self.eyes.len())];
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        for e in drawn {
            e.readback.encode_copy(&mut encoder, &e.target);
        }
        ctx.queue.submit([encoder.finish()]);
        let readbacks: Vec<&ColourReadback> = drawn.iter().map(|e| &e.readback).collect();
        Ok(read_colours(&ctx.device, &readbacks)?)
    }

    /// [`Self::draw`] then [`Self::read`].
    pub fn render(
        &mut self,
        ctx: &GpuContext,
        frame: &FrameScene,
        face: &CrtFace,
        eyes: &[DVec3],
        other_eyes: &[DVec3],
        passes: &PassList,
    ) -> Result<Vec<Vec<[f32; 4]>>, RenderError> {
        self.draw(ctx, frame, face, eyes, other_eyes, passes, false)?;
        self.read(ctx)
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
fn virtual_points<'a>(
    frame: &'a FrameScene,
    all: &'a [WorldVertex],
    ranges: &'a [ObjectRange],
) -> impl Iterator<Item = DVec3> + 'a {
    ranges
        .iter()
        .filter(|(oi, _)| frame.showcase.objects[*oi].kind == ObjectKind::Virtual)
        .flat_map(|(_, r)| all[r.start as usize..r.end as usize].iter())
        .map(|v| glam::Vec3::from_array(v.position).as_dvec3())
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
            .ok_or(RenderError::NoFace { index: self.face })?;
        let head = frame.heads.get(self.observer).ok_or(RenderError::NoHead {
            frame: frame.frame,
            observer: self.observer,
        })?;
        let ipd = scene
            .observers
            .get(self.observer)
            .map_or(showcase_proto::Observer::DEFAULT_IPD, |o| o.ipd);
        let eyes = showcase_proto::Observer::eyes(head, ipd).map(|e| e.as_dvec3());
        let key = FrameKey::face(self.face, self.observer, frame);
        if let Some((last_key, output)) = &self.last
            && *last_key == key
        {
            self.last_passes.clear();
            return Ok(output.clone());
        }
        let resolved = FrameScene::resolve(scene, frame)?;
        let other_eyes = other_eyes(&resolved, self.observer);
        let passes = PassList::for_face(&resolved, other_eyes.len() + eyes.len() - 1);
        let images =
            self.pipeline
                .render(&self.ctx, &resolved, face, &eyes, &other_eyes, &passes)?;
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
        check_scene_version(&format!("face {}", self.face), frame, self.scene_version)?;
        self.render_frame(frame, scene)
    }

    fn present(&mut self, frame: u64) -> Result<(), RenderError> {
        self.presented.push(frame);
        Ok(())
    }
}
