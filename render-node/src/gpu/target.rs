//! Offscreen render targets (linear RGBA f32 colour plus f32 depth) and their readback to the CPU.

use super::GpuError;
use showcase_light::finite::finite_or_zero;

/// Colour format of an [`OffscreenTarget`]: linear RGBA, 32-bit float per
/// channel (renderable, not blendable, in core WebGPU).
pub const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// Depth format of an [`OffscreenTarget`].
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A colour texture and a depth texture of the same size, for passes that
/// render offscreen and read the result back (irradiance maps, shadow
/// maps, tests). Pixel rows run from the top-left, as in the devices'
/// OpenCV convention.
#[derive(Debug)]
pub struct OffscreenTarget {
    width: u32,
    height: u32,
    colour: wgpu::Texture,
    colour_view: wgpu::TextureView,
    depth: wgpu::Texture,
    depth_view: wgpu::TextureView,
}

impl OffscreenTarget {
    /// Create a `width x height` target. Both textures can be rendered to,
    /// sampled, and copied out.
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Result<Self, GpuError> {
        let limit = device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > limit || height > limit {
            return Err(GpuError::BadTargetSize {
                width,
                height,
                limit,
            });
        }
        let make = |label, format| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
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
        let colour = make("offscreen colour", COLOUR_FORMAT);
        let depth = make("offscreen depth", DEPTH_FORMAT);
        Ok(Self {
            width,
            height,
            colour_view: colour.create_view(&wgpu::TextureViewDescriptor::default()),
            depth_view: depth.create_view(&wgpu::TextureViewDescriptor::default()),
            colour,
            depth,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The colour texture (format [`COLOUR_FORMAT`]).
    pub fn colour(&self) -> &wgpu::Texture {
        &self.colour
    }

    /// A view of the whole colour texture, for a colour attachment.
    pub fn colour_view(&self) -> &wgpu::TextureView {
        &self.colour_view
    }

    /// The depth texture (format [`DEPTH_FORMAT`]).
    pub fn depth(&self) -> &wgpu::Texture {
        &self.depth
    }

    /// A view of the whole depth texture, for a depth attachment.
    pub fn depth_view(&self) -> &wgpu::TextureView {
        &self.depth_view
    }

    /// Read the colour texture back: `width * height` pixels, row-major
    /// from the top-left. Waits for all submitted work.
    pub fn read_rgba_f32(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Vec<[f32; 4]>, GpuError> {
        let bytes = read_texture(device, queue, &self.colour, wgpu::TextureAspect::All, 16)?;
        Ok(bytes
            .chunks_exact(16)
            .map(|px| std::array::from_fn(|c| f32_at(px, 4 * c)))
            .collect())
    }

    /// Read the depth texture back: `width * height` depths in `0..1`,
    /// row-major from the top-left. Waits for all submitted work.
    pub fn read_depth(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Vec<f32>, GpuError> {
        let bytes = read_texture(
            device,
            queue,
            &self.depth,
            wgpu::TextureAspect::DepthOnly,
            4,
        )?;
        Ok(bytes.chunks_exact(4).map(|px| f32_at(px, 0)).collect())
    }
}

/// The f32 at byte offset `at`, in the native byte order of the copy.
fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_ne_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

/// `bytes_per_row` of a copy rounded up to `COPY_BYTES_PER_ROW_ALIGNMENT`.
pub fn padded_bytes_per_row(width: u32, bytes_per_pixel: u32) -> u32 {
    let unpadded = width * bytes_per_pixel;
    unpadded.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// Copy one aspect of a 2D texture into a mappable buffer, wait, and
/// return its rows tightly packed (the copy's row padding removed).
fn read_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    aspect: wgpu::TextureAspect,
    bytes_per_pixel: u32,
) -> Result<Vec<u8>, GpuError> {
    let (width, height) = (texture.width(), texture.height());
    let padded = padded_bytes_per_row(width, bytes_per_pixel);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: u64::from(padded) * u64::from(height),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("readback"),
    });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(height),
            },
        },
        texture.size(),
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
    let row = (width * bytes_per_pixel) as usize;
    let mut out = Vec::with_capacity(row * height as usize);
    {
        let view = buffer
            .get_mapped_range(..)
            .map_err(|e| GpuError::Map(e.to_string()))?;
        for r in 0..height as usize {
            let start = r * padded as usize;
            out.extend_from_slice(&view[start..start + row]);
        }
    }
    buffer.unmap();
    Ok(out)
}

/// A mappable buffer that an [`OffscreenTarget`]'s colour is copied into
/// inside the frame's own command buffer, kept across frames, so that a
/// frame's readback costs one copy and one map (no allocation, no extra
/// submission).
#[derive(Debug)]
pub struct ColourReadback {
    width: u32,
    height: u32,
    padded: u32,
    buffer: wgpu::Buffer,
}

impl ColourReadback {
    /// A readback buffer for `width x height` colour targets.
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Self {
        let padded = padded_bytes_per_row(width, 16);
        Self {
            width,
            height,
            padded,
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("colour readback"),
                size: u64::from(padded) * u64::from(height.max(1)),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
        }
    }

