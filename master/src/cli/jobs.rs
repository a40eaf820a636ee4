//! The job subcommands' arguments (`demo`, `run`, `check`, `calibrate`, `capture`,
//! `radiosity`, `replay`, `certs`) and how each becomes a library call.

use super::runtime;
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// Arguments of `demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "showcase-out")]
    pub out: PathBuf,
    /// Frames of the interactive stage.
    #[arg(long, default_value_t = 240)]
    pub frames: u64,
    /// Scene file, or a built-in scene (`builtin:showcase`, the default
    /// demo cabinet; `builtin:figure3`; `builtin:cornell`). Every phase
    /// runs on it; one it cannot support is skipped with the reason.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Paths per irradiance-cache point of the physically complete ground
    /// truth (every bounce, path-traced by the simulated showcase); its
    /// noise is in the report (`ground_truth_noise_rel_rmse`,
    /// `compared_noise_rel_rmse`) and falls about as 1/sqrt(paths).
    #[arg(long, default_value_t = crate::demo::TRUTH_PATHS, value_parser = clap::value_parser!(u32).range(8..))]
    pub truth_paths: u32,
}

impl From<DemoArgs> for crate::demo::DemoOptions {
    fn from(a: DemoArgs) -> Self {
        Self {
            out: a.out,
            frames: a.frames,
            scene: a.scene,
            truth_paths: a.truth_paths,
        }
    }
}

/// Arguments of `run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Cluster configuration (see deploy/).
    #[arg(long)]
    pub config: PathBuf,
    /// Captured reflectance maps to start with: every map in this folder
    /// (what `capture --out DIR` wrote). The nodes get them in their
    /// snapshot; in global mode a real object whose material names one
    /// (`reflectance_map`) is solved with its reflectance.
    #[arg(long, value_name = "DIR")]
    pub maps: Option<PathBuf>,
    /// Write one JSON line of measurements per frame to this file.
    #[arg(long)]
    pub metrics: Option<PathBuf>,
    /// Record every tracking datagram to this session file.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Serve the live dashboard (page, /api/state, /metrics) on this
    /// address, e.g. 127.0.0.1:8080 (port 0: any free port, printed).
    #[arg(long, value_name = "HOST:PORT")]
    pub dashboard: Option<std::net::SocketAddr>,
    /// Allow a dashboard address other than loopback; needs an access token.
    #[arg(long, requires = "dashboard")]
    pub dashboard_public: bool,
    /// The dashboard's access token (at least 16 characters); better set in
    /// $SHOWCASE_DASHBOARD_TOKEN, out of the process list. Every request
    /// then needs `Authorization: Bearer TOKEN` or `?token=TOKEN`.
    #[arg(long, requires = "dashboard", value_name = "TOKEN")]
    pub dashboard_token: Option<String>,
}

impl RunArgs {
    /// The dashboard's options, the token from the flag or the environment.
    fn dashboard(&self) -> Option<crate::cluster::dashboard::DashboardOptions> {
        use crate::cluster::dashboard::{DashboardOptions, TOKEN_ENV};
        Some(DashboardOptions {
            addr: self.dashboard?,
            public: self.dashboard_public,
            token: self
                .dashboard_token
                .clone()
                .or_else(|| std::env::var(TOKEN_ENV).ok().filter(|t| !t.is_empty())),
        })
    }
}

/// `run`: the live master of a cluster.
pub(super) fn run_master(args: &RunArgs) -> Result<()> {
    runtime()?.block_on(crate::cluster::commands::run_master(
        &args.config,
        args.maps.as_deref(),
        args.metrics.as_deref(),
        args.record.as_deref(),
        args.dashboard().as_ref(),
    ))
}

/// Arguments of `check`.
#[derive(Debug, Args)]
pub struct CheckArgs {
    /// Cluster configuration (see deploy/).
    #[arg(long)]
    pub config: PathBuf,
}

