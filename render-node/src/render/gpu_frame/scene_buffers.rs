//! The scene's world-space vertices, as both roles draw them: made from
//! a frame's objects on the CPU (flat normals, degenerate triangles left
//! out) and kept on the GPU across frames, uploaded only when they change.
//! On a CPU rasteriser every allocation and upload is a fixed per-frame
//! cost.

use glam::DVec3;
use showcase_proto::{ObjectKind, Showcase};

use crate::gpu::GpuError;
use crate::gpu::shadow_views::WorldVertex;
use crate::gpu::shadow_views::occluders::ObjectVertices;
use crate::gpu::upload::UploadBuffer;
use crate::render::RenderError;
use showcase_light::world_matrix;

/// Which vertex buffer of [`SceneBuffers`] a shadow draw uses (part of
/// its geometry identity).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexSet {
    /// Every object.
    All,
    /// The real objects (phantoms).
    Real,
    /// The virtual objects.
    Virtual,
}

/// The scene's world-space vertices on the GPU: every object, the real
/// ones and the virtual ones, each in object order.
#[derive(Debug)]
pub struct SceneBuffers {
    all: Vec<WorldVertex>,
    ranges: Vec<ObjectRange>,
    kinds: Vec<ObjectKind>,
    /// The real set's vertices (as uploaded to its buffer).
    real: Vec<WorldVertex>,
    /// Per triangle of `all`: its object and its index in the object's
    /// mesh.
    all_triangles: Vec<(u32, u32)>,
    /// The same for the real set.
    real_triangles: Vec<(u32, u32)>,
    real_count: u32,
    virtual_count: u32,
    buffers: [UploadBuffer; 3],
    generation: u64,
    uploaded: bool,
}

impl SceneBuffers {
    /// Empty buffers (nothing uploaded yet).
    pub fn new(device: &wgpu::Device) -> Self {
        let vertex = || UploadBuffer::new(device, "world vertices", wgpu::BufferUsages::VERTEX);
        Self {
            all: Vec::new(),
            ranges: Vec::new(),
            kinds: Vec::new(),
            real: Vec::new(),
            all_triangles: Vec::new(),
            real_triangles: Vec::new(),
            real_count: 0,
            virtual_count: 0,
            buffers: [vertex(), vertex(), vertex()],
            generation: 0,
            uploaded: false,
        }
    }

    /// Transform `showcase`'s meshes to world space and upload them if
    /// they differ from what the buffers hold. Returns true when they did.
    pub fn update(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        showcase: &Showcase,
    ) -> Result<bool, RenderError> {
        let WorldVertices {
            vertices: all,
            ranges,
            triangles,
        } = world_vertices_by_object(showcase, None)?;
        let kinds: Vec<ObjectKind> = ranges
            .iter()
            .map(|(oi, _)| showcase.objects[*oi].kind)
            .collect();
        let all_triangles = ranges
            .iter()
            .flat_map(|(oi, r)| {
                triangles[r.start as usize / 3..r.end as usize / 3]
                    .iter()
                    .map(|&t| (*oi as u32, t))
            })
            .collect::<Vec<_>>();
        if self.uploaded
            && all == self.all
            && ranges == self.ranges
            && kinds == self.kinds
            && all_triangles == self.all_triangles
        {
            return Ok(false);
        }
        let real_triangles = ranges
            .iter()
            .zip(&kinds)
            .filter(|(_, k)| **k == ObjectKind::Real)
            .flat_map(|((_, r), _)| {
                all_triangles[r.start as usize / 3..r.end as usize / 3]
                    .iter()
                    .copied()
            })
            .collect::<Vec<_>>();
        let of = |kind: ObjectKind| -> Vec<WorldVertex> {
            ranges
                .iter()
                .zip(&kinds)
                .filter(|(_, k)| **k == kind)
                .flat_map(|((_, r), _)| all[r.start as usize..r.end as usize].iter().copied())
                .collect()
        };
        let (real, virt) = (of(ObjectKind::Real), of(ObjectKind::Virtual));
        let limit = device.limits().max_buffer_size;
        let bytes = (all.len() * size_of::<WorldVertex>()) as u64;
        if bytes > limit {
            return Err(GpuError::MeshTooLarge {
                item: 0,
                bytes,
                limit,
            }
            .into());
        }
        self.buffers[0].write(device, queue, &all);
        self.buffers[1].write(device, queue, &real);
        self.buffers[2].write(device, queue, &virt);
        self.real_count = real.len() as u32;
        self.virtual_count = virt.len() as u32;
        self.all = all;
        self.ranges = ranges;
        self.kinds = kinds;
        self.all_triangles = all_triangles;
        self.real_triangles = real_triangles;
        self.real = real;
        self.generation += 1;
        self.uploaded = true;
        Ok(true)
    }

