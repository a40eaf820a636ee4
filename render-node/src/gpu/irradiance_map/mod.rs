//! Irradiance map pass: the projector role's per-pixel `L` and device
//! values from the real phantoms, the light samples, the eyes and the
//! shadow views' distance maps. CPU reference:
//! `showcase_light::render::projector::irradiance_map_cpu` (units and rules there).

use std::sync::OnceLock;

use bytemuck::{Pod, Zeroable};

use super::GpuError;
use super::frame_arrays::{ArraySpace, uniform_capacity};
use super::pipeline::{
    TrianglePipeline, entry, fragment_texture, one_group_layout, opaque, uniform_buffer,
};
use super::shadow_views::{ShadowMaps, world_vertex_layout};
use super::target::{COLOUR_FORMAT, DEPTH_FORMAT, OffscreenTarget};

pub mod floor;

use super::field::field_value_layout;

/// Mirrors WGSL `struct Frame` in `irradiance_map.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniform {
    /// The projector's `clip_from_world`.
    pub clip_from_world: [[f32; 4]; 4],
    /// xyz projector centre.
    pub projector: [f32; 4],
    /// rgb ambient irradiance.
    pub ambient: [f32; 4],
    /// gamma, eta, black level, cos floor.
    pub response: [f32; 4],
    /// light samples, eyes, shadow map size, flags (1 shadows, 2 occlusion,
    /// 4 blend weights other than 1, 8 a global-illumination field).
    pub counts: [u32; 4],
    /// near and far plane of the shadow views (depth back to distance).
    pub shadow: [f32; 4],
}

/// Alpha codes of the irradiance output.
pub mod state {
    /// No real surface.
    pub const BACKGROUND: f32 = 0.0;
    /// Surface, value in range.
    pub const UNCLIPPED: f32 = 1.0;
    /// Surface, value clamped.
    pub const CLIPPED: f32 = 2.0;
    /// Surface below the cos floor.
    pub const MASKED: f32 = 3.0;
}

/// The WGSL source of the pass (uniform arrays; see
/// [`ArraySpace::source`]).
pub const SOURCE: &str = super::shadow_lookup::with_shadow_lookup!("irradiance_map.wgsl");

/// Capacity of the uniform array `name` (`lights`, `eyes` or `views`) of
/// [`SOURCE`] (0 for another name).
pub fn capacity(name: &str) -> usize {
    uniform_capacity(SOURCE, name).unwrap_or(0)
}

/// The pipeline and bind group layout of one [`ArraySpace`].
#[derive(Debug)]
struct Variant {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

/// The compiled irradiance-map pipeline: the uniform-array variant, and
/// the storage-array one, compiled the first time a frame needs it.
#[derive(Debug)]
pub struct IrradianceMapPass {
    uniform: Variant,
    storage: OnceLock<Variant>,
}

/// A bind group of the pass with the pipeline of its [`ArraySpace`].
#[derive(Debug)]
pub struct IrradianceBindGroup {
    group: wgpu::BindGroup,
    pipeline: wgpu::RenderPipeline,
    space: ArraySpace,
}

impl IrradianceBindGroup {
    /// Where the shader reads its per-frame arrays from.
    pub fn space(&self) -> ArraySpace {
        self.space
    }
}

/// The buffers and maps the pass reads, uploaded (see
/// [`IrradianceMapPass::bind_group`]).
#[derive(Debug)]
pub struct IrradianceBindings<'a> {
    /// The [`FrameUniform`].
    pub frame: &'a wgpu::Buffer,
    /// [`LightSampleGpu`](super::shadow_lookup::LightSampleGpu)s (at
    /// least one element, may be a placeholder).
    pub lights: &'a wgpu::Buffer,
    /// [`EyeGpu`](super::shadow_lookup::EyeGpu)s (at least one element,
    /// may be a placeholder).
    pub eyes: &'a wgpu::Buffer,
    /// The shadow views buffer.
    pub views: &'a wgpu::Buffer,
    /// The distance maps.
    pub maps: &'a ShadowMaps,
    /// The projector's blend weights (`R32Float`, projector-sized).
    pub blend: &'a wgpu::TextureView,
    /// Where the arrays are read from ([`IrradianceMapPass::space`] of
    /// their lengths).
    pub space: ArraySpace,
}

/// The light's shadow maps (a depth array) at binding `first` and the
/// projector's blend weights (a float texture) at `first + 1`, both read
/// by the fragment stage: the irradiance map's and its floor pass's.
pub(super) fn shadow_and_blend(first: u32) -> [wgpu::BindGroupLayoutEntry; 2] {
    [
        fragment_texture(
            first,
            wgpu::TextureSampleType::Depth,
            wgpu::TextureViewDimension::D2Array,
        ),
        fragment_texture(
            first + 1,
            wgpu::TextureSampleType::Float { filterable: false },
            wgpu::TextureViewDimension::D2,
        ),
    ]
}