/// `check`: print every problem of a cluster config and what it names
/// (exit 1), or a short summary of what was checked (exit 0).
pub(super) fn check(args: &CheckArgs) -> Result<()> {
    let report = crate::cluster::check::check_cluster(&args.config);
    for p in &report.problems {
        println!("{p}");
    }
    if !report.problems.is_empty() {
        anyhow::bail!(
            "{} problem{} in {}: fix {} and run check again",
            report.problems.len(),
            if report.problems.len() == 1 { "" } else { "s" },
            args.config.display(),
            if report.problems.len() == 1 {
                "it"
            } else {
                "them"
            }
        );
    }
    println!("ok: {}", report.checked.join("; "));
    Ok(())
}

/// Calibration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CalibrationMethod {
    /// DLT + RQ start, Levenberg-Marquardt refinement.
    Lm,
    /// The paper's baseline: Powell's direction-set method.
    Powell,
}

impl From<CalibrationMethod> for crate::calibrate::Method {
    fn from(m: CalibrationMethod) -> Self {
        match m {
            CalibrationMethod::Lm => Self::Lm,
            CalibrationMethod::Powell => Self::Powell,
        }
    }
}

/// Arguments of `calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Input correspondences (JSON), for a projector or camera.
    #[arg(long, required_unless_present_any = ["photometric", "structured_light"])]
    pub points: Option<PathBuf>,
    /// Output calibration (JSON); with `--photometric` a folder, which
    /// gets one `<face>-photometric.json` per face, one
    /// `<projector>-photometric.json` per projector and `summary.json`;
    /// with `--structured-light` a folder, which gets one
    /// `<projector>.json` per projector (the file `--points` writes) and
    /// `summary.json`.
    #[arg(long)]
    pub out: PathBuf,
    /// Solver.
    #[arg(long, value_enum, default_value_t = CalibrationMethod::Lm)]
    pub method: CalibrationMethod,
    /// Calibrate the faces and projectors photometrically instead: each
    /// face's CRT and beam splitter, measured by the scene's camera in its
    /// observer's place, and each projector's light per value and channel
    /// by the same camera, as the profile its node encodes with. Runs on the simulated
    /// showcase of `--scene` (no real camera is attached to this build).
    #[arg(long, requires = "scene", conflicts_with = "points")]
    pub photometric: bool,
    /// Calibrate every projector of `--config` by structured light: Gray
    /// codes shown by each projector, decoded from the config's camera
    /// (trusted as calibrated), each decoded pixel a 2D-3D
    /// correspondence on the known scene, solved by DLT + LM. Runs
    /// through the config's nodes: this process listens as its master,
    /// its projector nodes show the patterns, its camera node captures
    /// them (as `capture --config`); with `--sim-in-process`, on an
    /// in-process simulated showcase of the config's scene instead.
    #[arg(long, requires = "config", conflicts_with_all = ["points", "photometric"])]
    pub structured_light: bool,
    /// With `--structured-light`: no nodes, the simulated showcase of the
    /// config's scene in this process.
    #[arg(long, requires = "structured_light")]
    pub sim_in_process: bool,
    /// With `--structured-light` through the nodes: they run in sim mode
    /// (`showcase-node --sim-light`), so each fit is judged against the
    /// scene's projector.
    #[arg(long, requires = "structured_light", conflicts_with = "sim_in_process")]
    pub sim: bool,
    /// With `--structured-light` through the nodes: seconds to wait for
    /// the camera and projector nodes to join.
    #[arg(long, default_value_t = 30)]
    pub wait_s: u64,
    /// With `--structured-light`: the cluster configuration (its scene,
    /// camera node and projector nodes).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// With `--photometric`: the scene, or a built-in one
    /// (`builtin:showcase`); with `--structured-light`, another scene than
    /// the config's.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// With `--structured-light`: camera exposure in seconds (default: the
    /// camera's own), rounded to whole colour-wheel turns.
    #[arg(long)]
    pub exposure: Option<f64>,
    /// With `--structured-light`: the projector's pixel value for lit
    /// pattern pixels, 0 to 1.
    #[arg(long, default_value_t = 1.0)]
    pub level: f32,
    /// With `--structured-light`: camera frames averaged per pattern.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub frames: u32,
    /// With `--structured-light --sim-in-process`: paths per camera pixel
    /// of the simulated showcase's light transport (a full-white pattern).
    #[arg(long, default_value_t = crate::calibrate::structured_light::SIM_SAMPLES, value_parser = clap::value_parser!(u32).range(1..))]
    pub sim_samples: u32,
    /// With `--photometric`: paths per irradiance-cache point of the
    /// simulated real light.
    #[arg(long, default_value_t = crate::demo::TRUTH_PATHS, value_parser = clap::value_parser!(u32).range(8..))]
    pub truth_paths: u32,
}

