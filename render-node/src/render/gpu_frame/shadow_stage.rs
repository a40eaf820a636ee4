//! The shadow stage both roles run before their own pass: the shadow
//! distance maps (reallocated only when they must grow), the light
//! samples' and shadow views' uploads with the bind group naming them,
//! and the encoding of the light samples' cube layers and the eyes'
//! layers (a layer whose view and geometry did not change is kept).

use super::inputs::FrameInputs;
use super::scene_buffers::{SceneBuffers, VertexSet};
use super::timed::TimedEncoder;
use crate::gpu::GpuError;
use crate::gpu::frame_arrays::ARRAY_USAGE;
use crate::gpu::shadow_lookup::LightSampleGpu;
use crate::gpu::shadow_views::occluders::{cube_occluder_ranges, ranges_identity};
use crate::gpu::shadow_views::{LayerDraw, ShadowDraw, ShadowMaps, ShadowView, ShadowViewsPass};
use crate::gpu::upload::UploadBuffer;
use crate::render::RenderError;
use crate::render::passes::Pass;
use showcase_light::render::frame::FrameScene;

/// Default size of each shadow distance map (texels per side).
pub const DEFAULT_SHADOW_RES: u32 = 1024;

/// Which objects a light sample's cube layers hold: occluder culling, a
/// choice of the role, because what may be left out depends on which
/// surfaces look the light maps up.
///
/// The projector culls ([`Self::ShadowingReal`]). Its irradiance map
/// looks the light maps up from real surfaces only, so an object that
/// can shadow no real surface (a wall of the room seen from a light
/// inside it) is left out of all six faces, and every object is left out
/// of the faces its bounds do not reach: fewer triangles rasterised per
/// sample on a CPU rasteriser. A left-out object can only turn a lookup
/// at its own edges from shadowed to lit where the exact ray is not
/// blocked, so pixels move towards the CPU reference, never away from it
/// (`tests/it/render/projector.rs`, culled against unculled maps).
///
/// The face does not cull ([`Self::Every`]). It looks the light maps up
/// from the virtual objects it shades as well as from real surfaces (the
/// phantoms it fills in occlusion shadows, the cube maps' environment),
/// and the culling test counts only real surfaces as receivers: it could
/// leave out an object that shadows only a virtual one. Culling against
/// every object as a receiver would be sound, but it changes the edge
/// texels above, so the face's output would not stay byte-identical, and
/// that change has not been measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightOccluders {
    /// Every object, in every face.
    Every,
    /// Only the objects that can shadow a real surface, each in the faces
    /// its bounds reach into (`shadow_views::occluders`).
    ShadowingReal,
}

/// The shadow maps and what a frame uploads for them, kept across frames
/// (create once per device and pipeline).
#[derive(Debug)]
pub struct ShadowStage {
    pass: ShadowViewsPass,
    res: u32,
    lights: UploadBuffer,
    views: UploadBuffer,
    maps: Option<ShadowMaps>,
    /// The shadow bind group and the views buffer generation it names.
    bind: Option<(u64, wgpu::BindGroup)>,
    last_layers_drawn: u32,
}

impl ShadowStage {
    /// Compile the pass; maps get `res` texels per side (at least 1). The
    /// light and view buffers are at least the capacity (elements) that
    /// `capacity` gives for the sampling shader's `lights` and `views`
    /// arrays, so that they bind whole as its uniform arrays.
    pub fn new(device: &wgpu::Device, res: u32, capacity: fn(&str) -> usize) -> Self {
        // Bindable as the sampling shader's uniform arrays (whole
        // capacity) or as storage (the shadow views pass, long frames).
        let array = |label, bytes: usize| {
            UploadBuffer::with_min_size(device, label, ARRAY_USAGE, bytes as u64)
        };
        Self {
            pass: ShadowViewsPass::new(device),
            res: res.max(1),
            lights: array(
                "light samples",
                capacity("lights") * size_of::<LightSampleGpu>(),
            ),
            views: array("shadow views", capacity("views") * size_of::<ShadowView>()),
            maps: None,
            bind: None,
            last_layers_drawn: 0,
        }
    }

    /// Texels per side of each map.
    pub fn res(&self) -> u32 {
        self.res
    }

