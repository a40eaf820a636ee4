//! `showcase-master bench TARGET`: the arguments and one function per
//! target that turns them into the bench's options and emits its records.

use super::{parse_size, runtime};
use crate::scene_file::shared_data;
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use std::path::{Path, PathBuf};

/// What to benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BenchTarget {
    /// Device calibration.
    Calibration,
    /// Reflectance capture.
    Reflectance,
    /// Reflectance capture through a loopback cluster (sim nodes) against
    /// the in-process capture: maps' error and wall time, by method.
    CaptureCluster,
    /// Radiosity.
    Radiosity,
    /// The real-time renderer (both roles also in global mode: variant
    /// `global`, the bench scene's field solved first).
    Render,
    /// The cluster runtime.
    Cluster,
    /// The cluster under faults: hostile tracking datagrams, kill -9 and
    /// SIGSTOP of a node, kill -9 and restart of the master (processes).
    Faults,
    /// Memory over a long run: 4 nodes at 120 Hz, RSS against frames.
    Soak,
    /// The live dashboard's cost: master CPU with it off and on (pairs of
    /// clusters run at the same time, 4 node processes at 120 Hz each), and
    /// eviction to the page's stream.
    Dashboard,
    /// Global illumination: the projectors' maps and the faces' views
    /// (the GPU renderers, or their CPU references without an adapter) in
    /// direct and global mode at one frame of the walk, judged in the
    /// physically complete world; and the live loopback cluster's update
    /// latency and cost in both modes (`--live-frames`).
    Gi,
    /// Photometric consistency: each face calibrated through its beam
    /// splitter by a camera in its observer's place, the recovered
    /// parameters against the simulated devices' truth, and the observers'
    /// CIEDE2000 over whole views and the occluding-occlusion seams,
    /// uncalibrated, calibrated and with the true parameters (global mode,
    /// one frame of the walk).
    Photometric,
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
    /// Frames per configuration (default: 600 for cluster, 30 for render,
    /// 12000 for soak; dashboard: the measured window of each pair, 1200
    /// frames = 10 s at 120 Hz; gi and photometric: the one frame of the walk judged, 60).
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
    /// reference, gathered, sweep, scaling, probes, incremental,
    /// incremental_object, augmented, hierarchical.
    #[arg(long, value_delimiter = ',')]
    pub kinds: Vec<String>,
    /// Radiosity only: the `incremental_object` records to make, as
    /// OBJECT@AREA with OBJECT `short_block` or `small_cube` and AREA the
    /// largest patch in m^2 (default: both at 0.02 and 0.005).
    #[arg(long, value_delimiter = ',')]
    pub object_records: Vec<String>,
    /// Radiosity: timed runs per `incremental_object` record (default 5);
    /// dashboard: pairs of clusters, one with it and one without (default 8).
    #[arg(long)]
    pub repeats: Option<usize>,
    /// Faults and dashboard: the `showcase-node` binary (default: beside
    /// this one).
    #[arg(long)]
    pub node_bin: Option<PathBuf>,
    /// Faults and dashboard: keep the work folder (config, logs, metrics).
    #[arg(long)]
    pub keep: bool,
    /// Gi: the scenes, each `SCENE` or `SCENE@AREA` with AREA the
    /// largest radiosity patch in m^2 (default:
    /// builtin:showcase,builtin:figure3,builtin:showcase@0.0004);
    /// photometric: the scenes (default: builtin:showcase).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<PathBuf>,
    /// Gi and photometric: paths per irradiance-cache point of the
    /// complete views (default: the demo's; gi then raises them four-fold,
    /// up to 16 times, while the truth's noise is over a third of global
    /// mode's camera figure, and each record says how many it used).
    #[arg(long, value_parser = clap::value_parser!(u32).range(8..))]
    pub truth_paths: Option<u32>,
    /// Gi only: also judge the projectors' maps without occlusion shadows.
    #[arg(long)]
    pub without_occlusion: bool,
    /// Gi only: frames of the live loopback cluster per mode, direct and
    /// global side by side (default 600 at 60 Hz; 0: offline figures only).
    #[arg(long)]
    pub live_frames: Option<u64>,
}

