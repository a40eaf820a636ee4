//! What the passes' pipelines share: bind-group layout entries, opaque
//! colour targets, the depth test, and one triangle-list render pipeline.

/// Binding `binding` of a bind-group layout, seen by `visibility` (no
/// array).
pub(crate) fn entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty,
        count: None,
    }
}

/// A uniform buffer, with dynamic offsets when `dynamic`, of at least
/// `min_size` bytes (any size when `None`).
pub(crate) fn uniform_buffer(dynamic: bool, min_size: Option<u64>) -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: dynamic,
        min_binding_size: min_size.and_then(wgpu::BufferSize::new),
    }
}

/// A read-only storage buffer of any size.
pub(crate) fn read_only_storage() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only: true },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

/// A single-sampled texture.
pub(crate) fn texture(
    sample_type: wgpu::TextureSampleType,
    view_dimension: wgpu::TextureViewDimension,
) -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type,
        view_dimension,
        multisampled: false,
    }
}

/// Binding `binding`: a single-sampled texture read by the fragment
/// stage.
pub(crate) fn fragment_texture(
    binding: u32,
    sample_type: wgpu::TextureSampleType,
    view_dimension: wgpu::TextureViewDimension,
) -> wgpu::BindGroupLayoutEntry {
    entry(
        binding,
        wgpu::ShaderStages::FRAGMENT,
        texture(sample_type, view_dimension),
    )
}

/// A colour target of `format`, written whole with no blending.
pub(crate) fn opaque(format: wgpu::TextureFormat) -> Option<wgpu::ColorTargetState> {
    Some(wgpu::ColorTargetState {
        format,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    })
}

/// A pipeline layout of one bind group.
pub(crate) fn one_group_layout(
    device: &wgpu::Device,
    label: &str,
    group: &wgpu::BindGroupLayout,
) -> wgpu::PipelineLayout {
    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(group)],
        immediate_size: 0,
    })
}

/// A triangle-list render pipeline: every pass draws triangles with a
/// depth buffer it writes (or none), and either colour targets or depth
/// alone.
pub(crate) struct TrianglePipeline<'a> {
    /// Debug label.
    pub(crate) label: &'a str,
    /// The pipeline layout.
    pub(crate) layout: &'a wgpu::PipelineLayout,
    /// The module holding both entry points.
    pub(crate) shader: &'a wgpu::ShaderModule,
    /// The vertex entry point and its vertex buffers.
    pub(crate) vertex: (&'a str, &'a [Option<wgpu::VertexBufferLayout<'a>>]),
    /// The faces culled (none: two-sided).
    pub(crate) cull_mode: Option<wgpu::Face>,
    /// The depth format and comparison, depth written (none: no depth
    /// test).
    pub(crate) depth: Option<(wgpu::TextureFormat, wgpu::CompareFunction)>,
    /// The fragment entry point and its colour targets (none: depth only).
    pub(crate) fragment: Option<(&'a str, &'a [Option<wgpu::ColorTargetState>])>,
}

impl TrianglePipeline<'_> {
    /// Compile the pipeline on `device`.
    pub(crate) fn build(self, device: &wgpu::Device) -> wgpu::RenderPipeline {
        let (vs, buffers) = self.vertex;
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(self.label),
            layout: Some(self.layout),
            vertex: wgpu::VertexState {
                module: self.shader,
                entry_point: Some(vs),
                compilation_options: Default::default(),
                buffers,
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: self.cull_mode,
                ..Default::default()
            },
            depth_stencil: self.depth.map(|(format, compare)| wgpu::DepthStencilState {
                format,
                depth_write_enabled: Some(true),
                depth_compare: Some(compare),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: self.fragment.map(|(fs, targets)| wgpu::FragmentState {
                module: self.shader,
                entry_point: Some(fs),
                compilation_options: Default::default(),
                targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    }
}
