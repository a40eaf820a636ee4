//! `showcase-camera`: the real camera's setup tool. Lists what a V4L2
//! camera offers, records frames with manual exposure and gain into a
//! recorded-camera folder (checking the first frame's levels), and checks
//! a recorded folder offline. The V4L2 commands need the `v4l2` feature.

use anyhow::{Result, bail};
use clap::{Parser, Subcommand};
use showcase_render::camera::recorded::RecordedCamera;
use showcase_render::camera::{LevelLimits, Levels, Settings, check_levels};
use std::path::PathBuf;
use std::process::ExitCode;

/// Set up and check a real camera for Showcase's capture.
#[derive(Debug, Parser)]
#[command(name = "showcase-camera", version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List the formats, sizes and exposure/gain controls of a V4L2 camera.
    Formats {
        /// The device node.
        #[arg(default_value = "/dev/video0")]
        device: PathBuf,
    },
    /// Record frames from a V4L2 camera into a recorded-camera folder,
    /// with manual exposure and gain; stops when the first frame (of the
    /// white-lit scene) is saturated or dark.
    Record(RecordArgs),
    /// Check a recorded-camera folder: every frame readable, timestamps,
    /// and the first frame's levels (of the white-lit scene).
    Check {
        /// The folder.
        dir: PathBuf,
        /// Skip the level check (a recording of another scene).
        #[arg(long)]
        no_level_check: bool,
    },
}

#[derive(Debug, clap::Args)]
#[cfg_attr(not(all(feature = "v4l2", target_os = "linux")), allow(dead_code))]
struct RecordArgs {
    /// The device node.
    #[arg(default_value = "/dev/video0")]
    device: PathBuf,
    /// Output folder (camera.json and one PNG per frame).
    #[arg(long)]
    out: PathBuf,
    /// Exposure time in milliseconds (manual exposure; 0.1 ms steps).
    #[arg(long)]
    exposure_ms: f64,
    /// The camera's gain control value (`formats` shows its range); left
    /// as it is when not given (auto gain is off either way).
    #[arg(long)]
    gain: Option<i32>,
    /// Fixed white balance in kelvin (auto white balance is off either way).
    #[arg(long)]
    white_balance_k: Option<i32>,
    /// Pixel format (YUYV, MJPG, NV12, ...); the best offered when not given.
    #[arg(long)]
    format: Option<String>,
    /// Frame size WIDTHxHEIGHT, when no --camera gives it.
    #[arg(long)]
    size: Option<String>,
    /// The scene's camera as JSON (`{"name", "device", "response"}`): its
    /// size is asked for and its calibration stored in the recording.
    #[arg(long)]
    camera: Option<PathBuf>,
    /// Frames to record.
    #[arg(long, default_value_t = 10)]
    frames: u32,
    /// Frames per second to ask for.
    #[arg(long)]
    fps: Option<f64>,
    /// Record even when the first frame is saturated or dark.
    #[arg(long)]
    no_level_check: bool,
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("showcase-camera: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Formats { device } => formats(device),
        Command::Record(args) => record(args),
        Command::Check {
            dir,
            no_level_check,
        } => check(dir, no_level_check),
    }
}

fn describe(levels: &Levels) -> String {
    format!(
        "peak code {} of {} ({:.0} %), {:.3} % of the pixels saturated",
        levels.peak,
        levels.top,
        f64::from(levels.peak) / f64::from(levels.top.max(1)) * 100.0,
        levels.saturated_fraction * 100.0
    )
}

fn check(dir: PathBuf, no_level_check: bool) -> Result<()> {
    let mut cam = RecordedCamera::open(&dir)?;
    let index = cam.index().clone();
    println!(
        "{}: {} frames of {}x{}, {} bits",
        dir.display(),
        index.frames.len(),
        index.device.width,
        index.device.height,
        index.bits
    );
    let limits = LevelLimits::default();
    let mut previous: Option<f64> = None;
    for k in 0..index.frames.len() {
        let f = cam.next_frame()?;
        let levels = Levels::of(&f.frame, limits.peak_quantile);
        let interval = previous.map_or(String::new(), |p| {
            format!(", {:.1} ms after the previous", (f.timestamp_s - p) * 1e3)
        });
        previous = Some(f.timestamp_s);
        println!(
            "  frame {k} (#{}): t = {:.4} s{interval}, exposure {:.2} ms, {}",
            f.sequence,
            f.timestamp_s,
            f.exposure_s * 1e3,
            describe(&levels)
        );
        if k == 0 && !no_level_check {
            let settings = Settings {
                exposure_s: f.exposure_s,
                gain: None,
            };
            check_levels(&f.frame, &limits, settings)?;
        }
    }
    println!("ok");
    Ok(())
}

#[cfg(not(all(feature = "v4l2", target_os = "linux")))]
fn formats(_device: PathBuf) -> Result<()> {
    bail!("this showcase-camera was built without V4L2: build it with `--features v4l2` (Linux)")
}

#[cfg(not(all(feature = "v4l2", target_os = "linux")))]
fn record(_args: RecordArgs) -> Result<()> {
    bail!("this showcase-camera was built without V4L2: build it with `--features v4l2` (Linux)")
}

#[cfg(all(feature = "v4l2", target_os = "linux"))]
fn formats(device: PathBuf) -> Result<()> {
    use showcase_render::camera::v4l2;
    let info = v4l2::list(&device)?;
    println!(
        "{}: '{}' (driver {}, {})",
        info.path.display(),
        info.card,
        info.driver,
        info.bus
    );
    println!("formats:");
    for f in &info.formats {
        println!("  {f}");
    }
    println!("controls (min..max step, default, now):");
    for c in &info.controls {
        let now = c.value.map_or("?".to_string(), |v| v.to_string());
        println!(
            "  {}: {}..{} step {}, default {}, now {now}",
            c.name, c.min, c.max, c.step, c.default
        );
    }
    Ok(())
}

