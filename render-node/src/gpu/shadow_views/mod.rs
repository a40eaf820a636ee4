//! Shadow views pass: depth maps from light samples (cube faces) and
//! eyes (one view fitted around the occluders) into layers of one depth
//! array texture, which the irradiance-map and face passes turn back into
//! distances from the view's origin and compare against. Depth only (no
//! fragment shader, no colour target): the cheapest fill a rasteriser has,
//! which matters on a CPU one. CPU reference: visibility rays
//! (`showcase_light::render::projector`).

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};

use super::GpuError;
use super::pipeline::{TrianglePipeline, entry, one_group_layout, read_only_storage};
use super::target::DEPTH_FORMAT;

pub mod occluders;

/// Near plane of every shadow view (metres). The sampling passes need it
/// (with the frame's far plane) to turn depth back into distance.
pub const SHADOW_NEAR: f32 = 1e-3;

/// Mirrors WGSL `struct ShadowView` in `shadow_views.wgsl` (and in
/// `shadow_lookup.part.wgsl`, which the sampling passes share).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ShadowView {
    /// Clip space of this view.
    pub clip_from_world: [[f32; 4]; 4],
    /// xyz origin, w texel angle (radians).
    pub origin: [f32; 4],
}

/// Mirrors WGSL `struct VertexIn` of the shadow and irradiance passes: a
/// world-space position and its triangle's unit normal.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct WorldVertex {
    /// World position.
    pub position: [f32; 3],
    /// Unit geometric normal of the vertex's triangle.
    pub normal: [f32; 3],
}

/// The vertex layout of [`WorldVertex`].
pub fn world_vertex_layout() -> wgpu::VertexBufferLayout<'static> {
    const ATTRIBUTES: [wgpu::VertexAttribute; 2] =
        wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3];
    wgpu::VertexBufferLayout {
        array_stride: size_of::<WorldVertex>() as wgpu::BufferAddress,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &ATTRIBUTES,
    }
}

fn perspective_view(
    origin: Vec3,
    dir: Vec3,
    up: Vec3,
    fov: f32,
    near: f32,
    far: f32,
) -> ShadowView {
    let clip = Mat4::perspective_rh(fov, 1.0, near, far) * Mat4::look_to_rh(origin, dir, up);
    ShadowView {
        clip_from_world: clip.to_cols_array_2d(),
        origin: [origin.x, origin.y, origin.z, 0.0],
    }
}

/// The six 90-degree cube faces around `origin`; every direction lies in
/// one of them. `res` is the map size in texels.
pub fn cube_views(origin: Vec3, near: f32, far: f32, res: u32) -> Vec<ShadowView> {
    let faces = [
        (Vec3::X, Vec3::Y),
        (Vec3::NEG_X, Vec3::Y),
        (Vec3::Y, Vec3::Z),
        (Vec3::NEG_Y, Vec3::Z),
        (Vec3::Z, Vec3::Y),
        (Vec3::NEG_Z, Vec3::Y),
    ];
    let texel = 2.0 / res.max(1) as f32;
    faces
        .iter()
        .map(|&(dir, up)| {
            let mut v = perspective_view(origin, dir, up, std::f32::consts::FRAC_PI_2, near, far);
            v.origin[3] = texel;
            v
        })
        .collect()
}

/// Views from `origin` covering the sphere `(centre, radius)`: one view
/// fitted around it, or the cube when `origin` is (nearly) inside it.
pub fn fitted_views(
    origin: Vec3,
    centre: Vec3,
    radius: f32,
    near: f32,
    far: f32,
    res: u32,
) -> Vec<ShadowView> {
    let to = centre - origin;
    let d = to.length();
    if !(d > 1.05 * radius && radius > 0.0) {
        return cube_views(origin, near, far, res);
    }
    let half = (radius / d).asin() * 1.02 + 1e-3;
    if half >= 1.2 {
        return cube_views(origin, near, far, res);
    }
    let dir = to / d;
    let up = if dir.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
    let mut v = perspective_view(origin, dir, up, 2.0 * half, near, far);
    v.origin[3] = 2.0 * half.tan() / res.max(1) as f32;
    vec![v]
}

/// What a layer of [`ShadowMaps`] holds: the view it was drawn with and
/// the identity of the geometry drawn (see [`ShadowDraw::geometry`]).
type LayerContent = (ShadowView, u64);

/// The distance maps: one `res x res` layer per view. They remember what
/// each layer was drawn with, so that a layer whose view and geometry did
/// not change is not drawn again (a light or eye that did not move).
#[derive(Debug)]
pub struct ShadowMaps {
    res: u32,
    layers: u32,
    texture: wgpu::Texture,
    array_view: wgpu::TextureView,
    layer_views: Vec<wgpu::TextureView>,
    contents: Vec<Option<LayerContent>>,
}