/// Run the bench `args.target` names, with its progress on a terminal: a
/// bar of its configurations where it has a fixed list (calibration,
/// reflectance, cluster), else a spinner with the time so far (radiosity
/// says which records it is making); a line says when it starts. `faults`
/// and `soak` print a line per step or per tenth of the frames instead, so
/// no bar overdraws them.
pub(super) fn bench(args: &BenchArgs) -> Result<()> {
    let name = format!("bench {:?}", args.target).to_lowercase();
    eprintln!("{name}: running (release builds only give meaningful times)...");
    let pb = match args.target {
        BenchTarget::Faults | BenchTarget::Soak | BenchTarget::Dashboard => {
            indicatif::ProgressBar::hidden()
        }
        _ => crate::progress::spinner(name, None),
    };
    let result = match args.target {
        BenchTarget::Calibration => calibration(args, &pb),
        BenchTarget::Reflectance => reflectance(args, &pb),
        BenchTarget::CaptureCluster => super::capture_cluster::bench(args, &pb),
        BenchTarget::Radiosity => radiosity(args, &pb),
        BenchTarget::Render => render(args, &pb),
        BenchTarget::Cluster => cluster(args, &pb),
        BenchTarget::Faults => faults(args, &pb),
        BenchTarget::Soak => soak(args, &pb),
        BenchTarget::Dashboard => dashboard(args, &pb),
        BenchTarget::Gi => gi(args, &pb),
        BenchTarget::Photometric => photometric(args, &pb),
    };
    pb.finish_and_clear();
    result
}

/// Turn the spinner `pb` into a bar of `len` steps.
fn as_bar(pb: &indicatif::ProgressBar, len: u64) {
    pb.set_style(crate::progress::bar_style());
    pb.set_length(len);
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

/// Clear the progress `pb`, then print a bench's records as one JSON
/// array, or write them as a report.
/// [`emit_bench`], for the targets' own modules.
pub(super) fn emit<T: serde::Serialize>(
    args: &BenchArgs,
    pb: &indicatif::ProgressBar,
    records: &[T],
) -> Result<()> {
    emit_bench(args, pb, records)
}

fn emit_bench<T: serde::Serialize>(
    args: &BenchArgs,
    pb: &indicatif::ProgressBar,
    records: &[T],
) -> Result<()> {
    pb.finish_and_clear();
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
        let index = crate::bench_report::write_index(
            &args.out,
            &format!("showcase-master bench {:?}", args.target).to_lowercase(),
            &machine(),
        )
        .with_context(|| format!("cannot write the index of {}", args.out.display()))?;
        eprintln!("wrote {}", index.display());
    }
    Ok(())
}

fn calibration(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    use crate::calibrate::structured_light::{SIM_SAMPLES, StructuredLightOptions, bench};
    let scene = crate::scene_file::load_any(&crate::demo::default_scene())?;
    let sweep = crate::calibrate::BENCH_CONFIGURATIONS;
    as_bar(pb, (sweep + 3 * scene.projectors.len()) as u64);
    let mut records = crate::calibrate::bench_calibration_with(&|k, what| {
        pb.set_position(k as u64);
        pb.set_message(what.to_string());
    });
    records.extend(bench::bench_showcase(
        &scene,
        &StructuredLightOptions::default(),
        SIM_SAMPLES,
        &|k, what| {
            pb.set_position((sweep + k) as u64);
            pb.set_message(what.to_string());
        },
    )?);
    if !args.json {
        crate::calibrate::write_bench_report(&records, &args.out)
            .with_context(|| format!("cannot write the report to {}", args.out.display()))?;
    }
    emit_bench(args, pb, &records)
}

fn reflectance(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    let opts = crate::capture::bench::BenchOptions {
        cornell: shared_data("cornell-box.obj"),
        progress: pb.clone(),
        ..Default::default()
    };
    as_bar(pb, opts.configurations());
    let records = crate::capture::bench_reflectance(&opts)?;
    if !args.json {
        crate::capture::write_report(&records, &args.out)?;
    }
    emit_bench(args, pb, &records)
}

fn radiosity(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    use crate::radiosity_job::bench::{ObjectRecords, bench_radiosity_kinds};
    let objects = ObjectRecords::parse(&args.object_records, args.repeats)?;
    let records = bench_radiosity_kinds(
        &shared_data("cornell-box.obj"),
        &args.kinds,
        &objects,
        &|kind| pb.set_message(format!("{kind} records")),
    )?;
    if !args.json {
        crate::radiosity_job::report::write_report(&records, &args.out, &machine())?;
    }
    emit_bench(args, pb, &records)
}

