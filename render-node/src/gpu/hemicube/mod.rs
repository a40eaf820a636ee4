//! GPU hemi-cube item buffers: every element triangle rasterised with its id into the five faces of a hemi-cube (R32Uint + depth), read back in the CPU hemi-cube's pixel order.
//!
//! This replaces [`HemiCube::item_buffer`](showcase_light::radiosity::hemicube::HemiCube::item_buffer)
//! (one BVH ray per pixel centre) by rasterisation, which samples the same
//! pixel centres: the two agree except at pixels whose centre falls on a
//! triangle edge (fill rule against ray-triangle test, f32 against f64
//! vertices). The delta form factors are then accumulated on the CPU in
//! f64 by [`HemiCube::accumulate`](showcase_light::radiosity::hemicube::HemiCube::accumulate).
//!
//! Layout: one 2D-array layer per shot, `resolution` wide and
//! `3 * resolution` tall: the top face in rows `0..n`, then the side faces
//! `+x`, `-x`, `+y`, `-y` of the local frame, `n / 2` rows each, so that a
//! layer read row by row is the item buffer as
//! [`HemiCube::new`](showcase_light::radiosity::hemicube::HemiCube::new) orders it.
//! Each face is one draw of all triangles with its own viewport and
//! projection; a batch of shots is one submission and one readback.

use bytemuck::{Pod, Zeroable};
use glam::{DMat4, DVec3, DVec4};
use std::sync::Mutex;
use wgpu::util::DeviceExt;

use super::pipeline::{TrianglePipeline, entry, one_group_layout, opaque, uniform_buffer};
use super::target::padded_bytes_per_row;
use super::{GpuContext, GpuError};
use showcase_light::radiosity::hemicube::{
    HemiCubeShot, ItemBufferError, ItemBufferRasteriser, ItemBufferScene, ItemTriangle, NO_ITEM,
};

/// Format of the item buffer (item id + 1; 0 is no item).
pub const ITEM_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// Depth format (reversed: near / distance).
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Near plane distance (m); reversed depth keeps precision beyond it.
pub const NEAR: f64 = 1e-6;
/// The eye is lifted off the shooter's surface by this fraction of the
/// scene's largest absolute coordinate (tens of f32 ulps), as the CPU
/// lifts its rays by `SceneGeometry::epsilon`: otherwise the shooter's own
/// plane, edge-on, rounds into the first row of the side faces.
const EYE_LIFT: f64 = 1e-5;
/// Faces per hemi-cube.
const FACES: usize = 5;
/// Readback bytes a batch may use; the batch size follows from it.
const BATCH_BYTES: u64 = 32 << 20;
/// Most shots per batch.
const MAX_BATCH: u32 = 64;

/// Mirrors WGSL `struct Face` in `hemicube.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct FaceUniform {
    clip_from_world: [[f32; 4]; 4],
    origin: [f32; 4],
}

/// Mirrors WGSL `struct VertexIn` in `hemicube.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Vertex {
    position: [f32; 3],
    item: u32,
    normal: [f32; 3],
}

/// The compiled item-buffer pipeline on one device; create once and
/// [`Self::upload_triangles`] each solve's elements.
#[derive(Debug)]
pub struct GpuHemiCube {
    ctx: GpuContext,
    pipeline: wgpu::RenderPipeline,
    face_layout: wgpu::BindGroupLayout,
}