/// `calibrate`: fit one device and report its residual, or (with
/// `--photometric`) the faces' and projectors' profiles.
pub(super) fn calibrate(args: &CalibrateArgs) -> Result<()> {
    if args.structured_light {
        return calibrate_structured_light(args);
    }
    if args.photometric {
        let scene = args
            .scene
            .as_deref()
            .context("--photometric needs --scene")?;
        return crate::demo::photometric::run_calibrate_photometric(
            scene,
            &args.out,
            args.truth_paths,
        );
    }
    let points = args
        .points
        .as_deref()
        .context("give --points (fiducial correspondences) or --photometric")?;
    let c = crate::calibrate::run_calibrate_file(points, &args.out, args.method.into())?;
    eprintln!(
        "calibrated {} from {} points: rms {:.4} px; wrote {}",
        points.display(),
        c.residuals_px.len(),
        c.rms_px,
        args.out.display()
    );
    Ok(())
}

/// `calibrate --structured-light`: a bar per projector, a line per
/// projector, the files.
fn calibrate_structured_light(args: &CalibrateArgs) -> Result<()> {
    use crate::calibrate::structured_light::{
        StructuredLightJob, StructuredLightOptions, ThroughNodes, run_config_structured_light,
        run_structured_light,
    };
    if let Some(e) = args.exposure
        && !(e > 0.0 && e.is_finite())
    {
        anyhow::bail!("--exposure {e} must be a positive number of seconds");
    }
    if !(args.level > 0.0 && args.level <= 1.0) {
        anyhow::bail!("--level {} must be in (0, 1]", args.level);
    }
    let job = StructuredLightJob {
        config: args
            .config
            .clone()
            .context("--structured-light needs --config")?,
        scene: args.scene.clone(),
        out: args.out.clone(),
        options: StructuredLightOptions {
            exposure_s: args.exposure,
            frames: args.frames,
            level: args.level,
            ..StructuredLightOptions::default()
        },
        sim_samples: args.sim_samples,
    };
    let bars = std::sync::Mutex::new(None::<(String, indicatif::ProgressBar)>);
    let lines = crate::progress::LogLines::default();
    let progress = |name: &str, done: usize, total: usize, what: &str| {
        let mut bars = bars.lock().unwrap_or_else(|e| e.into_inner());
        if bars.as_ref().is_none_or(|(n, _)| n != name) {
            if let Some((_, pb)) = bars.take() {
                pb.finish_and_clear();
            }
            let pb = crate::progress::bar(format!("structured light {name}"), total as u64);
            *bars = Some((name.to_string(), pb));
        }
        if let Some((_, pb)) = bars.as_ref() {
            pb.set_position(done as u64);
            pb.set_message(what.to_string());
        }
        lines.say(|| format!("calibrate: {name}: {done}/{total} patterns ({what})"));
    };
    let summary = if args.sim_in_process {
        run_structured_light(&job, &progress)
    } else {
        let nodes = ThroughNodes {
            wait: std::time::Duration::from_secs(args.wait_s.max(1)),
            sim: args.sim,
        };
        run_config_structured_light(&job, &nodes, &|s| eprintln!("calibrate: {s}..."), &progress)
    };
    if let Some((_, pb)) = bars.lock().unwrap_or_else(|e| e.into_inner()).take() {
        pb.finish_and_clear();
    }
    let summary = summary?;
    for p in &summary.projectors {
        let o = &p.outcome;
        eprintln!(
            "calibrated {} by structured light: {} patterns, {} of {} lit camera pixels decoded, {} correspondences ({} outliers dropped), fit rms {:.3} px, held-out {:.3} px (decoded){}, in {:.1} s; wrote {}{}",
            p.device,
            o.patterns,
            o.valid_pixels,
            o.lit_pixels,
            o.fit_points,
            o.outliers,
            o.calibration.rms_px,
            o.heldout_rms_px,
            if p.sim_true_heldout_px >= 0.0 {
                format!(
                    ", {:.3} px against the sim's true projector",
                    p.sim_true_heldout_px
                )
            } else {
                String::new()
            },
            p.seconds,
            p.file.display(),
            match &p.node_reads {
                Some(f) if f != &p.file => format!(" (its node reads {})", f.display()),
                _ => String::new(),
            }
        );
    }
    eprintln!(
        "calibrate: {} projectors seen by {} in {:.1} s; wrote {}",
        summary.projectors.len(),
        summary.camera,
        summary.seconds,
        args.out.join("summary.json").display()
    );
    Ok(())
}