/// The render bench's options from the flags (the renderer's defaults for
/// what is not given).
fn render_options(args: &BenchArgs) -> Result<showcase_render::render::bench::BenchOptions> {
    let mut opts = showcase_render::render::bench::BenchOptions::default();
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
    Ok(opts)
}

/// The global-illumination field of the render bench's scene at its
/// first frame, for the projector and face variant `global`.
fn render_bench_field(
    scene: &showcase_proto::Showcase,
    pb: &indicatif::ProgressBar,
) -> Result<std::sync::Arc<showcase_light::render::IndirectField>> {
    use showcase_render::render::bench::{bench_frame, bench_projector};
    let mut s = scene.clone();
    s.projectors = vec![bench_projector(640, 480)];
    let frame = showcase_light::render::FrameScene::resolve(&s, &bench_frame(&s, "full", 0))?;
    let t = std::time::Instant::now();
    let (field, elements) = crate::radiosity_job::indirect_field(
        &frame.showcase,
        &frame.eyes,
        &crate::radiosity_job::RadiosityOptions::default(),
    )?;
    pb.suspend(|| {
        eprintln!(
            "global variant: correction of {elements} elements solved in {:.1} s",
            t.elapsed().as_secs_f64()
        )
    });
    Ok(std::sync::Arc::new(field))
}

