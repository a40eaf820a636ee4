//! The floor of the projector (and face) pass on an adapter: stripped
//! versions of the irradiance-map pass that keep one cost each, so that a
//! benchmark can say what the real pass cannot go below. `Geometry` keeps
//! the rasterisation and vertex work (the real pass's vertex shader,
//! depth test and targets, a constant fragment); `FullScreen` keeps only
//! the fill of the targets (one triangle over the whole target, constant
//! fragment); `Fetches(k)` adds `k` texel fetches per pixel from the
//! shadow maps (and the blend weights), the lookups the real fragment
//! shader makes, and nothing else. Used by `render::bench::floor`.

use super::super::pipeline::{TrianglePipeline, entry, one_group_layout, opaque, uniform_buffer};
use super::super::shadow_views::world_vertex_layout;
use super::super::target::{COLOUR_FORMAT, DEPTH_FORMAT, OffscreenTarget};

/// Why a stripped pass cannot be recorded.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum FloorError {
    /// The targets given are not as many as the pass was compiled for.
    #[error("floor pass writes {expected} targets but {given} were given")]
    TargetCount {
        /// Targets the pass writes.
        expected: u32,
        /// Targets given.
        given: u32,
    },
    /// The targets differ in size.
    #[error(
        "floor pass targets differ in size: {width}x{height} against {first_width}x{first_height}"
    )]
    SizeMismatch {
        /// The first target's width.
        first_width: u32,
        /// The first target's height.
        first_height: u32,
        /// The other target's width.
        width: u32,
        /// The other target's height.
        height: u32,
    },
}

/// One stripped pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FloorKind {
    /// The real pass's geometry, vertex shader and depth test with a
    /// fragment shader that writes constants.
    Geometry,
    /// A full-screen triangle with a fragment shader that writes constants.
    FullScreen,
    /// A full-screen triangle whose fragment shader makes this many texel
    /// fetches from the shadow maps (at addresses that move with the pixel
    /// as the real lookups do) and writes their sum.
    Fetches(u32),
}

/// The WGSL source of a [`FloorKind`] writing `targets` colour targets.
pub fn floor_source(kind: FloorKind, targets: u32) -> String {
    let mut s = String::from(
        "@group(0) @binding(0) var<uniform> clip_from_world: mat4x4<f32>;\n\
         @group(0) @binding(1) var maps: texture_depth_2d_array;\n\
         @group(0) @binding(2) var blend: texture_2d<f32>;\n\
         struct VertexIn { @location(0) position: vec3<f32>, @location(1) normal: vec3<f32> }\n",
    );
    s.push_str("struct Out {\n");
    for t in 0..targets {
        s.push_str(&format!("    @location({t}) c{t}: vec4<f32>,\n"));
    }
    s.push_str("}\n");
    s.push_str(
        "@vertex fn vs_geometry(v: VertexIn) -> @builtin(position) vec4<f32> {\n\
         \x20   return clip_from_world * vec4<f32>(v.position, 1.0);\n}\n\
         @vertex fn vs_full(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {\n\
         \x20   let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));\n\
         \x20   return vec4<f32>(uv * 2.0 - 1.0, 0.5, 1.0);\n}\n",
    );
    s.push_str("@fragment fn fs_main(@builtin(position) frag: vec4<f32>) -> Out {\n");
    s.push_str("    var sum = 0.0;\n");
    if let FloorKind::Fetches(k) = kind {
        s.push_str(
            "    let px = vec2<u32>(frag.xy);\n\
             \x20   let bsize = textureDimensions(blend);\n\
             \x20   let res = textureDimensions(maps);\n\
             \x20   let layers = textureNumLayers(maps);\n\
             \x20   let f = frag.xy / vec2<f32>(bsize);\n",
        );
        for j in 0..k {
            // Each lookup reads its own layer at a point that moves with
            // the pixel, scaled and mirrored differently per lookup (as
            // different views project a surface).
            let scale = 0.4 + 0.1 * f64::from(j % 5);
            let (a, b) = if j % 2 == 0 { ("x", "y") } else { ("y", "x") };
            s.push_str(&format!(
                "    sum += textureLoad(maps, min(vec2<u32>(vec2<f32>(f.{a}, f.{b}) * {scale:?} * vec2<f32>(res)), res - 1u), {j}u % layers, 0);\n"
            ));
        }
    }
    s.push_str("    var out: Out;\n");
    for t in 0..targets {
        s.push_str(&format!(
            "    out.c{t} = vec4<f32>(sum, 0.25, 0.5, {}.0);\n",
            t + 1
        ));
    }
    s.push_str("    return out;\n}\n");
    s
}

