//! Cube-map pass (paper section 5.3): the real environment (the phantoms
//! with their albedo, lit by the virtual lights with the light shadow
//! views and the ambient term; in global mode with all their indirect
//! light, [`super::field`]) drawn from the centre of each reflective
//! virtual object into six 90-degree layers of one colour array texture
//! ([`CubeMaps`]), with each texel's distance from the centre in alpha
//! ([`NO_SURFACE_DISTANCE`] where nothing real is seen), which the face
//! view looks up distance-corrected along reflected rays. The
//! shader is the face view's (`vs_main`, `fs_environment`), so a cube
//! texel is shaded exactly as the face view shades a surface; each layer
//! has its own uniform whose eye is the map's centre and whose
//! `clip_from_world` is that face's view
//! ([`super::shadow_views::cube_views`]). CPU reference:
//! `showcase_light::render::cube_map::cube_map_cpu`.

use std::ops::Range;

use glam::Vec3;

use super::GpuError;
use super::face_view::{FaceBindGroup, FaceBindings, FaceFrameUniform, Variants};
use super::shadow_views::cube_views;
use super::target::{COLOUR_FORMAT, DEPTH_FORMAT, padded_bytes_per_row};
use super::upload::UploadBuffer;
use showcase_light::digest::Fnv64;
use showcase_light::finite::finite_or_zero;
use showcase_light::render::cube_map::NO_SURFACE_DISTANCE;

/// Near plane of the cube faces (metres from the centre).
pub const CUBE_NEAR: f32 = 1e-3;

/// The compiled cube-map pipeline.
#[derive(Debug)]
pub struct CubeMapPass {
    variants: Variants,
}

/// What one cube-map draw renders: the phantoms' ranges of the world
/// vertex buffer, drawn as instances `first_instance + i` (their albedos'
/// indices).
#[derive(Debug)]
pub struct CubeDraws<'a> {
    /// World vertices of every object (in global mode split into the
    /// field's pieces, [`super::field`]).
    pub vertices: &'a wgpu::Buffer,
    /// The global-illumination field at each of `vertices` (zeros in
    /// direct mode).
    pub values: &'a wgpu::Buffer,
    /// Vertex range of each phantom.
    pub phantoms: &'a [Range<u32>],
    /// Instance (albedo index) of the first phantom.
    pub first_instance: u32,
}

impl CubeMapPass {
    /// Compile the pipeline for [`CubeMaps`]' formats.
    pub fn new(device: &wgpu::Device) -> Self {
        Self {
            variants: Variants::new(device, false, &["fs_environment"]),
        }
    }

    /// The bind group of one layer's `bindings` (`cube_maps` unset: the
    /// pass draws them).
    pub fn bind_group(&self, device: &wgpu::Device, bindings: &FaceBindings<'_>) -> FaceBindGroup {
        self.variants.bind_group(device, bindings)
    }

    /// Record one render pass per layer in `layers` (with `binds[i]`, the
    /// bind group of layer `layers.start + i`): clear to radiance 0 at
    /// distance [`NO_SURFACE_DISTANCE`] and depth 1,
    /// draw the phantoms. Returns the layers drawn.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        maps: &CubeMaps,
        layers: Range<u32>,
        binds: &[FaceBindGroup],
        draws: &CubeDraws<'_>,
    ) -> u32 {
        let mut drawn = 0;
        for (layer, bind) in layers.zip(binds) {
            let (Some(target), Some(pipeline)) =
                (maps.layer_views.get(layer as usize), bind.pipeline(0))
            else {
                continue;
            };
            drawn += 1;
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("cube map face"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            a: f64::from(NO_SURFACE_DISTANCE),
                            ..wgpu::Color::TRANSPARENT
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &maps.depth_view,
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
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind.group(), &[]);
            pass.set_vertex_buffer(0, draws.vertices.slice(..));
            pass.set_vertex_buffer(1, draws.values.slice(..));
            for (i, r) in draws.phantoms.iter().enumerate() {
                if !r.is_empty() {
                    let instance = draws.first_instance + i as u32;
                    pass.draw(r.clone(), instance..instance + 1);
                }
            }
        }
        drawn
    }
}

