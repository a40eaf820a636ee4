//! wgpu device bring-up and GPU passes. Every pass that computes a result
//! the product uses has a CPU reference in `showcase_light` and a test
//! comparing the two; the shadow views are checked through the passes that
//! read them, and the floor passes (timing only) have none.
//!
//! The shape follows the wgpu examples: [`GpuContext::new_headless`] opens
//! a device without any surface, and all work functions take
//! `&wgpu::Device, &wgpu::Queue`, so that tests and the node can pass in
//! their own device. Passes draw into an [`OffscreenTarget`], which reads
//! back as linear RGBA f32.
//!
//! Each pass lives in `gpu/<pass>/{mod.rs,<pass>.wgsl}`; its WGSL is
//! loaded with `include_wgsl!`, and every `.wgsl` file is validated by a
//! naga test that needs no GPU.

pub mod cube_map;
pub mod face_view;
pub mod field;
pub mod flat_lambert;
pub mod frame_arrays;
pub mod hemicube;
pub mod irradiance_map;
pub(crate) mod pipeline;
pub mod shadow_lookup;
pub mod shadow_views;
pub mod target;
pub mod upload;

pub use flat_lambert::{FlatLambertBatch, FlatLambertPass};
pub use target::OffscreenTarget;

use showcase_light::raster::SceneError;

/// Why a GPU operation failed.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter matched (no driver, or no Vulkan loader installed).
    #[error("no gpu adapter found: {0}")]
    NoAdapter(#[from] wgpu::RequestAdapterError),
    /// The adapter refused to open a device.
    #[error("gpu device request failed: {0}")]
    RequestDevice(#[from] wgpu::RequestDeviceError),
    /// Waiting for the device failed (lost device, timeout).
    #[error("gpu poll failed: {0}")]
    Poll(#[from] wgpu::PollError),
    /// Mapping a readback buffer failed.
    #[error("gpu buffer mapping failed: {0}")]
    Map(String),
    /// The target size is zero or larger than the device allows.
    #[error("target size {width}x{height} is empty or exceeds the device limit {limit}")]
    BadTargetSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// `max_texture_dimension_2d` of the device.
        limit: u32,
    },
    /// The target does not match the scene's device resolution.
    #[error("target is {target_width}x{target_height} but the scene's device is {width}x{height}")]
    SizeMismatch {
        /// Target width.
        target_width: u32,
        /// Target height.
        target_height: u32,
        /// Device width.
        width: u32,
        /// Device height.
        height: u32,
    },
    /// A mesh's vertex data does not fit in one GPU buffer.
    #[error("item {item}: {bytes} bytes of vertex data exceed the device's buffer limit {limit}")]
    MeshTooLarge {
        /// Index into the scene's items.
        item: usize,
        /// Size of the vertex data.
        bytes: u64,
        /// `max_buffer_size` of the device.
        limit: u64,
    },
    /// The scene cannot be drawn.
    #[error(transparent)]
    Scene(#[from] SceneError),
}

/// An open wgpu device with its queue, and what the adapter is. Cloning
/// shares the device (wgpu handles are reference-counted).
#[derive(Clone, Debug)]
pub struct GpuContext {
    /// The logical device.
    pub device: wgpu::Device,
    /// Its submission queue.
    pub queue: wgpu::Queue,
    /// Name, backend and driver of the adapter the device was opened on.
    pub adapter_info: wgpu::AdapterInfo,
}

impl GpuContext {
    /// Open the highest-performance adapter without a surface (headless),
    /// honouring wgpu's environment variables `WGPU_BACKEND` and
    /// `WGPU_POWER_PREF`. On a machine without a GPU this finds
    /// lavapipe (Mesa's software Vulkan) if `mesa-vulkan-drivers` is
    /// installed.
    pub fn new_headless() -> Result<Self, GpuError> {
        pollster::block_on(Self::new_headless_async())
    }

    /// [`Self::new_headless`] for callers already in an async context.
    pub async fn new_headless_async() -> Result<Self, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::from_env()
                    .unwrap_or(wgpu::PowerPreference::HighPerformance),
                force_fallback_adapter: false,
                compatible_surface: None,
                ..Default::default()
            })
            .await?;
        let adapter_info = adapter.get_info();
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("showcase"),
                required_features: wgpu::Features::empty(),
                // WebGPU defaults, but as large textures and buffers as
                // the adapter has (scanned meshes can be large).
                required_limits: wgpu::Limits {
                    max_buffer_size: adapter.limits().max_buffer_size,
                    ..wgpu::Limits::default().using_resolution(adapter.limits())
                },
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await?;
        tracing::info!(
            adapter = %adapter_info.name,
            backend = ?adapter_info.backend,
            driver = %adapter_info.driver,
            "gpu device open"
        );
        Ok(Self {
            device,
            queue,
            adapter_info,
        })
    }

    /// One line naming the adapter, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)
    /// (Vulkan, Cpu, driver llvmpipe)`.
    pub fn describe(&self) -> String {
        let i = &self.adapter_info;
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            i.name, i.backend, i.device_type, i.driver, i.driver_info
        )
    }
}

/// Block until all work submitted to `device` has finished, e.g. to
/// measure a frame's render time or before presenting at a swap barrier.
pub fn wait_idle(device: &wgpu::Device) -> Result<(), GpuError> {
    device.poll(wgpu::PollType::wait_indefinitely())?;
    Ok(())
}
