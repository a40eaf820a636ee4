//! The `window` feature: a node shows its presented frames full screen on a
//! real display (winit window, wgpu surface). The frame's linear values
//! are encoded for the device at this boundary: a projector's values are
//! already its drive values (exponent 1), a CRT face's radiance is raised
//! to `1 / gamma` of its face (the CRT's inverse response).
//!
//! winit owns the main thread; the node runs on another and hands each
//! presented image over through the event loop ([`WindowSink`], a
//! [`FrameSink`]). The window opens its own device on the adapter that
//! can present to it; images travel as CPU pixels between the two.

use crate::gpu::pipeline::{
    TrianglePipeline, entry, fragment_texture, one_group_layout, opaque, uniform_buffer,
};
use crate::node::present::FrameSink;
use crate::node::{OutputImage, RenderError};
use std::sync::Arc;
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, EventLoop, EventLoopProxy};
use winit::window::{Fullscreen, Window, WindowId};

/// What the node thread tells the window.
#[derive(Debug)]
pub enum WindowMessage {
    /// Show this frame now.
    Frame(u64, OutputImage),
    /// The node stopped: close the window.
    Quit,
}

/// Why the window failed.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    /// winit could not run.
    #[error("window: {0}")]
    EventLoop(#[from] winit::error::EventLoopError),
    /// The window or its surface could not be set up.
    #[error("window: {0}")]
    Setup(String),
}

/// Hands presented frames to the window's event loop.
#[derive(Debug, Clone)]
pub struct WindowSink(EventLoopProxy<WindowMessage>);

impl WindowSink {
    /// Tell the window to close (the node stopped).
    pub fn quit(&self) {
        // The loop may already be gone (the window was closed): fine.
        let _ = self.0.send_event(WindowMessage::Quit);
    }
}

impl FrameSink for WindowSink {
    fn show(&mut self, frame: u64, image: OutputImage) -> Result<(), RenderError> {
        self.0
            .send_event(WindowMessage::Frame(frame, image))
            .map_err(|_| RenderError::WindowClosed)
    }
}

/// The event loop (create it on the main thread) and a sink feeding it.
pub fn event_loop() -> Result<(EventLoop<WindowMessage>, WindowSink), WindowError> {
    let event_loop = EventLoop::<WindowMessage>::with_user_event().build()?;
    let sink = WindowSink(event_loop.create_proxy());
    Ok((event_loop, sink))
}

/// Run the full-screen window until the node quits or the window is
/// closed; `encode_gamma` is the exponent's inverse applied at the device
/// boundary (1 for projectors, the face's gamma for CRT faces).
pub fn run(
    event_loop: EventLoop<WindowMessage>,
    title: &str,
    encode_gamma: f32,
) -> Result<(), WindowError> {
    let mut app = App {
        title: title.to_string(),
        encode_gamma: if encode_gamma.is_finite() && encode_gamma > 0.0 {
            encode_gamma
        } else {
            1.0
        },
        window: None,
        gpu: None,
        error: None,
    };
    event_loop.run_app(&mut app)?;
    match app.error {
        Some(e) => Err(WindowError::Setup(e)),
        None => Ok(()),
    }
}

struct App {
    title: String,
    encode_gamma: f32,
    window: Option<Arc<Window>>,
    gpu: Option<Gpu>,
    error: Option<String>,
}

struct Gpu {
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    config: wgpu::SurfaceConfiguration,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    image: Option<(wgpu::Texture, wgpu::BindGroup)>,
}

const SHADER: &str = r"
struct Params { gamma: f32, _p0: f32, target_size: vec2<f32> };
@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var frame: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32(i32(i) / 2) * 4.0 - 1.0;
    let y = f32(i32(i) % 2) * 4.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    let size = vec2<f32>(textureDimensions(frame));
    let target_size = params.target_size;
    let texel = vec2<i32>(clamp(p.xy / target_size * size, vec2<f32>(0.0), size - 1.0));
    let v = clamp(textureLoad(frame, texel, 0).rgb, vec3<f32>(0.0), vec3<f32>(1.0));
    return vec4<f32>(pow(v, vec3<f32>(1.0 / params.gamma)), 1.0);
}
";

