//! The node's real window on a real X server: a face frame rendered on the
//! GPU is shown full screen by `showcase_render::window` in a child
//! process, the server's pixels are read back (a screenshot, X11
//! `GetImage` of the root window) and compared with the frame after the
//! device response (`CrtPhotometry::drive`, 8 bits).
//!
//! - One output on Xvfb's one screen.
//! - Two outputs on one PC: Xorg with its dummy video driver, configured
//!   with two monitors side by side (two CRTCs, as two video outputs of
//!   one card; Xvfb has one CRTC), each window on the monitor it names.
//!
//! Both servers come from `scripts/setup.sh`. Without one the test fails
//! when `CI` is set and otherwise says it skips, as the GPU tests do.

use super::gpu_or_skip;
use super::scenes::bench;
use anyhow::{Context, Result, bail, ensure};
use glam::Vec3;
use showcase_proto::{BeamSplitter, CrtPhotometry, CrtResponse};
use showcase_render::node::OutputImage;
use showcase_render::node::renderer::Renderer;
use showcase_render::render::bench::{bench_face, bench_frame};
use showcase_render::render::face_gpu::FaceRenderer;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
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
/// Each monitor of the two-output test (a mode of Xorg's own list; its
/// dummy driver takes no screen under 128 pixels high).
const MONITOR: (u32, u32) = (640, 480);

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

