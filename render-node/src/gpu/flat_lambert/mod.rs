//! Flat Lambert pass: draws a [`FlatLambertScene`] into an [`OffscreenTarget`], one colour per triangle; the bring-up pass checked pixel-wise against `showcase_light::raster`.
//!
//! The rules (clip mapping, culling, fill rule, depth, shading) are those
//! documented in `showcase_light::raster`; this pass must match that CPU
//! reference everywhere except at its `uncertain` pixels.

use bytemuck::{Pod, Zeroable};
use glam::{DMat3, Mat4};
use wgpu::util::DeviceExt;

use super::GpuError;
use super::pipeline::{TrianglePipeline, entry, opaque, uniform_buffer};
use super::target::{COLOUR_FORMAT, DEPTH_FORMAT, OffscreenTarget};
use showcase_light::raster::{FlatLambertScene, face_normal, normal_from_object};

/// Mirrors WGSL `struct View` in `flat_lambert.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ViewUniform {
    clip_from_world: [[f32; 4]; 4],
    to_light: [f32; 4],
}

/// Mirrors WGSL `struct Object` in `flat_lambert.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ObjectUniform {
    world_from_object: [[f32; 4]; 4],
    normal_from_object: [[f32; 4]; 4],
    albedo: [f32; 4],
}

/// Mirrors WGSL `struct VertexIn` in `flat_lambert.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Vertex {
    position: [f32; 3],
    face_normal: [f32; 3],
}

/// The compiled pipeline and its bind group layouts; create once per
/// device and reuse for every frame.
#[derive(Debug)]
pub struct FlatLambertPass {
    pipeline: wgpu::RenderPipeline,
    view_layout: wgpu::BindGroupLayout,
    object_layout: wgpu::BindGroupLayout,
}

/// One mesh uploaded with its transform and albedo.
#[derive(Debug)]
struct UploadedItem {
    vertices: wgpu::Buffer,
    vertex_count: u32,
    bind_group: wgpu::BindGroup,
}

/// A scene uploaded to the GPU for [`FlatLambertPass`]: vertex buffers,
/// uniforms and bind groups. Drawing it again costs no uploads.
#[derive(Debug)]
pub struct FlatLambertBatch {
    width: u32,
    height: u32,
    view_bind_group: wgpu::BindGroup,
    items: Vec<UploadedItem>,
}

fn uniform_layout(device: &wgpu::Device, label: &str) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &[entry(
            0,
            wgpu::ShaderStages::VERTEX,
            uniform_buffer(false, None),
        )],
    })
}

fn uniform_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    contents: &[u8],
) -> wgpu::BindGroup {
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::UNIFORM,
    });
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: buffer.as_entire_binding(),
        }],
    })
}