impl App {
    fn setup(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let window = Arc::new(
            event_loop
                .create_window(
                    Window::default_attributes()
                        .with_title(self.title.clone())
                        .with_fullscreen(Some(Fullscreen::Borderless(None))),
                )
                .map_err(|e| e.to_string())?,
        );
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| e.to_string())?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
            ..Default::default()
        }))
        .map_err(|e| e.to_string())?;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("showcase window"),
            ..Default::default()
        }))
        .map_err(|e| e.to_string())?;
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or("the surface cannot present from this adapter")?;
        // Values are encoded here, so write them unchanged: prefer a
        // non-sRGB format.
        let caps = surface.get_capabilities(&adapter);
        if let Some(f) = caps.formats.iter().find(|f| !f.is_srgb()) {
            config.format = *f;
        }
        surface.configure(&device, &config);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("present"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("present"),
            entries: &[
                entry(0, wgpu::ShaderStages::FRAGMENT, uniform_buffer(false, None)),
                fragment_texture(
                    1,
                    wgpu::TextureSampleType::Float { filterable: false },
                    wgpu::TextureViewDimension::D2,
                ),
            ],
        });
        // A full-screen triangle: no vertex buffers, no depth.
        let pipeline = TrianglePipeline {
            label: "present",
            layout: &one_group_layout(&device, "present", &layout),
            shader: &module,
            vertex: ("vs_main", &[]),
            cull_mode: None,
            depth: None,
            fragment: Some(("fs_main", &[opaque(config.format)])),
        }
        .build(&device);
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("present params"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.gpu = Some(Gpu {
            surface,
            device,
            queue,
            config,
            pipeline,
            layout,
            params,
            image: None,
        });
        self.window = Some(window);
        Ok(())
    }

    fn upload(&mut self, image: &OutputImage) {
        let Some(gpu) = &mut self.gpu else {
            return;
        };
        let (w, h) = (image.width.max(1), image.height.max(1));
        if image.rgba.len() != (image.width as usize) * (image.height as usize) {
            return;
        }
        let size = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        let stale = gpu
            .image
            .as_ref()
            .is_none_or(|(t, _)| t.width() != w || t.height() != h);
        if stale {
            let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("presented frame"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba32Float,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            let bind = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("present"),
                layout: &gpu.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: gpu.params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                ],
            });
            gpu.image = Some((texture, bind));
        }
        if let Some((texture, _)) = &gpu.image {
            gpu.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                bytemuck::cast_slice(&image.rgba),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(16 * w),
                    rows_per_image: Some(h),
                },
                size,
            );
        }
    }

    fn draw(&mut self) {
        let Some(gpu) = &mut self.gpu else {
            return;
        };
        let Some((_, bind)) = &gpu.image else {
            return;
        };
        let frame = match gpu.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                gpu.surface.configure(&gpu.device, &gpu.config);
                return;
            }
            // Occluded, timed out or invalid: skip this frame.
            _ => return,
        };
        let params = [
            self.encode_gamma,
            0.0,
            gpu.config.width as f32,
            gpu.config.height as f32,
        ];
        gpu.queue
            .write_buffer(&gpu.params, 0, bytemuck::cast_slice(&params));
        let view = frame
            .texture
            .create_view(&wgpu::TextureViewDescriptor::default());
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("present"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&gpu.pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.draw(0..3, 0..1);
        }
        gpu.queue.submit([encoder.finish()]);
        gpu.queue.present(frame);
    }
}

impl ApplicationHandler<WindowMessage> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        if let Err(e) = self.setup(event_loop) {
            self.error = Some(e);
            event_loop.exit();
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(gpu) = &mut self.gpu {
                    gpu.config.width = size.width.max(1);
                    gpu.config.height = size.height.max(1);
                    gpu.surface.configure(&gpu.device, &gpu.config);
                }
                self.draw();
            }
            WindowEvent::RedrawRequested => self.draw(),
            _ => {}
        }
    }

    fn user_event(&mut self, event_loop: &ActiveEventLoop, message: WindowMessage) {
        match message {
            WindowMessage::Frame(_, image) => {
                self.upload(&image);
                self.draw();
            }
            WindowMessage::Quit => event_loop.exit(),
        }
    }
}
