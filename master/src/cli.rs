//! The `showcase-master` command line: argument definitions and dispatch.
//! The binary only parses, sets up tracing and calls [`run`].

use anyhow::{Context, Result};
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
    /// Record every tracking datagram to this session file.
    #[arg(long)]
    pub record: Option<PathBuf>,
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
    /// Where hemi-cube item buffers are made: `cpu` (rays) or `gpu`
    /// (wgpu rasterisation).
    #[arg(long, default_value = "cpu")]
    pub form_factors: crate::radiosity_job::FormFactorDevice,
}

/// Arguments of `replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// Recorded session file (`demo` writes one: `showcase-out/session.jsonl`).
    #[arg(long)]
    pub session: PathBuf,
    /// Scene file (default: the built-in demo cabinet).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Frame rate of the replay.
    #[arg(long, default_value_t = 60.0)]
    pub hz: f32,
    /// Frames to run (default: the recording's length).
    #[arg(long)]
    pub frames: Option<u64>,
    /// Write every node's per-frame output hashes to this JSON file.
    #[arg(long)]
    pub out: Option<PathBuf>,
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
    /// Frames per configuration (default: 600 for cluster, 30 for render).
    #[arg(long)]
    pub frames: Option<u64>,
    /// Cluster only: node counts to run (default: 2,4,8).
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u16).range(1..=64))]
    pub nodes: Vec<u16>,
    /// Cluster only: frame rates to run, in Hz (default: 60,120).
    #[arg(long, value_delimiter = ',')]
    pub hz: Vec<f32>,
    /// Render only: output sizes `WxH` (default: 640x480,1024x768,1920x1080).
    #[arg(long, value_delimiter = ',')]
    pub sizes: Vec<String>,
    /// Render only: shadow map texels per side (default: the renderer's).
    #[arg(long)]
    pub shadow_res: Option<u32>,
    /// Render only: skip the CPU references (no accuracy figures; fast at large sizes).
    #[arg(long)]
    pub no_accuracy: bool,
    /// Render only: measure the adapter's floor instead of the passes: one
    /// JSON record (key `floor`) per stripped pass: the irradiance pass
    /// with a constant fragment, a full-screen triangle with a constant
    /// fragment, the same plus the texel fetches the real shaders make per
    /// pixel (projector and stereo face), the six light shadow views (all
    /// objects, occluders only, cleared only) and the readback (copies
    /// only, one target, both targets).
    #[arg(long)]
    pub floor: bool,
    /// Radiosity only: make only the records of these kinds (default: all):
    /// reference, gathered, sweep, scaling, incremental, incremental_object,
    /// augmented.
    #[arg(long, value_delimiter = ',')]
    pub kinds: Vec<String>,
    /// Radiosity only: the `incremental_object` records to make, as
    /// OBJECT@AREA with OBJECT `short_block` or `small_cube` and AREA the
    /// largest patch in m^2 (default: both at 0.02 and 0.005).
    #[arg(long, value_delimiter = ',')]
    pub object_records: Vec<String>,
    /// Radiosity only: timed runs per `incremental_object` record
    /// (default 5).
    #[arg(long)]
    pub repeats: Option<usize>,
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

/// A file of the shared data set: `../shared/data/NAME` from the working
/// directory (the repository root), else beside the source tree.
fn shared_data(name: &str) -> PathBuf {
    let here = PathBuf::from("../shared/data").join(name);
    if here.is_file() {
        return here;
    }
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data")
        .join(name)
}

/// The machine a benchmark ran on, for reports.
fn machine() -> String {
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!(
        "{} {}, {cores} cores",
        std::env::consts::OS,
        std::env::consts::ARCH
    )
}

fn parse_vec3(flag: &str, s: &str) -> Result<glam::DVec3> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{flag} {s:?}: expected x,y,z"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(glam::DVec3::new(x, y, z)),
        _ => anyhow::bail!("{flag} {s:?}: expected three finite numbers x,y,z"),
    }
}

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

fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")
}

