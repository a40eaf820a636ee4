//! The face role on the GPU: per-eye views through a CRT face with phantom
//! depth, shadow types 2 and 3, occluding occlusion shadows and cube-map
//! reflections (kept across frames while the lights and the geometry stay
//! put), drawn after the frame layer's shadow stage, and the
//! [`Renderer`](super::Renderer) of a face node (both eyes of one
//! observer, side by side). CPU reference:
//! [`showcase_light::render::face::face_image_cpu`].

use std::ops::Range;

use glam::{DVec3, Vec3};
use showcase_proto::{CrtFace, ObjectKind};

use super::RenderSetupError;
use super::gpu_frame::{
    FrameInputs, LightOccluders, ObjectRange, PassTimes, SceneBuffers, ShadowStage, TimedEncoder,
    VertexSet,
};
use super::passes::{Pass, PassList};
use super::renderer::RenderError;
use crate::gpu::cube_map::{CubeDraws, CubeMapFrames};
use crate::gpu::face_view::{
    self, FaceBindGroup, FaceBindings, FaceDraws, FaceFrameUniform, FaceViewPass, NO_OWN_EYE,
};
use crate::gpu::field::FieldBuffers;
use crate::gpu::frame_arrays::{ARRAY_USAGE, ArraySpace};
use crate::gpu::shadow_lookup::EyeGpu;
use crate::gpu::shadow_views::SHADOW_NEAR;
use crate::gpu::target::{ColourReadback, read_colours};
use crate::gpu::upload::UploadBuffer;
use crate::gpu::{GpuContext, OffscreenTarget};
use showcase_light::digest::Fnv64;
use showcase_light::mirror_view::FaceView;
use showcase_light::render::cube_map::{DEFAULT_CUBE_RES, reflective_centres};
use showcase_light::render::frame::FrameScene;

mod renderer;

pub use renderer::FaceRenderer;

/// Near and far clip distances of face views (metres along the screen normal).
pub const FACE_NEAR: f64 = 0.01;
/// See [`FACE_NEAR`].
pub const FACE_FAR: f64 = 20.0;

/// The compiled face pipeline and the GPU state it keeps across frames
/// (create once per device and face): the scene's vertices and the shadow
/// stage (see [`super::gpu_frame`]), the cube maps (drawn again only when
/// what they show changed), the face view's uploads, and one uniform,
/// bind group, target and readback buffer per eye.
#[derive(Debug)]
pub struct FacePipeline {
    scene: SceneBuffers,
    /// Every object as the face view draws it: split into the
    /// global-illumination field's pieces in global mode.
    field: FieldBuffers,
    shadow: ShadowStage,
    face: FaceViewPass,
    albedos: UploadBuffer,
    other_eyes: UploadBuffer,
    cubes: CubeMapFrames,
    eyes: Vec<EyeResources>,
    /// How many of `eyes` the last frame drew.
    drawn: usize,
    /// Cube maps the last frame used.
    cube_count: usize,
}

/// One eye's uniform, bind groups, targets and readback buffer.
#[derive(Debug)]
struct EyeResources {
    frame: UploadBuffer,
    /// The bind group and the buffer (and cube map) generations and the
    /// array space it names.
    bind: Option<(([u64; 6], ArraySpace), FaceBindGroup)>,
    /// The seen-through pass's bind group (made with `bind`).
    seen_bind: Option<FaceBindGroup>,
    target: OffscreenTarget,
    /// What the eye sees of the real surfaces' own interreflection
    /// (global mode; zero in direct mode: textures start cleared).
    seen: OffscreenTarget,
    /// Whether `seen` holds a drawn image (to clear once back in direct
    /// mode).
    seen_drawn: bool,
    readback: ColourReadback,
}

/// The objects of a face frame as draw instances: the virtual objects,
/// then the phantoms (the real objects), each with its albedo, and the
/// cube maps of the reflective virtual objects.
#[derive(Debug, Default)]
struct Instances {
    /// Vertex range of each phantom.
    phantoms: Vec<Range<u32>>,
    /// Vertex range of each virtual object.
    virtuals: Vec<Range<u32>>,
    /// Whether each virtual object is a mirror with a cube map.
    mirrors: Vec<bool>,
    /// Per instance its albedo, w 1 + its cube map (0 for none); after
    /// the instances, each cube map's centre.
    albedos: Vec<[f32; 4]>,
    /// The entry of `albedos` holding cube map 0's centre.
    first_centre: u32,
    /// The cube maps' centres, in object order.
    centres: Vec<Vec3>,
}

/// What one face frame draws, gathered on the CPU before anything is
/// uploaded or encoded.
#[derive(Debug)]
struct FaceFrame {
    /// The frame layer's inputs (light samples, filled eyes, views).
    inputs: FrameInputs,
    /// The objects as draw instances.
    instances: Instances,
    /// The frame uniform every eye's and cube layer's starts from: no
    /// view, no eye, no filled eyes, light shadows only.
    base: FaceFrameUniform,
    /// Where the shader reads its arrays from.
    space: ArraySpace,
}