impl ShadowMaps {
    /// Allocate `layers` maps of `res x res` (at least one layer, so that
    /// the binding exists even without views).
    pub fn new(device: &wgpu::Device, res: u32, layers: u32) -> Result<Self, GpuError> {
        let limits = device.limits();
        let layers = layers.max(1);
        if res == 0
            || res > limits.max_texture_dimension_2d
            || layers > limits.max_texture_array_layers
        {
            return Err(GpuError::BadTargetSize {
                width: res,
                height: layers,
                limit: limits
                    .max_texture_dimension_2d
                    .min(limits.max_texture_array_layers),
            });
        }
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow depth maps"),
            size: wgpu::Extent3d {
                width: res,
                height: res,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let layer_views = (0..layers)
            .map(|layer| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    label: Some("shadow layer"),
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: layer,
                    array_layer_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let array_view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("shadow maps"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        Ok(Self {
            res,
            layers,
            texture,
            array_view,
            layer_views,
            contents: vec![None; layers as usize],
        })
    }

    /// Forget what the layers hold, so that the next draw redraws them all.
    pub fn invalidate(&mut self) {
        self.contents.iter_mut().for_each(|c| *c = None);
    }

    /// Size of a layer in texels.
    pub fn res(&self) -> u32 {
        self.res
    }

    /// Number of layers.
    pub fn layers(&self) -> u32 {
        self.layers
    }

    /// The whole array, for sampling.
    pub fn array_view(&self) -> &wgpu::TextureView {
        &self.array_view
    }

    /// The texture.
    pub fn texture(&self) -> &wgpu::Texture {
        &self.texture
    }
}

/// The compiled shadow-views pipeline.
#[derive(Debug)]
pub struct ShadowViewsPass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

/// Geometry to draw into a range of layers.
#[derive(Debug)]
pub struct ShadowDraw<'a> {
    /// World-space vertices, [`WorldVertex`] layout.
    pub vertices: &'a wgpu::Buffer,
    /// Number of vertices.
    pub vertex_count: u32,
    /// Layers (= view indices) to draw into.
    pub layers: std::ops::Range<u32>,
    /// Identity of the vertex data: the same value promises the same
    /// vertices, so that a layer already drawn with the same view and
    /// geometry is kept instead of drawn again. Callers must change it
    /// whenever the buffer's contents change.
    pub geometry: u64,
}

impl ShadowViewsPass {
    /// Compile the pipeline.
    pub fn new(device: &wgpu::Device) -> Self {
        let shader = device.create_shader_module(wgpu::include_wgsl!("shadow_views.wgsl"));
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow views"),
            entries: &[entry(0, wgpu::ShaderStages::VERTEX, read_only_storage())],
        });
        let pipeline = TrianglePipeline {
            label: "shadow views",
            layout: &one_group_layout(device, "shadow views", &layout),
            shader: &shader,
            vertex: ("vs_main", &[Some(world_vertex_layout())]),
            // Surfaces are two-sided occluders.
            cull_mode: None,
            depth: Some((DEPTH_FORMAT, wgpu::CompareFunction::Less)),
            // Depth only.
            fragment: None,
        }
        .build(device);
        Self { pipeline, layout }
    }

    /// The bind group of the views buffer (create once per buffer).
    pub fn bind_group(&self, device: &wgpu::Device, views: &wgpu::Buffer) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow views"),
            layout: &self.layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: views.as_entire_binding(),
            }],
        })
    }

    /// Record one render pass per layer of each draw whose content
    /// changed: clear the depth to 1 (the far plane), draw the geometry with that
    /// layer's view (`views[layer]`, as uploaded into the buffer of
    /// `bind_group`). A layer that already holds the same view and
    /// geometry is skipped. Returns the number of layers drawn.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        maps: &mut ShadowMaps,
        bind_group: &wgpu::BindGroup,
        views: &[ShadowView],
        draws: &[ShadowDraw<'_>],
    ) -> u32 {
        let mut drawn = 0;
        for draw in draws {
            let whole = 0..draw.vertex_count;
            for layer in draw.layers.clone() {
                drawn += self.encode_layer(
                    encoder,
                    maps,
                    bind_group,
                    views,
                    &LayerDraw {
                        vertices: draw.vertices,
                        layer,
                        ranges: std::slice::from_ref(&whole),
                        geometry: draw.geometry,
                    },
                );
            }
        }
        drawn
    }

    /// [`Self::encode`] for draws of one layer each, each drawing only
    /// its vertex ranges (an empty list clears the layer). Returns the
    /// number of layers drawn.
    pub fn encode_layers(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        maps: &mut ShadowMaps,
        bind_group: &wgpu::BindGroup,
        views: &[ShadowView],
        draws: &[LayerDraw<'_>],
    ) -> u32 {
        draws
            .iter()
            .map(|d| self.encode_layer(encoder, maps, bind_group, views, d))
            .sum()
    }

    fn encode_layer(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        maps: &mut ShadowMaps,
        bind_group: &wgpu::BindGroup,
        views: &[ShadowView],
        draw: &LayerDraw<'_>,
    ) -> u32 {
        let layer = draw.layer;
        let (Some(target), Some(view)) = (
            maps.layer_views.get(layer as usize),
            views.get(layer as usize),
        ) else {
            return 0;
        };
        let content = Some((*view, draw.geometry));
        if maps.contents[layer as usize] == content {
            return 0;
        }
        maps.contents[layer as usize] = content;
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shadow view"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: target,
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
        let mut bound = false;
        for range in draw.ranges.iter().filter(|r| r.start < r.end) {
            if !bound {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, bind_group, &[]);
                pass.set_vertex_buffer(0, draw.vertices.slice(..));
                bound = true;
            }
            pass.draw(range.clone(), layer..layer + 1);
        }
        1
    }
}

