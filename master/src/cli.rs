//! The `showcase-master` command line: argument definitions and dispatch.
//! The binary only parses, sets up tracing and calls [`run`].

use anyhow::Result;
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

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

/// Arguments of `demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "showcase-out")]
    pub out: PathBuf,
    /// Frames of the interactive stage.
    #[arg(long, default_value_t = 240)]
    pub frames: u64,
    /// Scene file (default: the built-in demo cabinet).
    #[arg(long)]
    pub scene: Option<PathBuf>,
}

/// Arguments of `run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Cluster configuration (see deploy/).
    #[arg(long)]
    pub config: PathBuf,
    /// Write one JSON line of measurements per frame to this file.
    #[arg(long)]
    pub metrics: Option<PathBuf>,
}

/// Calibration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CalibrationMethod {
    /// DLT + RQ start, Levenberg-Marquardt refinement.
    Lm,
    /// The paper's baseline: Powell's direction-set method.
    Powell,
}

/// Arguments of `calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Input correspondences (JSON).
    #[arg(long)]
    pub points: PathBuf,
    /// Output calibration (JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Solver.
    #[arg(long, value_enum, default_value_t = CalibrationMethod::Lm)]
    pub method: CalibrationMethod,
}

/// Arguments of `capture`.
#[derive(Debug, Args)]
pub struct CaptureArgs {
    /// Scene file.
    #[arg(long)]
    pub scene: PathBuf,
    /// Capture from the simulated showcase.
    #[arg(long)]
    pub sim: bool,
    /// Output folder for the reflectance maps and summary.
    #[arg(long)]
    pub out: PathBuf,
}

/// Arguments of `radiosity`.
#[derive(Debug, Args)]
pub struct RadiosityArgs {
    /// Scene file (TOML, or an OBJ such as the Cornell box).
    #[arg(long)]
    pub scene: PathBuf,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Largest patch area in square metres.
    #[arg(long)]
    pub max_patch_area: Option<f64>,
    /// Hemi-cube resolution (pixels along the top face).
    #[arg(long)]
    pub hemicube: Option<u32>,
    /// Stop when the unshot energy fraction falls below this.
    #[arg(long)]
    pub threshold: Option<f64>,
}

/// Arguments of `replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// Recorded session file.
    #[arg(long)]
    pub session: PathBuf,
}

/// Arguments of `certs`.
#[derive(Debug, Args)]
pub struct CertsArgs {
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Node names to issue certificates for.
    #[arg(long = "node", required = true)]
    pub nodes: Vec<String>,
}

/// What to benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BenchTarget {
    /// Device calibration.
    Calibration,
    /// Reflectance capture.
    Reflectance,
    /// Radiosity.
    Radiosity,
    /// The real-time renderer.
    Render,
    /// The cluster runtime.
    Cluster,
}

/// Arguments of `bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to benchmark.
    #[arg(value_enum)]
    pub target: BenchTarget,
    /// Print one JSON array on stdout instead of writing a report.
    #[arg(long)]
    pub json: bool,
    /// Report folder (without --json).
    #[arg(long, default_value = "showcase-bench")]
    pub out: PathBuf,
}

/// Subcommands of `sim`.
#[derive(Debug, Subcommand)]
pub enum SimCommand {
    /// Render a view of a scene lit by its own emitters, as linear radiance.
    Render(SimRenderArgs),
}

/// Arguments of `sim render`.
#[derive(Debug, Args)]
pub struct SimRenderArgs {
    /// Scene file.
    #[arg(long)]
    pub scene: PathBuf,
    /// Eye position `x,y,z`.
    #[arg(long, allow_hyphen_values = true)]
    pub eye: String,
    /// Look-at target `x,y,z`.
    #[arg(long, allow_hyphen_values = true)]
    pub target: String,
    /// Up vector `x,y,z`.
    #[arg(long, allow_hyphen_values = true, default_value = "0,1,0")]
    pub up: String,
    /// Horizontal field of view in degrees.
    #[arg(long)]
    pub fov_deg: f64,
    /// Image size `WxH`.
    #[arg(long, default_value = "512x512")]
    pub size: String,
    /// Output file (.pfm).
    #[arg(long)]
    pub out: PathBuf,
}

/// A capability that a later piece of work will build.
#[derive(Debug, thiserror::Error)]
#[error("{command}: {capability} is not built yet (tracked in issue #{issue}); nothing was done")]
pub struct NotBuilt {
    /// The command line that asked for it.
    pub command: &'static str,
    /// What is missing.
    pub capability: &'static str,
    /// The issue that delivers it.
    pub issue: u32,
}

fn not_built(command: &'static str, capability: &'static str, issue: u32) -> anyhow::Error {
    NotBuilt {
        command,
        capability,
        issue,
    }
    .into()
}

/// Execute a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Demo(args) => crate::demo::run(&args),
        Command::Run(_) => Err(not_built("run", "the cluster master", 7)),
        Command::Calibrate(_) => Err(not_built("calibrate", "device calibration", 4)),
        Command::Capture(_) => Err(not_built("capture", "reflectance capture", 3)),
        Command::Radiosity(_) => Err(not_built("radiosity", "augmented radiosity", 5)),
        Command::Replay(_) => Err(not_built("replay", "session replay", 7)),
        Command::Certs(args) => {
            let certs = crate::certs::generate(&args.nodes)?;
            let files = crate::certs::write(&args.out, &certs)?;
            for f in &files {
                println!("{}", f.display());
            }
            eprintln!(
                "wrote a cluster CA and {} certificates to {}; keep ca.key offline",
                certs.peers.len(),
                args.out.display()
            );
            Ok(())
        }
        Command::Bench(args) => match args.target {
            BenchTarget::Calibration => {
                Err(not_built("bench calibration", "device calibration", 4))
            }
            BenchTarget::Reflectance => {
                Err(not_built("bench reflectance", "reflectance capture", 3))
            }
            BenchTarget::Radiosity => Err(not_built("bench radiosity", "augmented radiosity", 5)),
            BenchTarget::Render => Err(not_built("bench render", "the real-time renderer", 6)),
            BenchTarget::Cluster => Err(not_built("bench cluster", "the cluster runtime", 7)),
        },
        Command::Sim(SimCommand::Render(_)) => {
            Err(not_built("sim render", "the simulated showcase", 3))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn help_lists_every_subcommand() {
        let help = Cli::command().render_help().to_string();
        for sub in [
            "demo",
            "run",
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
    fn unbuilt_commands_fail_naming_the_capability() {
        let cli = Cli::try_parse_from(["showcase-master", "replay", "--session", "x"]).unwrap();
        let err = run(cli).unwrap_err().to_string();
        assert_eq!(
            err,
            "replay: session replay is not built yet (tracked in issue #7); nothing was done"
        );
    }
}
