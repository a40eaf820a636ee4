//! A projector's blend weights ([`showcase_light::render::blend`]) as a texture,
//! kept until what they depend on changes.

use showcase_proto::{ObjectKind, Projector};

use crate::gpu::GpuContext;
use crate::render::RenderError;
use showcase_light::render::frame::FrameScene;

/// What a projector's blend weights depend on: the projectors, which one
/// this is, and the real objects (meshes and transforms).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct BlendKey {
    pub(super) projector: Option<usize>,
    pub(super) projectors: Vec<showcase_proto::PinholeDevice>,
    real: Vec<(showcase_proto::MeshId, showcase_proto::Transform)>,
}

/// A projector's blend weights on the GPU ([`super::blend`]).
#[derive(Debug)]
pub(super) struct BlendTexture {
    pub(super) key: BlendKey,
    _texture: wgpu::Texture,
    pub(super) view: wgpu::TextureView,
}

impl BlendTexture {
    /// The weights of `projector` in `frame` (all 1 when it overlaps no
    /// other projector or is not one of the scene's).
    pub(super) fn new(
        ctx: &GpuContext,
        frame: &FrameScene,
        projector: &Projector,
        key: BlendKey,
    ) -> Result<Self, RenderError> {
        let (w, h) = (projector.device.width, projector.device.height);
        let weights: Vec<f32> = match key.projector {
            Some(i) if key.projectors.len() > 1 => {
                let real = frame.geometry(&showcase_light::ObjectFilter::Real)?;
                showcase_light::render::blend::Blend::new(&frame.showcase.projectors)?
                    .weight_image(i, &real)?
                    .data
            }
            _ => vec![1.0; (w as usize) * (h as usize)],
        };
        let size = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("projector blend"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        ctx.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            bytemuck::cast_slice(&weights),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * w),
                rows_per_image: Some(h),
            },
            size,
        );
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        Ok(Self {
            key,
            _texture: texture,
            view,
        })
    }
}

pub(super) fn blend_key(frame: &FrameScene, projector: &Projector) -> BlendKey {
    let projectors = &frame.showcase.projectors;
    BlendKey {
        projector: showcase_light::render::blend::index_of(projectors, projector),
        projectors: projectors.iter().map(|p| p.device.clone()).collect(),
        real: frame
            .showcase
            .objects
            .iter()
            .filter(|o| o.kind == ObjectKind::Real)
            .map(|o| (o.mesh, o.transform))
            .collect(),
    }
}
