//! The projectors' global-illumination correction
//! ([`showcase_light::render::IndirectField`]) as the irradiance map pass
//! draws it: in global mode the real set is drawn split into the field's
//! pieces ([`IndirectField::pieces`]: the radiosity mesh's leaves inside
//! each scene triangle), each vertex carrying the field, so the rasteriser
//! interpolates it as `RadiosityMesh::interpolate` does, linearly inside
//! each piece. The pieces' corners are placed on the scene triangle as it
//! is drawn now, so they cover exactly what the direct set covers.
//!
//! Looking the field up per fragment instead (descending the quadtree in
//! the shader) doubled the pass on lavapipe (`bench render`, 640x480:
//! 72 ms against 38 ms); the pieces cost a vertex attribute.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use showcase_light::render::IndirectField;
use std::sync::Arc;

use crate::gpu::shadow_views::WorldVertex;
use crate::gpu::upload::UploadBuffer;

/// Mirrors the pass's second vertex buffer (location 2): the field at a
/// drawn vertex (W/m^2 per channel).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct FieldValue {
    /// rgb.
    pub value: [f32; 3],
}

/// The second vertex buffer's layout (location 2).
pub fn field_value_layout() -> wgpu::VertexBufferLayout<'static> {
    const ATTRIBUTES: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![2 => Float32x3];
    wgpu::VertexBufferLayout {
        array_stride: size_of::<FieldValue>() as wgpu::BufferAddress,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRIBUTES,
    }
}

/// The real set (`real`: three vertices per triangle; `triangles`: each
/// one's object and mesh triangle) split into `field`'s pieces, with the
/// field at every vertex. A triangle off the field's mesh stays whole,
/// with the field 0.
pub fn field_geometry(
    field: &IndirectField,
    real: &[WorldVertex],
    triangles: &[(u32, u32)],
) -> (Vec<WorldVertex>, Vec<FieldValue>) {
    let mut vertices = Vec::with_capacity(real.len());
    let mut values = Vec::with_capacity(real.len());
    for (corners, &(object, triangle)) in real.chunks_exact(3).zip(triangles) {
        let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(corners[k].position));
        let normal = corners[0].normal;
        let Some(pieces) = field.pieces(object, triangle) else {
            vertices.extend_from_slice(corners);
            values.extend([FieldValue::zeroed(); 3]);
            continue;
        };
        for piece in pieces {
            for (uv, value) in piece.corners.iter().zip(piece.values) {
                let (u, v) = (uv.x as f32, uv.y as f32);
                vertices.push(WorldVertex {
                    position: ((1.0 - u - v) * a + u * b + v * c).to_array(),
                    normal,
                });
                values.push(FieldValue {
                    value: value.as_vec3().to_array(),
                });
            }
        }
    }
    (vertices, values)
}

/// The real set as the pass draws it in global mode, kept across frames
/// and rebuilt only when the field or the scene's vertices change; without
/// a field, zeros beside the scene's own real set.
#[derive(Debug)]
pub struct FieldBuffers {
    vertices: UploadBuffer,
    values: UploadBuffer,
    count: u32,
    /// The field drawn and the scene buffers' generation it was matched
    /// with.
    key: Option<(Option<Arc<IndirectField>>, u64)>,
}

impl FieldBuffers {
    /// Empty buffers.
    pub fn new(device: &wgpu::Device) -> Self {
        let vertex = |label| UploadBuffer::new(device, label, wgpu::BufferUsages::VERTEX);
        Self {
            vertices: vertex("field vertices"),
            values: vertex("field values"),
            count: 0,
            key: None,
        }
    }

    /// Bring the buffers up to `field` on the real set `real` with
    /// `triangles` (the scene buffers' `generation`).
    pub fn update(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        field: Option<&Arc<IndirectField>>,
        real: &[WorldVertex],
        triangles: &[(u32, u32)],
        generation: u64,
    ) {
        let same_field = |held: &Option<Arc<IndirectField>>| match (held, field) {
            (None, None) => true,
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        };
        if self
            .key
            .as_ref()
            .is_some_and(|(f, g)| same_field(f) && *g == generation)
        {
            return;
        }
        match field {
            Some(f) => {
                let (vertices, values) = field_geometry(f, real, triangles);
                self.vertices.write(device, queue, &vertices);
                self.values.write(device, queue, &values);
                self.count = vertices.len() as u32;
            }
            None => {
                self.values
                    .write(device, queue, &vec![FieldValue::zeroed(); real.len()]);
                self.count = real.len() as u32;
            }
        }
        self.key = Some((field.cloned(), generation));
    }

    /// The split real set (in global mode; `None` without a field: draw
    /// the scene's own real set) and its vertex count.
    pub fn vertices(&self) -> Option<(&wgpu::Buffer, u32)> {
        self.key
            .as_ref()
            .is_some_and(|(f, _)| f.is_some())
            .then(|| (self.vertices.buffer(), self.count))
    }

    /// The field at each drawn vertex (zeros without a field).
    pub fn values(&self) -> &wgpu::Buffer {
        self.values.buffer()
    }
}
