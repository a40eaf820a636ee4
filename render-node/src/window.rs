//! The `window` feature (on by default): a node shows its presented frames
//! full screen on a real display (winit window, wgpu surface), on the
//! monitor its configuration names ([`pick_monitor`]). The frame's linear values
//! are encoded for the device at this boundary, as each image says
//! ([`OutputImage::encoding`]): a projector's values are already its drive
//! values, a CRT face's radiance goes through its face's photometric
//! profile ([`showcase_proto::CrtPhotometry::drive`]: the splitter's
//! `T / R`, less the black level, over the peak, to `1 / gamma`, per
//! channel).
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
use winit::monitor::MonitorHandle;
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

/// The event loop and a sink feeding it. The node binary creates it on
/// the main thread, as macOS and Windows require; on X11 and Wayland any
/// thread may (the window tests run it on a test thread).
pub fn event_loop() -> Result<(EventLoop<WindowMessage>, WindowSink), WindowError> {
    let mut builder = EventLoop::<WindowMessage>::with_user_event();
    #[cfg(all(unix, not(target_vendor = "apple"), not(target_os = "android")))]
    {
        use winit::platform::wayland::EventLoopBuilderExtWayland;
        use winit::platform::x11::EventLoopBuilderExtX11;
        EventLoopBuilderExtX11::with_any_thread(&mut builder, true);
        EventLoopBuilderExtWayland::with_any_thread(&mut builder, true);
    }
    let event_loop = builder.build()?;
    let sink = WindowSink(event_loop.create_proxy());
    Ok((event_loop, sink))
}

/// A monitor as the display server names it, and where it is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MonitorInfo {
    /// Its name (`DP-1`), or `monitor N` when the server gives none.
    pub name: String,
    /// Top-left corner on the desktop (physical pixels).
    pub position: (i32, i32),
    /// Size (physical pixels).
    pub size: (u32, u32),
}

impl std::fmt::Display for MonitorInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} ({}x{} at {},{})",
            self.name, self.size.0, self.size.1, self.position.0, self.position.1
        )
    }
}

fn monitor_info(i: usize, m: &MonitorHandle) -> MonitorInfo {
    let (p, s) = (m.position(), m.size());
    MonitorInfo {
        name: m.name().unwrap_or_else(|| format!("monitor {i}")),
        position: (p.x, p.y),
        size: (s.width, s.height),
    }
}