#[cfg(all(feature = "v4l2", target_os = "linux"))]
fn record(args: RecordArgs) -> Result<()> {
    use anyhow::Context;
    use showcase_proto::{Camera, CameraResponse, PinholeDevice};
    use showcase_render::camera::decode::PixelFormat;
    use showcase_render::camera::recorded::Recorder;
    use showcase_render::camera::v4l2::{V4l2Camera, V4l2Config};

    let exposure_s = args.exposure_ms * 1e-3;
    if !(exposure_s.is_finite() && exposure_s > 0.0) {
        bail!("--exposure-ms {} must be a positive time", args.exposure_ms);
    }
    let (device, mut response) = match (&args.camera, &args.size) {
        (Some(path), _) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            let camera: Camera = serde_json::from_str(&text)
                .with_context(|| format!("{}: not a scene camera", path.display()))?;
            (camera.device, camera.response)
        }
        (None, Some(size)) => {
            let (w, h) = size
                .split_once(['x', 'X'])
                .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
                .with_context(|| format!("--size {size}: expected WIDTHxHEIGHT"))?;
            // Uncalibrated: a 60° placeholder until the geometric and
            // photometric calibrations replace it.
            let device = PinholeDevice::look_at(
                glam::DVec3::ZERO,
                glam::DVec3::Z,
                glam::DVec3::NEG_Y,
                60.0,
                w,
                h,
            );
            (device, CameraResponse::default())
        }
        (None, None) => bail!("give the frame size: --size WIDTHxHEIGHT or --camera FILE"),
    };
    let format = args
        .format
        .as_deref()
        .map(|f| {
            PixelFormat::parse(f).with_context(|| {
                format!("--format {f}: not one of YUYV, UYVY, MJPG, JPEG, NV12, YU12, GREY, Y16, RGB24, BGR24")
            })
        })
        .transpose()?;
    let mut config = V4l2Config::new(&args.device);
    config.format = format;
    config.exposure_s = exposure_s;
    config.gain = args.gain;
    config.white_balance_k = args.white_balance_k;
    config.fps = args.fps;
    config.limits = None;
    let mut cam = V4l2Camera::open(config, device.clone(), response.clone())?;
    response.bits = cam.format().format.bits();
    response.exposure_s = cam.exposure_s() as f32;
    println!(
        "{}: {} at {:.1} frames/s, {}",
        args.device.display(),
        cam.format(),
        1.0 / cam.frame_period_s(),
        cam.settings()
    );
    let mut rec = Recorder::create(&args.out, device, response)?;
    let limits = LevelLimits::default();
    for k in 0..args.frames.max(1) {
        let f = cam.capture_timed()?;
        let levels = Levels::of(&f.frame, limits.peak_quantile);
        println!(
            "  frame {k} (#{}): t = {:.4} s, {}",
            f.sequence,
            f.timestamp_s,
            describe(&levels)
        );
        if k == 0 && !args.no_level_check {
            check_levels(&f.frame, &limits, cam.settings())?;
        }
        rec.push(&f)?;
    }
    let dir = rec.finish()?;
    println!(
        "recorded {} frames in {}",
        args.frames.max(1),
        dir.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;
    use showcase_light::Image;
    use showcase_light::hardware::CameraFrame;
    use showcase_proto::{CameraResponse, PinholeDevice};
    use showcase_render::camera::TimedFrame;
    use showcase_render::camera::recorded::Recorder;

    #[test]
    fn the_command_line_is_well_formed() {
        Cli::command().debug_assert();
    }

    /// A one-frame recording whose pixels are `code(x)` on 64x48.
    fn recording(name: &str, code: impl Fn(u32) -> u16) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("showcase-camera-cli-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let device = PinholeDevice::look_at(
            glam::DVec3::ZERO,
            glam::DVec3::Z,
            glam::DVec3::NEG_Y,
            60.0,
            64,
            48,
        );
        let mut rec = Recorder::create(&dir, device, CameraResponse::default()).unwrap();
        rec.push(&TimedFrame {
            frame: CameraFrame {
                codes: Image::from_fn(64, 48, |x, _| [code(x); 3]),
                bits: 8,
            },
            timestamp_s: 1.0,
            start_of_exposure: false,
            sequence: 7,
            exposure_s: 0.02,
        })
        .unwrap();
        rec.finish().unwrap()
    }

    #[test]
    fn check_passes_a_good_recording_and_names_what_to_change() {
        let good = recording("good", |x| (x * 3 + 40) as u16);
        check(good.clone(), false).unwrap();
        let dark = recording("dark", |x| x as u16);
        let e = check(dark.clone(), false).unwrap_err().to_string();
        assert!(
            e.contains("dark frame") && e.contains("raise the exposure"),
            "{e}"
        );
        check(dark.clone(), true).unwrap();
        let bright = recording("bright", |x| if x < 8 { 255 } else { 200 });
        let e = check(bright.clone(), false).unwrap_err().to_string();
        assert!(
            e.contains("saturated frame") && e.contains("lower the exposure"),
            "{e}"
        );
        for dir in [good, dark, bright] {
            std::fs::remove_dir_all(dir).unwrap();
        }
        let e = check(PathBuf::from("/nonexistent/recording"), false).unwrap_err();
        assert!(e.to_string().contains("camera.json"), "{e}");
    }

    #[cfg(not(all(feature = "v4l2", target_os = "linux")))]
    #[test]
    fn without_v4l2_the_camera_commands_say_how_to_build() {
        let e = formats(PathBuf::from("/dev/video0")).unwrap_err();
        assert!(e.to_string().contains("--features v4l2"), "{e}");
    }
}
