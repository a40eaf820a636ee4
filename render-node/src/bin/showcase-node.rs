//! `showcase-node`: a render node of the Showcase cluster. It drives one
//! CRT face or one projector (or a camera) for the master named in the
//! cluster configuration, headless, until Ctrl-C.

use anyhow::{Context, Result};
use clap::Parser;
use showcase_proto::config::ClusterConfig;
use showcase_render::net::ClusterIdentity;
use showcase_render::node::{NodeRuntime, StateHashRenderer, run_node};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tokio_util::sync::CancellationToken;

/// A Showcase render node.
#[derive(Debug, Parser)]
#[command(name = "showcase-node", version, about, long_about = None)]
struct NodeCli {
    /// Cluster configuration (see deploy/).
    #[arg(long)]
    config: PathBuf,
    /// This node's name in the configuration.
    #[arg(long)]
    name: String,
    /// Master address, overriding the configuration.
    #[arg(long)]
    master: Option<SocketAddr>,
    /// Write the images of these frames (comma-separated) as PNG.
    #[arg(long, value_delimiter = ',')]
    write_frames: Vec<u64>,
    /// Folder for --write-frames.
    #[arg(long, default_value = "frames")]
    frames_dir: PathBuf,
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    match run(NodeCli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: NodeCli) -> Result<()> {
    let text = std::fs::read_to_string(&cli.config)
        .with_context(|| format!("cannot read cluster config {}", cli.config.display()))?;
    let label = cli.config.display().to_string();
    let cfg = ClusterConfig::parse(&text, &label)?;
    let node = cfg.node(&cli.name, &label)?;
    let base = cli.config.parent().unwrap_or(Path::new("."));
    let identity = ClusterIdentity::load(&base.join(&cfg.master.certs), &node.name)?;
    let rt = NodeRuntime {
        name: node.name.clone(),
        role: node.role,
        master: cli.master.unwrap_or(cfg.master.listen),
        identity,
        bind: node
            .bind
            .unwrap_or_else(|| "0.0.0.0:0".parse().expect("valid address")),
        capabilities: Default::default(),
        write_frames: (!cli.write_frames.is_empty())
            .then(|| (cli.frames_dir.clone(), cli.write_frames.clone())),
    };
    tracing::warn!(
        "output {:?}: the real-time renderer (issue #6) is not built yet; this node presents a digest of each frame's state, no pixels",
        node.output
    );
    let mut renderer = StateHashRenderer::new(node.output.clone(), node.role);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    runtime.block_on(async {
        let stop = CancellationToken::new();
        let s = stop.clone();
        tokio::spawn(async move {
            let _ = tokio::signal::ctrl_c().await;
            s.cancel();
        });
        let log = run_node(rt, &mut renderer, stop).await?;
        eprintln!(
            "node stopped after presenting {} frames ({} joins)",
            log.presented.len(),
            log.joins
        );
        anyhow::Ok(())
    })
}