/// Geometry to draw into one layer: some vertex ranges of a buffer.
#[derive(Debug)]
pub struct LayerDraw<'a> {
    /// World-space vertices, [`WorldVertex`] layout.
    pub vertices: &'a wgpu::Buffer,
    /// The layer (= view index) to draw into.
    pub layer: u32,
    /// Vertex ranges to draw (none: the layer is only cleared).
    pub ranges: &'a [std::ops::Range<u32>],
    /// Identity of what the ranges hold, as [`ShadowDraw::geometry`]: the
    /// same value promises the same vertices.
    pub geometry: u64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use showcase_light::render::cube_map::{texel_direction, world_to_face};

    fn ndc(v: &ShadowView, p: Vec3) -> Option<Vec3> {
        let c = Mat4::from_cols_array_2d(&v.clip_from_world) * p.extend(1.0);
        (c.w > 0.0).then(|| c.truncate() / c.w)
    }

    #[test]
    fn every_direction_falls_in_exactly_one_cube_face_interior() {
        let o = Vec3::new(0.1, 0.2, 0.3);
        let views = cube_views(o, 1e-3, 10.0, 256);
        for d in [
            Vec3::new(1.0, 0.3, -0.2),
            Vec3::new(-0.2, -1.0, 0.5),
            Vec3::new(0.4, 0.4, -0.9),
            Vec3::new(0.0, 0.99, 0.1),
        ] {
            let inside = views
                .iter()
                .filter(|v| {
                    ndc(v, o + d).is_some_and(|n| {
                        n.x.abs() < 1.0 && n.y.abs() < 1.0 && n.z > 0.0 && n.z < 1.0
                    })
                })
                .count();
            assert_eq!(inside, 1, "{d}");
        }
    }

    #[test]
    fn world_to_face_is_the_projection_of_the_major_axis_face() {
        use rand::{Rng, SeedableRng};
        let o = Vec3::new(0.3, -0.1, 0.2);
        let views = cube_views(o, 1e-3, 10.0, 256);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for _ in 0..2000 {
            let d = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if d.length() < 1e-3 {
                continue;
            }
            let (face, c) = world_to_face(d.as_dvec3());
            let c = c.as_vec3();
            let n = ndc(&views[face], o + d).expect("in front of its face");
            assert!(
                n.x.abs() <= 1.0 + 1e-6 && n.y.abs() <= 1.0 + 1e-6,
                "{d}: {n}"
            );
            let analytic = c.truncate() / c.z;
            assert!(
                (analytic - n.truncate()).abs().max_element() < 1e-5,
                "{d}: face {face} analytic {analytic} matrix {n}"
            );
        }
    }

    #[test]
    fn faces_match_the_shadow_cube_views() {
        // The texel's direction projects into the same texel through the
        // GPU pass's view matrices.
        let views = cube_views(glam::Vec3::ZERO, 0.01, 10.0, 8);
        for (face, v) in views.iter().enumerate() {
            let m = glam::Mat4::from_cols_array_2d(&v.clip_from_world);
            let d = texel_direction(face, 2, 5, 8).as_vec3();
            let c = m * d.extend(1.0);
            let ndc = glam::Vec2::new(c.x, c.y) / c.w;
            let tx = ((ndc.x * 0.5 + 0.5) * 8.0).floor() as u32;
            let ty = ((0.5 - ndc.y * 0.5) * 8.0).floor() as u32;
            assert!(c.w > 0.0 && (tx, ty) == (2, 5), "face {face}: {ndc}");
        }
    }

    #[test]
    fn fitted_view_covers_the_sphere() {
        let o = Vec3::new(0.0, 0.5, 2.0);
        let (c, r) = (Vec3::new(0.2, 0.1, 0.0), 0.3);
        let views = fitted_views(o, c, r, 1e-3, 10.0, 256);
        assert_eq!(views.len(), 1);
        for d in [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::NEG_X,
            Vec3::NEG_Y,
            Vec3::NEG_Z,
        ] {
            let n = ndc(&views[0], c + d * r).unwrap();
            assert!(n.x.abs() < 1.0 && n.y.abs() < 1.0, "{d}: {n}");
        }
        let inside = fitted_views(c, c, r, 1e-3, 10.0, 256);
        assert_eq!(inside.len(), 6);
    }
}
