//! GPU state both roles keep across frames: the scene's world-space
//! vertices (uploaded only when they change), the shadow distance maps
//! (reallocated only when they must grow) and the per-frame uploads. Only
//! what a frame changes is sent to the GPU; on a CPU rasteriser every
//! allocation and upload is a fixed per-frame cost.

use showcase_proto::{ObjectKind, Showcase};

use super::RenderError;
use super::projector_gpu::{ObjectRange, world_vertices_by_object};
use crate::gpu::GpuError;
use crate::gpu::shadow_views::occluders::ObjectVertices;
use crate::gpu::shadow_views::{ShadowMaps, WorldVertex};
use crate::gpu::upload::UploadBuffer;

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
        let (all, ranges) = world_vertices_by_object(showcase, None)?;
        let kinds: Vec<ObjectKind> = ranges
            .iter()
            .map(|(oi, _)| showcase.objects[*oi].kind)
            .collect();
        if self.uploaded && all == self.all && ranges == self.ranges && kinds == self.kinds {
            return Ok(false);
        }
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
        self.generation += 1;
        self.uploaded = true;
        Ok(true)
    }

    /// Every object's world vertices (as last updated).
    pub fn all(&self) -> &[WorldVertex] {
        &self.all
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

/// Make `maps` hold at least `layers` layers of `res` texels (keeping
/// them, and what they hold, when they already do). Returns true when
/// the maps were (re)allocated, so that bind groups naming them must be
/// rebuilt.
pub fn ensure_maps(
    maps: &mut Option<ShadowMaps>,
    device: &wgpu::Device,
    res: u32,
    layers: u32,
) -> Result<bool, RenderError> {
    if let Some(m) = maps
        && m.res() == res
        && m.layers() >= layers
    {
        return Ok(false);
    }
    *maps = Some(ShadowMaps::new(device, res, layers)?);
    Ok(true)
}

/// A far plane at least `far`, rounded up to a power of two, so that a
/// moving light or eye changes the shadow views' projection (and forces
/// layers to be redrawn) only when the scene's extent really changes.
pub fn stable_far(far: f32) -> f32 {
    if !(far.is_finite() && far > 0.0) {
        return far;
    }
    let rounded = 2f32.powi(far.log2().ceil() as i32);
    if rounded >= far {
        rounded
    } else {
        2.0 * rounded
    }
}

#[cfg(test)]
mod tests {
    use super::stable_far;

    #[test]
    fn stable_far_rounds_up_to_a_power_of_two() {
        for (far, expected) in [(1.0, 1.0), (3.2, 4.0), (4.0, 4.0), (4.01, 8.0), (0.3, 0.5)] {
            assert_eq!(stable_far(far), expected, "{far}");
        }
        assert!(stable_far(f32::NAN).is_nan());
    }
}