/// The monitor `wanted` names among `monitors`: by name, else by index
/// (`"0"`, `"1"`); an error lists what there is.
pub fn pick_monitor(monitors: &[MonitorInfo], wanted: &str) -> Result<usize, String> {
    if let Some(i) = monitors.iter().position(|m| m.name == wanted) {
        return Ok(i);
    }
    if let Ok(i) = wanted.parse::<usize>()
        && i < monitors.len()
    {
        return Ok(i);
    }
    let have = if monitors.is_empty() {
        "none".to_owned()
    } else {
        monitors
            .iter()
            .enumerate()
            .map(|(i, m)| format!("{i}: {m}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    Err(format!(
        "no monitor {wanted:?} on this display (it has {have}); set the node's `monitor` in the \
         cluster configuration to one of these names or indices"
    ))
}

/// The monitors of the display the process can reach (`$DISPLAY`,
/// `$WAYLAND_DISPLAY`), in the server's order: what `monitor` may name.
pub fn list_monitors() -> Result<Vec<MonitorInfo>, WindowError> {
    struct List(Result<Vec<MonitorInfo>, WindowError>);
    impl ApplicationHandler<WindowMessage> for List {
        fn resumed(&mut self, event_loop: &ActiveEventLoop) {
            self.0 = Ok(event_loop
                .available_monitors()
                .enumerate()
                .map(|(i, m)| monitor_info(i, &m))
                .collect());
            event_loop.exit();
        }
        fn window_event(&mut self, _: &ActiveEventLoop, _: WindowId, _: WindowEvent) {}
    }
    let (event_loop, _) = event_loop()?;
    let mut list = List(Err(WindowError::Setup(
        "the display never became ready".into(),
    )));
    event_loop.run_app(&mut list)?;
    list.0
}

/// Run the full-screen window until the node quits or the window is
/// closed, on `monitor` (a name or an index, see [`pick_monitor`]; `None`:
/// the primary monitor); `gamma_override`, if any, replaces the display
/// gamma of every image's encoding (per channel for a CRT face's profile,
/// 1 for values already drive values).
pub fn run(
    event_loop: EventLoop<WindowMessage>,
    title: &str,
    monitor: Option<&str>,
    gamma_override: Option<f32>,
) -> Result<(), WindowError> {
    let mut app = App {
        title: title.to_string(),
        monitor: monitor.map(str::to_owned),
        gamma_override: gamma_override.filter(|g| g.is_finite() && *g > 0.0),
        encoding: [[1.0; 4], [0.0; 4], [1.0; 4], [1.0; 4]],
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
    monitor: Option<String>,
    gamma_override: Option<f32>,
    /// The shown image's encoding as the shader's rows: `T / R`, black
    /// level, peak and `1 / gamma`, per channel.
    encoding: [[f32; 4]; 4],
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
struct Params {
    scale: vec4<f32>,
    black: vec4<f32>,
    peak: vec4<f32>,
    inv_gamma: vec4<f32>,
    target_size: vec2<f32>,
    _pad: vec2<f32>,
};
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
    let l = textureLoad(frame, texel, 0).rgb;
    let x = clamp((l * params.scale.rgb - params.black.rgb) / params.peak.rgb, vec3<f32>(0.0), vec3<f32>(1.0));
    return vec4<f32>(pow(x, params.inv_gamma.rgb), 1.0);
}
";

impl App {
    /// The monitor to fill: the named one, else the primary (or the first).
    fn monitor(&self, event_loop: &ActiveEventLoop) -> Result<MonitorHandle, String> {
        let handles: Vec<MonitorHandle> = event_loop.available_monitors().collect();
        match &self.monitor {
            Some(wanted) => {
                let infos: Vec<MonitorInfo> = handles
                    .iter()
                    .enumerate()
                    .map(|(i, m)| monitor_info(i, m))
                    .collect();
                let i = pick_monitor(&infos, wanted)?;
                Ok(handles[i].clone())
            }
            None => event_loop
                .primary_monitor()
                .or_else(|| handles.first().cloned())
                .ok_or_else(|| "the display has no monitor".to_owned()),
        }
    }

    fn setup(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let monitor = self.monitor(event_loop)?;
        // Position and size as well as the full-screen request: without a
        // window manager (a bare X server) the request alone does nothing.
        let window = Arc::new(
            event_loop
                .create_window(
                    Window::default_attributes()
                        .with_title(self.title.clone())
                        .with_decorations(false)
                        .with_position(monitor.position())
                        .with_inner_size(monitor.size())
                        .with_fullscreen(Some(Fullscreen::Borderless(Some(monitor)))),
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
            size: 80,
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
        let [scale, black, peak, inv_gamma] = self.encoding;
        let mut params = [0.0f32; 20];
        for (row, v) in [scale, black, peak, inv_gamma].iter().enumerate() {
            params[4 * row..4 * row + 4].copy_from_slice(v);
        }
        params[16] = gpu.config.width as f32;
        params[17] = gpu.config.height as f32;
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
                self.encoding = encoding_rows(image.encoding.as_ref(), self.gamma_override);
                self.upload(&image);
                self.draw();
            }
            WindowMessage::Quit => event_loop.exit(),
        }
    }
}

/// The present shader's rows for `encoding` (`None`: values already drive
/// values): `T / R` (0 where `R` is not positive: black), black level,
/// peak and `1 / gamma` per channel, the gamma replaced by `gamma` if
/// given; the same arithmetic as [`showcase_proto::CrtPhotometry::drive`].
fn encoding_rows(
    encoding: Option<&showcase_proto::CrtPhotometry>,
    gamma: Option<f32>,
) -> [[f32; 4]; 4] {
    let row = |v: glam::Vec3| [v.x, v.y, v.z, 1.0];
    let mut rows = [[1.0; 4], [0.0; 4], [1.0; 4], [1.0; 4]];
    if let Some(e) = encoding {
        let (t, r) = (e.splitter.transmission, e.splitter.reflection);
        let ratio = glam::Vec3::from_array(std::array::from_fn(|c| {
            if r[c] > 0.0 { t[c] / r[c] } else { 0.0 }
        }));
        rows = [
            row(ratio),
            row(e.crt.black_level),
            row(e.crt.peak.max(glam::Vec3::splat(1e-6))),
            row(e.crt.gamma.max(glam::Vec3::splat(1e-3)).recip()),
        ];
    }
    if let Some(g) = gamma {
        rows[3] = row(glam::Vec3::splat(1.0 / g));
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use showcase_proto::{BeamSplitter, CrtPhotometry, CrtResponse};

    /// The present shader's arithmetic, on the CPU.
    fn shade(rows: &[[f32; 4]; 4], l: Vec3) -> Vec3 {
        let v = |i: usize| Vec3::new(rows[i][0], rows[i][1], rows[i][2]);
        let x = ((l * v(0) - v(1)) / v(2)).clamp(Vec3::ZERO, Vec3::ONE);
        Vec3::new(x.x.powf(v(3).x), x.y.powf(v(3).y), x.z.powf(v(3).z))
    }

    #[test]
    fn a_monitor_is_picked_by_name_or_index_and_a_wrong_one_is_listed() {
        let m = |name: &str, x| MonitorInfo {
            name: name.into(),
            position: (x, 0),
            size: (1920, 1080),
        };
        let monitors = [m("DP-1", 0), m("DP-2", 1920), m("1", 3840)];
        assert_eq!(pick_monitor(&monitors, "DP-2"), Ok(1));
        assert_eq!(pick_monitor(&monitors, "0"), Ok(0));
        // A name wins over an index.
        assert_eq!(pick_monitor(&monitors, "1"), Ok(2));
        let e = pick_monitor(&monitors, "HDMI-1").unwrap_err();
        assert!(
            e.contains("\"HDMI-1\"") && e.contains("1: DP-2 (1920x1080 at 1920,0)"),
            "{e}"
        );
        assert!(pick_monitor(&monitors, "3").is_err());
        assert!(pick_monitor(&[], "0").unwrap_err().contains("it has none"));
    }

    #[test]
    fn the_window_encodes_what_the_profile_drives() {
        let profile = CrtPhotometry {
            crt: CrtResponse {
                gamma: Vec3::new(2.4, 2.5, 2.3),
                peak: Vec3::new(2.0, 1.8, 2.2),
                black_level: Vec3::splat(0.004),
            },
            splitter: BeamSplitter {
                transmission: Vec3::new(0.62, 0.6, 0.57),
                reflection: Vec3::new(0.33, 0.35, 0.37),
            },
        };
        let rows = encoding_rows(Some(&profile), None);
        for l in [0.0f32, 0.003, 0.05, 0.4, 1.0, 5.0] {
            let radiance = Vec3::new(l, 0.8 * l, 1.2 * l);
            let (got, want) = (shade(&rows, radiance), profile.drive(radiance));
            assert!(
                (got - want).abs().max_element() < 1e-5,
                "{radiance}: {got} vs {want}"
            );
        }
        // Projector values pass through.
        let plain = encoding_rows(None, None);
        assert_eq!(
            shade(&plain, Vec3::new(0.2, 0.5, 0.9)),
            Vec3::new(0.2, 0.5, 0.9)
        );
        // An override replaces the gamma only.
        let g = encoding_rows(Some(&profile), Some(1.0));
        assert_eq!(g[0], rows[0]);
        assert_eq!(g[3], [1.0; 4]);
    }
}