/// Arguments of `capture`.
#[derive(Debug, Args)]
pub struct CaptureArgs {
    /// Scene file.
    #[arg(long, required_unless_present = "config")]
    pub scene: Option<PathBuf>,
    /// Capture through the cluster of this configuration: its master
    /// listens, its projector and camera nodes (those of the scene's
    /// projector 0 and camera 0) show and capture; the maps are published
    /// to the running nodes. With `--sim` the nodes run with `--sim-light`.
    #[arg(long, conflicts_with = "scene")]
    pub config: Option<PathBuf>,
    /// With `--config`: `naive`, `piecewise`, `corrected` or `all`.
    #[arg(long)]
    pub method: Option<String>,
    /// With `--config`: frames averaged per radiance map.
    #[arg(long, default_value_t = 16)]
    pub frames: u32,
    /// With `--config`: seconds to wait for the nodes to join.
    #[arg(long, default_value_t = 30)]
    pub wait_s: u64,
    /// Capture from the simulated showcase.
    #[arg(long)]
    pub sim: bool,
    /// Output folder for the reflectance maps and summary.
    #[arg(long)]
    pub out: PathBuf,
    /// Also print the summary (written to `<out>/summary.json`) on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `capture --sim`: the capture job with its default options.
pub(super) fn capture(args: &CaptureArgs) -> Result<()> {
    if let Some(config) = &args.config {
        return super::capture_cluster::capture(args, config);
    }
    if !args.sim {
        anyhow::bail!(
            "capture: only --sim (the simulated showcase) is available; real projector and camera drivers are not part of this build"
        );
    }
    let scene = crate::scene_file::load_any(args.scene.as_deref().context("give --scene")?)?;
    let stages = crate::capture::CAPTURE_STAGES.len() as u64;
    let pb = crate::progress::bar("capture", stages);
    let to_log = !std::io::IsTerminal::is_terminal(&std::io::stderr());
    let summary = crate::capture::run_capture_staged(
        &scene,
        &args.out,
        &crate::capture::CaptureOptions::default(),
        &|i, name| {
            pb.set_position(i as u64);
            pb.set_message(name.to_string());
            if to_log {
                eprintln!("capture: stage {}/{stages}: {name}...", i + 1);
            }
        },
    );
    pb.finish_and_clear();
    let summary = summary?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    }
    eprintln!(
        "capture: {} frames, rel RMSE {:.4} against the sim's albedo over {:.0}% of the object pixels, in {:.1} s; wrote {}",
        summary.frames,
        summary.rel_rmse,
        100.0 * summary.coverage,
        summary.seconds.total,
        args.out.join("summary.json").display()
    );
    Ok(())
}

