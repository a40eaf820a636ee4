//! `showcase-node`: a render node of the Showcase cluster. It drives one
//! CRT face or one projector (or a camera) for the master named in the
//! cluster configuration, headless, until SIGINT or SIGTERM.

use anyhow::{Context, Result};
use clap::Parser;
use showcase_proto::config::{ClusterConfig, HostPort};
use showcase_render::gpu::GpuContext;
use showcase_render::net::{ClusterIdentity, resolve};
use showcase_render::node::{
    CameraSpec, CaptureHost, LightBus, NodeRuntime, OutputRenderer, Renderer, SimCameraNode,
    SimProjectorNode, StateHashRenderer, V4l2NodeOptions, run_node_with_devices,
};
use showcase_render::render::gpu_frame::DEFAULT_SHADOW_RES;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tokio_util::sync::CancellationToken;

/// A Showcase render node.
#[derive(Debug, Parser)]
#[command(name = "showcase-node", version, about, long_about = None)]
struct NodeCli {
    /// Cluster configuration (see deploy/).
    #[arg(long, required_unless_present = "list_monitors")]
    config: Option<PathBuf>,
    /// This node's name in the configuration.
    #[arg(long, required_unless_present = "list_monitors")]
    name: Option<String>,
    /// Master address (HOST:PORT or IP:PORT), overriding the configuration.
    #[arg(long)]
    master: Option<String>,
    /// Write the images of these frames (comma-separated) as PNG.
    #[arg(long, value_delimiter = ',')]
    write_frames: Vec<u64>,
    /// Folder for --write-frames.
    #[arg(long, default_value = "frames")]
    frames_dir: PathBuf,
    /// What draws the frames: `gpu` (the real-time renderer, wgpu; on a
    /// machine without a GPU, Mesa's lavapipe) or `state-hash` (a digest
    /// of each frame's state, no pixels: for cluster tests).
    #[arg(long, value_enum, default_value_t = RendererKind::Gpu)]
    renderer: RendererKind,
    /// Sim mode: hold the simulated device of this node's output for the
    /// master's capture requests, the room's light shared through this
    /// folder (a projector node writes what it shows there, a camera
    /// node lights its simulated showcase from it). Every node of one
    /// simulated room names the same folder.
    #[arg(long)]
    sim_light: Option<PathBuf>,
    /// A camera node's camera: `v4l2:/dev/videoN[:WIDTHxHEIGHT[:FORMAT]]`
    /// (a real camera, built with `--features v4l2`; the size defaults to
    /// the scene camera's, which it must equal) or `recorded:DIR` (a
    /// folder `showcase-camera record` made, replayed). Exposure and gain
    /// are fixed by each capture request; auto exposure, gain and white
    /// balance stay off.
    #[arg(long, conflicts_with = "sim_light")]
    camera: Option<CameraSpec>,
    /// With --camera v4l2:...: the gain control's value the camera was
    /// calibrated at (`showcase-camera formats` shows its range; left as it
    /// is when not given).
    #[arg(long, requires = "camera")]
    camera_gain: Option<i32>,
    /// With --camera v4l2:...: fixed white balance in kelvin.
    #[arg(long, requires = "camera")]
    camera_white_balance_k: Option<i32>,
    /// With --sim-light: paths per camera pixel of the sim's light
    /// transport.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..))]
    sim_samples: u32,
    /// Shadow map size per view, in texels a side.
    #[arg(long, default_value_t = DEFAULT_SHADOW_RES)]
    shadow_res: u32,
    /// Show the presented frames full screen on this machine's display, on
    /// the monitor the node's `monitor` names (default: the primary).
    #[cfg(feature = "window")]
    #[arg(long)]
    window: bool,
    /// With --window: fill this monitor (a name or an index from
    /// --list-monitors), overriding the configuration.
    #[cfg(feature = "window")]
    #[arg(long)]
    monitor: Option<String>,
    /// Print the monitors of this machine's display (names and indices for
    /// a node's `monitor`) and exit.
    #[cfg(feature = "window")]
    #[arg(long)]
    list_monitors: bool,
    /// With --window: replace the display gamma of the device encoding
    /// (default: a CRT face's from its photometric profile, 1 for a
    /// projector, whose values are already drive values).
    #[cfg(feature = "window")]
    #[arg(long)]
    display_gamma: Option<f32>,
}