impl Instances {
    /// The instances of the objects of `ranges` (the scene buffers'), with
    /// a cube map per reflective virtual object when `cubes`; each range
    /// as `field` draws it.
    fn new(frame: &FrameScene, ranges: &[ObjectRange], field: &FieldBuffers, cubes: bool) -> Self {
        let centres = if cubes {
            reflective_centres(frame)
        } else {
            Vec::new()
        };
        let mut out = Self::default();
        let mut phantom_albedos = Vec::new();
        for (oi, r) in ranges {
            let o = &frame.showcase.objects[*oi];
            let r = &field.range(r);
            // w: 1 + the object's cube map, 0 for none (face_view.wgsl).
            let map = centres.iter().position(|(c, _)| c == oi);
            let a = o
                .material
                .albedo
                .extend(map.map_or(0.0, |k| k as f32 + 1.0))
                .to_array();
            match o.kind {
                ObjectKind::Real => {
                    out.phantoms.push(r.clone());
                    phantom_albedos.push(a);
                }
                ObjectKind::Virtual => {
                    out.virtuals.push(r.clone());
                    out.mirrors.push(map.is_some());
                    out.albedos.push(a);
                }
            }
        }
        // Instances: virtual objects first, then phantoms; after them
        // the cube maps' centres (the distance-corrected lookup's origin).
        out.albedos.extend(phantom_albedos);
        out.first_centre = out.albedos.len() as u32;
        out.centres = centres.iter().map(|(_, c)| c.as_vec3()).collect();
        let centre_entries = out.centres.iter().map(|c| c.extend(0.0).to_array());
        out.albedos.extend(centre_entries);
        out
    }
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
        // or as storage (long frames).
        let array = |label, name, element: usize| {
            let bytes = face_view::capacity(name) * element;
            UploadBuffer::with_min_size(device, label, ARRAY_USAGE, bytes as u64)
        };
        Self {
            scene: SceneBuffers::new(device),
            field: FieldBuffers::new(device),
            shadow: ShadowStage::new(device, shadow_res, face_view::capacity),
            face: FaceViewPass::new(device),
            albedos: array("face albedos", "albedos", size_of::<[f32; 4]>()),
            other_eyes: array("face other eyes", "eyes", size_of::<EyeGpu>()),
            cubes: CubeMapFrames::new(device, cube_res),
            eyes: Vec::new(),
            drawn: 0,
            cube_count: 0,
        }
    }

    /// Shadow map layers the last [`Self::draw`] drew (the others held
    /// the same view and geometry already).
    pub fn last_layers_drawn(&self) -> u32 {
        self.shadow.last_layers_drawn()
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
        let mut steps = TimedEncoder::new(ctx, timed);
        self.scene
            .update(&ctx.device, &ctx.queue, &frame.showcase)?;
        self.field.update(
            &ctx.device,
            &ctx.queue,
            frame.indirect.as_ref(),
            self.scene.all(),
            self.scene.all_triangles(),
            self.scene.generation(),
        );
        // Every tracked eye but the drawn one casts occlusion shadows this
        // view fills: the other observers' eyes, then this observer's own
        // eyes (each eye's uniform names its own entry, which it skips).
        let filled = other_eyes.iter().chain(eyes).copied();
        let from = eyes.first().copied().unwrap_or(DVec3::ZERO);
        let res = self.shadow.res();
        let inputs = FrameInputs::new(frame, &self.scene, from, filled, passes, res);
        let cubes = passes.runs(Pass::CubeMaps);
        let f = self.face_frame(frame, inputs, cubes);
        self.upload(ctx, &f)?;
        let draw_cubes = cubes && self.prepare_cube_maps(ctx, &f)?;
        self.prepare_eyes(ctx, face, eyes, other_eyes.len(), &f)?;
        steps.step("setup")?;
        // The face looks the light maps up from virtual surfaces too.
        let occluders = LightOccluders::Every;
        self.shadow
            .encode(&mut steps, &self.scene, frame, &f.inputs, occluders)?;
        self.encode_cube_maps(ctx, &mut steps, draw_cubes, &f)?;
        self.encode_views(steps.encoder(), eyes.len(), &f.instances);
        steps.step(Pass::FaceView.name())?;
        self.drawn = eyes.len();
        Ok(steps.submit())
    }

    /// The instances, base uniform and array space of a frame of
    /// `inputs`, with cube maps when `cubes`.
    fn face_frame(&self, frame: &FrameScene, inputs: FrameInputs, cubes: bool) -> FaceFrame {
        let instances = Instances::new(frame, self.scene.ranges(), &self.field, cubes);
        let base = FaceFrameUniform {
            clip_from_world: [[0.0; 4]; 4],
            eye: [0.0; 4],
            ambient: frame.ambient().as_vec3().extend(0.0).to_array(),
            counts: [
                inputs.lights.len() as u32,
                0,
                self.shadow.res(),
                u32::from(inputs.shadows),
            ],
            shadow: [SHADOW_NEAR, inputs.far, 0.0, 0.0],
            cube: [
                self.cubes.res(),
                instances.centres.len() as u32,
                instances.first_centre,
                0,
            ],
            own: [NO_OWN_EYE, 0, 0, 0],
        };
        let space = face_view::space(
            inputs.lights.len(),
            inputs.views.len(),
            instances.albedos.len(),
            inputs.eyes.len(),
        );
        FaceFrame {
            inputs,
            instances,
            base,
            space,
        }
    }

    /// Prepare the shadow stage, upload the albedos and the filled eyes
    /// (the eyes' bind groups are rebuilt when the maps were reallocated)
    /// and make room for a cube map per centre.
    fn upload(&mut self, ctx: &GpuContext, f: &FaceFrame) -> Result<(), RenderError> {
        let (device, queue) = (&ctx.device, &ctx.queue);
        if self.shadow.prepare(device, queue, &f.inputs)? {
            self.eyes.iter_mut().for_each(|e| e.bind = None);
        }
        self.albedos.write(device, queue, &f.instances.albedos);
        self.other_eyes.write(device, queue, &f.inputs.eyes);
        self.cubes.reserve(device, f.instances.centres.len())?;
        self.cube_count = f.instances.centres.len();
        Ok(())
    }

    /// Whether what the cube maps show changed since they were drawn,
    /// so that [`Self::encode_cube_maps`] must draw them (the layers'
    /// uniforms are uploaded then); only for a frame that runs
    /// [`Pass::CubeMaps`].
    fn prepare_cube_maps(&mut self, ctx: &GpuContext, f: &FaceFrame) -> Result<bool, RenderError> {
        // The maps show the lights, every object's geometry (phantoms,
        // and virtual objects as shadow casters), the phantoms' albedos
        // and the light views.
        let mut content = Fnv64::default();
        content.write(&self.scene.geometry(VertexSet::All).to_le_bytes());
        content.write(bytemuck::cast_slice(&f.instances.albedos));
        content.write(&self.field.content().to_le_bytes());
        content.write(bytemuck::cast_slice(&f.inputs.lights));
        let light_layers = &f.inputs.light_layers;
        content.write(bytemuck::cast_slice(
            &f.inputs.views[light_layers.start as usize..light_layers.end as usize],
        ));
        Ok(self.cubes.prepare(
            &ctx.device,
            &ctx.queue,
            &f.instances.centres,
            &f.base,
            FACE_FAR as f32,
            content.finish(),
        )?)
    }

    /// Each drawn eye's target (all made again when the face's size
    /// changed or more eyes are drawn), uniform and bind group; the eyes'
    /// own entries in the filled eyes follow the `first_own` others.
    fn prepare_eyes(
        &mut self,
        ctx: &GpuContext,
        face: &CrtFace,
        eyes: &[DVec3],
        first_own: usize,
        f: &FaceFrame,
    ) -> Result<(), RenderError> {
        let (device, queue) = (&ctx.device, &ctx.queue);
        self.ensure_eye_targets(device, face, eyes.len())?;
        let (inputs, base, space) = (&f.inputs, &f.base, f.space);
        let flags = u32::from(inputs.shadows)
            | (u32::from(inputs.occlusion) << 1)
            | (u32::from(self.field.has_field()) << 2);
        let cube_maps = self.cubes.maps().ok_or(RenderError::NothingDrawn)?;
        let (lights, views) = (self.shadow.lights(), self.shadow.views());
        for (k, (&eye, res)) in eyes.iter().zip(self.eyes.iter_mut()).enumerate() {
            let view =
                FaceView::new(face, eye, FACE_NEAR, FACE_FAR).ok_or(RenderSetupError::NonFinite)?;
            let uniform = FaceFrameUniform {
                clip_from_world: view.clip_from_world.as_mat4().to_cols_array_2d(),
                eye: eye.as_vec3().extend(0.0).to_array(),
                counts: [
                    base.counts[0],
                    inputs.eyes.len() as u32,
                    base.counts[2],
                    flags,
                ],
                own: [(first_own + k) as u32, 0, 0, 0],
                ..*base
            };
            res.frame.write(device, queue, &[uniform]);
            let generations = (
                [
                    res.frame.generation(),
                    lights.generation(),
                    views.generation(),
                    self.albedos.generation(),
                    self.other_eyes.generation(),
                    self.cubes.generation(),
                ],
                space,
            );
            if res.bind.as_ref().is_none_or(|(g, _)| *g != generations) {
                let bindings = FaceBindings {
                    frame: res.frame.buffer(),
                    lights: lights.buffer(),
                    views: views.buffer(),
                    maps: self.shadow.maps()?,
                    albedos: self.albedos.buffer(),
                    other_eyes: self.other_eyes.buffer(),
                    cube_maps: Some(cube_maps.array_view()),
                    seen_through: Some(res.seen.colour_view()),
                    space,
                };
                res.bind = Some((generations, self.face.bind_group(device, &bindings)));
                let seen = FaceBindings {
                    cube_maps: None,
                    seen_through: None,
                    ..bindings
                };
                res.seen_bind = Some(self.face.seen_through_bind_group(device, &seen));
            }
        }
        Ok(())
    }

    /// A target and readback buffer per eye of `face`'s size (all made
    /// again when the size changed or more eyes are drawn).
    fn ensure_eye_targets(
        &mut self,
        device: &wgpu::Device,
        face: &CrtFace,
        eyes: usize,
    ) -> Result<(), RenderError> {
        let size = (face.width, face.height);
        if self.eyes.len() >= eyes
            && self
                .eyes
                .iter()
                .all(|e| (e.target.width(), e.target.height()) == size)
        {
            return Ok(());
        }
        self.eyes = (0..eyes)
            .map(|_| {
                Ok(EyeResources {
                    frame: UploadBuffer::new(device, "face frame", wgpu::BufferUsages::UNIFORM),
                    bind: None,
                    seen_bind: None,
                    target: OffscreenTarget::new(device, face.width, face.height)?,
                    seen: OffscreenTarget::new(device, face.width, face.height)?,
                    seen_drawn: false,
                    readback: ColourReadback::new(device, face.width, face.height),
                })
            })
            .collect::<Result<_, RenderError>>()?;
        Ok(())
    }

    /// Draw the cube maps' layers as a step of `steps` when `draw`, or
    /// note that the maps were kept.
    fn encode_cube_maps(
        &mut self,
        ctx: &GpuContext,
        steps: &mut TimedEncoder<'_>,
        draw: bool,
        f: &FaceFrame,
    ) -> Result<(), RenderError> {
        if !draw {
            self.cubes.kept();
            return Ok(());
        }
        let lights = self.shadow.lights().buffer();
        let bindings = FaceBindings {
            // Replaced by each layer's own uniform.
            frame: lights,
            lights,
            views: self.shadow.views().buffer(),
            maps: self.shadow.maps()?,
            albedos: self.albedos.buffer(),
            other_eyes: self.other_eyes.buffer(),
            cube_maps: None,
            seen_through: None,
            space: f.space,
        };
        let (vertices, _) = drawn_vertices(&self.field, &self.scene);
        let draws = CubeDraws {
            vertices,
            values: self.field.values(),
            phantoms: &f.instances.phantoms,
            first_instance: f.instances.virtuals.len() as u32,
        };
        let maps = f.instances.centres.len();
        self.cubes
            .encode(&ctx.device, steps.encoder(), maps, &bindings, &draws);
        steps.step(Pass::CubeMaps.name())?;
        Ok(())
    }

    /// Record the face view of the first `eyes` eyes, each after its
    /// seen-through pass in global mode (or its clearing, once, back in
    /// direct mode).
    fn encode_views(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        eyes: usize,
        instances: &Instances,
    ) {
        // Without virtual objects the phantoms have nothing to hide and no
        // occlusion shadow to fill (the eyes' views are empty), so they
        // would draw the clear colour: skip them (the image is the same).
        let nothing_virtual = instances.virtuals.iter().all(|r| r.is_empty());
        let (vertices, _) = drawn_vertices(&self.field, &self.scene);
        let draws = FaceDraws {
            vertices,
            values: self.field.values(),
            phantoms: if nothing_virtual {
                &[]
            } else {
                &instances.phantoms
            },
            virtuals: &instances.virtuals,
            mirrors: &instances.mirrors,
        };
        let global = self.field.has_field();
        for res in self.eyes.iter_mut().take(eyes) {
            if let Some(seen) = &res.seen_bind
                && (global || res.seen_drawn)
            {
                self.face
                    .encode_seen_through(encoder, &res.seen, seen, &draws, global);
                res.seen_drawn = global;
            }
            if let Some((_, bind)) = &res.bind {
                self.face.encode(encoder, &res.target, bind, &draws);
            }
        }
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

/// Every object's vertices as the instances' ranges name them: split
/// into the field's pieces in global mode.
fn drawn_vertices<'a>(field: &'a FieldBuffers, scene: &'a SceneBuffers) -> (&'a wgpu::Buffer, u32) {
    field
        .vertices()
        .unwrap_or_else(|| scene.buffer(VertexSet::All))
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
