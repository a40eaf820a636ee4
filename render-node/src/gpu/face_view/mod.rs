//! Face view pass: one eye's view of the virtual objects through a CRT
//! face, with phantom depth, shadow types 2 and 3 from the light shadow
//! views, and reflective objects showing their cube maps
//! ([`super::cube_map`] draws those with this module's shader). CPU
//! reference: `showcase_light::render::face::face_image_cpu`.

use std::sync::OnceLock;

use bytemuck::{Pod, Zeroable};

use super::frame_arrays::{ArraySpace, uniform_capacity};

use super::field::field_value_layout;
use super::pipeline::{self, TrianglePipeline, opaque, texture, uniform_buffer};
use super::shadow_views::{ShadowMaps, world_vertex_layout};
use super::target::{COLOUR_FORMAT, DEPTH_FORMAT, OffscreenTarget};

/// Mirrors WGSL `struct Frame` in `face_view.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FaceFrameUniform {
    /// The eye's `FaceView::clip_from_world`.
    pub clip_from_world: [[f32; 4]; 4],
    /// xyz eye.
    pub eye: [f32; 4],
    /// rgb ambient irradiance.
    pub ambient: [f32; 4],
    /// light samples, other eyes, shadow map size, flags (1 shadows, 2
    /// occluding occlusion shadows, 4 global mode's seen-through image).
    pub counts: [u32; 4],
    /// near and far plane of the shadow views (depth back to distance).
    pub shadow: [f32; 4],
    /// x: cube map texels per side, y: cube maps, z: the entry of the
    /// albedos buffer holding cube map 0's centre (map `k`'s at `z + k`).
    pub cube: [u32; 4],
    /// x: this eye's own entry in the eyes buffer, skipped by the
    /// occluding occlusion shadows ([`NO_OWN_EYE`] for none).
    pub own: [u32; 4],
}

/// [`FaceFrameUniform::own`] when the eyes buffer holds no entry of the
/// drawn eye.
pub const NO_OWN_EYE: u32 = u32::MAX;

/// The buffers and maps the pass reads (see [`FaceViewPass::bind_group`]).
#[derive(Clone, Copy, Debug)]
pub struct FaceBindings<'a> {
    /// This eye's [`FaceFrameUniform`].
    pub frame: &'a wgpu::Buffer,
    /// [`super::shadow_lookup::LightSampleGpu`]s (at least one element, may be a placeholder).
    pub lights: &'a wgpu::Buffer,
    /// The shadow views buffer.
    pub views: &'a wgpu::Buffer,
    /// The distance maps.
    pub maps: &'a ShadowMaps,
    /// Linear RGB albedo per draw instance: the virtual objects, then the
    /// phantoms (`[f32; 4]` each, at least one); then the cube maps'
    /// centres (xyz, from [`FaceFrameUniform::cube`]`[2]`).
    pub albedos: &'a wgpu::Buffer,
    /// The other observers' eyes as [`super::shadow_lookup::EyeGpu`]s (at least one element).
    pub other_eyes: &'a wgpu::Buffer,
    /// The cube maps' array view (six layers per map, at least one
    /// layer); `None` for the cube-map pass, which draws them, and the
    /// seen-through pass.
    pub cube_maps: Option<&'a wgpu::TextureView>,
    /// This eye's seen-through image ([`FaceViewPass::encode_seen_through`]:
    /// the real surfaces' own interreflection behind each pixel, zero in
    /// direct mode); set exactly when `cube_maps` is.
    pub seen_through: Option<&'a wgpu::TextureView>,
    /// Where the arrays are read from ([`space`] of their lengths).
    pub space: ArraySpace,
}

/// What the pass draws: ranges of one world-space vertex buffer.
#[derive(Debug)]
pub struct FaceDraws<'a> {
    /// World vertices of every object (in global mode split into the
    /// field's pieces, [`super::field`]).
    pub vertices: &'a wgpu::Buffer,
    /// The global-illumination field at each of `vertices` (zeros in
    /// direct mode).
    pub values: &'a wgpu::Buffer,
    /// Vertex range of each phantom (instances after the virtual objects).
    pub phantoms: &'a [std::ops::Range<u32>],
    /// Vertex range of each virtual object (instances from 0).
    pub virtuals: &'a [std::ops::Range<u32>],
    /// Whether each virtual object (as `virtuals`) is a mirror with a cube
    /// map (albedo w > 0), drawn by the mirror pipeline; missing entries
    /// are diffuse.
    pub mirrors: &'a [bool],
}