/// Arguments of `radiosity`.
#[derive(Debug, Args)]
pub struct RadiosityArgs {
    /// Scene file (TOML, or an OBJ such as the Cornell box) or built-in
    /// scene (`builtin:figure3`).
    #[arg(long)]
    pub scene: PathBuf,
    /// Output folder (the solution, the maps and `summary.json`).
    #[arg(long)]
    pub out: PathBuf,
    /// Largest patch area in square metres (default: the scene's
    /// `patch_area`, else 0.01).
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
    /// `auto` (hierarchical above 4,000 elements), `progressive` (with a
    /// final gather; cost grows as the square of the elements) or
    /// `hierarchical` (with clustering; about linear).
    #[arg(long, default_value = "auto")]
    pub solver: crate::radiosity_job::Solver,
    /// Hierarchical solver: refine a link while its estimated error may
    /// exceed this fraction of the injected power (smaller: more links,
    /// more accurate, slower).
    #[arg(long)]
    pub epsilon: Option<f64>,
    /// Hierarchical solver: memory it may use, in MB (default: 80 % of
    /// the available memory). A mesh that cannot fit is refused before
    /// solving, with the estimate.
    #[arg(long)]
    pub max_memory_mb: Option<f64>,
    /// Hierarchical solver: stop gathering after this many seconds and
    /// write what it has (the summary says `complete: false`).
    #[arg(long)]
    pub time_budget: Option<f64>,
    /// Also print the summary (written to `<out>/summary.json`) on stdout.
    #[arg(long)]
    pub json: bool,
}

impl From<&RadiosityArgs> for crate::radiosity_job::RadiosityOptions {
    fn from(a: &RadiosityArgs) -> Self {
        Self {
            max_patch_area: a.max_patch_area,
            hemicube: a.hemicube,
            threshold: a.threshold,
            solver: a.solver,
            epsilon: a.epsilon,
            max_memory_mb: a.max_memory_mb,
            ..Default::default()
        }
    }
}

/// `radiosity`: solve a scene, with the shots and the unshot energy as
/// progress; the summary goes to `<out>/summary.json` (and to stdout with
/// `--json`), and one line says what was done and where.
pub(super) fn radiosity(args: &RadiosityArgs) -> Result<()> {
    let pb = crate::progress::spinner("radiosity", Some("shots"));
    let mut options: crate::radiosity_job::RadiosityOptions = args.into();
    options.progress = crate::progress::radiosity_shots(&pb, "radiosity");
    let budget = match args.time_budget {
        Some(s) if !(s > 0.0 && s.is_finite()) => {
            anyhow::bail!("--time-budget {s} must be a positive number of seconds")
        }
        s => s.map(std::time::Duration::from_secs_f64),
    };
    options.hierarchy_progress = crate::progress::radiosity_gathers(&pb, "radiosity", budget);
    eprintln!("radiosity: solving {}...", args.scene.display());
    let summary =
        crate::radiosity_job::run_radiosity_on(&args.scene, &args.out, &options, args.form_factors);
    pb.finish_and_clear();
    let summary = summary?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    }
    eprintln!(
        "radiosity: {} solver{}, {} patches, {} elements, {} links, {} {} to {:.4} {} in {:.1} s ({:.1} s solving, the rest the irradiance maps); wrote {} ({}, {} irradiance maps, {} light maps)",
        summary.solver,
        if summary.complete {
            ""
        } else {
            " (stopped by the time budget)"
        },
        summary.patches,
        summary.elements,
        summary.links,
        summary.shots,
        if summary.solver == "hierarchical" {
            "gathers"
        } else {
            "shots"
        },
        summary.unshot_fraction,
        if summary.solver == "hierarchical" {
            "residual"
        } else {
            "unshot"
        },
        summary.seconds,
        summary.solve_seconds,
        args.out.join("summary.json").display(),
        summary.solution.display(),
        summary.irradiance_maps.len(),
        summary.light_maps.len()
    );
    Ok(())
}

/// Arguments of `replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// Recorded session file (`demo` writes one: `showcase-out/session.jsonl`).
    #[arg(long)]
    pub session: PathBuf,
    /// Scene file or built-in scene (default: `builtin:showcase`, the demo
    /// cabinet).
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

/// `replay`: drive the cluster from a recording; print each node's digest.
pub(super) fn replay(args: &ReplayArgs) -> Result<()> {
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

/// `certs`: write the cluster CA and the nodes' certificates.
pub(super) fn certs(args: &CertsArgs) -> Result<()> {
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
