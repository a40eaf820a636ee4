//! Face view pass: one eye's view of the virtual objects through a CRT
//! face, with phantom depth, shadow types 2 and 3 from the light shadow
//! views, and reflective objects showing their cube maps
//! ([`super::cube_map`] draws those with this module's shader). CPU
//! reference: `crate::render::face::face_image_cpu`.

use bytemuck::{Pod, Zeroable};

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
    /// occluding occlusion shadows).
    pub counts: [u32; 4],
    /// near and far plane of the shadow views (depth back to distance).
    pub shadow: [f32; 4],
    /// x: cube map texels per side.
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
    /// [`super::irradiance_map::LightSampleGpu`]s (at least one element, may be a placeholder).
    pub lights: &'a wgpu::Buffer,
    /// The shadow views buffer.
    pub views: &'a wgpu::Buffer,
    /// The distance maps.
    pub maps: &'a ShadowMaps,
    /// Linear RGB albedo per draw instance: the virtual objects, then the
    /// phantoms (`[f32; 4]` each, at least one).
    pub albedos: &'a wgpu::Buffer,
    /// The other observers' eyes as [`super::irradiance_map::EyeGpu`]s (at least one element).
    pub other_eyes: &'a wgpu::Buffer,
    /// The cube maps' array view (six layers per map, at least one
    /// layer); `None` for the cube-map pass, which draws them.
    pub cube_maps: Option<&'a wgpu::TextureView>,
}

/// What the pass draws: ranges of one world-space vertex buffer.
#[derive(Debug)]
pub struct FaceDraws<'a> {
    /// World vertices of every object.
    pub vertices: &'a wgpu::Buffer,
    /// Vertex range of each phantom (instances after the virtual objects).
    pub phantoms: &'a [std::ops::Range<u32>],
    /// Vertex range of each virtual object (instances from 0).
    pub virtuals: &'a [std::ops::Range<u32>],
}

/// The compiled face pipelines (phantom depth, virtual shading).
#[derive(Debug)]
pub struct FaceViewPass {
    phantom: wgpu::RenderPipeline,
    shaded: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

fn entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
        ty,
        count: None,
    }
}

fn storage() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

/// The face view shader (also the cube-map pass's).
pub fn shader(device: &wgpu::Device) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("face_view"),
        source: wgpu::ShaderSource::Wgsl(std::borrow::Cow::Borrowed(
            super::shadow_lookup::with_shadow_lookup!("face_view.wgsl"),
        )),
    })
}

/// The bind group layout of the face view pass, or with `cube_maps`
/// false that of the cube-map pass (no binding 6).
pub fn bind_group_layout(device: &wgpu::Device, cube_maps: bool) -> wgpu::BindGroupLayout {
    let mut entries = vec![
        entry(
            0,
            wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
        ),
        entry(1, storage()),
        entry(2, storage()),
        entry(
            3,
            wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Depth,
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
        ),
        entry(4, storage()),
        entry(5, storage()),
    ];
    if cube_maps {
        entries.push(entry(
            6,
            wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
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
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("face view"),
        layout,
        entries: &entries,
    })
}

/// A pipeline of the face view shader with fragment entry point `fs`
/// into [`OffscreenTarget`]'s formats (depth tested and written, no
/// culling): the face view's and the cube-map pass's.
pub fn render_pipeline(
    device: &wgpu::Device,
    shader: &wgpu::ShaderModule,
    pipeline_layout: &wgpu::PipelineLayout,
    fs: &str,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(fs),
        layout: Some(pipeline_layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(world_vertex_layout())],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            // Two-sided, as in the CPU reference (so the mirror's
            // winding flip needs no special case).
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: shader,
            entry_point: Some(fs),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: COLOUR_FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

impl FaceViewPass {
    /// Compile the pipelines for [`OffscreenTarget`]'s formats.
    pub fn new(device: &wgpu::Device) -> Self {
        let shader = shader(device);
        let layout = bind_group_layout(device, true);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("face view"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let make = |fs: &str| render_pipeline(device, &shader, &pipeline_layout, fs);
        Self {
            phantom: make("fs_phantom"),
            shaded: make("fs_virtual"),
            layout,
        }
    }

    /// The bind group of `bindings` (create once per set of buffers);
    /// `bindings.cube_maps` must be set.
    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        bindings: &FaceBindings<'_>,
    ) -> wgpu::BindGroup {
        bind_group(device, &self.layout, bindings)
    }

    /// Record the pass into `target`: clear to 0 and depth 1, draw the
    /// phantoms (black with depth, or lit inside other observers'
    /// occlusion shadows), then the virtual objects shaded.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &OffscreenTarget,
        bind_group: &wgpu::BindGroup,
        draws: &FaceDraws<'_>,
    ) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("face view"),
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
        });
        pass.set_bind_group(0, bind_group, &[]);
        pass.set_vertex_buffer(0, draws.vertices.slice(..));
        pass.set_pipeline(&self.phantom);
        let first_phantom = draws.virtuals.len() as u32;
        for (i, r) in draws.phantoms.iter().enumerate() {
            if !r.is_empty() {
                let instance = first_phantom + i as u32;
                pass.draw(r.clone(), instance..instance + 1);
            }
        }
        pass.set_pipeline(&self.shaded);
        for (i, r) in draws.virtuals.iter().enumerate() {
            if !r.is_empty() {
                pass.draw(r.clone(), i as u32..i as u32 + 1);
            }
        }
    }
}