/// Print a bench's records as one JSON array, or write them as a report.
fn emit_bench<T: serde::Serialize>(args: &BenchArgs, records: &[T]) -> Result<()> {
    let json = serde_json::to_string_pretty(records)?;
    if args.json {
        println!("{json}");
    } else {
        std::fs::create_dir_all(&args.out)
            .with_context(|| format!("cannot create {}", args.out.display()))?;
        let path = args
            .out
            .join(format!("{:?}.json", args.target).to_lowercase());
        std::fs::write(&path, json).with_context(|| format!("cannot write {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// Execute a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Demo(args) => crate::demo::run(&args),
        Command::Run(args) => runtime()?.block_on(crate::cluster::commands::run_master(
            &args.config,
            args.metrics.as_deref(),
            args.record.as_deref(),
        )),
        Command::Calibrate(args) => {
            let method = match args.method {
                CalibrationMethod::Lm => crate::calibrate::Method::Lm,
                CalibrationMethod::Powell => crate::calibrate::Method::Powell,
            };
            let c = crate::calibrate::run_calibrate_file(&args.points, &args.out, method)?;
            eprintln!(
                "calibrated {} from {} points: rms {:.4} px; wrote {}",
                args.points.display(),
                c.residuals_px.len(),
                c.rms_px,
                args.out.display()
            );
            Ok(())
        }
        Command::Capture(args) => {
            if !args.sim {
                anyhow::bail!(
                    "capture: only --sim (the simulated showcase) is available; real projector and camera drivers are not part of this build"
                );
            }
            let scene = crate::scene_file::load_any(&args.scene)?;
            let summary = crate::capture::run_capture(&scene, &args.out)?;
            println!("{}", serde_json::to_string_pretty(&summary)?);
            Ok(())
        }
        Command::Radiosity(args) => {
            let opts = crate::radiosity_job::RadiosityOptions {
                max_patch_area: args.max_patch_area,
                hemicube: args.hemicube,
                threshold: args.threshold,
            };
            let summary = crate::radiosity_job::run_radiosity_on(
                &args.scene,
                &args.out,
                &opts,
                args.form_factors,
            )?;
            println!("{}", serde_json::to_string_pretty(&summary)?);
            Ok(())
        }
        Command::Replay(args) => {
            let scene_path = args
                .scene
                .clone()
                .unwrap_or_else(crate::demo::default_scene);
            let scene = crate::scene_file::load_any(&scene_path)?;
            let outcome = runtime()?.block_on(crate::cluster::commands::replay(
                &scene,
                &args.session,
                args.hz,
                args.frames,
            ))?;
            for n in &outcome.nodes {
                println!("{} {} frames digest {}", n.name, n.hashes.len(), n.digest);
            }
            if let Some(out) = &args.out {
                std::fs::write(out, serde_json::to_string_pretty(&outcome)?)
                    .with_context(|| format!("cannot write {}", out.display()))?;
            }
            Ok(())
        }
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
                let records = crate::calibrate::bench_calibration();
                if !args.json {
                    crate::calibrate::write_bench_report(&records, &args.out).with_context(
                        || format!("cannot write the report to {}", args.out.display()),
                    )?;
                }
                emit_bench(&args, &records)
            }
            BenchTarget::Reflectance => {
                let opts = crate::capture::bench::BenchOptions {
                    cornell: shared_data("cornell-box.obj"),
                    ..Default::default()
                };
                let records = crate::capture::bench_reflectance(&opts)?;
                if !args.json {
                    crate::capture::write_report(&records, &args.out)?;
                }
                emit_bench(&args, &records)
            }
            BenchTarget::Radiosity => {
                use crate::radiosity_job::bench::{ObjectRecords, bench_radiosity_kinds};
                let objects = ObjectRecords::parse(&args.object_records, args.repeats)?;
                let records =
                    bench_radiosity_kinds(&shared_data("cornell-box.obj"), &args.kinds, &objects)?;
                if !args.json {
                    crate::radiosity_job::report::write_report(&records, &args.out, &machine())?;
                }
                emit_bench(&args, &records)
            }
            BenchTarget::Render => {
                use showcase_render::render::bench::{BenchOptions, bench_render, bench_scene};
                let room = crate::scene_file::load_any(&shared_data("cornell-box.obj"))?;
                let walls = room
                    .objects
                    .iter()
                    .filter(|o| {
                        ["floor", "ceiling", "back", "right_green", "left_red"]
                            .contains(&o.name.as_str())
                    })
                    .filter_map(|o| {
                        Some((
                            o.name.clone(),
                            room.mesh(&o.mesh)?.clone(),
                            o.material.albedo,
                        ))
                    })
                    .collect();
                let bunny = crate::scene_file::load_any(&shared_data("bunny.obj"))?;
                let bunny = bunny
                    .objects
                    .first()
                    .and_then(|o| bunny.mesh(&o.mesh))
                    .context("bunny.obj has no mesh")?
                    .clone();
                let scene = bench_scene(walls, bunny);
                let ctx = showcase_render::gpu::GpuContext::new_headless()?;
                eprintln!("bench render on {}", ctx.describe());
                let mut opts = BenchOptions::default();
                if let Some(f) = args.frames {
                    opts.frames = f as usize;
                }
                if !args.sizes.is_empty() {
                    opts.sizes = args
                        .sizes
                        .iter()
                        .map(|s| parse_size(s))
                        .collect::<Result<_>>()?;
                }
                if let Some(r) = args.shadow_res {
                    anyhow::ensure!(
                        (1..=16384).contains(&r),
                        "--shadow-res {r}: must be 1 to 16384 texels"
                    );
                    opts.shadow_res = r;
                }
                opts.accuracy = !args.no_accuracy;
                if args.floor {
                    let records =
                        showcase_render::render::bench::floor::bench_floor(&ctx, &scene, &opts)?;
                    return emit_bench(&args, &records);
                }
                let records = bench_render(&ctx, &scene, &opts)?;
                emit_bench(&args, &records)
            }
            BenchTarget::Cluster => {
                let scene = crate::scene_file::load_any(&crate::demo::default_scene())?;
                let nodes: Vec<usize> = if args.nodes.is_empty() {
                    vec![2, 4, 8]
                } else {
                    args.nodes.iter().map(|&n| n as usize).collect()
                };
                let hz = if args.hz.is_empty() {
                    vec![60.0, 120.0]
                } else {
                    args.hz.clone()
                };
                if let Some(bad) = hz
                    .iter()
                    .find(|h| !(h.is_finite() && (1.0..=1000.0).contains(*h)))
                {
                    anyhow::bail!("--hz {bad}: a frame rate must be between 1 and 1000 Hz");
                }
                let records = runtime()?.block_on(crate::cluster::commands::bench_cluster(
                    &scene,
                    args.frames.unwrap_or(600),
                    &nodes,
                    &hz,
                ))?;
                emit_bench(&args, &records)
            }
        },
        Command::Sim(SimCommand::Render(a)) => {
            let (width, height) = parse_size(&a.size)?;
            crate::capture::sim_render_command(
                &a.scene,
                parse_vec3("--eye", &a.eye)?,
                parse_vec3("--target", &a.target)?,
                parse_vec3("--up", &a.up)?,
                a.fov_deg,
                width,
                height,
                &a.out,
            )?;
            eprintln!("wrote {}", a.out.display());
            Ok(())
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
