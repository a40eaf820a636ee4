//! The node's real window on a real X server (Xvfb): a face frame rendered
//! on the GPU is shown full screen by `showcase_render::window` in a child
//! process, the server's pixels are read back (a screenshot, X11
//! `GetImage` of the root window) and compared with the frame after the
//! device response (`CrtPhotometry::drive`, 8 bits).
//!
//! Xvfb comes from `scripts/setup.sh`. Without it the test fails when `CI`
//! is set and otherwise says it skips, as the GPU tests do.

use super::gpu_or_skip;
use super::scenes::bench;
use anyhow::{Context, Result, bail, ensure};
use glam::Vec3;
use showcase_proto::{BeamSplitter, CrtPhotometry, CrtResponse};
use showcase_render::node::renderer::Renderer;
use showcase_render::render::bench::{bench_face, bench_frame};
use showcase_render::render::face_gpu::FaceRenderer;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};
use x11rb::connection::Connection;
use x11rb::protocol::xproto::{ConnectionExt, ImageFormat};

/// The child reads the frame to show from this file.
const CHILD_FRAME: &str = "SHOWCASE_TEST_WINDOW_FRAME";
/// The child fills this monitor (`pick_monitor`: a name or an index).
const CHILD_MONITOR: &str = "SHOWCASE_TEST_WINDOW_MONITOR";
/// One eye's image; the face draws both side by side, so the screen is
/// twice as wide.
const EYE: (u32, u32) = (160, 120);

/// A CRT and splitter far from the identity, so that a window showing the
/// linear values, or another profile, cannot pass.
fn profile() -> CrtPhotometry {
    CrtPhotometry {
        crt: CrtResponse {
            gamma: Vec3::new(2.4, 2.2, 2.6),
            peak: Vec3::new(1.6, 1.4, 1.8),
            black_level: Vec3::splat(0.0005),
        },
        splitter: BeamSplitter {
            transmission: Vec3::new(0.6, 0.55, 0.5),
            reflection: Vec3::new(0.35, 0.4, 0.45),
        },
    }
}

/// Processes killed when the test ends, however it ends.
struct Kill(Vec<Child>);

impl Drop for Kill {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Start Xvfb with one screen of `size` and 24-bit colour; its display
/// number, once it accepts connections. `None`: no Xvfb here and `CI` is
/// not set.
fn xvfb(size: (u32, u32), procs: &mut Kill) -> Result<Option<u32>> {
    let spawned = Command::new("Xvfb")
        .args([
            "-displayfd",
            "1",
            "-nolisten",
            "tcp",
            "-noreset",
            "-screen",
            "0",
        ])
        .arg(format!("{}x{}x24", size.0, size.1))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn();
    let mut child = match spawned {
        Ok(c) => c,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if std::env::var_os("CI").is_some() {
                bail!("Xvfb is not installed and CI is set (scripts/setup.sh installs xvfb)");
            }
            eprintln!("skipping: Xvfb is not installed (scripts/setup.sh installs it)");
            return Ok(None);
        }
        Err(e) => return Err(e).context("cannot start Xvfb"),
    };
    let out = child.stdout.take().context("Xvfb's stdout")?;
    procs.0.push(child);
    // With -displayfd, Xvfb writes its display number once it is ready.
    let mut line = String::new();
    BufReader::new(out)
        .read_line(&mut line)
        .context("reading Xvfb's display number")?;
    let display = line
        .trim()
        .parse()
        .with_context(|| format!("Xvfb printed {line:?}, not a display number"))?;
    Ok(Some(display))
}

/// The root window's pixels as RGB bytes (24-bit TrueColor, 32 bits a
/// pixel: B, G, R, pad).
fn screenshot(display: u32, size: (u32, u32)) -> Result<Vec<[u8; 3]>> {
    let (conn, screen) = x11rb::connect(Some(&format!(":{display}")))
        .with_context(|| format!("cannot connect to X display :{display}"))?;
    let root = conn.setup().roots[screen].root;
    let reply = conn
        .get_image(
            ImageFormat::Z_PIXMAP,
            root,
            0,
            0,
            size.0 as u16,
            size.1 as u16,
            !0,
        )?
        .reply()?;
    let n = (size.0 * size.1) as usize;
    ensure!(
        reply.depth == 24 && reply.data.len() == 4 * n,
        "unexpected image: depth {}, {} bytes for {n} pixels",
        reply.depth,
        reply.data.len()
    );
    Ok(reply
        .data
        .chunks_exact(4)
        .map(|p| [p[2], p[1], p[0]])
        .collect())
}