/// What draws the frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum RendererKind {
    /// The real-time renderer on the GPU.
    Gpu,
    /// A digest of each frame's state.
    StateHash,
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        // Colours only for a person at a terminal, not in files or the journal.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    match run(NodeCli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// `--master HOST:PORT` or `IP:PORT` to the address it resolves to.
fn resolve_master(master: &str) -> Result<SocketAddr> {
    let addr: HostPort = master
        .parse()
        .map_err(|e| anyhow::anyhow!("--master {e}"))?;
    Ok(resolve(&addr, "--master")?)
}

fn run(cli: NodeCli) -> Result<()> {
    #[cfg(feature = "window")]
    if cli.list_monitors {
        let monitors = showcase_render::window::list_monitors()
            .context("cannot reach the display (is DISPLAY or WAYLAND_DISPLAY set?)")?;
        if monitors.is_empty() {
            println!("the display has no monitor");
        }
        for (i, m) in monitors.iter().enumerate() {
            println!("{i}: {m}");
        }
        return Ok(());
    }
    let (Some(config), Some(name)) = (&cli.config, &cli.name) else {
        anyhow::bail!("--config and --name are required");
    };
    let text = std::fs::read_to_string(config)
        .with_context(|| format!("cannot read cluster config {}", config.display()))?;
    let label = config.display().to_string();
    let cfg = ClusterConfig::parse(&text, &label)?;
    let node = cfg.node(name, &label)?;
    let base = config.parent().unwrap_or(Path::new("."));
    let identity = ClusterIdentity::load(&base.join(&cfg.master.certs), &node.name)?;
    let rt = NodeRuntime {
        name: node.name.clone(),
        role: node.role,
        master: match &cli.master {
            Some(m) => resolve_master(m)?,
            None => resolve(&cfg.master.listen, "master.listen")?,
        },
        identity,
        bind: match &node.bind {
            Some(b) => resolve(b, &format!("node {:?}.bind", node.name))?,
            None => "0.0.0.0:0".parse().expect("valid address"),
        },
        capabilities: Default::default(),
        write_frames: (!cli.write_frames.is_empty())
            .then(|| (cli.frames_dir.clone(), cli.write_frames.clone())),
        keep_presented: false,
    };
    anyhow::ensure!(
        (16..=8192).contains(&cli.shadow_res),
        "--shadow-res {}: must be between 16 and 8192",
        cli.shadow_res
    );
    let mut renderer: Box<dyn Renderer> = match (cli.renderer, node.role) {
        (RendererKind::StateHash, role) => {
            Box::new(StateHashRenderer::new(node.output.clone(), role))
        }
        (RendererKind::Gpu, showcase_proto::Role::Camera) => {
            tracing::info!(output = %node.output, "a camera node captures, it does not render: presenting frame-state digests");
            Box::new(StateHashRenderer::new(node.output.clone(), node.role))
        }
        (RendererKind::Gpu, role) => {
            let ctx = GpuContext::new_headless().context(
                "no GPU adapter (install mesa-vulkan-drivers for lavapipe, or run with --renderer state-hash)",
            )?;
            tracing::info!(output = %node.output, adapter = %ctx.describe(), "rendering on the GPU");
            Box::new(OutputRenderer::new(
                ctx,
                node.output.clone(),
                role,
                cli.shadow_res,
            )?)
        }
    };
    let devices = match (&cli.sim_light, node.role) {
        (None, _) => host_camera(&cli, node.role, &node.output)?,
        (Some(dir), role) => {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("--sim-light {}: cannot create", dir.display()))?;
            let bus = LightBus::Dir(dir.clone());
            match role {
                showcase_proto::Role::Projector => {
                    Some(CaptureHost::new(SimProjectorNode::new(&node.output, bus)))
                }
                showcase_proto::Role::Camera => Some(CaptureHost::new(SimCameraNode::new(
                    &node.output,
                    bus,
                    showcase_light::sim::SimConfig {
                        samples_per_pixel: cli.sim_samples,
                        ..Default::default()
                    },
                ))),
                showcase_proto::Role::Face => None,
            }
        }
    };
    let stop = CancellationToken::new();
    #[cfg(feature = "window")]
    if cli.window {
        use showcase_render::node::present::Presenting;
        if let Some(gamma) = cli.display_gamma {
            anyhow::ensure!(
                gamma.is_finite() && gamma > 0.0,
                "--display-gamma {gamma}: must be a positive number"
            );
        }
        let gamma = cli.display_gamma;
        let monitor = cli.monitor.clone().or_else(|| node.monitor.clone());
        let (event_loop, sink) = showcase_render::window::event_loop()?;
        let title = format!("showcase {}", node.name);
        let node_stop = stop.clone();
        let quit = sink.clone();
        let node_thread = std::thread::spawn(move || {
            let mut presenting = Presenting::new(renderer, sink);
            let r = drive(rt, &mut presenting, devices, node_stop);
            quit.quit();
            r
        });
        let shown = showcase_render::window::run(event_loop, &title, monitor.as_deref(), gamma);
        stop.cancel();
        let node = node_thread
            .join()
            .map_err(|_| anyhow::anyhow!("the node thread panicked"))?;
        shown?;
        return node;
    }
    drive(rt, renderer.as_mut(), devices, stop)
}

