//! Buffers that live across frames: uploaded with `Queue::write_buffer`
//! each frame, reallocated only when the data outgrows them, so that the
//! passes create no buffers (and, while nothing grows, no bind groups) per
//! frame. On a CPU rasteriser (lavapipe) allocation is a fixed per-frame
//! cost that dominates small outputs.

use bytemuck::{Pod, Zeroable};

/// A GPU buffer of `usage | COPY_DST` rewritten in place each frame.
#[derive(Debug)]
pub struct UploadBuffer {
    label: &'static str,
    usage: wgpu::BufferUsages,
    /// Smallest size of any allocation (a uniform array binding needs the
    /// whole declared array).
    min_bytes: u64,
    buffer: wgpu::Buffer,
    /// Bumped on every reallocation (bind groups naming it must be rebuilt).
    generation: u64,
}

/// Smallest allocation (also the size of the placeholder for empty data).
const MIN_BYTES: u64 = 256;

impl UploadBuffer {
    /// An empty buffer of `usage` (plus `COPY_DST`).
    pub fn new(device: &wgpu::Device, label: &'static str, usage: wgpu::BufferUsages) -> Self {
        Self::with_min_size(device, label, usage, MIN_BYTES)
    }

    /// An empty buffer of `usage` (plus `COPY_DST`) that is never smaller
    /// than `min_bytes` (rounded up to a multiple of 16).
    pub fn with_min_size(
        device: &wgpu::Device,
        label: &'static str,
        usage: wgpu::BufferUsages,
        min_bytes: u64,
    ) -> Self {
        let usage = usage | wgpu::BufferUsages::COPY_DST;
        let min_bytes = min_bytes.max(MIN_BYTES).next_multiple_of(16);
        Self {
            label,
            usage,
            min_bytes,
            buffer: Self::allocate(device, label, usage, min_bytes),
            generation: 0,
        }
    }

    fn allocate(
        device: &wgpu::Device,
        label: &'static str,
        usage: wgpu::BufferUsages,
        size: u64,
    ) -> wgpu::Buffer {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        })
    }

    /// Upload `data` (one zeroed `T` when empty, so that a binding of it
    /// is never empty), growing the buffer when it does not fit.
    pub fn write<T: Pod + Zeroable>(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        data: &[T],
    ) {
        let placeholder = [T::zeroed()];
        let data = if data.is_empty() {
            &placeholder[..]
        } else {
            data
        };
        let bytes: &[u8] = bytemuck::cast_slice(data);
        // write_buffer needs a multiple of 4 bytes; Pod structs of f32/u32
        // always are, but pad defensively.
        let padded;
        let bytes = if bytes.len().is_multiple_of(4) {
            bytes
        } else {
            padded = [bytes, &[0u8; 3][..4 - bytes.len() % 4]].concat();
            &padded[..]
        };
        let needed = bytes.len() as u64;
        if needed > self.buffer.size() {
            let size = needed.next_power_of_two().max(self.min_bytes);
            self.buffer = Self::allocate(device, self.label, self.usage, size);
            self.generation += 1;
        }
        queue.write_buffer(&self.buffer, 0, bytes);
    }

    /// The buffer (valid until the next [`Self::write`] that grows it).
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Reallocations so far.
    pub fn generation(&self) -> u64 {
        self.generation
    }
}