fn render(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    use showcase_render::render::bench::{bench_render, floor::bench_floor};
    let scene = crate::render_bench::bench_scene(
        &shared_data("cornell-box.obj"),
        &shared_data("bunny.obj"),
    )?;
    let ctx = showcase_render::gpu::GpuContext::new_headless()?;
    pb.suspend(|| eprintln!("bench render on {}", ctx.describe()));
    let mut opts = render_options(args)?;
    if args.floor {
        return emit_bench(args, pb, &bench_floor(&ctx, &scene, &opts)?);
    }
    opts.indirect = Some(render_bench_field(&scene, pb)?);
    let records = bench_render(&ctx, &scene, &opts)?;
    if !args.json {
        let plot = crate::render_bench::error_vs_time_plot(&records);
        if !plot.series.is_empty() {
            std::fs::create_dir_all(&args.out)
                .with_context(|| format!("cannot create {}", args.out.display()))?;
            let path = args.out.join("render.svg");
            std::fs::write(&path, plot.to_svg())
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    emit_bench(args, pb, &records)
}

fn cluster(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
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
    as_bar(pb, (nodes.len() * hz.len()) as u64);
    let records = runtime()?.block_on(crate::cluster::commands::bench_cluster(
        &scene,
        args.frames.unwrap_or(600),
        &nodes,
        &hz,
        &|n, hz| {
            pb.inc(1);
            pb.suspend(|| eprintln!("bench cluster: {n} nodes at {hz} Hz done"));
        },
    ))?;
    emit_bench(args, pb, &records)
}

fn faults(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    let record = crate::cluster::faults::bench_faults(&crate::cluster::faults::FaultOptions {
        scene: crate::demo::default_scene(),
        node_bin: args.node_bin.clone(),
        keep: args.keep,
    })?;
    emit_bench(args, pb, &[record])
}

fn soak(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    let scene = crate::scene_file::load_any(&crate::demo::default_scene())?;
    let frames = args.frames.unwrap_or(12_000);
    anyhow::ensure!(
        frames >= 100,
        "--frames {frames}: a soak needs at least 100 frames"
    );
    let record = runtime()?.block_on(crate::cluster::soak::bench_soak(&scene, frames))?;
    emit_bench(args, pb, &[record])
}

fn dashboard(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    use crate::cluster::dashboard::bench::{DashboardBenchOptions, bench_dashboard};
    let frames = args.frames.unwrap_or(1200);
    anyhow::ensure!(
        (120..=720_000).contains(&frames),
        "--frames {frames}: the window must be 120 to 720000 frames (1 s to 100 min at 120 Hz)"
    );
    let pairs = args.repeats.unwrap_or(8);
    anyhow::ensure!(
        (1..=100).contains(&pairs),
        "--repeats {pairs}: 1 to 100 pairs of clusters"
    );
    let record = bench_dashboard(&DashboardBenchOptions {
        scene: crate::demo::default_scene(),
        node_bin: args.node_bin.clone(),
        pairs,
        window: std::time::Duration::from_secs_f64(frames as f64 / 120.0),
        keep: args.keep,
    })?;
    emit_bench(args, pb, &[record])
}

/// A `bench gi` scene, `SCENE` or `SCENE@AREA` (the largest radiosity
/// patch of global mode's solution, m^2).
fn gi_scene_entry(entry: &Path) -> Result<(PathBuf, Option<f64>)> {
    let text = entry.to_string_lossy();
    let Some((scene, area)) = text.rsplit_once('@') else {
        return Ok((entry.to_path_buf(), None));
    };
    let area: f64 = area.parse().ok().filter(|a: &f64| a.is_finite() && *a > 0.0).with_context(|| {
        format!("{text}: after '@' comes the largest patch area in m^2, a positive number such as 0.0004")
    })?;
    Ok((PathBuf::from(scene), Some(area)))
}

/// How far `bench gi` may raise the demo's truth paths, as a factor.
const MAX_TRUTH_RAISE: u32 = 16;

fn gi(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    use crate::demo::gi::{GiBenchOptions, bench_gi_scene};
    // The demo scene also at about 20,000 elements, to show how the cost
    // grows (18,159 at 0.0004 m^2 patches, against 11,988 by default).
    let scenes = if args.scenes.is_empty() {
        vec![
            PathBuf::from("builtin:showcase"),
            PathBuf::from("builtin:figure3"),
            PathBuf::from("builtin:showcase@0.0004"),
        ]
    } else {
        args.scenes.clone()
    };
    let mut records = Vec::new();
    for entry in &scenes {
        let (scene, patch_area) = gi_scene_entry(entry)?;
        let options = GiBenchOptions {
            frame: args.frames.unwrap_or(60),
            truth_paths: args.truth_paths.unwrap_or(crate::demo::TRUTH_PATHS),
            // Given paths are kept as they are.
            max_truth_paths: args
                .truth_paths
                .unwrap_or(MAX_TRUTH_RAISE * crate::demo::TRUTH_PATHS),
            without_occlusion: args.without_occlusion,
            live_frames: args.live_frames.unwrap_or(600),
            patch_area,
        };
        pb.set_message(format!("{}", entry.display()));
        records.extend(
            bench_gi_scene(&scene, &options)
                .with_context(|| format!("bench gi on {}", entry.display()))?,
        );
    }
    emit_bench(args, pb, &records)
}

fn photometric(args: &BenchArgs, pb: &indicatif::ProgressBar) -> Result<()> {
    use crate::demo::photometric::{NOMINAL_GAMMA, bench_photometric_scene};
    let scenes = if args.scenes.is_empty() {
        vec![PathBuf::from("builtin:showcase")]
    } else {
        args.scenes.clone()
    };
    let mut records = Vec::new();
    for scene in &scenes {
        pb.set_message(format!("{}", scene.display()));
        let truth = crate::scene_file::load_any(scene)?;
        // The nodes know the devices' geometry but not their photometry:
        // they start from a nominal CRT behind an ideal combiner, and from
        // the projectors' model.
        let mut nodes = truth.clone();
        for f in &mut nodes.faces {
            f.photometry = showcase_proto::CrtPhotometry::nominal(NOMINAL_GAMMA);
        }
        for p in &mut nodes.projectors {
            p.response.photometry = None;
        }
        let (_, record) = bench_photometric_scene(
            &truth,
            &nodes,
            args.frames.unwrap_or(60),
            args.truth_paths.unwrap_or(crate::demo::TRUTH_PATHS),
        )
        .with_context(|| format!("bench photometric on {}", scene.display()))?;
        records.push(record);
    }
    emit_bench(args, pb, &records)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gi_scenes_may_name_their_largest_patch() {
        let entry = |s: &str| gi_scene_entry(Path::new(s));
        assert_eq!(
            entry("builtin:showcase@0.0004").unwrap(),
            (PathBuf::from("builtin:showcase"), Some(0.0004))
        );
        assert_eq!(
            entry("scenes/a.toml").unwrap(),
            (PathBuf::from("scenes/a.toml"), None)
        );
        for bad in ["builtin:showcase@", "x@-1", "x@abc", "x@inf"] {
            let e = format!("{:#}", entry(bad).unwrap_err());
            assert!(e.contains(bad) && e.contains("positive"), "{bad}: {e}");
        }
    }
}
