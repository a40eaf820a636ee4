//! `showcase-node`: a render node of the Showcase cluster. It drives one
//! CRT face or one projector (or a camera) for the master.

use clap::Parser;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;

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
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = NodeCli::parse();
    tracing::debug!(?cli, "starting");
    eprintln!(
        "error: showcase-node --name {}: the cluster runtime is not built yet (tracked in issue #7); nothing was done",
        cli.name
    );
    ExitCode::FAILURE
}
