//! Face view pass: one eye's view of the virtual objects through a CRT
//! face, with phantom depth and shadow types 2 and 3 from the light
//! shadow views. CPU reference: `crate::render::face::face_image_cpu`.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::irradiance_map::{EyeGpu, LightSampleGpu};
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
}

/// What the pass draws.
#[derive(Debug)]
pub struct FaceInputs<'a> {
    /// The frame uniform.
    pub frame: FaceFrameUniform,
    /// Light samples.
    pub lights: &'a [LightSampleGpu],
    /// The shadow views buffer.
    pub views: &'a wgpu::Buffer,
    /// The distance maps.
    pub maps: &'a ShadowMaps,
    /// World vertices of every object.
    pub vertices: &'a wgpu::Buffer,
    /// Vertex range and albedo of each phantom.
    pub phantoms: &'a [(std::ops::Range<u32>, [f32; 4])],
    /// The other observers' eyes (may be empty).
    pub other_eyes: &'a [EyeGpu],
    /// Vertex range and albedo of each virtual object.
    pub virtuals: &'a [(std::ops::Range<u32>, [f32; 4])],
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

impl FaceViewPass {
    /// Compile the pipelines for [`OffscreenTarget`]'s formats.
    pub fn new(device: &wgpu::Device) -> Self {
        let shader = device.create_shader_module(wgpu::include_wgsl!("face_view.wgsl"));
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("face view"),
            entries: &[
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
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                ),
                entry(4, storage()),
                entry(5, storage()),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("face view"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let make = |fs: &str| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(fs),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &shader,
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
                    module: &shader,
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
        };
        Self {
            phantom: make("fs_phantom"),
            shaded: make("fs_virtual"),
            layout,
        }
    }

    /// Record the pass into `target`: clear to 0 and depth 1, draw the
    /// phantoms (black with depth, or lit inside other observers'
    /// occlusion shadows), then the virtual objects shaded.
    pub fn encode(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        target: &OffscreenTarget,
        inputs: &FaceInputs<'_>,
    ) {
        let buffer = |label, bytes: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage,
            })
        };
        let frame = buffer(
            "face frame",
            bytemuck::bytes_of(&inputs.frame),
            wgpu::BufferUsages::UNIFORM,
        );
        let placeholder_light = [LightSampleGpu::zeroed()];
        let lights = if inputs.lights.is_empty() {
            &placeholder_light[..]
        } else {
            inputs.lights
        };
        let lights = buffer(
            "face lights",
            bytemuck::cast_slice(lights),
            wgpu::BufferUsages::STORAGE,
        );
        // Instances: virtual objects first, then phantoms.
        let mut albedo: Vec<[f32; 4]> = inputs
            .virtuals
            .iter()
            .chain(inputs.phantoms)
            .map(|(_, a)| *a)
            .collect();
        if albedo.is_empty() {
            albedo.push([0.0; 4]);
        }
        let albedos = buffer(
            "face albedos",
            bytemuck::cast_slice(&albedo),
            wgpu::BufferUsages::STORAGE,
        );
        let placeholder_eye = [EyeGpu::zeroed()];
        let eyes = if inputs.other_eyes.is_empty() {
            &placeholder_eye[..]
        } else {
            inputs.other_eyes
        };
        let eyes = buffer(
            "face other eyes",
            bytemuck::cast_slice(eyes),
            wgpu::BufferUsages::STORAGE,
        );
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("face view"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: frame.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: lights.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: inputs.views.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(inputs.maps.array_view()),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: albedos.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: eyes.as_entire_binding(),
                },
            ],
        });
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
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &bind_group, &[]);
        pass.set_vertex_buffer(0, inputs.vertices.slice(..));
        pass.set_pipeline(&self.phantom);
        let first_phantom = inputs.virtuals.len() as u32;
        for (i, (r, _)) in inputs.phantoms.iter().enumerate() {
            if !r.is_empty() {
                let instance = first_phantom + i as u32;
                pass.draw(r.clone(), instance..instance + 1);
            }
        }
        pass.set_pipeline(&self.shaded);
        for (i, (r, _)) in inputs.virtuals.iter().enumerate() {
            if !r.is_empty() {
                pass.draw(r.clone(), i as u32..i as u32 + 1);
            }
        }
    }
}