/// The compiled face pipelines (phantom depth, virtual shading).
#[derive(Debug)]
pub struct FaceViewPass {
    variants: Variants,
    /// The seen-through pass (`fs_seen_through`, no face textures).
    seen_through: Variants,
}

fn entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    pipeline::entry(binding, wgpu::ShaderStages::VERTEX_FRAGMENT, ty)
}

/// The WGSL source of the face view (and cube-map) shader (uniform
/// arrays; see [`ArraySpace::source`]).
pub const SOURCE: &str = super::shadow_lookup::with_shadow_lookup!("face_view.wgsl");

/// Capacity of the uniform array `name` (`lights`, `views`, `albedos` or
/// `eyes`) of [`SOURCE`] (0 for another name).
pub fn capacity(name: &str) -> usize {
    uniform_capacity(SOURCE, name).unwrap_or(0)
}

/// The space a frame of `lights` light samples, `views` shadow views,
/// `albedos` draw instances and `eyes` other eyes reads its arrays from.
pub fn space(lights: usize, views: usize, albedos: usize, eyes: usize) -> ArraySpace {
    ArraySpace::for_lengths(
        SOURCE,
        &[
            (lights, "lights"),
            (views, "views"),
            (albedos, "albedos"),
            (eyes, "eyes"),
        ],
    )
}

/// The face view shader (also the cube-map pass's) for `space`.
pub fn shader(device: &wgpu::Device, space: ArraySpace) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("face_view"),
        source: wgpu::ShaderSource::Wgsl(space.source(SOURCE)),
    })
}

/// The layout and pipelines (one per fragment entry point) of one
/// [`ArraySpace`].
#[derive(Debug)]
struct Variant {
    layout: wgpu::BindGroupLayout,
    pipelines: Vec<wgpu::RenderPipeline>,
}

/// The pipelines of fragment entry points of the face view shader in
/// both array spaces (the storage one compiled when first needed).
#[derive(Debug)]
pub(crate) struct Variants {
    cube_maps: bool,
    entries: &'static [&'static str],
    uniform: Variant,
    storage: OnceLock<Variant>,
}

/// A bind group with the pipelines of its [`ArraySpace`], one per
/// fragment entry point of the pass that made it.
#[derive(Debug)]
pub struct FaceBindGroup {
    group: wgpu::BindGroup,
    pipelines: Vec<wgpu::RenderPipeline>,
}

impl FaceBindGroup {
    /// The bind group.
    pub(crate) fn group(&self) -> &wgpu::BindGroup {
        &self.group
    }

    /// The pipeline of the pass's `i`th fragment entry point.
    pub(crate) fn pipeline(&self, i: usize) -> Option<&wgpu::RenderPipeline> {
        self.pipelines.get(i)
    }
}

impl Variants {
    /// Compile the uniform variant of `entries` (with the layout of
    /// [`bind_group_layout`] for `cube_maps`).
    pub(crate) fn new(
        device: &wgpu::Device,
        cube_maps: bool,
        entries: &'static [&'static str],
    ) -> Self {
        Self {
            cube_maps,
            entries,
            uniform: Self::variant(device, cube_maps, entries, ArraySpace::Uniform),
            storage: OnceLock::new(),
        }
    }

    fn variant(
        device: &wgpu::Device,
        cube_maps: bool,
        entries: &[&str],
        space: ArraySpace,
    ) -> Variant {
        let shader = shader(device, space);
        let layout = bind_group_layout(device, cube_maps, space);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(if cube_maps { "face view" } else { "cube map" }),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipelines = entries
            .iter()
            .map(|fs| render_pipeline(device, &shader, &pipeline_layout, fs))
            .collect();
        Variant { layout, pipelines }
    }

    /// A bind group of `bindings` in `bindings.space`.
    pub(crate) fn bind_group(
        &self,
        device: &wgpu::Device,
        bindings: &FaceBindings<'_>,
    ) -> FaceBindGroup {
        let variant = match bindings.space {
            ArraySpace::Uniform => &self.uniform,
            ArraySpace::Storage => self.storage.get_or_init(|| {
                Self::variant(device, self.cube_maps, self.entries, ArraySpace::Storage)
            }),
        };
        FaceBindGroup {
            group: bind_group(device, &variant.layout, bindings),
            pipelines: variant.pipelines.clone(),
        }
    }
}