/// Start the X server `server` (which `-displayfd 1` makes print its
/// display number on stdout once it accepts connections); its display
/// number. `None`: `name` is not installed here and `CI` is not set.
fn start_x(mut server: Command, name: &str, procs: &mut Kill) -> Result<Option<u32>> {
    let spawned = server
        .args(["-displayfd", "1", "-nolisten", "tcp", "-noreset"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn();
    let mut child = match spawned {
        Ok(c) => c,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if std::env::var_os("CI").is_some() {
                bail!("{name} is not installed and CI is set (scripts/setup.sh installs it)");
            }
            eprintln!("skipping: {name} is not installed (scripts/setup.sh installs it)");
            return Ok(None);
        }
        Err(e) => return Err(e).with_context(|| format!("cannot start {name}")),
    };
    let out = child.stdout.take().context("the X server's stdout")?;
    procs.0.push(child);
    let mut line = String::new();
    BufReader::new(out)
        .read_line(&mut line)
        .with_context(|| format!("reading {name}'s display number"))?;
    let display = line
        .trim()
        .parse()
        .with_context(|| format!("{name} printed {line:?}, not a display number"))?;
    Ok(Some(display))
}

/// Xvfb with one screen of `size` and 24-bit colour.
fn xvfb(size: (u32, u32), procs: &mut Kill) -> Result<Option<u32>> {
    let mut server = Command::new("Xvfb");
    server
        .args(["-screen", "0"])
        .arg(format!("{}x{}x24", size.0, size.1));
    start_x(server, "Xvfb", procs)
}

/// The dummy driver's name of its `i`-th video output.
fn dummy_output(i: usize) -> String {
    format!("DUMMY{i}")
}

/// Xorg on its dummy video driver with `count` monitors of 640 x 480 (a
/// mode of the server's own list), side by side from the left, on
/// outputs [`dummy_output`] 0, 1, ...; its configuration and log go to
/// `dir`.
fn xorg_dummy(count: usize, dir: &Path, procs: &mut Kill) -> Result<Option<u32>> {
    let mut conf = String::from(
        "Section \"ServerFlags\"\n  Option \"DontVTSwitch\" \"true\"\n  \
         Option \"AllowMouseOpenFail\" \"true\"\n  Option \"PciForceNone\" \"true\"\n  \
         Option \"AutoEnableDevices\" \"false\"\n  Option \"AutoAddDevices\" \"false\"\n\
         EndSection\n\
         Section \"Device\"\n  Identifier \"card\"\n  Driver \"dummy\"\n  VideoRam 65536\n",
    );
    for i in 0..count {
        conf += &format!("  Option \"Monitor-{}\" \"monitor{i}\"\n", dummy_output(i));
    }
    conf += "EndSection\n";
    for i in 0..count {
        conf += &format!(
            "Section \"Monitor\"\n  Identifier \"monitor{i}\"\n  HorizSync 1.0 - 2000.0\n  \
             VertRefresh 1.0 - 200.0\n  Option \"PreferredMode\" \"{}x{}\"\n  \
             Option \"Enable\" \"true\"\n",
            MONITOR.0, MONITOR.1
        );
        conf += &if i == 0 {
            "  Option \"Primary\" \"true\"\n".to_string()
        } else {
            format!("  Option \"RightOf\" \"monitor{}\"\n", i - 1)
        };
        conf += "EndSection\n";
    }
    conf += &format!(
        "Section \"Screen\"\n  Identifier \"screen\"\n  Device \"card\"\n  Monitor \"monitor0\"\n  \
         DefaultDepth 24\n  SubSection \"Display\"\n    Depth 24\n    Virtual {} {}\n  \
         EndSubSection\nEndSection\n",
        count as u32 * MONITOR.0,
        MONITOR.1
    );
    let config = dir.join("xorg.conf");
    std::fs::write(&config, conf)?;
    let log = dir.join("xorg.log");
    let mut server = Command::new("Xorg");
    server
        .arg("-config")
        .arg(&config)
        .arg("-logfile")
        .arg(&log)
        .args(["-novtswitch", "-sharevts"]);
    // The scratch folder goes with the test: a failed start shows its
    // log's errors.
    start_x(server, "Xorg", procs).with_context(|| {
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        let errors: Vec<&str> = text.lines().filter(|l| l.contains("(EE)")).collect();
        format!("Xorg's log:\n{}", errors.join("\n"))
    })
}

/// The pixels of the root window's rectangle at `origin` of `size` as
/// RGB bytes (24-bit TrueColor, 32 bits a pixel: B, G, R, pad).
fn screenshot(display: u32, origin: (u32, u32), size: (u32, u32)) -> Result<Vec<[u8; 3]>> {
    let (conn, screen) = x11rb::connect(Some(&format!(":{display}")))
        .with_context(|| format!("cannot connect to X display :{display}"))?;
    let root = conn.setup().roots[screen].root;
    let reply = conn
        .get_image(
            ImageFormat::Z_PIXMAP,
            root,
            origin.0 as i16,
            origin.1 as i16,
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

/// A face frame of the render bench's scene with both eyes of `eye`,
/// rendered on the GPU: its linear pixels. `None`: no adapter here and
/// `CI` is not set.
fn face_frame(test: &str, eye: (u32, u32)) -> Result<Option<OutputImage>> {
    let Some(ctx) = gpu_or_skip(test)? else {
        return Ok(None);
    };
    let mut scene = bench()?;
    let mut face = bench_face(eye.0, eye.1);
    face.photometry = profile();
    scene.faces.push(face);
    let mut renderer = FaceRenderer::new(ctx, 0, 1, 256);
    renderer.set_scene(1, Arc::new(scene.clone()))?;
    let image = renderer
        .render(&bench_frame(&scene, "full", 0), &scene)?
        .image
        .context("a face renders an image")?;
    let size = (image.width, image.height);
    ensure!(size == (2 * eye.0, eye.1), "image {size:?}");
    ensure!(
        image.encoding == Some(profile()),
        "a face's image carries its profile"
    );
    Ok(Some(image))
}

/// The codes `image` shows with its profile, checked to be a frame the
/// screen could not show by chance: lit, and far from the linear values.
fn encoded(image: &OutputImage) -> Result<Vec<[u8; 3]>> {
    let encoding = image.encoding.context("the frame carries no profile")?;
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
    let changed = differing(&want, &linear);
    ensure!(
        changed > 1000,
        "the device response changes only {changed} pixels: it would not be seen"
    );
    Ok(want)
}

/// Pixels of two images whose codes differ by more than 8 in a channel.
fn differing(a: &[[u8; 3]], b: &[[u8; 3]]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 8))
        .count()
}

/// A child process showing `image` in its window on `monitor` of
/// `display`; its stderr goes to `dir/<monitor>.log`.
fn show(display: u32, image: &OutputImage, monitor: &str, dir: &Path) -> Result<(Child, PathBuf)> {
    let frame_file = dir.join(format!("{monitor}.json"));
    std::fs::write(
        &frame_file,
        serde_json::to_vec(&serde_json::json!({
            "width": image.width,
            "height": image.height,
            "rgba": image.rgba,
            "encoding": image.encoding,
        }))?,
    )?;
    let log = dir.join(format!("{monitor}.log"));
    let child = Command::new(std::env::current_exe()?)
        .args(["--ignored", "--exact", "render::window::child_window"])
        .env("DISPLAY", format!(":{display}"))
        .env_remove("WAYLAND_DISPLAY")
        .env(CHILD_FRAME, &frame_file)
        .env(CHILD_MONITOR, monitor)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log)?)
        .spawn()
        .context("cannot start the child window")?;
    Ok((child, log))
}

/// What one region of the screen must show.
struct Expected {
    /// Its top-left corner on the root window.
    origin: (u32, u32),
    size: (u32, u32),
    /// The codes, row by row.
    codes: Vec<[u8; 3]>,
}