/// Textures and buffers of one batch of shots, reused between batches.
#[derive(Debug)]
struct BatchTargets {
    items: wgpu::Texture,
    depth: wgpu::Texture,
    readback: wgpu::Buffer,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

/// Element triangles uploaded for hemi-cubes of one resolution.
#[derive(Debug)]
pub struct GpuHemiCubeScene {
    ctx: GpuContext,
    pipeline: wgpu::RenderPipeline,
    resolution: u32,
    batch: u32,
    uniform_stride: u64,
    padded_row: u32,
    vertices: Option<wgpu::Buffer>,
    vertex_count: u32,
    /// Eye lift off the surface (m): [`EYE_LIFT`] times the scene scale.
    lift: f64,
    targets: Mutex<BatchTargets>,
}

impl GpuHemiCube {
    /// Compile the pipeline on `ctx`'s device.
    pub fn new(ctx: &GpuContext) -> Self {
        let device = &ctx.device;
        let shader = device.create_shader_module(wgpu::include_wgsl!("hemicube.wgsl"));
        let face_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("hemicube face"),
            entries: &[entry(
                0,
                wgpu::ShaderStages::VERTEX,
                uniform_buffer(true, Some(size_of::<FaceUniform>() as u64)),
            )],
        });
        let pipeline = TrianglePipeline {
            label: "hemicube",
            layout: &one_group_layout(device, "hemicube", &face_layout),
            shader: &shader,
            vertex: (
                "vs_main",
                &[Some(wgpu::VertexBufferLayout {
                    array_stride: size_of::<Vertex>() as wgpu::BufferAddress,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![
                        0 => Float32x3, 1 => Uint32, 2 => Float32x3
                    ],
                })],
            ),
            // Both sides are drawn: back faces occlude; the fragment
            // shader decides facing from the triangle's plane, which
            // does not depend on the faces' handedness.
            cull_mode: None,
            depth: Some((DEPTH_FORMAT, wgpu::CompareFunction::Greater)),
            fragment: Some(("fs_main", &[opaque(ITEM_FORMAT)])),
        }
        .build(device);
        Self {
            ctx: ctx.clone(),
            pipeline,
            face_layout,
        }
    }

    /// Upload `triangles` for hemi-cubes of top-face `resolution` (even,
    /// 2..=4096, and `3 * resolution` within the device's texture limit).
    pub fn upload_triangles(
        &self,
        resolution: u32,
        triangles: &[ItemTriangle],
    ) -> Result<GpuHemiCubeScene, GpuError> {
        let device = &self.ctx.device;
        let limits = device.limits();
        if showcase_light::radiosity::hemicube::HemiCube::new(resolution).is_err()
            || 3 * resolution > limits.max_texture_dimension_2d
        {
            return Err(GpuError::BadTargetSize {
                width: resolution,
                height: resolution.saturating_mul(3),
                limit: limits.max_texture_dimension_2d,
            });
        }
        let bytes = (triangles.len() * 3 * size_of::<Vertex>()) as u64;
        if bytes > limits.max_buffer_size {
            return Err(GpuError::MeshTooLarge {
                item: 0,
                bytes,
                limit: limits.max_buffer_size,
            });
        }
        let vertices: Vec<Vertex> = triangles
            .iter()
            .filter(|t| t.item < NO_ITEM - 1 && t.normal.is_finite())
            .flat_map(|t| {
                let normal = t.normal.as_vec3().to_array();
                t.vertices.map(|v| Vertex {
                    position: v.as_vec3().to_array(),
                    item: t.item + 1,
                    normal,
                })
            })
            .collect();
        let vertex_count = vertices.len() as u32;
        let scale = triangles
            .iter()
            .flat_map(|t| t.vertices)
            .map(|v| v.abs().max_element())
            .filter(|m| m.is_finite())
            .fold(1e-3, f64::max);
        let vertices = (!vertices.is_empty()).then(|| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("hemicube vertices"),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::VERTEX,
            })
        });
        let padded_row = padded_bytes_per_row(resolution, 4);
        let layer_bytes = u64::from(padded_row) * 3 * u64::from(resolution);
        let batch = (BATCH_BYTES / layer_bytes)
            .clamp(1, u64::from(MAX_BATCH))
            .min(u64::from(limits.max_texture_array_layers)) as u32;
        let uniform_stride = (size_of::<FaceUniform>() as u64)
            .next_multiple_of(u64::from(limits.min_uniform_buffer_offset_alignment));
        let targets = self.batch_targets(resolution, batch, uniform_stride, layer_bytes);
        Ok(GpuHemiCubeScene {
            ctx: self.ctx.clone(),
            pipeline: self.pipeline.clone(),
            resolution,
            batch,
            uniform_stride,
            padded_row,
            vertices,
            vertex_count,
            lift: EYE_LIFT * scale,
            targets: Mutex::new(targets),
        })
    }

    fn batch_targets(
        &self,
        resolution: u32,
        batch: u32,
        uniform_stride: u64,
        layer_bytes: u64,
    ) -> BatchTargets {
        let device = &self.ctx.device;
        let size = wgpu::Extent3d {
            width: resolution,
            height: 3 * resolution,
            depth_or_array_layers: batch,
        };
        let texture = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let attachment = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let items = texture(
            "hemicube items",
            ITEM_FORMAT,
            attachment | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = texture("hemicube depth", DEPTH_FORMAT, attachment);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hemicube readback"),
            size: layer_bytes * u64::from(batch),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hemicube faces"),
            size: uniform_stride * (FACES as u64) * u64::from(batch),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("hemicube faces"),
            layout: &self.face_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &uniforms,
                    offset: 0,
                    size: wgpu::BufferSize::new(size_of::<FaceUniform>() as u64),
                }),
            }],
        });
        BatchTargets {
            items,
            depth,
            readback,
            uniforms,
            bind_group,
        }
    }
}