/// The cube maps: `res x res` linear RGB radiance and distance (alpha)
/// f32 layers, six per map (at
/// least one layer, so that the face view's binding exists without
/// maps), and one depth buffer the layers share.
#[derive(Debug)]
pub struct CubeMaps {
    res: u32,
    layers: u32,
    texture: wgpu::Texture,
    array_view: wgpu::TextureView,
    layer_views: Vec<wgpu::TextureView>,
    depth_view: wgpu::TextureView,
}

impl CubeMaps {
    /// Allocate `maps` cube maps of `res` texels per side.
    pub fn new(device: &wgpu::Device, res: u32, maps: u32) -> Result<Self, GpuError> {
        let limits = device.limits();
        let layers = maps.saturating_mul(6).max(1);
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
        let make = |label, format, layers| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: res,
                    height: res,
                    depth_or_array_layers: layers,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let texture = make("cube maps", COLOUR_FORMAT, layers);
        let depth = make("cube map depth", DEPTH_FORMAT, 1);
        let layer_views = (0..layers)
            .map(|layer| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    label: Some("cube map face"),
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    base_array_layer: layer,
                    array_layer_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let array_view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("cube maps"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        Ok(Self {
            res,
            layers,
            texture,
            array_view,
            layer_views,
            depth_view: depth.create_view(&wgpu::TextureViewDescriptor::default()),
        })
    }

    /// Texels per side.
    pub fn res(&self) -> u32 {
        self.res
    }

    /// Number of layers (six per map, at least one).
    pub fn layers(&self) -> u32 {
        self.layers
    }

    /// The whole array, for the face view.
    pub fn array_view(&self) -> &wgpu::TextureView {
        &self.array_view
    }

    /// Read every layer back (waits for submitted work): per layer,
    /// `res * res` texels (linear RGB radiance, distance) row-major from
    /// the top-left; non-finite values become 0.
    pub fn read(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Vec<Vec<[f32; 4]>>, GpuError> {
        let padded = padded_bytes_per_row(self.res, 16);
        let layer_bytes = u64::from(padded) * u64::from(self.res);
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cube map readback"),
            size: layer_bytes * u64::from(self.layers),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(self.res),
                },
            },
            self.texture.size(),
        );
        queue.submit([encoder.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            // The receiver lives until after the poll below.
            let _ = tx.send(r);
        });
        device.poll(wgpu::PollType::wait_indefinitely())?;
        rx.recv()
            .map_err(|e| GpuError::Map(e.to_string()))?
            .map_err(|e| GpuError::Map(e.to_string()))?;
        let mut out = Vec::with_capacity(self.layers as usize);
        {
            let view = buffer
                .get_mapped_range(..)
                .map_err(|e| GpuError::Map(e.to_string()))?;
            for layer in 0..self.layers as usize {
                let mut texels = Vec::with_capacity((self.res * self.res) as usize);
                for y in 0..self.res as usize {
                    let start = layer * layer_bytes as usize + y * padded as usize;
                    let row = &view[start..start + 16 * self.res as usize];
                    texels.extend(row.chunks_exact(16).map(|px| {
                        std::array::from_fn(|c| {
                            let v = f32::from_ne_bytes([
                                px[4 * c],
                                px[4 * c + 1],
                                px[4 * c + 2],
                                px[4 * c + 3],
                            ]);
                            finite_or_zero(v)
                        })
                    }));
                }
                out.push(texels);
            }
        }
        buffer.unmap();
        Ok(out)
    }
}

/// The cube maps a face pipeline keeps across frames: redrawn only when
/// what they show changes (the caller's content key: lights, geometry,
/// shadow views; and the centres, resolution and shading uniforms), so
/// that a moving head alone does not redraw them.
#[derive(Debug)]
pub struct CubeMapFrames {
    pass: CubeMapPass,
    res: u32,
    maps: Option<CubeMaps>,
    uniforms: Vec<UploadBuffer>,
    key: Option<u64>,
    generation: u64,
    last_layers_drawn: u32,
}