    /// True when `target` has this buffer's size.
    pub fn fits(&self, target: &OffscreenTarget) -> bool {
        (self.width, self.height) == (target.width(), target.height())
    }

    /// Record the copy of `target`'s colour (which must [`Self::fits`]).
    pub fn encode_copy(&self, encoder: &mut wgpu::CommandEncoder, target: &OffscreenTarget) {
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: target.colour(),
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &self.buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded),
                    rows_per_image: Some(self.height),
                },
            },
            target.colour().size(),
        );
    }
}

/// Map `readbacks` (their copies submitted), wait once, and return each
/// one's pixels, row-major from the top-left, non-finite values as 0.
pub fn read_colours(
    device: &wgpu::Device,
    readbacks: &[&ColourReadback],
) -> Result<Vec<Vec<[f32; 4]>>, GpuError> {
    let mut out: Vec<Vec<[f32; 4]>> = readbacks
        .iter()
        .map(|r| Vec::with_capacity(r.width as usize * r.height as usize))
        .collect();
    visit_colours(device, readbacks, |i, row| {
        out[i].extend(row.iter().map(|px| px.map(finite_or_zero)));
    })?;
    Ok(out)
}

/// Map `readbacks` (their copies submitted), wait once, and hand each
/// row of each, top to bottom, to `visit` (readback index, pixels as
/// stored: non-finite values are not replaced), without copying the
/// image; so a caller that needs only part of a target (a count over its
/// alpha) pays for no more.
pub fn visit_colours(
    device: &wgpu::Device,
    readbacks: &[&ColourReadback],
    mut visit: impl FnMut(usize, &[[f32; 4]]),
) -> Result<(), GpuError> {
    let (tx, rx) = std::sync::mpsc::channel();
    for (i, r) in readbacks.iter().enumerate() {
        let tx = tx.clone();
        r.buffer.map_async(wgpu::MapMode::Read, .., move |result| {
            // The receiver lives until after the poll below.
            let _ = tx.send((i, result));
        });
    }
    drop(tx);
    device.poll(wgpu::PollType::wait_indefinitely())?;
    let mut failed = None;
    for (_, result) in rx.iter() {
        if let Err(e) = result {
            failed = Some(GpuError::Map(e.to_string()));
        }
    }
    let mut unaligned = Vec::new();
    for (i, r) in readbacks.iter().enumerate() {
        if failed.is_some() {
            break;
        }
        match r.buffer.get_mapped_range(..) {
            Ok(view) => {
                let row = r.width as usize * 16;
                for y in 0..r.height as usize {
                    let start = y * r.padded as usize;
                    let bytes = &view[start..start + row];
                    // Rows start at multiples of 256 bytes of a mapping, so
                    // the cast succeeds; the per-value read is the fallback.
                    match bytemuck::try_cast_slice::<u8, [f32; 4]>(bytes) {
                        Ok(px) => visit(i, px),
                        Err(_) => {
                            unaligned.clear();
                            unaligned.extend(
                                bytes
                                    .chunks_exact(16)
                                    .map(|px| std::array::from_fn(|c| f32_at(px, 4 * c))),
                            );
                            visit(i, &unaligned);
                        }
                    }
                }
            }
            Err(e) => failed = Some(GpuError::Map(e.to_string())),
        }
    }
    for r in readbacks {
        // Unmapping a buffer whose map failed is harmless.
        r.buffer.unmap();
    }
    match failed {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::padded_bytes_per_row;

    #[test]
    fn rows_pad_to_the_copy_alignment() {
        // 256-byte alignment: 16 B/px rows of 1..=16 px fit in 256 bytes.
        for (width, bpp, expected) in [
            (1, 16, 256),
            (16, 16, 256),
            (17, 16, 512),
            (1024, 16, 16384),
            (1, 4, 256),
            (64, 4, 256),
            (65, 4, 512),
            (1023, 4, 4096),
        ] {
            assert_eq!(
                padded_bytes_per_row(width, bpp),
                expected,
                "{width} px x {bpp} B"
            );
        }
    }
}