fn array_entry(binding: u32, space: ArraySpace) -> wgpu::BindGroupLayoutEntry {
    entry(binding, wgpu::ShaderStages::FRAGMENT, space.binding_type())
}

impl IrradianceMapPass {
    /// Compile the pipeline for two [`OffscreenTarget`] colour formats.
    pub fn new(device: &wgpu::Device) -> Self {
        Self {
            uniform: Self::variant(device, ArraySpace::Uniform),
            storage: OnceLock::new(),
        }
    }

    /// The space a frame of `lights` light samples, `eyes` eyes and
    /// `views` shadow views reads its arrays from.
    pub fn space(lights: usize, eyes: usize, views: usize) -> ArraySpace {
        ArraySpace::for_lengths(
            SOURCE,
            &[(lights, "lights"), (eyes, "eyes"), (views, "views")],
        )
    }

    fn variant(device: &wgpu::Device, space: ArraySpace) -> Variant {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("irradiance_map"),
            source: wgpu::ShaderSource::Wgsl(space.source(SOURCE)),
        });
        let [shadow_maps, blend] = shadow_and_blend(4);
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("irradiance map"),
            entries: &[
                entry(
                    0,
                    wgpu::ShaderStages::VERTEX_FRAGMENT,
                    uniform_buffer(false, None),
                ),
                array_entry(1, space),
                array_entry(2, space),
                array_entry(3, space),
                shadow_maps,
                blend,
            ],
        });
        let pipeline = TrianglePipeline {
            label: "irradiance map",
            layout: &one_group_layout(device, "irradiance map", &layout),
            shader: &shader,
            vertex: (
                "vs_main",
                &[Some(world_vertex_layout()), Some(field_value_layout())],
            ),
            // Phantom surfaces are two-sided, as in the CPU reference.
            cull_mode: None,
            depth: Some((DEPTH_FORMAT, wgpu::CompareFunction::Less)),
            fragment: Some(("fs_main", &[opaque(COLOUR_FORMAT), opaque(COLOUR_FORMAT)])),
        }
        .build(device);
        Variant { pipeline, layout }
    }

    /// The bind group of `bindings` (create once per set of buffers and
    /// space); compiles the storage variant the first time it is needed.
    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        bindings: &IrradianceBindings<'_>,
    ) -> IrradianceBindGroup {
        let variant = match bindings.space {
            ArraySpace::Uniform => &self.uniform,
            ArraySpace::Storage => self
                .storage
                .get_or_init(|| Self::variant(device, ArraySpace::Storage)),
        };
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("irradiance map"),
            layout: &variant.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: bindings.frame.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: bindings.lights.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: bindings.eyes.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: bindings.views.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: wgpu::BindingResource::TextureView(bindings.maps.array_view()),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::TextureView(bindings.blend),
                },
            ],
        });
        IrradianceBindGroup {
            group,
            pipeline: variant.pipeline.clone(),
            space: bindings.space,
        }
    }

    /// Record the pass: clear both targets to 0 and depth to 1, draw the
    /// real phantoms (`vertex_count` of `vertices`, world space, and as
    /// many [`super::field::FieldValue`]s of `field_values`) with the inputs of
    /// `bind_group`. `irradiance` receives `L` and the state code, `value`
    /// the device values; both must have the projector's size.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        irradiance: &OffscreenTarget,
        value: &OffscreenTarget,
        bind_group: &IrradianceBindGroup,
        vertices: &wgpu::Buffer,
        field_values: &wgpu::Buffer,
        vertex_count: u32,
    ) -> Result<(), GpuError> {
        if (irradiance.width(), irradiance.height()) != (value.width(), value.height()) {
            return Err(GpuError::SizeMismatch {
                target_width: value.width(),
                target_height: value.height(),
                width: irradiance.width(),
                height: irradiance.height(),
            });
        }
        let attachment = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("irradiance map"),
            color_attachments: &[
                attachment(irradiance.colour_view()),
                attachment(value.colour_view()),
            ],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: irradiance.depth_view(),
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
        if vertex_count > 0 {
            pass.set_pipeline(&bind_group.pipeline);
            pass.set_bind_group(0, &bind_group.group, &[]);
            pass.set_vertex_buffer(0, vertices.slice(..));
            pass.set_vertex_buffer(1, field_values.slice(..));
            pass.draw(0..vertex_count, 0..1);
        }
        Ok(())
    }
}