/// Poll the screen until every region shows its codes within one (the
/// f32 arithmetic of the GPU and of `drive` may round a value the other
/// way), for at most 60 s; fail naming the region that does not, or a
/// child window (`procs` from index `first_child`, logs in `logs`) that
/// exited.
fn wait_until_shown(
    display: u32,
    expected: &[Expected],
    procs: &mut Kill,
    first_child: usize,
    logs: &[PathBuf],
) -> Result<()> {
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut worst = vec![(u8::MAX, usize::MAX); expected.len()];
    while Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(200));
        for (child, log) in procs.0[first_child..].iter_mut().zip(logs) {
            if let Some(status) = child.try_wait()? {
                bail!(
                    "a child window exited ({status}):\n{}",
                    std::fs::read_to_string(log).unwrap_or_default()
                );
            }
        }
        for (e, w) in expected.iter().zip(&mut worst) {
            let shot = screenshot(display, e.origin, e.size)?;
            let diffs: Vec<u8> = shot
                .iter()
                .zip(&e.codes)
                .map(|(a, b)| (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0))
                .collect();
            *w = (
                diffs.iter().copied().max().unwrap_or(0),
                diffs.iter().filter(|&&d| d > 1).count(),
            );
        }
        if worst.iter().all(|w| w.0 <= 1) {
            return Ok(());
        }
    }
    for (e, (worst, off)) in expected.iter().zip(worst) {
        ensure!(
            worst <= 1,
            "the screen at {:?} differs from the encoded frame by up to {worst} codes in {off} pixels",
            e.origin
        );
    }
    Ok(())
}

/// A scratch folder removed when the test ends.
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Result<Self> {
        let dir = std::env::temp_dir().join(format!("showcase-{test}-{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        Ok(Self(dir))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn the_window_shows_the_rendered_frame_after_the_device_response() -> Result<()> {
    let test = "the_window_shows_the_rendered_frame_after_the_device_response";
    // A face frame of the render bench's scene, with a mismatched CRT.
    let Some(image) = face_frame(test, EYE)? else {
        return Ok(());
    };
    let size = (image.width, image.height);
    let want = encoded(&image)?;
    let mut procs = Kill(Vec::new());
    let Some(display) = xvfb(size, &mut procs)? else {
        return Ok(());
    };
    let dir = Scratch::new("window")?;
    let (child, log) = show(display, &image, "screen", &dir.0)?;
    procs.0.push(child);
    let expected = Expected {
        origin: (0, 0),
        size,
        codes: want,
    };
    wait_until_shown(display, &[expected], &mut procs, 1, &[log])
}

/// Two outputs of one PC, as `deploy/cluster.toml` puts a face's and a
/// projector's node on one machine: each window fills the monitor its
/// node names, and each monitor shows its own node's frame.
#[test]
fn two_outputs_on_one_pc_each_fill_the_monitor_they_name() -> Result<()> {
    let test = "two_outputs_on_one_pc_each_fill_the_monitor_they_name";
    let Some(first) = face_frame(test, (MONITOR.0 / 2, MONITOR.1))? else {
        return Ok(());
    };
    // The second node's frame: the same pixels under another display's
    // profile, so the two monitors must show different codes.
    let second = OutputImage {
        encoding: Some(CrtPhotometry {
            crt: CrtResponse {
                gamma: Vec3::new(1.8, 2.0, 1.9),
                peak: Vec3::new(1.1, 1.2, 1.0),
                black_level: Vec3::splat(0.001),
            },
            ..profile()
        }),
        ..first.clone()
    };
    let frames = [first, second];
    let codes = [encoded(&frames[0])?, encoded(&frames[1])?];
    ensure!(
        differing(&codes[0], &codes[1]) > 1000,
        "the two frames show alike: a swapped monitor would pass"
    );
    let dir = Scratch::new("two-outputs")?;
    let mut procs = Kill(Vec::new());
    let Some(display) = xorg_dummy(2, &dir.0, &mut procs)? else {
        return Ok(());
    };
    // The second monitor's node starts first: a window that ignored its
    // monitor would take the primary one.
    let mut logs = Vec::new();
    let mut expected = Vec::new();
    for i in [1, 0] {
        let (child, log) = show(display, &frames[i], &dummy_output(i), &dir.0)?;
        procs.0.push(child);
        logs.push(log);
        expected.push(Expected {
            origin: (i as u32 * MONITOR.0, 0),
            size: MONITOR,
            codes: codes[i].clone(),
        });
    }
    wait_until_shown(display, &expected, &mut procs, 1, &logs)
}

/// The window of the tests above, in a process of its own (winit and the
/// X connection read `DISPLAY`): shows the frame in `CHILD_FRAME` on the
/// monitor `CHILD_MONITOR` until killed, again every 100 ms as a node
/// presents, for at most 120 s.
#[test]
#[ignore = "run as a child process by the window tests above"]
fn child_window() -> Result<()> {
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