/// The bind group layout of the face view pass, or with `cube_maps`
/// false that of the cube-map and seen-through passes (no bindings 6 and
/// 7), for `space`.
pub fn bind_group_layout(
    device: &wgpu::Device,
    cube_maps: bool,
    space: ArraySpace,
) -> wgpu::BindGroupLayout {
    let mut entries = vec![
        entry(0, uniform_buffer(false, None)),
        entry(1, space.binding_type()),
        entry(2, space.binding_type()),
        entry(
            3,
            texture(
                wgpu::TextureSampleType::Depth,
                wgpu::TextureViewDimension::D2Array,
            ),
        ),
        entry(4, space.binding_type()),
        entry(5, space.binding_type()),
    ];
    if cube_maps {
        entries.push(entry(
            6,
            texture(
                wgpu::TextureSampleType::Float { filterable: false },
                wgpu::TextureViewDimension::D2Array,
            ),
        ));
        entries.push(entry(
            7,
            texture(
                wgpu::TextureSampleType::Float { filterable: false },
                wgpu::TextureViewDimension::D2,
            ),
        ));
    }
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(if cube_maps { "face view" } else { "cube map" }),
        entries: &entries,
    })
}

/// A bind group of `bindings` for `layout` (from [`bind_group_layout`]
/// with `cube_maps` as `bindings.cube_maps.is_some()`).
pub fn bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    bindings: &FaceBindings<'_>,
) -> wgpu::BindGroup {
    let buffers = [
        bindings.frame,
        bindings.lights,
        bindings.views,
        bindings.albedos,
        bindings.other_eyes,
    ];
    let mut entries: Vec<wgpu::BindGroupEntry<'_>> = [0u32, 1, 2, 4, 5]
        .into_iter()
        .zip(buffers)
        .map(|(binding, b)| wgpu::BindGroupEntry {
            binding,
            resource: b.as_entire_binding(),
        })
        .collect();
    entries.push(wgpu::BindGroupEntry {
        binding: 3,
        resource: wgpu::BindingResource::TextureView(bindings.maps.array_view()),
    });
    if let Some(cube) = bindings.cube_maps {
        entries.push(wgpu::BindGroupEntry {
            binding: 6,
            resource: wgpu::BindingResource::TextureView(cube),
        });
    }
    if let Some(seen) = bindings.seen_through {
        entries.push(wgpu::BindGroupEntry {
            binding: 7,
            resource: wgpu::BindingResource::TextureView(seen),
        });
    }
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("face view"),
        layout,
        entries: &entries,
    })
}

/// A pipeline of the face view shader with fragment entry point `fs`
/// into [`OffscreenTarget`]'s formats (depth tested and written, no
/// culling), with the global-illumination field as a second vertex
/// buffer: the face view's, the cube-map pass's and the seen-through
/// pass's.
pub fn render_pipeline(
    device: &wgpu::Device,
    shader: &wgpu::ShaderModule,
    pipeline_layout: &wgpu::PipelineLayout,
    fs: &str,
) -> wgpu::RenderPipeline {
    TrianglePipeline {
        label: fs,
        layout: pipeline_layout,
        shader,
        vertex: (
            "vs_main",
            &[Some(world_vertex_layout()), Some(field_value_layout())],
        ),
        // Two-sided, as in the CPU reference (so the mirror's winding
        // flip needs no special case).
        cull_mode: None,
        depth: Some((DEPTH_FORMAT, wgpu::CompareFunction::Less)),
        fragment: Some((fs, &[opaque(COLOUR_FORMAT)])),
    }
    .build(device)
}