/// The devices of `--camera`: a camera node only.
fn host_camera(
    cli: &NodeCli,
    role: showcase_proto::Role,
    output: &str,
) -> Result<Option<CaptureHost>> {
    let Some(spec) = &cli.camera else {
        return Ok(None);
    };
    if role != showcase_proto::Role::Camera {
        anyhow::bail!(
            "--camera: this node drives a {role:?} output ({output:?}); only a camera node hosts a camera: give --camera to the node whose role is camera"
        );
    }
    let options = V4l2NodeOptions {
        gain: cli.camera_gain,
        white_balance_k: cli.camera_white_balance_k,
    };
    let host = showcase_render::node::camera_node(output, spec, options)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    tracing::info!(camera = ?spec, "camera node: captures with this machine's camera");
    Ok(Some(host))
}

/// Run the node until SIGINT or SIGTERM, `stop`, or a fatal error.
fn drive<R: Renderer + ?Sized>(
    rt: NodeRuntime,
    renderer: &mut R,
    devices: Option<CaptureHost>,
    stop: CancellationToken,
) -> Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    runtime.block_on(async {
        showcase_render::node::cancel_on_stop_signal(stop.clone());
        let log = run_node_with_devices(rt, renderer, devices, stop).await?;
        eprintln!(
            "node stopped after presenting {} frames ({} joins)",
            log.presented_count, log.joins
        );
        anyhow::Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_camera_node_hosts_a_camera() {
        let cli = NodeCli::try_parse_from([
            "showcase-node",
            "--config",
            "c.toml",
            "--name",
            "face-0",
            "--camera",
            "recorded:/nonexistent",
        ])
        .unwrap();
        let e = host_camera(&cli, showcase_proto::Role::Face, "face-0")
            .unwrap_err()
            .to_string();
        assert!(e.contains("only a camera node hosts a camera"), "{e}");
        let e = host_camera(&cli, showcase_proto::Role::Camera, "camera-0")
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent"), "{e}");
        let e = NodeCli::try_parse_from([
            "showcase-node",
            "--config",
            "c.toml",
            "--name",
            "camera-0",
            "--camera",
            "usb:0",
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("v4l2:/dev/videoN"), "{e}");
    }

    #[test]
    fn master_flag_takes_host_names_and_ips() {
        assert_eq!(
            resolve_master("localhost:4433").unwrap(),
            "127.0.0.1:4433".parse::<SocketAddr>().unwrap()
        );
        assert_eq!(
            resolve_master("192.168.10.10:4433").unwrap(),
            "192.168.10.10:4433".parse::<SocketAddr>().unwrap()
        );
        let err = resolve_master("pc-0").unwrap_err().to_string();
        assert!(
            err.starts_with("--master \"pc-0\" is not HOST:PORT"),
            "{err}"
        );
        let err = resolve_master("no-such-pc.invalid:4433")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("--master no-such-pc.invalid:4433: cannot resolve host"),
            "{err}"
        );
    }
}