/// Clip-from-world of each face of the hemi-cube of `shot`, in item-buffer
/// order, with its viewport rows `(first row, rows)` in the layer.
///
/// Each row of the matrix is a world vector `r` applied to `x - origin`:
/// clip x = across the face, clip y = down the face (NDC y is up, rows go
/// down), clip z = [`NEAR`] (reversed depth `near / w`), clip w = distance
/// along the face's axis.
pub fn face_projections(shot: &HemiCubeShot, resolution: u32) -> [(DMat4, u32, u32); FACES] {
    let [t1, t2, n] = shot.frame();
    let half = resolution / 2;
    // (axis, across, down): top face rows run along +y (NDC y = -y);
    // side face rows run up from the surface (NDC y = 1 - 2 z / d).
    let faces: [(DVec3, DVec3, DVec3); FACES] = [
        (n, t1, -t2),
        (t1, t2, t1 - 2.0 * n),
        (-t1, t2, -t1 - 2.0 * n),
        (t2, t1, t2 - 2.0 * n),
        (-t2, t1, -t2 - 2.0 * n),
    ];
    let o = shot.origin;
    let row = |r: DVec3| DVec4::new(r.x, r.y, r.z, -r.dot(o));
    let mut out = [(DMat4::IDENTITY, 0, 0); FACES];
    for (k, (axis, across, down)) in faces.into_iter().enumerate() {
        let rows = DMat4::from_cols(
            row(across),
            row(down),
            DVec4::new(0.0, 0.0, 0.0, NEAR),
            row(axis),
        );
        let (first, count) = if k == 0 {
            (0, resolution)
        } else {
            (resolution + (k as u32 - 1) * half, half)
        };
        out[k] = (rows.transpose(), first, count);
    }
    out
}

impl GpuHemiCubeScene {
    /// Top-face resolution.
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// Shots per submission.
    pub fn batch(&self) -> u32 {
        self.batch
    }

    /// One item buffer per shot (in [`HemiCube`](showcase_light::radiosity::hemicube::HemiCube)
    /// pixel order; [`NO_ITEM`] where no triangle is seen front-on), in
    /// batches of [`Self::batch`] shots per submission and readback.
    /// Shots with a non-finite origin or a normal that is not unit length
    /// see nothing.
    pub fn render_shots(&self, shots: &[HemiCubeShot]) -> Result<Vec<Vec<u32>>, GpuError> {
        let mut out = Vec::with_capacity(shots.len());
        let targets = self
            .targets
            .lock()
            .map_err(|e| GpuError::Map(format!("hemicube targets poisoned: {e}")))?;
        for chunk in shots.chunks(self.batch as usize) {
            self.render_chunk(&targets, chunk, &mut out)?;
        }
        Ok(out)
    }

    fn render_chunk(
        &self,
        t: &BatchTargets,
        shots: &[HemiCubeShot],
        out: &mut Vec<Vec<u32>>,
    ) -> Result<(), GpuError> {
        let (device, queue) = (&self.ctx.device, &self.ctx.queue);
        let n = self.resolution;
        let stride = self.uniform_stride as usize;
        let valid = |s: &HemiCubeShot| {
            s.origin.is_finite()
                && s.rotation.is_finite()
                && (s.normal.length_squared() - 1.0).abs() < 1e-6
        };
        let mut uniforms = vec![0u8; stride * FACES * shots.len()];
        let mut viewports = Vec::with_capacity(shots.len());
        for (i, shot) in shots.iter().enumerate() {
            let shot = &HemiCubeShot {
                origin: shot.origin + self.lift * shot.normal,
                ..*shot
            };
            let faces = face_projections(shot, n);
            for (k, (m, first, rows)) in faces.iter().enumerate() {
                let face = FaceUniform {
                    clip_from_world: m.as_mat4().to_cols_array_2d(),
                    origin: shot.origin.as_vec3().extend(0.0).to_array(),
                };
                let at = (i * FACES + k) * stride;
                uniforms[at..at + size_of::<FaceUniform>()]
                    .copy_from_slice(bytemuck::bytes_of(&face));
                viewports.push((*first, *rows));
            }
        }
        queue.write_buffer(&t.uniforms, 0, &uniforms);
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("hemicube"),
        });
        for (i, shot) in shots.iter().enumerate() {
            let layer = |texture: &wgpu::Texture| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: i as u32,
                    array_layer_count: Some(1),
                    ..Default::default()
                })
            };
            let (items, depth) = (layer(&t.items), layer(&t.depth));
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("hemicube"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &items,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            let Some(vertices) = self.vertices.as_ref().filter(|_| valid(shot)) else {
                continue;
            };
            pass.set_pipeline(&self.pipeline);
            pass.set_vertex_buffer(0, vertices.slice(..));
            for k in 0..FACES {
                let (first, rows) = viewports[i * FACES + k];
                pass.set_viewport(0.0, first as f32, n as f32, rows as f32, 0.0, 1.0);
                pass.set_bind_group(0, &t.bind_group, &[((i * FACES + k) * stride) as u32]);
                pass.draw(0..self.vertex_count, 0..1);
            }
        }
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &t.items,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &t.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(3 * n),
                },
            },
            wgpu::Extent3d {
                width: n,
                height: 3 * n,
                depth_or_array_layers: shots.len() as u32,
            },
        );
        queue.submit([encoder.finish()]);
        let layer_bytes = self.padded_row as u64 * 3 * u64::from(n);
        let slice = t.readback.slice(..layer_bytes * shots.len() as u64);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            // The receiver lives until after the poll below.
            let _ = tx.send(r);
        });
        device.poll(wgpu::PollType::wait_indefinitely())?;
        rx.recv()
            .map_err(|e| GpuError::Map(e.to_string()))?
            .map_err(|e| GpuError::Map(e.to_string()))?;
        let decoded = (|| -> Result<(), GpuError> {
            let view = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Map(e.to_string()))?;
            let words: &[u32] =
                bytemuck::try_cast_slice(&view).map_err(|e| GpuError::Map(e.to_string()))?;
            let row_words = (self.padded_row / 4) as usize;
            for i in 0..shots.len() {
                let layer = &words[i * row_words * 3 * n as usize..];
                let mut buffer = Vec::with_capacity(3 * (n * n) as usize);
                for r in 0..3 * n as usize {
                    // Stored as item + 1 with 0 for none: 0 wraps to NO_ITEM.
                    buffer.extend(
                        layer[r * row_words..r * row_words + n as usize]
                            .iter()
                            .map(|&v| v.wrapping_sub(1)),
                    );
                }
                out.push(buffer);
            }
            Ok(())
        })();
        t.readback.unmap();
        decoded
    }
}