impl FaceViewPass {
    /// Compile the pipelines for [`OffscreenTarget`]'s formats.
    pub fn new(device: &wgpu::Device) -> Self {
        Self {
            variants: Variants::new(
                device,
                true,
                &["fs_phantom", "fs_virtual", "fs_virtual_mirror"],
            ),
            seen_through: Variants::new(device, false, &["fs_seen_through"]),
        }
    }

    /// The seen-through pass's bind group of `bindings` (an eye's, without
    /// the face textures).
    pub fn seen_through_bind_group(
        &self,
        device: &wgpu::Device,
        bindings: &FaceBindings<'_>,
    ) -> FaceBindGroup {
        self.seen_through.bind_group(device, bindings)
    }

    /// Record the seen-through pass into `target` (global mode): clear to
    /// 0 and depth 1, then, with `draw`, draw the phantoms' own
    /// interreflected radiance (`rho / pi * cabinet`), the nearest
    /// winning: what this eye sees of the real surfaces through the
    /// virtual objects. Without `draw` the target is only cleared.
    pub fn encode_seen_through(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &OffscreenTarget,
        bind_group: &FaceBindGroup,
        draws: &FaceDraws<'_>,
        draw: bool,
    ) {
        let mut pass = begin(encoder, target, "seen through");
        let Some(pipeline) = bind_group.pipeline(0) else {
            return;
        };
        if !draw {
            return;
        }
        bind(&mut pass, bind_group, draws);
        pass.set_pipeline(pipeline);
        draw_phantoms(&mut pass, draws);
    }

    /// The bind group of `bindings` (create once per set of buffers and
    /// space); `bindings.cube_maps` must be set.
    pub fn bind_group(&self, device: &wgpu::Device, bindings: &FaceBindings<'_>) -> FaceBindGroup {
        self.variants.bind_group(device, bindings)
    }

    /// Record the pass into `target`: clear to 0 and depth 1, draw the
    /// phantoms (black with depth, or lit inside other observers'
    /// occlusion shadows), then the virtual objects shaded.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &OffscreenTarget,
        bind_group: &FaceBindGroup,
        draws: &FaceDraws<'_>,
    ) {
        let mut pass = begin(encoder, target, "face view");
        let (Some(phantom), Some(shaded), Some(mirror)) = (
            bind_group.pipeline(0),
            bind_group.pipeline(1),
            bind_group.pipeline(2),
        ) else {
            return;
        };
        bind(&mut pass, bind_group, draws);
        pass.set_pipeline(phantom);
        draw_phantoms(&mut pass, draws);
        for (pipeline, mirrors) in [(shaded, false), (mirror, true)] {
            pass.set_pipeline(pipeline);
            for (i, r) in draws.virtuals.iter().enumerate() {
                if !r.is_empty() && draws.mirrors.get(i).copied().unwrap_or(false) == mirrors {
                    pass.draw(r.clone(), i as u32..i as u32 + 1);
                }
            }
        }
    }
}

/// A render pass into `target` that clears it to 0 and depth 1.
fn begin<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    target: &OffscreenTarget,
    label: &'static str,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target.colour_view(),
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: target.depth_view(),
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

/// Bind `bind_group` and the vertex and field buffers of `draws`.
fn bind(pass: &mut wgpu::RenderPass<'_>, bind_group: &FaceBindGroup, draws: &FaceDraws<'_>) {
    pass.set_bind_group(0, bind_group.group(), &[]);
    pass.set_vertex_buffer(0, draws.vertices.slice(..));
    pass.set_vertex_buffer(1, draws.values.slice(..));
}

/// Draw each phantom of `draws` with the pipeline set (its instance
/// after the virtual objects').
fn draw_phantoms(pass: &mut wgpu::RenderPass<'_>, draws: &FaceDraws<'_>) {
    let first_phantom = draws.virtuals.len() as u32;
    for (i, r) in draws.phantoms.iter().enumerate() {
        if !r.is_empty() {
            let instance = first_phantom + i as u32;
            pass.draw(r.clone(), instance..instance + 1);
        }
    }
}