impl FlatLambertPass {
    /// Compile the pipeline for [`OffscreenTarget`]'s formats.
    pub fn new(device: &wgpu::Device) -> Self {
        let shader = device.create_shader_module(wgpu::include_wgsl!("flat_lambert.wgsl"));
        let view_layout = uniform_layout(device, "flat lambert view");
        let object_layout = uniform_layout(device, "flat lambert object");
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("flat lambert"),
            bind_group_layouts: &[Some(&view_layout), Some(&object_layout)],
            immediate_size: 0,
        });
        let pipeline = TrianglePipeline {
            label: "flat lambert",
            layout: &layout,
            shader: &shader,
            vertex: (
                "vs_main",
                &[Some(wgpu::VertexBufferLayout {
                    array_stride: size_of::<Vertex>() as wgpu::BufferAddress,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
                })],
            ),
            // Counter-clockwise in NDC (y up) is a front face (wgpu's
            // default winding); see `light::raster` for why that is the
            // mesh's outer side.
            cull_mode: Some(wgpu::Face::Back),
            depth: Some((DEPTH_FORMAT, wgpu::CompareFunction::Less)),
            fragment: Some(("fs_main", &[opaque(COLOUR_FORMAT)])),
        }
        .build(device);
        Self {
            pipeline,
            view_layout,
            object_layout,
        }
    }

    /// Validate `scene` and upload it: one non-indexed vertex buffer per
    /// item (each vertex carries its triangle's object-space normal) and
    /// the uniforms. A mesh too large for one buffer is an error, not a
    /// wgpu validation panic.
    pub fn upload(
        &self,
        device: &wgpu::Device,
        scene: &FlatLambertScene<'_>,
    ) -> Result<FlatLambertBatch, GpuError> {
        scene.validate()?;
        let to_light = scene.light_direction().as_vec3();
        let view = ViewUniform {
            clip_from_world: scene.device.clip_from_world().as_mat4().to_cols_array_2d(),
            to_light: to_light.extend(0.0).to_array(),
        };
        let view_bind_group =
            uniform_bind_group(device, &self.view_layout, "view", bytemuck::bytes_of(&view));
        let limit = device.limits().max_buffer_size;
        let mut items = Vec::with_capacity(scene.items.len());
        for (index, item) in scene.items.iter().enumerate() {
            let mesh = item.mesh;
            let bytes = (mesh.triangles.len() * 3 * size_of::<Vertex>()) as u64;
            if bytes > limit {
                return Err(GpuError::MeshTooLarge {
                    item: index,
                    bytes,
                    limit,
                });
            }
            let vertices: Vec<Vertex> = mesh
                .triangles
                .iter()
                .flat_map(|&tri| {
                    let n = face_normal(mesh, tri).as_vec3().to_array();
                    tri.map(|i| Vertex {
                        position: mesh.positions[i as usize].to_array(),
                        face_normal: n,
                    })
                })
                .collect();
            let object = ObjectUniform {
                world_from_object: item.transform.matrix().to_cols_array_2d(),
                normal_from_object: mat3_as_mat4(normal_from_object(&item.transform)),
                albedo: item.albedo.extend(0.0).to_array(),
            };
            items.push(UploadedItem {
                vertices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("flat lambert vertices"),
                    contents: bytemuck::cast_slice(&vertices),
                    usage: wgpu::BufferUsages::VERTEX,
                }),
                vertex_count: vertices.len() as u32,
                bind_group: uniform_bind_group(
                    device,
                    &self.object_layout,
                    "object",
                    bytemuck::bytes_of(&object),
                ),
            });
        }
        Ok(FlatLambertBatch {
            width: scene.device.width,
            height: scene.device.height,
            view_bind_group,
            items,
        })
    }

    /// Record the pass into `encoder`: clear `target` to colour
    /// `[0, 0, 0, 0]` and depth 1, then draw every item in order.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &OffscreenTarget,
        batch: &FlatLambertBatch,
    ) -> Result<(), GpuError> {
        if (target.width(), target.height()) != (batch.width, batch.height) {
            return Err(GpuError::SizeMismatch {
                target_width: target.width(),
                target_height: target.height(),
                width: batch.width,
                height: batch.height,
            });
        }
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("flat lambert"),
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
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &batch.view_bind_group, &[]);
        for item in &batch.items {
            if item.vertex_count == 0 {
                continue;
            }
            pass.set_bind_group(1, &item.bind_group, &[]);
            pass.set_vertex_buffer(0, item.vertices.slice(..));
            pass.draw(0..item.vertex_count, 0..1);
        }
        Ok(())
    }

    /// Encode and submit the pass; read the result with
    /// [`OffscreenTarget::read_rgba_f32`].
    pub fn render(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &OffscreenTarget,
        batch: &FlatLambertBatch,
    ) -> Result<(), GpuError> {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("flat lambert"),
        });
        self.encode(&mut encoder, target, batch)?;
        queue.submit([encoder.finish()]);
        Ok(())
    }
}

/// A 3x3 matrix in the upper-left of a 4x4 (WGSL has no padded mat3 in
/// uniforms that bytemuck could mirror simply).
fn mat3_as_mat4(m: DMat3) -> [[f32; 4]; 4] {
    Mat4::from_mat3(m.as_mat3()).to_cols_array_2d()
}