impl CubeMapFrames {
    /// Compile the pass; maps get `res` texels per side (at least 1).
    pub fn new(device: &wgpu::Device, res: u32) -> Self {
        Self {
            pass: CubeMapPass::new(device),
            res: res.max(1),
            maps: None,
            uniforms: Vec::new(),
            key: None,
            generation: 0,
            last_layers_drawn: 0,
        }
    }

    /// Texels per side.
    pub fn res(&self) -> u32 {
        self.res
    }

    /// Identity of the texture [`CubeMaps::array_view`] names: it changes
    /// when the maps are reallocated (bind groups naming it are stale).
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Layers the last [`Self::encode`] drew (0 when the maps were kept).
    pub fn last_layers_drawn(&self) -> u32 {
        self.last_layers_drawn
    }

    /// The maps (after [`Self::prepare`]).
    pub fn maps(&self) -> Option<&CubeMaps> {
        self.maps.as_ref()
    }

    /// Make room for `maps` maps (at least one layer, so that the face
    /// view's binding exists when no map is drawn).
    pub fn reserve(&mut self, device: &wgpu::Device, maps: usize) -> Result<(), GpuError> {
        let layers = (maps * 6).max(1) as u32;
        if self.maps.as_ref().is_none_or(|m| m.layers() < layers) {
            self.maps = Some(CubeMaps::new(device, self.res, layers.div_ceil(6))?);
            self.generation += 1;
            self.key = None;
        }
        Ok(())
    }

    /// Make room for one map per centre and upload each layer's uniform
    /// (`base` with that face's view and the centre as its eye) when the
    /// key of (`content`, `base`, `centres`) differs from the drawn one.
    /// Returns whether [`Self::encode`] must draw.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        centres: &[Vec3],
        base: &FaceFrameUniform,
        far: f32,
        content: u64,
    ) -> Result<bool, GpuError> {
        self.reserve(device, centres.len())?;
        let mut h = Fnv64::default();
        h.write(&content.to_le_bytes());
        h.write(bytemuck::bytes_of(base));
        h.write(&far.to_le_bytes());
        h.write(bytemuck::cast_slice(
            &centres.iter().map(|c| c.to_array()).collect::<Vec<_>>(),
        ));
        let key = h.finish();
        if self.key == Some(key) {
            return Ok(false);
        }
        self.key = Some(key);
        while self.uniforms.len() < centres.len() * 6 {
            self.uniforms.push(UploadBuffer::new(
                device,
                "cube map frame",
                wgpu::BufferUsages::UNIFORM,
            ));
        }
        for (k, c) in centres.iter().enumerate() {
            for (f, view) in cube_views(*c, CUBE_NEAR, far, self.res).iter().enumerate() {
                let uniform = FaceFrameUniform {
                    clip_from_world: view.clip_from_world,
                    eye: c.extend(0.0).to_array(),
                    ..*base
                };
                self.uniforms[6 * k + f].write(device, queue, &[uniform]);
            }
        }
        Ok(true)
    }

    /// Draw the `maps` layers of [`Self::prepare`] (`bindings.frame` is
    /// replaced by each layer's uniform, `bindings.cube_maps` ignored).
    pub fn encode(
        &mut self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        maps: usize,
        bindings: &FaceBindings<'_>,
        draws: &CubeDraws<'_>,
    ) -> u32 {
        let binds: Vec<FaceBindGroup> = self
            .uniforms
            .iter()
            .take(maps * 6)
            .map(|u| {
                self.pass.bind_group(
                    device,
                    &FaceBindings {
                        frame: u.buffer(),
                        cube_maps: None,
                        ..*bindings
                    },
                )
            })
            .collect();
        let Some(target) = self.maps.as_ref() else {
            return 0;
        };
        self.last_layers_drawn =
            self.pass
                .encode(encoder, target, 0..binds.len() as u32, &binds, draws);
        self.last_layers_drawn
    }

    /// Note that the last frame drew no layer (the maps were kept or
    /// not needed).
    pub fn kept(&mut self) {
        self.last_layers_drawn = 0;
    }
}
