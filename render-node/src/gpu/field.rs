//! The global-illumination field
//! ([`showcase_light::render::IndirectField`]) as the passes draw it: in
//! global mode the irradiance map pass draws the real set, and the face
//! view every object, split into the field's pieces ([`IndirectField::pieces`]: the radiosity mesh's leaves inside
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

/// Mirrors the passes' second vertex buffer: the field at a drawn vertex
/// (W/m^2 per channel, [`showcase_light::render::IndirectLight`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct FieldValue {
    /// What the displays add (location 2).
    pub add: [f32; 3],
    /// The real surfaces' own interreflection (location 3).
    pub cabinet: [f32; 3],
}

/// The second vertex buffer's layout (locations 2 and 3).
pub fn field_value_layout() -> wgpu::VertexBufferLayout<'static> {
    const ATTRIBUTES: [wgpu::VertexAttribute; 2] =
        wgpu::vertex_attr_array![2 => Float32x3, 3 => Float32x3];
    wgpu::VertexBufferLayout {
        array_stride: size_of::<FieldValue>() as wgpu::BufferAddress,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRIBUTES,
    }
}

/// A vertex set split into a field's pieces ([`field_geometry`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FieldGeometry {
    /// Three per piece.
    pub vertices: Vec<WorldVertex>,
    /// The field at each of `vertices`.
    pub values: Vec<FieldValue>,
    /// Per input triangle, the first of `vertices` its pieces hold, and
    /// after the last `vertices.len()`.
    pub starts: Vec<u32>,
}

/// A vertex set (`set`: three vertices per triangle; `triangles`: each
/// one's object and mesh triangle) split into `field`'s pieces, with the
/// field at every vertex. A triangle off the field's mesh stays whole,
/// with the field 0.
pub fn field_geometry(
    field: &IndirectField,
    set: &[WorldVertex],
    triangles: &[(u32, u32)],
) -> FieldGeometry {
    let mut vertices = Vec::with_capacity(set.len());
    let mut values = Vec::with_capacity(set.len());
    let mut starts = Vec::with_capacity(triangles.len() + 1);
    for (corners, &(object, triangle)) in set.chunks_exact(3).zip(triangles) {
        starts.push(vertices.len() as u32);
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
                    add: value.add.as_vec3().to_array(),
                    cabinet: value.cabinet.as_vec3().to_array(),
                });
            }
        }
    }
    starts.push(vertices.len() as u32);
    FieldGeometry {
        vertices,
        values,
        starts,
    }
}

/// A vertex set as a pass draws it in global mode (the projectors' real
/// set, the faces' every object), kept across frames and rebuilt only
/// when the field or the scene's vertices change; without a field, zeros
/// beside the scene's own set.
#[derive(Debug)]
pub struct FieldBuffers {
    vertices: UploadBuffer,
    values: UploadBuffer,
    count: u32,
    /// [`FieldGeometry::starts`] of the split set (empty without a field).
    starts: Vec<u32>,
    /// Bumped whenever the buffers' contents change.
    content: u64,
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
            starts: Vec::new(),
            content: 0,
            key: None,
        }
    }

    /// Bring the buffers up to `field` on the vertex set `set` with
    /// `triangles` (the scene buffers' `generation`).
    pub fn update(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        field: Option<&Arc<IndirectField>>,
        set: &[WorldVertex],
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
                let g = field_geometry(f, set, triangles);
                self.vertices.write(device, queue, &g.vertices);
                self.values.write(device, queue, &g.values);
                self.count = g.vertices.len() as u32;
                self.starts = g.starts;
            }
            None => {
                self.values
                    .write(device, queue, &vec![FieldValue::zeroed(); set.len()]);
                self.count = set.len() as u32;
                self.starts.clear();
            }
        }
        self.key = Some((field.cloned(), generation));
        self.content += 1;
    }

    /// Identity of the buffers' contents: changes with every rebuild.
    pub fn content(&self) -> u64 {
        self.content
    }

    /// Whether a field is drawn (global mode).
    pub fn has_field(&self) -> bool {
        self.key.as_ref().is_some_and(|(f, _)| f.is_some())
    }

    /// Where the vertices of `range` of the scene's own set (whole
    /// triangles) lie in the split set: `range` itself without a field.
    pub fn range(&self, range: &std::ops::Range<u32>) -> std::ops::Range<u32> {
        let at = |v: u32| {
            if self.starts.is_empty() {
                v
            } else {
                self.starts
                    .get(v as usize / 3)
                    .copied()
                    .unwrap_or(self.count)
            }
        };
        at(range.start)..at(range.end)
    }

    /// The split set (in global mode; `None` without a field: draw the
    /// scene's own set) and its vertex count.
    pub fn vertices(&self) -> Option<(&wgpu::Buffer, u32)> {
        self.has_field()
            .then(|| (self.vertices.buffer(), self.count))
    }

    /// The field at each drawn vertex (zeros without a field).
    pub fn values(&self) -> &wgpu::Buffer {
        self.values.buffer()
    }
}