/// A compiled stripped pass and its bind group layout.
#[derive(Debug)]
pub struct FloorPass {
    kind: FloorKind,
    targets: u32,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

/// What a [`FloorPass`] reads.
#[derive(Debug)]
pub struct FloorBindings<'a> {
    /// A uniform buffer starting with the projector's `clip_from_world`
    /// (the real pass's frame uniform does).
    pub frame: &'a wgpu::Buffer,
    /// The shadow maps (depth array).
    pub maps: &'a wgpu::TextureView,
    /// The blend weights (`R32Float`).
    pub blend: &'a wgpu::TextureView,
}

impl FloorPass {
    /// Compile `kind` for `targets` (1 to 8) [`OffscreenTarget`] colour
    /// targets.
    pub fn new(device: &wgpu::Device, kind: FloorKind, targets: u32) -> Self {
        let targets = targets.clamp(1, 8);
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("irradiance floor"),
            source: wgpu::ShaderSource::Wgsl(floor_source(kind, targets).into()),
        });
        let [shadow_maps, blend] = super::shadow_and_blend(1);
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("irradiance floor"),
            entries: &[
                entry(0, wgpu::ShaderStages::VERTEX, uniform_buffer(false, None)),
                shadow_maps,
                blend,
            ],
        });
        let colour_targets = vec![opaque(COLOUR_FORMAT); targets as usize];
        let geometry = kind == FloorKind::Geometry;
        let layouts = [Some(world_vertex_layout())];
        let pipeline = TrianglePipeline {
            label: "irradiance floor",
            layout: &one_group_layout(device, "irradiance floor", &layout),
            shader: &shader,
            vertex: if geometry {
                ("vs_geometry", &layouts)
            } else {
                ("vs_full", &[])
            },
            cull_mode: None,
            // The real pass's depth test; a full-screen pass needs none.
            depth: geometry.then_some((DEPTH_FORMAT, wgpu::CompareFunction::Less)),
            fragment: Some(("fs_main", &colour_targets)),
        }
        .build(device);
        Self {
            kind,
            targets,
            pipeline,
            layout,
        }
    }

    /// The pass's kind.
    pub fn kind(&self) -> FloorKind {
        self.kind
    }

    /// The bind group of `bindings`.
    pub fn bind_group(&self, device: &wgpu::Device, b: &FloorBindings<'_>) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("irradiance floor"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: b.frame.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(b.maps),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(b.blend),
                },
            ],
        })
    }

    /// Record the pass into `targets` (as many as it was compiled for,
    /// all one size; the first one's depth is used by `Geometry`),
    /// clearing them as the real pass does; `vertices` (`vertex_count`
    /// world vertices) are drawn by `Geometry` only.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &[&OffscreenTarget],
        bind_group: &wgpu::BindGroup,
        vertices: &wgpu::Buffer,
        vertex_count: u32,
    ) -> Result<(), FloorError> {
        let Some(first) = targets.first() else {
            return Err(FloorError::TargetCount {
                expected: self.targets,
                given: 0,
            });
        };
        let mismatch = targets
            .iter()
            .find(|t| (t.width(), t.height()) != (first.width(), first.height()));
        if let Some(t) = mismatch {
            return Err(FloorError::SizeMismatch {
                first_width: first.width(),
                first_height: first.height(),
                width: t.width(),
                height: t.height(),
            });
        }
        if targets.len() as u32 != self.targets {
            return Err(FloorError::TargetCount {
                expected: self.targets,
                given: targets.len() as u32,
            });
        }
        let attachments: Vec<_> = targets
            .iter()
            .map(|t| {
                Some(wgpu::RenderPassColorAttachment {
                    view: t.colour_view(),
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })
            })
            .collect();
        let geometry = self.kind == FloorKind::Geometry;
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("irradiance floor"),
            color_attachments: &attachments,
            depth_stencil_attachment: geometry.then(|| wgpu::RenderPassDepthStencilAttachment {
                view: first.depth_view(),
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
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        if geometry {
            if vertex_count > 0 {
                pass.set_vertex_buffer(0, vertices.slice(..));
                pass.draw(0..vertex_count, 0..1);
            }
        } else {
            pass.draw(0..3, 0..1);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn validate(src: &str) {
        let module = naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{e}\n{src}"));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{e:?}\n{src}"));
    }

    #[test]
    fn every_floor_shader_is_valid_wgsl() {
        for kind in [
            FloorKind::Geometry,
            FloorKind::FullScreen,
            FloorKind::Fetches(1),
            FloorKind::Fetches(6),
        ] {
            for targets in [1, 2] {
                validate(&floor_source(kind, targets));
            }
        }
    }

    #[test]
    fn the_fetch_shader_makes_exactly_the_fetches_asked_for() {
        for k in [0, 1, 4, 6] {
            let src = floor_source(FloorKind::Fetches(k), 2);
            assert_eq!(src.matches("textureLoad(").count(), k as usize, "{src}");
        }
        assert_eq!(
            floor_source(FloorKind::FullScreen, 2)
                .matches("textureLoad(")
                .count(),
            0
        );
    }
}
