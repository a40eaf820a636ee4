//! The `showcase-master` command line: argument definitions and dispatch.
//! The binary only parses, sets up tracing and calls [`run`]; each
//! subcommand's arguments become the plain options of the library module
//! that does the work, so only this module knows clap.

mod bench;
mod capture_cluster;
mod jobs;
mod sim;

pub use bench::{BenchArgs, BenchTarget};
pub use jobs::{
    CalibrateArgs, CalibrationMethod, CaptureArgs, CertsArgs, CheckArgs, DemoArgs, RadiosityArgs,
    ReplayArgs, RunArgs,
};
pub use sim::{SimCommand, SimRenderArgs};

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

/// Showcase master: consistent illumination for the Virtual Showcase.
#[derive(Debug, Parser)]
#[command(name = "showcase-master", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands of `showcase-master`.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the whole pipeline on the built-in simulated showcase.
    Demo(DemoArgs),
    /// Run the master of a render cluster.
    Run(RunArgs),
    /// Check a cluster config and everything it names before a show.
    Check(CheckArgs),
    /// Calibrate a projector or camera from fiducial correspondences.
    Calibrate(CalibrateArgs),
    /// Capture reflectance maps of the real objects.
    Capture(CaptureArgs),
    /// Solve augmented radiosity and write the solution and irradiance maps.
    Radiosity(RadiosityArgs),
    /// Drive the cluster from a recorded tracking session.
    Replay(ReplayArgs),
    /// Create the cluster CA and per-node certificates.
    Certs(CertsArgs),
    /// Benchmarks of run time against error.
    Bench(BenchArgs),
    /// Tools of the simulated showcase.
    #[command(subcommand)]
    Sim(SimCommand),
}

/// Execute a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Demo(args) => crate::demo::run(&args.into()),
        Command::Run(args) => jobs::run_master(&args),
        Command::Check(args) => jobs::check(&args),
        Command::Calibrate(args) => jobs::calibrate(&args),
        Command::Capture(args) => jobs::capture(&args),
        Command::Radiosity(args) => jobs::radiosity(&args),
        Command::Replay(args) => jobs::replay(&args),
        Command::Certs(args) => jobs::certs(&args),
        Command::Bench(args) => bench::bench(&args),
        Command::Sim(command) => sim::sim(&command),
    }
}

/// Parse an image size `WxH`, each side 1 to 16384; errors name it as
/// `--size`.
fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("--size {s:?}: expected WxH"))?;
    let w: u32 = w
        .trim()
        .parse()
        .with_context(|| format!("--size {s:?}: bad width"))?;
    let h: u32 = h
        .trim()
        .parse()
        .with_context(|| format!("--size {s:?}: bad height"))?;
    anyhow::ensure!(
        w > 0 && h > 0 && w <= 16384 && h <= 16384,
        "--size {s:?}: out of 1..=16384"
    );
    Ok((w, h))
}

/// A multi-threaded tokio runtime for the async commands.
fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")
}

#[cfg(test)]
mod tests {
    use super::sim::parse_vec3;
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn help_lists_every_subcommand() {
        let help = Cli::command().render_help().to_string();
        for sub in [
            "demo",
            "run",
            "check",
            "calibrate",
            "capture",
            "radiosity",
            "replay",
            "certs",
            "bench",
            "sim",
        ] {
            assert!(help.contains(sub), "help lacks {sub}:\n{help}");
        }
        Cli::command().debug_assert();
    }

    #[test]
    fn bad_input_names_the_file_or_value() {
        let cli = Cli::try_parse_from([
            "showcase-master",
            "radiosity",
            "--scene",
            "no-such.toml",
            "--out",
            "y",
        ])
        .unwrap();
        let err = format!("{:#}", run(cli).unwrap_err());
        assert!(err.contains("no-such.toml"), "{err}");
        assert_eq!(
            parse_vec3("--eye", "1,2").unwrap_err().to_string(),
            "--eye \"1,2\": expected three finite numbers x,y,z"
        );
        assert!(parse_vec3("--eye", "1,nan,2").is_err());
        assert_eq!(parse_size("640x480").unwrap(), (640, 480));
        assert!(parse_size("0x480").is_err() && parse_size("640").is_err());
    }
}