impl ItemBufferRasteriser for GpuHemiCube {
    fn describe(&self) -> String {
        format!("gpu hemi-cube on {}", self.ctx.describe())
    }

    fn upload(
        &self,
        resolution: u32,
        triangles: &[ItemTriangle],
    ) -> Result<Box<dyn ItemBufferScene>, ItemBufferError> {
        self.upload_triangles(resolution, triangles)
            .map(|s| Box::new(s) as Box<dyn ItemBufferScene>)
            .map_err(|e| ItemBufferError::Raster(e.to_string()))
    }
}

impl ItemBufferScene for GpuHemiCubeScene {
    fn batch_size(&self) -> usize {
        self.batch as usize
    }

    fn render(&self, shots: &[HemiCubeShot]) -> Result<Vec<Vec<u32>>, ItemBufferError> {
        self.render_shots(shots)
            .map_err(|e| ItemBufferError::Raster(e.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use showcase_light::radiosity::hemicube::HemiCube;

    /// Every pixel-centre direction of the CPU hemi-cube, projected with
    /// its face's matrix, lands in the centre of the same pixel of the
    /// layer: the GPU layout is the CPU item-buffer order.
    #[test]
    fn face_projections_map_pixel_centres_to_their_pixels() {
        for (n, rotation) in [(8u32, 0.0), (16, 1.3), (32, 4.0)] {
            let shot = HemiCubeShot {
                origin: DVec3::new(0.2, -0.4, 1.5),
                normal: DVec3::new(0.3, 0.5, -0.8).normalize(),
                rotation,
            };
            let cube = HemiCube::new(n).unwrap();
            let directions = cube.world_directions(shot.normal, shot.rotation);
            let faces = face_projections(&shot, n);
            for (index, d) in directions.iter().enumerate() {
                let (row, col) = (index / n as usize, index % n as usize);
                let k = if row < n as usize {
                    0
                } else {
                    1 + (row - n as usize) / (n as usize / 2)
                };
                let (m, first, rows) = faces[k];
                let clip = m * (shot.origin + 0.7 * d).extend(1.0);
                assert!(clip.w > 0.0);
                let ndc = clip.truncate() / clip.w;
                // Viewport transform: x right from column 0, y down from
                // the face's first row.
                let x = (ndc.x + 1.0) * 0.5 * n as f64;
                let y = first as f64 + (1.0 - ndc.y) * 0.5 * rows as f64;
                assert!((x - (col as f64 + 0.5)).abs() < 1e-9, "{n} {index}: x {x}");
                assert!((y - (row as f64 + 0.5)).abs() < 1e-9, "{n} {index}: y {y}");
                assert!(ndc.z > 0.0 && ndc.z <= 1.0);
            }
        }
    }
}