    /// Make the maps hold a layer per view of `inputs`, upload its views
    /// and light samples and refresh the bind group. Returns true when
    /// the maps were (re)allocated, so that bind groups naming them must
    /// be rebuilt.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        inputs: &FrameInputs,
    ) -> Result<bool, GpuError> {
        let layers = inputs.views.len() as u32;
        let reallocate = self
            .maps
            .as_ref()
            .is_none_or(|m| m.res() != self.res || m.layers() < layers);
        if reallocate {
            self.maps = Some(ShadowMaps::new(device, self.res, layers)?);
        }
        self.views.write(device, queue, &inputs.views);
        self.lights.write(device, queue, &inputs.lights);
        let generation = self.views.generation();
        if self.bind.as_ref().is_none_or(|(g, _)| *g != generation) {
            let bind = self.pass.bind_group(device, self.views.buffer());
            self.bind = Some((generation, bind));
        }
        Ok(reallocate)
    }

    /// The maps (after [`Self::prepare`]).
    pub fn maps(&self) -> Result<&ShadowMaps, RenderError> {
        self.maps.as_ref().ok_or(RenderError::NothingDrawn)
    }

    /// The light samples' buffer, as last uploaded.
    pub fn lights(&self) -> &UploadBuffer {
        &self.lights
    }

    /// The shadow views' buffer, as last uploaded.
    pub fn views(&self) -> &UploadBuffer {
        &self.views
    }

    /// Layers the last [`Self::encode`] drew (the others held the same
    /// view and geometry already).
    pub fn last_layers_drawn(&self) -> u32 {
        self.last_layers_drawn
    }

    /// Draw the layers of `inputs` that changed, as steps of `steps`: the
    /// light samples' cube layers with `occluders` (when `inputs.shadows`),
    /// then the eyes' layers with the virtual objects (when
    /// `inputs.occlusion`).
    pub fn encode(
        &mut self,
        steps: &mut TimedEncoder<'_>,
        scene: &SceneBuffers,
        frame: &FrameScene,
        inputs: &FrameInputs,
        occluders: LightOccluders,
    ) -> Result<(), RenderError> {
        let (Some(maps), Some((_, bind))) = (self.maps.as_mut(), &self.bind) else {
            return Err(RenderError::NothingDrawn);
        };
        let mut drawn = 0;
        if inputs.shadows {
            let ranges = light_layer_ranges(scene, frame, inputs, occluders);
            let (vertices, _) = scene.buffer(VertexSet::All);
            let geometry = scene.geometry(VertexSet::All);
            let draws: Vec<LayerDraw<'_>> = ranges
                .iter()
                .map(|(layer, ranges)| LayerDraw {
                    vertices,
                    layer: *layer,
                    ranges,
                    geometry: ranges_identity(geometry, ranges),
                })
                .collect();
            drawn += self
                .pass
                .encode_layers(steps.encoder(), maps, bind, &inputs.views, &draws);
            steps.step(Pass::LightShadowViews.name())?;
        }
        if inputs.occlusion {
            let (vertices, vertex_count) = scene.buffer(VertexSet::Virtual);
            let draw = ShadowDraw {
                vertices,
                vertex_count,
                layers: inputs.eye_layers.clone(),
                geometry: scene.geometry(VertexSet::Virtual),
            };
            drawn += self
                .pass
                .encode(steps.encoder(), maps, bind, &inputs.views, &[draw]);
            steps.step(Pass::EyeShadowViews.name())?;
        }
        self.last_layers_drawn = drawn;
        Ok(())
    }
}

/// Each light layer of `inputs` and the vertex ranges of the scene's
/// buffer of every object that it draws.
fn light_layer_ranges(
    scene: &SceneBuffers,
    frame: &FrameScene,
    inputs: &FrameInputs,
    occluders: LightOccluders,
) -> Vec<(u32, Vec<std::ops::Range<u32>>)> {
    let everything = 0..scene.all().len() as u32;
    if occluders == LightOccluders::Every {
        return inputs
            .light_layers
            .clone()
            .map(|layer| (layer, vec![everything.clone()]))
            .collect();
    }
    let objects = scene.object_vertices(&frame.showcase);
    let mut per_layer = Vec::with_capacity(inputs.light_layers.len());
    for (s, l) in frame.samples.iter().zip(&inputs.lights) {
        let first = l.views[0] as usize;
        let cube = &inputs.views[first..first + l.views[1] as usize];
        let ranges = cube_occluder_ranges(scene.all(), &objects, s.position, cube);
        for (k, ranges) in ranges.into_iter().enumerate() {
            per_layer.push(((first + k) as u32, ranges));
        }
    }
    per_layer
}