/// The 8-bit code a channel value in `[0, 1]` is shown with.
fn code(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

#[test]
fn the_window_shows_the_rendered_frame_after_the_device_response() -> Result<()> {
    let test = "the_window_shows_the_rendered_frame_after_the_device_response";
    let Some(ctx) = gpu_or_skip(test)? else {
        return Ok(());
    };
    // A face frame of the render bench's scene, with a mismatched CRT.
    let mut scene = bench()?;
    let mut face = bench_face(EYE.0, EYE.1);
    face.photometry = profile();
    scene.faces.push(face);
    let mut renderer = FaceRenderer::new(ctx, 0, 1, 256);
    renderer.set_scene(1, Arc::new(scene.clone()))?;
    let image = renderer
        .render(&bench_frame(&scene, "full", 0), &scene)?
        .image
        .context("a face renders an image")?;
    let size = (image.width, image.height);
    ensure!(size == (2 * EYE.0, EYE.1), "image {size:?}");
    let encoding = image
        .encoding
        .context("a face's image carries its profile")?;
    ensure!(encoding == profile(), "the image carries another profile");
    let want: Vec<[u8; 3]> = image
        .rgba
        .iter()
        .map(|p| {
            let d = encoding.drive(Vec3::new(p[0], p[1], p[2]));
            [code(d.x), code(d.y), code(d.z)]
        })
        .collect();
    let linear: Vec<[u8; 3]> = image
        .rgba
        .iter()
        .map(|p| [code(p[0]), code(p[1]), code(p[2])])
        .collect();
    let lit = want.iter().filter(|p| p.iter().any(|&c| c > 40)).count();
    ensure!(lit > 1000, "the frame is nearly black ({lit} lit pixels)");
    let encoded_differs = want
        .iter()
        .zip(&linear)
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 8))
        .count();
    ensure!(
        encoded_differs > 1000,
        "the device response changes only {encoded_differs} pixels: it would not be seen"
    );

    let mut procs = Kill(Vec::new());
    let Some(display) = xvfb(size, &mut procs)? else {
        return Ok(());
    };
    let dir = std::env::temp_dir().join(format!("showcase-window-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let frame_file = dir.join("frame.json");
    std::fs::write(
        &frame_file,
        serde_json::to_vec(&serde_json::json!({
            "width": image.width,
            "height": image.height,
            "rgba": image.rgba,
            "encoding": encoding,
        }))?,
    )?;
    let log = dir.join("child.log");
    procs.0.push(
        Command::new(std::env::current_exe()?)
            .args(["--ignored", "--exact", "render::window::child_window"])
            .env("DISPLAY", format!(":{display}"))
            .env_remove("WAYLAND_DISPLAY")
            .env(CHILD_FRAME, &frame_file)
            .env(CHILD_MONITOR, "screen")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log)?)
            .spawn()
            .context("cannot start the child window")?,
    );

    // The window shows the frame once it is set up: poll the screen.
    let deadline = Instant::now() + Duration::from_secs(60);
    let (mut worst, mut off) = (u8::MAX, usize::MAX);
    while Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(200));
        if let Some(status) = procs.0[1].try_wait()? {
            bail!(
                "the child window exited ({status}):\n{}",
                std::fs::read_to_string(&log).unwrap_or_default()
            );
        }
        let shot = screenshot(display, size)?;
        let diffs: Vec<u8> = shot
            .iter()
            .zip(&want)
            .map(|(a, b)| (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0))
            .collect();
        worst = diffs.iter().copied().max().unwrap_or(0);
        off = diffs.iter().filter(|&&d| d > 1).count();
        if worst <= 1 {
            break;
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    // Every pixel within one code: the f32 arithmetic of the GPU and of
    // `drive` may round a value the other way.
    ensure!(
        worst <= 1,
        "the screen differs from the encoded frame by up to {worst} codes in {off} pixels"
    );
    Ok(())
}

/// The window of the test above, in a process of its own (winit and the
/// X connection read `DISPLAY`): shows the frame in `CHILD_FRAME` on the
/// monitor `CHILD_MONITOR` until killed, again every 100 ms as a node
/// presents, for at most 120 s.
#[test]
#[ignore = "run as a child process by the_window_shows_the_rendered_frame_after_the_device_response"]
fn child_window() -> Result<()> {
    use showcase_render::node::OutputImage;
    use showcase_render::node::present::FrameSink;
    let file = std::env::var(CHILD_FRAME).context("only the window test runs this")?;
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(Path::new(&file))?)?;
    let image = OutputImage {
        width: serde_json::from_value(v["width"].clone())?,
        height: serde_json::from_value(v["height"].clone())?,
        rgba: serde_json::from_value(v["rgba"].clone())?,
        encoding: Some(serde_json::from_value(v["encoding"].clone())?),
    };
    let monitor = std::env::var(CHILD_MONITOR).ok();
    let (event_loop, sink) = showcase_render::window::event_loop()?;
    let mut feed = sink.clone();
    std::thread::spawn(move || {
        for frame in 0..1200 {
            if feed.show(frame, image.clone()).is_err() {
                return;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        feed.quit();
    });
    showcase_render::window::run(event_loop, "showcase window test", monitor.as_deref(), None)?;
    Ok(())
}