    /// Every object's world vertices (as last updated).
    pub fn all(&self) -> &[WorldVertex] {
        &self.all
    }

    /// The vertices of [`VertexSet::Real`]'s buffer.
    pub fn real(&self) -> &[WorldVertex] {
        &self.real
    }

    /// Per triangle of [`VertexSet::Real`]'s buffer, in its order: the
    /// object and the triangle's index in the object's mesh.
    pub fn real_triangles(&self) -> &[(u32, u32)] {
        &self.real_triangles
    }

    /// Per triangle of [`Self::all`], in its order: the object and the
    /// triangle's index in the object's mesh.
    pub fn all_triangles(&self) -> &[(u32, u32)] {
        &self.all_triangles
    }

    /// Identity of the buffers' contents: changes with every upload.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Each drawn object's index and its range in [`Self::all`].
    pub fn ranges(&self) -> &[ObjectRange] {
        &self.ranges
    }

    /// Each drawn object's range in [`Self::all`] and whether it is real
    /// (a receiver of `showcase`'s lights), for the light cube faces'
    /// occluder culling.
    pub fn object_vertices(&self, showcase: &Showcase) -> Vec<ObjectVertices> {
        self.ranges
            .iter()
            .map(|(oi, r)| ObjectVertices {
                range: r.clone(),
                receiver: showcase
                    .objects
                    .get(*oi)
                    .is_some_and(|o| o.kind == ObjectKind::Real),
            })
            .collect()
    }

    /// The buffer of `set` and its vertex count.
    pub fn buffer(&self, set: VertexSet) -> (&wgpu::Buffer, u32) {
        match set {
            VertexSet::All => (self.buffers[0].buffer(), self.all.len() as u32),
            VertexSet::Real => (self.buffers[1].buffer(), self.real_count),
            VertexSet::Virtual => (self.buffers[2].buffer(), self.virtual_count),
        }
    }

    /// Identity of the contents of `set`'s buffer, for
    /// [`crate::gpu::shadow_views::ShadowDraw::geometry`].
    pub fn geometry(&self, set: VertexSet) -> u64 {
        self.generation << 2 | set as u64
    }
}

/// An object index and its vertex range in a vertex buffer.
pub type ObjectRange = (usize, std::ops::Range<u32>);

/// The world-space vertices of a scene's objects
/// ([`world_vertices_by_object`]).
#[derive(Clone, Debug, PartialEq)]
pub struct WorldVertices {
    /// Three per triangle, flat normals.
    pub vertices: Vec<WorldVertex>,
    /// The vertex range of each object drawn, as `(object index, range)`
    /// in object order.
    pub ranges: Vec<ObjectRange>,
    /// Per triangle drawn (a third as many as `vertices`): its index in
    /// its object's mesh.
    pub triangles: Vec<u32>,
}

/// World-space vertices (three per triangle, flat normals) of the objects
/// of `kind` (`None`: all), degenerate triangles left out.
pub fn world_vertices_by_object(
    showcase: &Showcase,
    kind: Option<ObjectKind>,
) -> Result<WorldVertices, RenderError> {
    let mut out = Vec::new();
    let mut ranges = Vec::new();
    let mut triangles = Vec::new();
    for (oi, o) in showcase.objects.iter().enumerate() {
        if kind.is_some_and(|k| k != o.kind) {
            continue;
        }
        let start = out.len() as u32;
        let name = || o.name.clone();
        let mesh =
            showcase
                .mesh(&o.mesh)
                .ok_or_else(|| showcase_light::GeometryError::MissingMesh {
                    object: oi,
                    name: name(),
                })?;
        let m = world_matrix(&o.transform).ok_or_else(|| {
            showcase_light::GeometryError::BadTransform {
                object: oi,
                name: name(),
            }
        })?;
        for (ti, tri) in mesh.triangles.iter().enumerate() {
            let mut v = [DVec3::ZERO; 3];
            for (k, &i) in tri.iter().enumerate() {
                let p = mesh.positions.get(i as usize).ok_or_else(|| {
                    showcase_light::GeometryError::IndexOutOfRange {
                        object: oi,
                        name: name(),
                        triangle: ti,
                        index: i,
                    }
                })?;
                v[k] = m.transform_point3(p.as_dvec3());
            }
            let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
            if n == DVec3::ZERO || !n.is_finite() {
                continue;
            }
            let normal = n.as_vec3().to_array();
            triangles.push(ti as u32);
            out.extend(v.iter().map(|p| WorldVertex {
                position: p.as_vec3().to_array(),
                normal,
            }));
        }
        ranges.push((oi, start..out.len() as u32));
    }
    Ok(WorldVertices {
        vertices: out,
        ranges,
        triangles,
    })
}
